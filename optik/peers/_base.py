"""What every peer adapter is: an import check, a model check per robot, then queries.

An adapter turns one query (a 4x4 target pose of the tool in the world frame, a start
``q0`` inside the limits) into a joint vector in optik's joint order and units (rad, m).
It never judges its own answer: the caller verifies every ``q`` with optik's forward
kinematics and limits (:func:`optik.verify.verify`). Before its first query on a robot
the adapter builds the peer's model and checks that it *is* optik's model — the peer's
forward kinematics equal optik's at random in-limit configurations to
:data:`FK_MATCH_TOL` — or raises :class:`PeerUnavailable` with the reason.
"""

from __future__ import annotations

import importlib
import importlib.metadata
import math
import time
from abc import ABC, abstractmethod
from collections.abc import Callable
from dataclasses import dataclass, field, fields
from typing import Any, ClassVar, Final

import numpy as np

from optik._checks import FloatArray
from optik._interrupts import reraise_interrupt
from optik.errors import OptikError
from optik.model import Robot

__all__ = ["FK_MATCH_TOL", "Peer", "PeerAnswer", "PeerUnavailable", "fk_mismatch"]

#: Largest difference (m, or entry of a rotation matrix) between a peer's forward
#: kinematics and optik's at random configurations before the peer's model is rejected.
FK_MATCH_TOL: Final[float] = 1e-9


class PeerUnavailable(OptikError):
    """A peer cannot run: its package does not import, or it cannot model this robot.

    Attributes:
        peer: the peer's registry name.
        reason: why, in one sentence.
    """

    def __init__(self, peer: str, reason: str) -> None:
        self.peer = peer
        self.reason = reason
        super().__init__(f"peer {peer!r} unavailable: {reason}")


@dataclass(frozen=True)
class PeerAnswer:
    """A peer's answer to one query, before any verification.

    Attributes:
        q: joint vector (dof,) in optik's order and units (rad, m), or ``None`` when the
            peer returned no answer.
        iterations: the peer's own iteration count over every attempt; ``None`` when it
            reports none.
        claimed: the peer's own success flag; ``None`` when it makes no claim. Recorded
            beside optik's verdict, never used as it.
        note: a short remark (a backend exception's text, ``"no branch inside the limits"``).
    """

    q: FloatArray | None
    iterations: int | None = None
    claimed: bool | None = None
    note: str = ""


def fk_mismatch(
    fk: Callable[[FloatArray], Any], robot: Robot, count: int = 20, seed: int = 12345
) -> float:
    """Largest entry of ``|fk(q) - robot.fk(q)|`` over ``count`` random in-limit ``q``.

    Joints without limits draw in [-pi, pi]. A peer FK that raises, or returns something
    that is not a finite 4x4, counts as an infinite mismatch.
    """
    rng = np.random.default_rng(seed)
    lower = np.where(np.isfinite(robot.lower), robot.lower, -math.pi)
    upper = np.where(np.isfinite(robot.upper), robot.upper, math.pi)
    worst = 0.0
    for _ in range(count):
        q = rng.uniform(lower, upper)
        T = np.asarray(fk(q), dtype=float)
        if T.shape != (4, 4) or not np.all(np.isfinite(T)):
            return math.inf
        worst = max(worst, float(np.abs(T - robot.fk(q)).max()))
    return worst


