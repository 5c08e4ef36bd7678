"""Input validation shared by every layer: types, ranges, shapes and finiteness.

Every public entry point checks its arguments here, so that bad input raises an
:class:`~optik.errors.OptikError` naming the argument and showing the value, never a
bare ``TypeError``, a NaN or a silently changed answer:

- :func:`check_real`, :func:`check_int`, :func:`check_bool`, :func:`check_choice` and
  :func:`check_length` for scalars (a ``bool`` is never taken for a number, nor the
  string ``"false"`` for a boolean);
- :func:`as_float_array`, :func:`check_finite`, :func:`finite_array` and
  :func:`check_length_array` for arrays (complex, bool, string and object arrays of
  non-numbers are rejected, never cast);
- :func:`not_a_file` for an input file that cannot be read.

Lengths are bounded by :data:`MAX_LENGTH_M`.
"""

from __future__ import annotations

import math
import numbers
from collections.abc import Collection
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from optik.errors import ArgumentError, NonFiniteError, ShapeError

FloatArray = NDArray[np.float64]

MAX_LENGTH_M = 1e9
"""Largest accepted magnitude of a length (m).

Applies to DH ``a`` and ``d``, URDF origins, tool and base translations, prismatic joint
ranges and joint values, path and target coordinates. The solvers form squared distances
and sums of squares of lengths, which overflow to ``inf`` near 1e154 m; 1e9 m (beyond the
Moon's orbit) leaves a wide margin for those products and for sums over long chains,
while every real arm is far inside it. At 1e9 m a float64 still resolves 1e-7 m.
"""

_NUMERIC_KINDS = "fiu"


def read_number(text: str, kind: type = float) -> Any:
    """``float(text)`` (or ``int``) of a file's or command line's number, Python's own syntax out.

    Python reads ``"1_0"`` as 10 (digit grouping in code), and the digits of every script
    (``"٠.٥"``, ``"０.２"``); in a path file, a URDF (urdfdom reads neither) or an option
    they are typos or a locale's digits, not plain decimal numbers.

    Raises:
        ValueError: an underscore or a character beyond ASCII in ``text``, or what
            ``kind(text)`` raises.
    """
    if "_" in text:
        raise ValueError(f"an underscore in the number {text!r}")
    if not text.isascii():
        raise ValueError(f"not a plain decimal number: {text!r}")
    return kind(text)


def _ragged(name: str, value: Any) -> ShapeError:
    """The error for nested sequences of different lengths, naming the lengths."""
    try:
        lengths = [len(row) if hasattr(row, "__len__") else "a number" for row in value]
    except TypeError:
        lengths = []
    detail = "expected rows of equal length, got a ragged sequence"
    if len({str(n) for n in lengths}) < 2:  # ragged deeper down: no lengths to show
        return ShapeError(name, "regular", (), detail)
    shown = ", ".join(str(n) for n in lengths[:8]) + (", ..." if len(lengths) > 8 else "")
    return ShapeError(name, "regular", (), f"{detail} (row lengths {shown})")


def _is_real_scalar(value: Any) -> bool:
    """A real number that is not a bool (Python or numpy)."""
    return isinstance(value, numbers.Real) and not isinstance(value, bool | np.bool_)


def check_real(
    name: str,
    value: Any,
    *,
    allow_nan: bool = False,
    allow_inf: bool = False,
    positive: bool = False,
    nonnegative: bool = False,
    minimum: float | None = None,
    maximum: float | None = None,
) -> float:
    """Return ``value`` as a float after checking it is a real number in range.

    Args:
        name: argument name used in error messages.
        value: an ``int``, ``float`` or numpy real scalar (or a 0-d real array); ``bool``,
            complex, strings and ``None`` are rejected.
        allow_nan: accept NaN.
        allow_inf: accept ``+inf`` and ``-inf``.
        positive: require ``value > 0``.
        nonnegative: require ``value >= 0``.
        minimum: require ``value >= minimum``.
        maximum: require ``value <= maximum``.

    Raises:
        ArgumentError: wrong type or out of range; the message names ``name`` and shows
            the value.
    """
    raw = value
    if isinstance(value, np.ndarray) and value.ndim == 0 and value.dtype.kind in _NUMERIC_KINDS:
        value = value.item()
    if not _is_real_scalar(value):
        raise ArgumentError(name, raw, "a real number")
    try:
        number = float(value)
    except (OverflowError, TypeError, ValueError) as exc:
        raise ArgumentError(name, raw, "a real number representable as a float") from exc
    if math.isnan(number) and not allow_nan:
        raise ArgumentError(name, raw, "a number, not NaN")
    if math.isinf(number) and not allow_inf:
        raise ArgumentError(name, raw, "a finite number")
    if not math.isnan(number):
        if positive and not number > 0:
            raise ArgumentError(name, raw, "a positive number")
        if nonnegative and not number >= 0:
            raise ArgumentError(name, raw, "a number >= 0")
        _check_range(name, raw, number, (minimum, maximum), "a number", "g")
    return number


