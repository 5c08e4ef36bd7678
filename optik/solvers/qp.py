"""The ``qp:<backend>`` family: IK by bounded differential-IK steps, one QP per step.

Every backend that ``qpsolvers`` knows is registered as ``qp:<name>``; those not installed
here stay registered (so asking for one gives an install hint) but are not listed by
``available_solvers()``. The step program is :func:`optik.programs.diff_qp.build_program`;
:func:`solve_program` hands it to the backend with the tolerances of
:data:`BACKEND_OPTIONS` and never lets a backend exception escape. The backends' own APIs
(DAQP, ProxQP, OSQP), set up once and updated, are in :mod:`optik.solvers.qp_direct`.
"""

from __future__ import annotations

import math
import warnings
from typing import Any, Final

import numpy as np
import qpsolvers
import qpsolvers.solvers
import scipy.sparse as spa

from optik._checks import MAX_LENGTH_M, FloatArray
from optik._interrupts import reraise_interrupt
from optik._kernels import drives_slide
from optik._numba import jit
from optik.limits import Q_CLIP_TOLERANCE
from optik.model import Robot
from optik.programs.diff_qp import DiffIKProgram, QPSolution
from optik.programs.step_arrays import (
    FILL_OK,
    StepBuffers,
    fill_step,
    step_arrays,
    take_step,
)
from optik.solvers._base import (
    IKQuery,
    IKSolver,
    SolverOutput,
    StepBackend,
    budget_now,
    register_solver,
)
from optik.solvers._lm_kernel import (
    MIN_DAMPING_SCALE,
    STALL_FLOOR,
    STALL_RATIO,
    STALL_WINDOW,
)
from optik.solvers.qp_direct import (
    BACKEND_OPTIONS,
    DirectBackend,
    backend_iterations,
    direct_backend,
    polish,
)
from optik.task import Task

__all__ = [
    "BACKEND_OPTIONS",
    "DirectBackend",
    "QPStepBackend",
    "QPStepSolver",
    "direct_backend",
    "installed_backends",
    "polish",
    "qpsolvers_backends",
    "solve_program",
]

_SUFFIX = "_solve_problem"


def qpsolvers_backends() -> list[str]:
    """Every backend name ``qpsolvers`` supports, installed or not, sorted."""
    names = {name[: -len(_SUFFIX)] for name in dir(qpsolvers.solvers) if name.endswith(_SUFFIX)}
    return sorted(names | set(qpsolvers.available_solvers))


def installed_backends() -> list[str]:
    """The ``qpsolvers`` backends that import on this machine, sorted."""
    return sorted(qpsolvers.available_solvers)


def _backend_problem(program: DiffIKProgram, backend: str) -> tuple[qpsolvers.Problem, float]:
    """The equilibrated QP (see :meth:`DiffIKProgram.equilibrated`) in the backend's format."""
    eq = program.equilibrated()
    P, A = eq.P, eq.A
    if backend in qpsolvers.sparse_solvers and backend not in qpsolvers.dense_solvers:
        P = spa.csc_matrix(P)
        A = None if A is None else spa.csc_matrix(A)
    return qpsolvers.Problem(P, eq.c, A=A, b=eq.b, lb=eq.lb, ub=eq.ub), eq.scale


