"""One exception tree for optik, rooted at :class:`OptikError` (a ``ValueError``).

Every error keeps the data it is about as attributes, so callers can react to it
without parsing the message.
"""

from __future__ import annotations

import math
import re
from collections.abc import Sequence
from typing import Any


class OptikError(ValueError):
    """Base class of every error raised by optik."""


class ShapeError(OptikError):
    """An array argument has the wrong shape."""

    def __init__(
        self, name: str, expected: str, got: tuple[int, ...], detail: str | None = None
    ) -> None:
        self.name = name
        self.expected = expected
        self.got = tuple(got)
        # ``detail`` says what is wrong where the shape is right (a pose's last row).
        message = detail if detail is not None else f"expected shape {expected}, got {self.got}"
        super().__init__(f"{name}: {message}")


class NonFiniteError(OptikError):
    """An array argument holds NaN or infinity where finite values are required."""

    def __init__(self, name: str, index: tuple[int, ...] | None = None) -> None:
        self.name = name
        # Plain ints: a numpy index would print as (np.int64(0),).
        self.index = None if index is None else tuple(int(i) for i in index)
        where = f" at index {self.index}" if self.index is not None else ""
        super().__init__(f"{name}: values must be finite, found NaN or inf{where}")


class InvalidRotationError(OptikError):
    """A 3x3 block is not a proper rotation (orthonormal with det +1)."""

    def __init__(self, name: str, orthogonality_error: float, determinant: float) -> None:
        self.name = name
        self.orthogonality_error = orthogonality_error
        self.determinant = determinant
        super().__init__(
            f"{name}: not a rotation matrix (max |R^T R - I| = {orthogonality_error:.3g}, "
            f"det = {determinant:.6g}; need <= 1e-6 and det = +1)"
        )


class ModelError(OptikError):
    """A robot description is inconsistent (joint types, parameters, limits)."""


class InvalidLimitsError(ModelError):
    """A joint's lower limit exceeds its upper limit, or a limit is NaN."""

    def __init__(self, joint: str, lower: Any, upper: Any, reason: str = "") -> None:
        self.joint = joint
        self.lower = lower
        self.upper = upper
        detail = reason or "lower > upper"
        shown = f"{_cut(lower)}, {_cut(upper)}"
        super().__init__(f"joint {joint!r}: invalid limits [{shown}] ({detail})")


def _cut(value: Any, most: int = 40) -> str:
    """``value`` as given, cut to ``most`` characters (an integer of 400 digits)."""
    text = str(value)
    return text if len(text) <= most else text[:most] + "..."


class URDFError(ModelError):
    """A URDF document cannot be turned into a serial chain."""


class JointLimitError(OptikError):
    """A joint value lies outside its limits.

    The message prints the value and the limits to every digit (shortest round-trip
    ``repr``) and the excess beyond the nearer limit: rounded to six digits, a value 2e-6
    above a limit of 2.89725 read as inside it.
    """

    def __init__(
        self, joint: str, value: float, lower: float, upper: float,
        unit: str = "rad or m", argument: str = "",
    ) -> None:  # fmt: skip
        self.joint = joint
        self.value = value
        self.lower = lower
        self.upper = upper
        x, lo, hi = float(value), float(lower), float(upper)
        excess = max(lo - x, x - hi)
        by = f" by {excess:.3g} {unit}" if math.isfinite(excess) else ""
        where = f"{argument}: " if argument else ""  # the argument that holds the value
        super().__init__(
            f"{where}joint {joint!r}: value {x!r} outside its limits [{lo!r}, {hi!r}] ({unit}){by}"
        )


class ProblemFileError(OptikError):
    """A problem file is malformed; the message names the file, the table and the field."""

    def __init__(self, path: str, table: str, field: str, message: str) -> None:
        self.path = path
        self.table = table
        self.field = field
        self.detail = message
        # The whole file (no table, no field) needs no location: "file not found".
        location = f"[{table}]" if table else ("(top level)" if field else "")
        field_part = f" field {field!r}" if field else ""
        where = f"{location}{field_part}"
        super().__init__(f"{path}: {where}: {message}" if where else f"{path}: {message}")


class SingularMatrixError(OptikError):
    """A matrix is rank deficient (or numerically so) for the requested inverse."""

    def __init__(self, condition_number: float, message: str = "") -> None:
        self.condition_number = condition_number
        text = message or "matrix is singular or too ill-conditioned"
        super().__init__(f"{text} (condition number {condition_number:.3g})")


class NoSolutionError(OptikError):
    """A program has no feasible point; ``program`` holds it for inspection."""

    def __init__(self, message: str, program: Any = None) -> None:
        self.program = program
        super().__init__(message)


class UnknownSolverError(OptikError):
    """A solver name is not registered or its backend is not installed."""

    def __init__(self, name: str, available: Sequence[str], hint: str = "") -> None:
        self.name = name
        self.available = list(available)
        extra = f" {hint}" if hint else ""
        super().__init__(f"unknown solver {name!r}; installed: {', '.join(self.available)}.{extra}")


class SolverError(OptikError):
    """A backend raised while solving; its message is kept."""

    def __init__(self, solver: str, message: str) -> None:
        self.solver = solver
        self.backend_message = message
        super().__init__(f"solver {solver!r} failed: {message}")


class AnalyticIKError(OptikError):
    """A robot has no closed-form family, or the family does not fit the robot."""


class OutputFileError(OptikError):
    """A file cannot be written where asked (a folder there, a file as parent, no access)."""

    def __init__(self, path: str, reason: str) -> None:
        self.path = path
        self.reason = reason
        super().__init__(f"cannot write {path}: {reason}")


class ResultsFileError(OptikError):
    """A results table is malformed; the message names the file and the line (1-based)."""

    def __init__(self, path: str, line: int, message: str) -> None:
        self.path = path
        self.line = line
        self.detail = message
        super().__init__(f"{path}, line {line}: {message}")


class ArgumentError(OptikError):
    """An argument has the wrong type or a value outside its allowed range.

    Attributes:
        name: the argument's name.
        value: the value given.
        expected: what the argument must be, in words.
    """

    def __init__(self, name: str, value: Any, expected: str) -> None:
        self.name = name
        self.value = value
        self.expected = expected
        super().__init__(f"{name}: expected {expected}, got {_show(value)}")


class KernelCacheWarning(UserWarning):
    """numba has nowhere to keep optik's compiled kernels: each process compiles them.

    Given once, at import, when optik's ``__pycache__`` folders, ``NUMBA_CACHE_DIR`` and
    the user's cache folder all cannot be written; set ``NUMBA_CACHE_DIR`` to a folder
    the user can write.
    """


def _show(value: Any, limit: int = 80) -> str:
    """``repr`` of ``value`` with its type, on one line, cut to ``limit`` characters.

    An array's repr can be huge, and spans lines: each line break and the indent after it
    become one space, so that a message stays one line.
    """
    text = re.sub(r"\n\s*", " ", repr(value))
    if len(text) > limit:
        text = text[: limit - 3] + "..."
    return f"{text} ({type(value).__name__})"