def _check_range(
    name: str,
    raw: Any,
    number: float,
    bounds: tuple[float | None, float | None],
    what: str,
    spec: str = "",
) -> None:
    """Raise :class:`ArgumentError` when ``number`` lies outside ``bounds`` (either ``None``).

    The message asks for ``what >= minimum`` (or ``<= maximum``), the bound formatted
    with ``spec`` (``"g"`` for real numbers, ``""`` for integers).
    """
    minimum, maximum = bounds
    if minimum is not None and number < minimum:
        raise ArgumentError(name, raw, f"{what} >= {minimum:{spec}}")
    if maximum is not None and number > maximum:
        raise ArgumentError(name, raw, f"{what} <= {maximum:{spec}}")


def check_int(
    name: str, value: Any, *, minimum: int | None = None, maximum: int | None = None
) -> int:
    """Return ``value`` as an int after checking it is an integer in ``[minimum, maximum]``.

    A float with an integral value (``3.0``) is accepted; ``bool``, a float with a
    fractional part, NaN, infinity and strings are rejected.

    Raises:
        ArgumentError: wrong type or out of range.
    """
    raw = value
    if isinstance(value, np.ndarray) and value.ndim == 0 and value.dtype.kind in _NUMERIC_KINDS:
        value = value.item()
    if isinstance(value, numbers.Integral) and not isinstance(value, bool | np.bool_):
        number = int(value)
    elif _is_real_scalar(value) and math.isfinite(float(value)) and float(value).is_integer():
        number = int(float(value))
    else:
        raise ArgumentError(name, raw, "an integer")
    _check_range(name, raw, number, (minimum, maximum), "an integer")
    return number


def check_bool(name: str, value: Any) -> bool:
    """Return ``value`` if it is a real boolean (``True``/``False``, or a numpy bool).

    Strings such as ``"false"`` and integers such as ``0`` are rejected: a truthiness
    test would take ``"false"`` for true.

    Raises:
        ArgumentError: not a boolean.
    """
    if not isinstance(value, bool | np.bool_):
        raise ArgumentError(name, value, "true or false (a boolean)")
    return bool(value)


def check_progress(value: Any, *, flag: bool = True, call: bool = True) -> Any:
    """Return a ``progress`` option: ``None``, a boolean (``flag``) or a callable (``call``).

    A callable is called as ``progress(done, total)``; a boolean turns a progress bar on or
    off (``None``: drawn when stderr is a terminal). Checked before any work is done, so
    that a wrong value is not found after the first step.

    Raises:
        ArgumentError: anything else.
    """
    if value is None:
        return None
    if flag and isinstance(value, bool | np.bool_):
        return bool(value)
    if call and callable(value):
        return value
    kinds = ["None"] + ["true or false"] * flag + ["a callable progress(done, total)"] * call
    raise ArgumentError("progress", value, ", ".join(kinds[:-1]) + " or " + kinds[-1])


def check_choice(name: str, value: Any, options: Collection[str]) -> str:
    """Return ``value`` if it is one of the strings ``options``.

    Raises:
        ArgumentError: not a string, or not among ``options`` (listed in the message).
    """
    if not isinstance(value, str) or value not in options:
        listed = ", ".join(repr(o) for o in options)
        raise ArgumentError(name, value, f"one of {listed}")
    return value


def check_length(name: str, value: Any, *, nonnegative: bool = False) -> float:
    """A finite length (m) of magnitude at most :data:`MAX_LENGTH_M`.

    Raises:
        ArgumentError: not a real number, not finite, or too large.
    """
    number = check_real(name, value, nonnegative=nonnegative)
    if abs(number) > MAX_LENGTH_M:
        raise ArgumentError(name, value, f"a length of magnitude <= {MAX_LENGTH_M:g} m")
    return number


def check_length_array(name: str, array: FloatArray, unit: str = "m") -> FloatArray:
    """Raise unless every entry of a finite array has magnitude <= :data:`MAX_LENGTH_M`.

    ``unit`` names the entries' unit in the message (``"m"``; ``"rad or m"`` for joint
    values).
    """
    if array.size and float(np.max(np.abs(array))) > MAX_LENGTH_M:
        index = tuple(int(i) for i in np.unravel_index(np.argmax(np.abs(array)), array.shape))
        what = "a length" if unit == "m" else "a value"
        raise ArgumentError(
            f"{name}{list(index)}" if index else name,
            float(array[index]),
            f"{what} of magnitude <= {MAX_LENGTH_M:g} {unit}",
        )
    return array


def finite_length_array(
    name: str, value: Any, trailing: tuple[int, ...], batch: bool = False, unit: str = "m"
) -> FloatArray:
    """:func:`finite_array` whose entries are also bounded by :data:`MAX_LENGTH_M`.

    For joint values and coordinates: a quick test accepts the common case, the exact
    checks run only to name a bad entry.

    Raises:
        ShapeError, ArgumentError, NonFiniteError: as :func:`finite_array`, and
            ArgumentError for an entry of magnitude above :data:`MAX_LENGTH_M`.
    """
    array = _shaped(name, value, trailing, batch)
    if _all_within(array, MAX_LENGTH_M):
        return array
    return check_length_array(name, check_finite(name, array), unit)