def solve_program(
    program: DiffIKProgram,
    backend: str,
    initvals: FloatArray | None = None,
    options: dict[str, Any] | None = None,
) -> QPSolution:
    """Solve a step program with a ``qpsolvers`` backend; never raises for a backend failure.

    Without ``options`` and ``initvals`` the backend's direct path runs
    (:func:`direct_backend`: its own API for daqp, ProxQP and OSQP), the one
    :func:`optik.diff_ik` uses; otherwise ``qpsolvers.solve_problem``.

    Args:
        program: the program (see :func:`optik.programs.diff_qp.build_program`).
        backend: a name in ``qpsolvers.available_solvers`` (without the ``qp:`` prefix).
        initvals: optional warm start (dof,).
        options: backend options replacing :data:`BACKEND_OPTIONS` entries.

    Returns:
        The backend's answer and claim, unchecked: a :class:`QPSolution` whose ``found`` is
        False (and ``status`` holds the exception text) if the backend raised.
    """
    name = f"qp:{backend}"
    if not program.bounds_consistent:
        return QPSolution(None, False, "inconsistent bounds (lower > upper)", name)
    if options is None and initvals is None:
        eq = program.equilibrated()
        n = program.dof
        m = 0 if eq.A is None else program.task_dim
        x, found, status, iterations = direct_backend(backend, n, m).solve(
            eq.P,
            eq.c,
            np.zeros((0, n)) if eq.A is None else eq.A,
            np.zeros(0) if eq.b is None else eq.b,
            np.full(n, -np.inf) if eq.lb is None else eq.lb,
            np.full(n, np.inf) if eq.ub is None else eq.ub,
        )
        return QPSolution(
            None if x is None else x / eq.scale, bool(found), status or "", name, iterations
        )
    kwargs = dict(BACKEND_OPTIONS.get(backend, {}))
    if options:
        kwargs.update(options)
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            problem, scale = _backend_problem(program, backend)
            start = None if initvals is None else np.asarray(initvals, dtype=np.float64) * scale
            solution = qpsolvers.solve_problem(problem, backend, initvals=start, **kwargs)
    except Exception as exc:  # a backend may raise anything; keep its text
        reraise_interrupt(exc)  # Ctrl-C is the caller's, not a failure
        return QPSolution(None, False, f"{type(exc).__name__}: {exc}", name)
    x = solution.x
    if x is not None:
        x = np.asarray(x, dtype=np.float64).reshape(-1) / scale
        if x.shape != (program.dof,):
            return QPSolution(None, False, f"returned x of shape {x.shape}", name)
    status = "; ".join(str(w.message) for w in caught) or ("solved" if solution.found else "")
    return QPSolution(
        x, bool(solution.found and x is not None), status, name, backend_iterations(solution)
    )


