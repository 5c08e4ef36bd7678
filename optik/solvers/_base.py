"""The solver contract and the one registry of solver names.

A backend family adds itself in one place: a subclass of :class:`IKSolver` decorated
with :func:`register`, or :func:`register_solver` calls for a family of names such as
``qp:<backend>``, each saying what the name provides (:data:`SOLVER_KINDS`: a whole IK
solver, or the backend of one differential-IK step). :func:`optik.solve_ik`,
:func:`optik.diff_ik`, the comparison runs and the report all resolve names here. Names
are looked up before any backend runs, so a bug inside a backend is never reported as
"solver not found".
"""

from __future__ import annotations

import math
import time
from abc import ABC, abstractmethod
from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from optik._checks import FloatArray
from optik._clock import budget_clock
from optik._interrupts import reraise_interrupt
from optik.errors import OptikError, SolverError, UnknownSolverError
from optik.model import Robot
from optik.programs.diff_qp import DiffIKProgram, QPSolution
from optik.solvers._lm_kernel import (
    COMPROMISE_MAX_ITER,
    COMPROMISE_RATIO,
    COMPROMISE_WINDOW,
    lm_solve,
)
from optik.solvers._starts import StartSequence
from optik.task import Task, as_task, balanced_search, task_error, task_errors_of, task_rows
from optik.verify import verify_one


def run_lm(
    query: IKQuery, q0: FloatArray, max_iter: int, w_bias: float, window: int, ratio: float
) -> tuple[FloatArray, int, bool]:
    """One compiled LM attempt on ``query`` from ``q0``: ``(q, iterations, converged)``.

    :func:`optik.solvers._lm_kernel.lm_solve` with the damping's bias ``w_bias`` and the
    stall rule ``(window, ratio)``.
    """
    q, it, ok, _, _ = lm_solve(
        query.robot.chain.kernel_args(query.bounds),
        query.target,
        query.spec.packed,
        np.ascontiguousarray(q0, dtype=float),
        int(max_iter),
        float(w_bias),
        np.int64(window),
        float(ratio),
    )
    return q, int(it), bool(ok)


def compromise(query: IKQuery, q0: FloatArray) -> tuple[FloatArray, int, bool]:
    """The task's weighted least-squares minimum from ``q0``: ``(q, iterations, converged)``.

    The compromise of a target that cannot be met (:mod:`optik.task`): the compiled LM
    on the query's own (graded) task, inside its box, until no progress is left
    (:data:`~optik.solvers._lm_kernel.COMPROMISE_RATIO`), at most
    :data:`~optik.solvers._lm_kernel.COMPROMISE_MAX_ITER` iterations, whatever the
    search's ``max_iter`` (a search's budget per attempt; a redundant arm's compromise
    took 425 iterations to its minimum). Whatever solver searched: the minimum is the
    task's, not the solver's.
    """
    return run_lm(
        query, q0, COMPROMISE_MAX_ITER, COMPROMISE_BIAS, COMPROMISE_WINDOW, COMPROMISE_RATIO
    )


def within_reach_of_tolerance(query: IKQuery, q0: FloatArray) -> tuple[bool, FloatArray, int]:
    """Whether an answer within the query's ``tol`` may lie near the task's minimum from ``q0``.

    A closed form's "no branch" proves that no configuration meets the target *exactly*;
    a tolerance admits configurations near it, which a search aimed at the target can miss:
    its least-squares minimum trades the position error against the rotation's, while a
    success bounds each (the UR5 at ``tol=0.05``: a configuration 0.047 m and 0.047 rad
    away, and no search of 200 restarts found it). The task's weighted minimum from ``q0``
    (:func:`compromise`, the cross-check's best attempt) measures the miss ``J = sum_i
    w_i e_i^2``; every success has ``J <= max(w_p) tol_p^2 + max(w_r) tol_r^2``, so a
    minimum above that (with the smallest weights) leaves no success near it, and the proof
    stands. Returns ``(near, q_min, iterations)``: ``near`` when the minimum is a success or
    within that bound (then nothing is proved), ``q_min`` (dof,) the minimum found.
    """
    q_min, iterations, _ = compromise(query, q0)
    position, orientation, _, success = verify_one(query.robot, q_min, query.target, query.spec)
    weights = query.spec.weights
    w_position, w_rotation = weights[:3], weights[3:]
    smallest = (  # products, not powers: a miss of 1e300 m is an infinite one, no error
        _least_positive(w_position) * position * position
        + _least_positive(w_rotation) * orientation * orientation
    )
    position_tol, orientation_tol = query.spec.position_tol, query.spec.orientation_tol
    bound = (
        float(np.max(w_position)) * position_tol * position_tol
        + float(np.max(w_rotation)) * orientation_tol * orientation_tol
    )
    return success or not smallest > bound, q_min, iterations