def _has_bool(value: Any) -> bool:
    """Whether a nested list/tuple holds a bool (numpy casts ``[True, 0.5]`` silently)."""
    try:
        items = np.asarray(value, dtype=object).ravel()
    except (TypeError, ValueError):
        return False
    return any(isinstance(item, bool | np.bool_) for item in items.tolist())


def as_float_array(name: str, value: Any) -> FloatArray:
    """Convert ``value`` to a float64 array, rejecting what is not an array of reals.

    Integer and float inputs convert; NaN and infinities pass (see :func:`check_finite`).

    Raises:
        ShapeError: ragged input (rows of different lengths).
        ArgumentError: ``None``, complex, boolean, string or datetime input, or an object
            array holding something other than real numbers.
    """
    if value is None:
        raise ArgumentError(name, value, "a numeric array")
    try:
        array = value if isinstance(value, np.ndarray) else np.asarray(value)
    except (TypeError, ValueError) as exc:
        raise _ragged(name, value) from exc
    kind = array.dtype.kind
    if kind == "c":
        raise ArgumentError(name, value, "a real array (complex values are not accepted)")
    if kind == "b":
        raise ArgumentError(name, value, "a numeric array (booleans are not numbers here)")
    if kind == "O":
        items = array.ravel().tolist()
        if not all(_is_real_scalar(item) for item in items):
            if any(isinstance(item, list | tuple | np.ndarray) for item in items):
                raise _ragged(name, value)
            raise ArgumentError(name, value, "an array of real numbers")
    elif kind not in _NUMERIC_KINDS:
        raise ArgumentError(name, value, "a numeric array")
    elif not isinstance(value, np.ndarray) and array.size and _has_bool(value):
        raise ArgumentError(name, value, "a numeric array (booleans are not numbers here)")
    try:
        return np.asarray(array, dtype=np.float64)
    except (OverflowError, TypeError, ValueError) as exc:
        raise ArgumentError(name, value, "an array of real numbers") from exc


_SMALL = 64  # below this many entries a Python loop beats a numpy call's overhead


def _all_within(array: FloatArray, bound: float) -> bool:
    """Whether every entry is finite with magnitude <= ``bound`` (a quick, exact test).

    Large arrays use two reductions (a NaN makes both fail). Not a dot product: BLAS
    may hand a long one to its threads, which costs milliseconds on a busy machine.
    """
    if array.size <= _SMALL:
        return all(-bound <= x <= bound for x in array.reshape(-1).tolist())
    flat = array.reshape(-1)
    return bool(flat.max() <= bound) and bool(flat.min() >= -bound)


def check_finite(name: str, array: FloatArray) -> FloatArray:
    """Raise :class:`NonFiniteError` naming the first NaN/inf entry of ``array``."""
    # The quick test proves the common case (all finite and below 1e150); the exact
    # test runs only when it fails.
    if array.dtype == np.float64 and _all_within(array, 1e150):
        return array
    if not np.isfinite(array).all():
        bad = np.argwhere(~np.isfinite(array))[0]
        raise NonFiniteError(name, tuple(int(i) for i in bad))
    return array


def finite_array(
    name: str, value: Any, trailing: tuple[int, ...], batch: bool = False
) -> FloatArray:
    """Return ``value`` as a finite float64 array of shape ``trailing`` (or ``(N, *trailing)``).

    Args:
        name: argument name used in error messages.
        value: array-like input (see :func:`as_float_array` for what is rejected).
        trailing: required trailing shape, e.g. ``(4, 4)``.
        batch: also accept one leading batch axis.

    Raises:
        ShapeError: wrong shape or ragged input.
        ArgumentError: not an array of real numbers.
        NonFiniteError: a NaN or infinite entry.
    """
    return check_finite(name, _shaped(name, value, trailing, batch))


def _shaped(name: str, value: Any, trailing: tuple[int, ...], batch: bool) -> FloatArray:
    array = as_float_array(name, value)
    nd = len(trailing)
    ok = array.shape == trailing or (batch and array.ndim == nd + 1 and array.shape[1:] == trailing)
    if not ok:
        dims = ", ".join(str(t) for t in trailing)
        alone = f"({dims},)" if nd == 1 else f"({dims})"  # written as numpy writes shapes
        expected = alone + (f" or (N, {dims})" if batch else "")
        raise ShapeError(name, expected, array.shape)
    return array


def not_a_file(path: Path) -> str:
    """Why ``path``, which is no file, cannot be read: a folder, or not found.

    A name the system cannot look up (too long, a NUL) counts as not found.
    """
    try:
        folder = path.is_dir()
    except (OSError, ValueError):
        folder = False
    return "a folder, not a file" if folder else "file not found"