@dataclass(eq=False)
class Peer(ABC):
    """One peer IK method: :meth:`load` once, :meth:`prepare` per robot, then :meth:`solve`.

    Subclasses are dataclasses (``@dataclass(eq=False, kw_only=True)``): they set the
    class attributes, declare their options as fields after the three shared ones (an
    option whose default is a number is stored as that kind of number) and their own
    state as fields with ``init=False, repr=False``, and implement :meth:`_prepare` and
    :meth:`solve`.

    Attributes:
        name: registry name (``"rtb"``, ``"ikpy"``...).
        module: the module whose import means "installed".
        distribution: the pip name of the package (its version is recorded).
        title: what the method is, for reports (``"Robotics Toolbox ETS.ik_LM"``).
        tol: the protocol's tolerance, m and rad: each adapter turns it into its own
            stopping criterion (stated in :meth:`settings`).
        seed: seed of the peer's random restarts.
        timeout_s: no new restart starts once a query has run this long, s (``None``: no
            limit); one attempt in progress is not interrupted.
        version: the installed version, after :meth:`load`.
        notes: remarks on the model of the last :meth:`prepare` (FK check, limits copied).
    """

    name: ClassVar[str]
    module: ClassVar[str]
    distribution: ClassVar[str]
    title: ClassVar[str]
    #: Whether the peer reports its own iteration counts.
    reports_iterations: ClassVar[bool] = True
    #: The model check's bound on ``|fk_peer - fk_optik|`` (m, or rotation entry).
    fk_tol: ClassVar[float] = FK_MATCH_TOL

    tol: float = 1e-6
    seed: int = 0
    timeout_s: float | None = None
    version: str = field(default="", init=False)
    notes: list[str] = field(default_factory=list, init=False)
    _robot: Robot | None = field(default=None, init=False, repr=False)
    _rng: np.random.Generator = field(init=False, repr=False)

    def __post_init__(self) -> None:
        if not (self.tol > 0 and math.isfinite(self.tol)):
            raise OptikError(f"tol must be positive and finite, got {self.tol!r}")
        if self.timeout_s is not None and not (self.timeout_s > 0):
            raise OptikError(f"timeout_s must be positive or None, got {self.timeout_s!r}")
        for option in fields(self):  # 10.0 or numpy.int64(10) as 10: settings are JSON
            if option.init and isinstance(option.default, int | float):
                setattr(self, option.name, type(option.default)(getattr(self, option.name)))
        self._rng = np.random.default_rng(self.seed)

    def load(self) -> None:
        """Import the peer's package and record its version.

        Raises:
            PeerUnavailable: the import fails (any exception: a missing package, a binary
                built for another numpy...), with the exception's text.
        """
        try:
            importlib.import_module(self.module)
        except Exception as exc:  # any import-time failure means "not usable here"
            raise PeerUnavailable(
                self.name,
                f"import {self.module} failed ({type(exc).__name__}: {exc}); "
                f"pip install {self.distribution} (or optik[peers])",
            ) from exc
        try:
            self.version = importlib.metadata.version(self.distribution)
        except importlib.metadata.PackageNotFoundError:
            self.version = "unknown"

    def prepare(self, robot: Robot) -> list[str]:
        """Build the peer's model of ``robot`` and check its FK against optik's.

        Args:
            robot: the robot to model.

        Returns:
            Notes on the model (where it came from, the FK difference found).

        Raises:
            PeerUnavailable: the peer is not installed or cannot model this robot (a
                joint type it lacks, a chain it has no solver for, an FK that differs).
        """
        if not self.version:
            self.load()
        self._robot = None
        try:
            notes = self._prepare(robot)
        except PeerUnavailable:
            raise
        except Exception as exc:  # the peer's own failure to build a model
            reraise_interrupt(exc)  # Ctrl-C is the caller's, not a failure
            raise PeerUnavailable(
                self.name, f"model construction failed: {type(exc).__name__}: {exc}"
            ) from exc
        self._robot = robot
        self.notes = notes
        return notes

    @property
    def robot(self) -> Robot:
        """The robot of the last successful :meth:`prepare`.

        Raises:
            OptikError: :meth:`prepare` has not succeeded yet.
        """
        if self._robot is None:
            raise OptikError(f"peer {self.name!r}: call prepare(robot) before solve")
        return self._robot

    def check_fk(self, fk: Callable[[FloatArray], Any], robot: Robot, what: str) -> str:
        """Compare ``fk`` with optik's; returns the note, raises when they differ.

        Args:
            fk: the peer's FK: joint values (dof,), rad or m, to the tool pose (4, 4), m.
            robot: the robot the peer models.
            what: the model's description, at the head of the note and of the error.

        Raises:
            PeerUnavailable: the largest difference exceeds :attr:`fk_tol`
                (:data:`FK_MATCH_TOL` unless the peer computes in lower precision).
        """
        mismatch = fk_mismatch(fk, robot)
        if not mismatch <= self.fk_tol:
            raise PeerUnavailable(
                self.name,
                f"{what}: FK differs from optik's by {mismatch:.2e} (> {self.fk_tol:g})",
            )
        return f"{what}: FK = optik FK (max difference {mismatch:.1e}, bound {self.fk_tol:g})"

    def reseed(self, seed: int) -> None:
        """Restart the random restarts from ``seed`` (a run reseeds before each target).

        Args:
            seed: seed of the random restarts, no unit.
        """
        self.seed = int(seed)
        self._rng = np.random.default_rng(self.seed)

    def out_of_time(self, start_time: float) -> bool:
        """Whether a query begun at ``start_time`` (``time.perf_counter``) is past ``timeout_s``.

        Args:
            start_time: the query's start, s, a ``time.perf_counter()`` reading.
        """
        return self.timeout_s is not None and time.perf_counter() - start_time > self.timeout_s

    def settings(self) -> dict[str, Any]:
        """The options that define this peer's rows (JSON-able), stopping rule included."""
        return {"tol": self.tol}

    @abstractmethod
    def _prepare(self, robot: Robot) -> list[str]:
        """Build and check the model (see :meth:`prepare`)."""

    @abstractmethod
    def solve(self, T_target: FloatArray, q0: FloatArray) -> PeerAnswer:
        """Answer one query (timed by the caller).

        Args:
            T_target: (4, 4) target pose of the tool in the world frame, m.
            q0: (dof,) start inside the limits, rad or m.
        """


def random_start(robot: Robot, rng: np.random.Generator) -> FloatArray:
    """A uniform in-limit configuration (joints without limits in [-pi, pi])."""
    lower = np.where(np.isfinite(robot.lower), robot.lower, -math.pi)
    upper = np.where(np.isfinite(robot.upper), robot.upper, math.pi)
    return rng.uniform(lower, upper)


def wrap_into_limits(
    q: FloatArray, lower: FloatArray, upper: FloatArray, q_ref: FloatArray
) -> FloatArray | None:
    """Move each angle by whole turns into ``[lower, upper]``, nearest ``q_ref``.

    Returns:
        The wrapped vector, or ``None`` when some angle has no turn inside its range.
    """
    out = np.empty_like(q)
    for i, (a, lo, hi, ref) in enumerate(zip(q, lower, upper, q_ref, strict=True)):
        k_lo = -math.inf if math.isinf(lo) else math.ceil((lo - a) / (2 * math.pi))
        k_hi = math.inf if math.isinf(hi) else math.floor((hi - a) / (2 * math.pi))
        if k_lo > k_hi:
            return None
        k = min(max(round((ref - a) / (2 * math.pi)), k_lo), k_hi)
        out[i] = a + 2 * math.pi * k
    return out