def _least_positive(weights: FloatArray) -> float:
    """The smallest positive weight, 0 when there is none (the axes are free)."""
    positive = weights[weights > 0.0]
    return float(np.min(positive)) if positive.size else 0.0


COMPROMISE_BIAS = 1e-9
"""The damping's bias of :func:`compromise` (``dls``'s ``w_bias`` is 1e-3). A
compromise's residual does not vanish, so the damping's own term (half the squared
error) keeps its steps regular; a bias near a search's would swamp the curvature of
rows weighted 1e-12 of the others (their steps 1e-3 of Gauss–Newton's: a UR5 beyond
its reach, orientation 1e12 times heavier than position, stopped 1.4 % above its
minimum, 0.1 rad away)."""


def search_length(robot: Robot) -> float:
    """The size (m) a search balances its units by: the robot's reach radius."""
    return robot.cached(_reach_radius)


def _reach_radius(robot: Robot) -> float:
    return float(robot.reach_sphere[1])


@dataclass(frozen=True)
class IKQuery:
    """One IK query, validated, in SI units.

    Attributes:
        robot: the robot.
        target: 4x4 world pose of the tool (a point uses only its translation).
        mode: the task's mode (``"pose"``, ``"position"``, ``"orientation"``, ``"axis"``).
        tol: the position tolerance (m); the orientation tolerance is the task's.
        task: the task (:mod:`optik.task`); default: ``mode`` with ``tol`` for both errors.
        bounds: ``(lower, upper)`` (dof,) each, the box the solver keeps ``q`` in: the
            joint limits narrowed by ``limit_margin`` and closed on frozen joints
            (default: the robot's limits). Success is still judged against the limits.
    """

    robot: Robot
    target: FloatArray
    mode: str
    tol: float
    task: Task | None = None
    bounds: tuple[FloatArray, FloatArray] | None = None

    @property
    def lower(self) -> FloatArray:
        """The lower bound (dof,) the solver keeps ``q`` above."""
        return self.robot.lower if self.bounds is None else self.bounds[0]

    @property
    def upper(self) -> FloatArray:
        """The upper bound (dof,) the solver keeps ``q`` below."""
        return self.robot.upper if self.bounds is None else self.bounds[1]

    @property
    def spec(self) -> Task:
        """The task this query solves."""
        return self.task if self.task is not None else as_task(self.mode, self.tol)

    def error_vector(self, T: FloatArray) -> FloatArray:
        """The task residual towards the target at pose ``T``: (3,) for a point, else (6,).

        ``[p* - p; log(R* R^T)]`` for a full pose with unit weights; weighted and in the
        target frame otherwise (:func:`optik.task.task_error`).
        """
        task = self.spec
        e = np.empty(6)
        task_error(np.ascontiguousarray(T, dtype=np.float64), self.target, task.packed, e,
                   np.empty((3, 4)))  # fmt: skip
        return e[:3].copy() if task.packed[10] == 2.0 else e

    def task_rows(self, J: FloatArray) -> FloatArray:
        """The task's Jacobian rows for the world-frame Jacobian ``J`` (6, dof) (a copy)."""
        rows = np.array(J, dtype=np.float64, order="C")
        m = task_rows(rows, self.target, self.spec.packed)
        return rows[:m]

    def errors(self, T: FloatArray) -> tuple[float, float]:
        """The judged (position, orientation) errors of pose ``T`` (:mod:`optik.task`)."""
        position, orientation = task_errors_of(
            np.ascontiguousarray(T, dtype=np.float64), self.target, self.spec.packed
        )
        return float(position), float(orientation)

    def searching(self, balanced: bool = False) -> IKQuery:
        """This query with its task's search twin (``self`` when that is its task).

        See :attr:`optik.task.Task.search`; ``balanced``: its units balanced for the
        robot's size (:func:`optik.task.balanced_search`, for the damped least squares
        whose damping reads them).
        """
        task = self.spec
        search = balanced_search(task, search_length(self.robot)) if balanced else task.search
        return self if search is task else replace(self, task=search)

    def converged(self, T: FloatArray) -> bool:
        """Both judged errors within the task's tolerances."""
        position, orientation = self.errors(T)
        task = self.spec
        return position <= task.position_tol and orientation <= task.orientation_tol