class QPStepSolver(IKSolver):
    """IK by repeated bounded damped-least-squares steps, each a QP of ``qpsolvers``.

    Each iteration solves, at the current ``q`` with the task residual ``e`` and its
    Jacobian rows ``J`` (:func:`optik.task.task_error` and :func:`optik.task.task_rows`:
    the task's weighted rows in the target frame, a plain pose or point in the world
    frame; the rows of zero weight are left out)::

        min  1/2 ||J_F dq_F - e||^2 + 1/2 lambda^2 ||dq_F||^2
        s.t. max(lower - q, -r) <= dq_F <= min(upper - q, r)

    over the joints ``F`` that the query's box (:attr:`IKQuery.bounds`: the limits less
    ``limit_margin``) leaves free; a frozen joint (lower == upper) is not a variable of
    the QP (no zero-width box for the backend) and keeps its value. The trust radius is
    ``r = min(trust_radius, trust_ratio ||e||)`` per joint (rad or m): a box far larger
    than the step slows interior-point backends (Clarabel stops with "insufficient
    progress" at 1e5 times the step). The damping is that of the compiled ``dls``
    (Sugihara's ``lambda^2 = s (||e||^2 / 2 + w_bias)``: large far from the target,
    vanishing near it) with Marquardt's scale ``s``: a step that lowers ``||e||`` is taken
    and ``s`` halves (to at least :attr:`min_scale`); a step that does not is refused and
    ``s`` grows fourfold.

    An attempt stops when the task's judged errors are within its two tolerances
    (:mod:`optik.task`), at ``max_iter`` QP solves, at the deadline, when ``s`` exceeds
    :attr:`max_scale` (no descent step: a local minimum), or when :attr:`stall_window`
    solves did not cut ``||e||^2`` to :attr:`stall_ratio` of its value while it is above
    :attr:`stall_floor` (restarting beats crawling: the rule of the compiled ``dls``).
    ``q`` never leaves the box: every step is bounded by it.
    """

    kind = "qp"
    default_max_iter = 100
    plain_tasks_only = False
    balanced = True  # its damping's bias and trust ratio read the residual's size
    #: Initial damping scale ``s``. Measured on 200 random Panda poses (qp:daqp): 0.01
    #: took 12.8 QP solves per target on average (95th percentile 38, the worst 244),
    #: 1.0 took 14.9 (38, 276); the plain Levenberg-Marquardt damping used before
    #: (``lambda`` from 1e-2, /3 and x10) took 17.6 (51, 668), and 35.2 (141, 882)
    #: without the stall rule.
    initial_scale: float = 1e-2
    #: Smallest damping scale (``dls``'s floor,
    #: :data:`optik.solvers._lm_kernel.MIN_DAMPING_SCALE`).
    min_scale: float = MIN_DAMPING_SCALE
    #: Largest damping scale before giving up (no descent step exists).
    max_scale: float = 1e12
    #: The bias ``w_bias`` of the damping (task units squared), as ``dls``'s.
    w_bias: float = 1e-3
    #: Largest joint step per iteration (rad or m).
    trust_radius: float = 0.5
    #: Largest joint step per iteration relative to the task error ``||e||``.
    trust_ratio: float = 1e3
    #: Solves over which ``||e||^2`` must fall to :attr:`stall_ratio` of its value.
    stall_window: int = STALL_WINDOW
    #: See :attr:`stall_window`.
    stall_ratio: float = STALL_RATIO
    #: No stall stop below this ``||e||^2`` (the last digits near a singularity).
    stall_floor: float = STALL_FLOOR

    def __init__(self, backend: str) -> None:
        self.backend = backend
        self.name = f"qp:{backend}"

    def solve(self, query: IKQuery, q0: FloatArray, max_iter: int, deadline: float) -> SolverOutput:
        """Refine ``q0`` towards ``query.target`` (see the class docstring for the program).

        Each iteration is one call of the backend's own API (:func:`direct_backend`) on
        the step program (:class:`~optik.programs.step_arrays.StepArrays`, set to the
        query's task and box), warm-started from the previous step's answer (DAQP's active
        set, ProxQP's and OSQP's primal-dual point), and one compiled call
        (:func:`_lm_move`) that evaluates the step, takes or refuses it and fills the next
        program.
        """
        task = query.spec
        lower, upper = query.lower, query.upper
        moving = _moving_joints(query)
        arrays = step_arrays(query.robot, _task_rows(task), "least_squares", moving)
        arrays.set_task(query.target, task.packed, lower, upper)
        nv = arrays.nv
        q = np.clip(np.asarray(q0, dtype=np.float64), lower, upper)
        e = np.zeros(6)
        q_new = np.empty_like(q)
        e_new = np.zeros(6)
        vmax = np.empty(query.robot.dof)
        reach = _trust_reach(query.robot, task)
        # A balanced search's residual is sqrt(bias) times its size in the arm's units
        # (optik.task.balanced_search): the damping's bias and the trust ratio follow it.
        bias = task.damping_bias
        lm = np.array(
            [np.inf, 0.0, 0.0, self.initial_scale, self.w_bias * bias, self.trust_radius,
             self.trust_ratio / math.sqrt(bias), self.min_scale]
        )  # fmt: skip
        buffers = arrays.buffers
        code = _lm_move(buffers, arrays.zero_step, q, e, q_new, e_new, vmax, reach, lm)
        err2, position, orientation = lm[:3].tolist()
        position_tol, orientation_tol = task.position_tol, task.orientation_tol
        if nv == 0:  # every joint frozen: nothing to solve, only to judge
            ok = position <= position_tol and orientation <= orientation_tol
            return SolverOutput(q, 0, ok, "converged" if ok else "every joint is frozen")
        backend = direct_backend(self.backend, nv, 0)
        scaled = arrays.scaled
        window, ratio, floor = self.stall_window, self.stall_ratio, self.stall_floor
        timed = deadline < math.inf
        history = [err2]  # ||e||^2 before each QP solve
        scale = self.initial_scale
        iterations = 0
        while True:
            if position <= position_tol and orientation <= orientation_tol:
                return SolverOutput(q, iterations, True, "converged")
            if iterations >= max_iter:
                return SolverOutput(q, iterations, False, "max_iter")
            if timed and budget_now() > deadline:
                return SolverOutput(q, iterations, False, "timeout")
            if scale > self.max_scale:
                return SolverOutput(
                    q, iterations, False, "stalled: no descent step (local minimum or limit)"
                )
            if iterations >= window and err2 > floor and ratio * history[-1 - window] < err2:
                return SolverOutput(q, iterations, False, "stalled: slow progress")
            if code != FILL_OK:
                return SolverOutput(
                    q, iterations, False, f"step program rejected (code {code})", True
                )
            x, _, status, _ = backend.solve_scaled(scaled, iterations > 0)
            iterations += 1
            if x is None:
                return SolverOutput(q, iterations, False, f"{self.name} failed: {status}", True)
            code = _lm_move(buffers, x, q, e, q_new, e_new, vmax, reach, lm)
            if code == _NOT_FINITE:
                return SolverOutput(q, iterations, False, f"{self.name} failed: {status}", True)
            err2, position, orientation, scale = lm[:4].tolist()
            history.append(err2)