@dataclass
class SolverOutput:
    """What a backend reports; optik verifies it independently afterwards.

    Attributes:
        q: final joint vector (dof,).
        iterations: iterations used.
        converged: the backend's own claim of convergence (kept for the "claims" check).
        message: backend status text, kept in the result.
        failed: the backend raised or returned no solution.
    """

    q: FloatArray
    iterations: int
    converged: bool
    message: str = ""
    failed: bool = False


@dataclass
class RunOutput:
    """The outcome of :meth:`IKSolver.run` over a sequence of starts (unverified claim).

    Attributes:
        q: the first converged attempt's joint vector, else the best one's (dof,).
        iterations: iterations over all attempts.
        restarts: attempts after the first.
        converged: the backend's claim for ``q``.
        message: the backend's text for ``q``.
        status_if_failed: ``"max_iter"``, ``"timeout"`` or ``"solver_failed"``: what to
            report when optik's own verification of ``q`` fails.
    """

    q: FloatArray
    iterations: int
    restarts: int
    converged: bool
    message: str
    status_if_failed: str


class IKSolver(ABC):
    """A numeric IK method: refines ``q0`` towards the query's target inside the limits.

    Subclasses set ``name`` and implement :meth:`solve`; :meth:`is_available` says whether
    the backend imports on this machine. :meth:`run` takes every solver through the one
    start policy (:mod:`optik.solvers._starts`); a compiled solver may override it with
    the same semantics.
    """

    name: str = ""
    kind: str = "iterative"
    default_max_iter: int = 100
    plain_tasks_only: bool = False
    """Whether the solver takes only a full pose or a point with unit weights inside the
    plain joint limits (the QP and CasADi forms of weighted and axis tasks, frozen joints
    and limit margins are not built yet)."""
    balanced: bool = False
    """Whether the solver searches with the task's units balanced for the arm's size
    (:func:`optik.task.balanced_search`): a damped or tolerance-driven search, whose
    damping and stopping rules read the residual's size."""

    @classmethod
    def is_available(cls) -> bool:
        """Whether the backend can run here (its imports succeed)."""
        return True

    @abstractmethod
    def solve(self, query: IKQuery, q0: FloatArray, max_iter: int, deadline: float) -> SolverOutput:
        """Refine ``q0``; stop at convergence, ``max_iter``, or at ``deadline``.

        ``deadline`` is on the clock of :func:`budget_now` (compilation not counted).
        """

    def run(
        self,
        query: IKQuery,
        starts: StartSequence,
        max_iter: int,
        last: int,
        deadline: float,
        start: int = 0,
    ) -> RunOutput:
        """Attempts from starts ``start..last`` until one is verified, or the deadline passes.

        A task with graded weights is searched with :attr:`optik.task.Task.search` (the
        same success, see :mod:`optik.task`); when no attempt succeeds, the best answer
        is taken to the graded task's compromise (:func:`compromise`), also after a
        timeout: it is bounded (at most ``COMPROMISE_MAX_ITER`` compiled iterations, a
        few milliseconds).
        """
        search = self.searched(query)
        found = self.attempts(search, starts, max_iter, last, deadline, start)
        # A plain task searched in the arm's units (not graded) has no compromise: its
        # best attempt is the answer, as on an arm of a metre.
        if search is query or not query.spec.is_graded or found.status_if_failed == "solver_failed":
            return found
        # Verified, not the backend's own claim (an NLP "solved to an acceptable level"
        # short of the task): such an answer needs the compromise too.
        if found.converged and verify_one(query.robot, found.q, query.target, query.spec)[3]:
            return found
        q, iterations, converged = compromise(query, found.q)
        message = "converged" if converged else found.message
        return RunOutput(
            q,
            found.iterations + iterations,
            found.restarts,
            converged,
            message,
            found.status_if_failed,
        )

    def searched(self, query: IKQuery) -> IKQuery:
        """The query :meth:`run` searches with: the search twin, balanced when :attr:`balanced`.

        See :meth:`IKQuery.searching`.
        """
        return query.searching(balanced=self.balanced)

    def attempts(
        self,
        query: IKQuery,
        starts: StartSequence,
        max_iter: int,
        last: int,
        deadline: float,
        start: int = 0,
    ) -> RunOutput:
        """:meth:`run` on ``query``'s own task (no search task).

        Each attempt's answer is verified from FK (:func:`optik.verify.verify_one`); the
        first verified one is returned, else the one with the smallest sum of errors.
        A backend exception ends the run with ``solver_failed`` and its text.
        """
        best: SolverOutput | None = None
        best_error = math.inf
        total_iterations = 0
        attempts = start
        timed_out = False
        all_failed = True
        while attempts <= last:
            if attempts > start and budget_now() > deadline:
                timed_out = True
                break
            q0 = starts.start(attempts)
            try:
                output = self.solve(query, q0, max_iter, deadline)
            except Exception as exc:  # a backend crash becomes a status, with its text
                reraise_interrupt(exc)  # Ctrl-C is the caller's, not a failure
                best = SolverOutput(q0, 0, False, f"{type(exc).__name__}: {exc}", failed=True)
                attempts += 1
                break
            attempts += 1
            total_iterations += output.iterations
            all_failed = all_failed and output.failed
            if output.failed:
                if best is None:
                    best = output
                continue
            position, orientation, violation, ok = verify_one(
                query.robot, output.q, query.target, query.spec
            )
            error = position + orientation + violation
            if best is None or best.failed or error < best_error:
                best, best_error = output, error
            if ok:
                break
            if budget_now() > deadline:
                timed_out = True
                break
        if best is None:  # pragma: no cover - at least one attempt always runs
            raise SolverError(self.name, "no IK attempt ran")
        status = "solver_failed" if all_failed else ("timeout" if timed_out else "max_iter")
        return RunOutput(
            best.q,
            total_iterations,
            max(attempts - 1 - start, 0),
            best.converged,
            best.message,
            status,
        )