# Entries of the state array of the qp:* loop (:func:`_lm_fill`, :func:`_lm_move`): the
# squared residual, the judged errors and the damping scale at the current q; then the
# settings (QPStepSolver's attributes of the same names).
_ERR2, _POSITION, _ORIENTATION, _SCALE, _W_BIAS, _RADIUS, _RATIO, _MIN_SCALE = range(8)
#: :func:`_lm_move`'s code for a backend point that is not finite.
_NOT_FINITE: Final[int] = -1


def _trust_reach(robot: Robot, task: Task) -> FloatArray:
    """(dof,) each joint's trust radius per unit of the loop's (rad; a slide's in m).

    1, but the arm's size ``L`` for a joint that drives a slide in a search measured in
    that size (:func:`optik.task.balanced_search`): a 4 km slide moved 0.5 m a step.
    """
    reach = np.ones(robot.dof)
    length = task.balance_length
    if length > 0.0:
        chain = robot.chain
        for a in range(robot.dof):
            if drives_slide(chain.prismatic, chain.C, chain.identity, a):
                reach[a] = length
    return reach


@jit
def _lm_fill(
    buffers: StepBuffers,
    q: np.ndarray,
    e: np.ndarray,
    vmax: np.ndarray,
    reach: np.ndarray,
    lm: np.ndarray,
) -> int:
    """Fill the step program at ``q`` for the residual ``e`` with the loop's damping.

    ``buffers`` is :attr:`~optik.programs.step_arrays.StepArrays.buffers`. The trust
    radius ``min(trust_radius, trust_ratio ||e||)`` times ``reach`` (:func:`_trust_reach`)
    goes into ``vmax`` (dof,), the damping
    is ``sqrt(s (||e||^2 / 2 + w_bias))`` (see :class:`QPStepSolver`); ``lm`` is the
    loop's state. Returns the code of :func:`~optik.programs.step_arrays.fill_step`.
    """
    err2 = lm[_ERR2]
    radius = min(lm[_RADIUS], lm[_RATIO] * math.sqrt(err2))
    for i in range(vmax.shape[0]):
        vmax[i] = radius * reach[i]
    damping = math.sqrt(lm[_SCALE] * (0.5 * err2 + lm[_W_BIAS]))
    const, const_layout, ints, buf, layout, identity = buffers
    yes = np.bool_(True)  # a value, not a literal (see _lm_move)
    return fill_step(
        const, const_layout, ints, q, e, vmax, buf, layout, 1.0, yes, Q_CLIP_TOLERANCE,
        MAX_LENGTH_M, 1.0, yes, yes, damping, identity,
    )  # fmt: skip