SOLVER_KINDS = ("ik", "step")
"""What a registered name provides: ``"ik"``, a whole IK solver (``solve_ik``'s
``solver=``, an :class:`IKSolver`); ``"step"``, a backend that solves one differential-IK
step program (``diff_ik``'s ``solver=``, a :class:`StepBackend`). One name may provide
both: ``qp:osqp`` is an IK loop of QP steps and the backend of one step."""


class StepBackend(ABC):
    """A backend that solves differential-IK step programs (built, not solved, elsewhere).

    Subclasses set ``name`` and implement :meth:`solve`, which never raises for a backend
    failure: the answer is checked by :func:`optik.diffik.verify_step`.
    """

    name: str = ""

    @abstractmethod
    def solve(self, program: DiffIKProgram, initvals: FloatArray | None = None) -> QPSolution:
        """The backend's answer and claim for ``program``, unchecked."""


_KIND_TEXT = {
    "ik": "a whole-IK solver",
    "step": "a step backend (qp:<name>, or a CasADi conic plugin casadi:<plugin>)",
}


@dataclass(frozen=True)
class _Provider:
    factory: Callable[[], Any]
    available: Callable[[], bool]
    install_hint: str


_REGISTRY: dict[str, dict[str, _Provider]] = {}
_INSTANCES: dict[tuple[str, str], Any] = {}


def _check_kind(kind: str) -> None:
    if kind not in SOLVER_KINDS:
        raise OptikError(f"solver kind must be one of {SOLVER_KINDS}, got {kind!r}")


def register_solver(
    name: str,
    factory: Callable[[], Any],
    available: Callable[[], bool],
    install_hint: str = "",
    kind: str = "ik",
) -> None:
    """Add what ``name`` provides of ``kind`` to the registry (the one place a backend is added).

    Args:
        name: the solver name, e.g. ``"qp:osqp"``.
        factory: builds the solver (an :class:`IKSolver` for ``"ik"``, a
            :class:`StepBackend` for ``"step"``); called once, on first use.
        available: whether the backend imports and runs on this machine.
        install_hint: what to tell a user who asks for it when it is not available.
        kind: one of :data:`SOLVER_KINDS`.
    """
    _check_kind(kind)
    _REGISTRY.setdefault(name, {})[kind] = _Provider(factory, available, install_hint)
    _INSTANCES.pop((name, kind), None)


def unregister_solver(name: str, kind: str = "ik") -> None:
    """Remove what ``name`` provides of ``kind`` (a no-op when it provides nothing)."""
    providers = _REGISTRY.get(name, {})
    providers.pop(kind, None)
    if not providers:
        _REGISTRY.pop(name, None)
    _INSTANCES.pop((name, kind), None)


def register(cls: type[IKSolver]) -> type[IKSolver]:
    """Class decorator: register ``cls`` under ``cls.name`` as an ``"ik"`` solver."""
    register_solver(cls.name, cls, cls.is_available)
    return cls


def available_solvers(kind: str = "ik") -> list[str]:
    """Registered names providing ``kind`` whose backend imports on this machine, sorted.

    Args:
        kind: ``"ik"`` (default: the names ``solve_ik`` takes) or ``"step"`` (the names
            ``diff_ik`` takes); see :data:`SOLVER_KINDS`.
    """
    _check_kind(kind)
    return sorted(
        name
        for name, providers in _REGISTRY.items()
        if kind in providers and providers[kind].available()
    )


def registered_solvers(kind: str = "ik") -> list[str]:
    """Every name registered for ``kind``, installed or not."""
    _check_kind(kind)
    return sorted(name for name, providers in _REGISTRY.items() if kind in providers)


def get_solver(name: str, kind: str = "ik") -> Any:
    """The solver registered as ``name`` for ``kind`` (one shared instance per name and kind).

    Raises:
        UnknownSolverError: not a string, unknown name (or not of this kind), or a known
            backend that is not installed; the message lists the installed names.
    """
    _check_kind(kind)
    provider = _REGISTRY.get(name, {}).get(kind) if isinstance(name, str) else None
    if provider is not None and provider.available():
        key = (name, kind)
        if key not in _INSTANCES:
            _INSTANCES[key] = provider.factory()
        return _INSTANCES[key]
    # Only an error lists the installed names (probing every backend is slow).
    listed = (["auto"] if kind == "ik" else []) + available_solvers(kind)
    if not isinstance(name, str):
        raise UnknownSolverError(repr(name), listed)
    if provider is None:
        other = [k for k in _REGISTRY.get(name, {}) if k != kind]
        hint = (
            f"It is registered as {_KIND_TEXT[other[0]]} (kind {other[0]!r}), not as "
            f"{_KIND_TEXT[kind]} (kind {kind!r})."
            if other
            else ""
        )
        raise UnknownSolverError(name, listed, hint)
    raise UnknownSolverError(name, listed, provider.install_hint or "Its backend is not installed.")


def now() -> float:
    """Monotonic time in seconds (``time.perf_counter``)."""
    return time.perf_counter()


def budget_now() -> float:
    """The clock deadlines are set and checked on: ``now()`` less numba compilation time.

    A first call that compiles a kernel is not charged to the caller's ``timeout_s``
    (:func:`optik._clock.budget_clock`).
    """
    return budget_clock()