@jit
def _lm_move(
    buffers: StepBuffers,
    x: np.ndarray,
    q: np.ndarray,
    e: np.ndarray,
    q_new: np.ndarray,
    e_new: np.ndarray,
    vmax: np.ndarray,
    reach: np.ndarray,
    lm: np.ndarray,
) -> int:
    """Marquardt's move on the backend's point ``x``, then the next program (one call).

    ``buffers`` is :attr:`~optik.programs.step_arrays.StepArrays.buffers`.

    The step is taken (``q``, ``e`` and the errors in ``lm`` replaced, the scale halved
    down to ``min_scale``) if it lowers ``||e||^2``, else refused (the scale quadrupled);
    then :func:`_lm_fill` at the resulting ``q``. Returns its code, or :data:`_NOT_FINITE`.

    An attempt starts with ``lm``'s squared error at ``inf`` and ``x`` zeros (nv,): the
    program is first filled at ``q`` with a zero residual (its bounds contain 0), the
    zero step measures the residual ``e`` and the errors at ``q``, the scale stays.
    """
    start = not lm[_ERR2] < np.inf
    if start:
        const, const_layout, ints, buf, layout, identity = buffers
        e[:] = 0.0
        # Booleans as values, not literals: numba compiles a callee once per pattern of
        # literal arguments, and fill_step is large (ProgramArrays.fill compiles it too).
        yes, no = np.bool_(True), np.bool_(False)
        fill_step(
            const, const_layout, ints, q, e, vmax, buf, layout, 1.0, yes, Q_CLIP_TOLERANCE,
            MAX_LENGTH_M, 1.0, no, yes, 0.0, identity,
        )  # fmt: skip
    err2, position, orientation = take_step(buffers, x, q_new, e_new)
    if not math.isfinite(err2):
        return _NOT_FINITE
    if err2 < lm[_ERR2]:
        q[:] = q_new
        e[:] = e_new
        lm[_ERR2] = err2
        lm[_POSITION] = position
        lm[_ORIENTATION] = orientation
        if not start:
            lm[_SCALE] = max(0.5 * lm[_SCALE], lm[_MIN_SCALE])
    else:
        lm[_SCALE] *= 4.0
    return _lm_fill(buffers, q, e, vmax, reach, lm)


class QPStepBackend(StepBackend):
    """A differential-IK step program solved by a ``qpsolvers`` backend (:func:`solve_program`)."""

    def __init__(self, backend: str) -> None:
        self.backend = backend
        self.name = f"qp:{backend}"

    def solve(self, program: DiffIKProgram, initvals: FloatArray | None = None) -> QPSolution:
        """The backend's answer and claim, unchecked; never raises for a backend failure."""
        return solve_program(program, self.backend, initvals)

    def direct(self, n: int, m: int) -> DirectBackend:
        """The calling thread's direct backend for ``n`` joints and ``m`` equality rows."""
        return direct_backend(self.backend, n, m)


def _task_rows(task: Task) -> tuple[int, ...]:
    """The rows of the task residual its step programs keep: those of positive weight."""
    rows = _ROWS_OF.get(task.weights.tobytes())
    if rows is None:
        rows = tuple(int(i) for i in np.flatnonzero(task.weights > 0.0))
        if len(_ROWS_OF) < 64:
            _ROWS_OF[task.weights.tobytes()] = rows
    return rows


_ROWS_OF: dict[bytes, tuple[int, ...]] = {}


def _moving_joints(query: IKQuery) -> tuple[int, ...]:
    """The joints the query's box leaves free to move (lower < upper)."""
    if query.bounds is None:  # the joint limits: every joint moves
        dof = query.robot.dof
        every = _EVERY_JOINT.get(dof)
        if every is None:
            every = _EVERY_JOINT[dof] = tuple(range(dof))
        return every
    lower, upper = query.bounds
    return tuple(int(i) for i in np.flatnonzero(lower < upper))


_EVERY_JOINT: dict[int, tuple[int, ...]] = {}


def _register_all() -> None:
    """Register ``qp:<name>`` (an IK loop and a step backend) for every ``qpsolvers`` backend."""
    for backend in qpsolvers_backends():

        def factory(backend: str = backend) -> IKSolver:
            return QPStepSolver(backend)

        def step_factory(backend: str = backend) -> StepBackend:
            return QPStepBackend(backend)

        def available(backend: str = backend) -> bool:
            return backend in qpsolvers.available_solvers

        hint = f"Install it with `pip install qpsolvers[{backend}]`."
        register_solver(f"qp:{backend}", factory, available, hint)
        register_solver(f"qp:{backend}", step_factory, available, hint, kind="step")


_register_all()
