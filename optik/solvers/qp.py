"""The ``qp:<backend>`` family: IK by bounded differential-IK steps, one QP per step.

Every backend that ``qpsolvers`` knows is registered as ``qp:<name>``; those not installed
here stay registered (so asking for one gives an install hint) but are not listed by
``available_solvers()``. The step program is :func:`optik.programs.diff_qp.build_program`;
:func:`solve_program` hands it to the backend with the tolerances of
:data:`BACKEND_OPTIONS` and never lets a backend exception escape.
"""

from __future__ import annotations

import warnings
from typing import Any, Final

import numpy as np
import qpsolvers
import qpsolvers.solvers
import scipy.sparse as spa

from optik._checks import FloatArray
from optik.programs.diff_qp import DiffIKProgram, QPSolution, build_program
from optik.solvers._base import (
    IKQuery,
    IKSolver,
    SolverOutput,
    StepBackend,
    budget_now,
    register_solver,
)

__all__ = [
    "BACKEND_OPTIONS",
    "QPStepBackend",
    "QPStepSolver",
    "installed_backends",
    "qpsolvers_backends",
    "solve_program",
]

#: Options passed to each ``qpsolvers`` backend: tight tolerances so that an unconstrained
#: step matches its closed form to about 1e-10 (measured figures in ``docs/programs.md``).
#: Backends marked "docs" are set from the ``qpsolvers`` documentation of their options
#: but are not installed on the development machine, so their accuracy is not measured.
BACKEND_OPTIONS: Final[dict[str, dict[str, Any]]] = {
    # Interior point, sparse: duality gap and feasibility tolerances.
    "clarabel": {
        "tol_gap_abs": 1e-11,
        "tol_gap_rel": 1e-11,
        "tol_feas": 1e-11,
        "tol_ktratio": 1e-8,
        "max_iter": 200,
    },
    # Dual active set, dense: exact up to rounding; tighten the feasibility tolerances.
    "daqp": {"primal_tol": 1e-12, "dual_tol": 1e-12},
    # ADMM, sparse: absolute tolerance only. OSQP's own Ruiz scaling is off: our programs
    # come equilibrated, and with it on, redundant least-squares steps stop 1e-9 from the
    # closed form (1e-11 without). 1e-12 stalled ("solved inaccurate") on some programs
    # with an active bound; 1e-10 keeps a margin. Polishing is off: it gains nothing and its
    # C code prints "Polishing not needed" to stdout whatever `verbose` says.
    "osqp": {
        "eps_abs": 1e-10,
        "eps_rel": 0.0,
        "eps_prim_inf": 1e-10,
        "eps_dual_inf": 1e-10,
        "scaling": 0,
        "polishing": False,
        "max_iter": 100_000,
    },
    # Proximal augmented Lagrangian, dense backend (our programs are small and dense).
    "proxqp": {"eps_abs": 1e-12, "eps_rel": 0.0, "backend": "dense", "max_iter": 10_000},
    # Goldfarb-Idnani dual active set: exact, no options.
    "quadprog": {},
    # docs: not installed here.
    "cvxopt": {"abstol": 1e-12, "reltol": 1e-12, "feastol": 1e-12},
    "ecos": {"abstol": 1e-12, "reltol": 1e-12, "feastol": 1e-12},
    "highs": {"primal_feasibility_tolerance": 1e-10, "dual_feasibility_tolerance": 1e-10},
    "hpipm": {"tol_eq": 1e-12, "tol_ineq": 1e-12, "tol_comp": 1e-12, "tol_stat": 1e-12},
    "piqp": {"eps_abs": 1e-12, "eps_rel": 0.0},
    "qpalm": {"eps_abs": 1e-12, "eps_rel": 0.0},
    "scs": {"eps_abs": 1e-10, "eps_rel": 0.0},
}

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

    Args:
        program: the program (see :func:`optik.programs.diff_qp.build_program`).
        backend: a name in ``qpsolvers.available_solvers`` (without the ``qp:`` prefix).
        initvals: optional warm start (dof,).
        options: backend options replacing :data:`BACKEND_OPTIONS` entries.

    Returns:
        The backend's answer and claim, unchecked: a :class:`QPSolution` whose ``found`` is
        False (and ``status`` holds the exception text) if the backend raised.
    """
    kwargs = dict(BACKEND_OPTIONS.get(backend, {}))
    if options:
        kwargs.update(options)
    name = f"qp:{backend}"
    if not program.bounds_consistent:
        return QPSolution(None, False, "inconsistent bounds (lower > upper)", name)
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            problem, scale = _backend_problem(program, backend)
            start = None if initvals is None else np.asarray(initvals, dtype=np.float64) * scale
            solution = qpsolvers.solve_problem(problem, backend, initvals=start, **kwargs)
    except Exception as exc:  # a backend may raise anything; keep its text
        return QPSolution(None, False, f"{type(exc).__name__}: {exc}", name)
    x = solution.x
    if x is not None:
        x = np.asarray(x, dtype=np.float64).reshape(-1) / scale
        if x.shape != (program.dof,):
            return QPSolution(None, False, f"returned x of shape {x.shape}", name)
    status = "; ".join(str(w.message) for w in caught) or ("solved" if solution.found else "")
    return QPSolution(
        x, bool(solution.found and x is not None), status, name, _iterations(solution)
    )


def _iterations(solution: qpsolvers.Solution) -> int:
    """Iterations reported by the backend, when its extras hold them (else -1)."""
    info = solution.extras.get("info") if isinstance(solution.extras, dict) else None
    for attr in ("iter", "iter_ext", "iterations"):
        value = getattr(info, attr, None)
        if isinstance(value, int | np.integer):
            return int(value)
    return -1


class QPStepSolver(IKSolver):
    """IK by repeated bounded damped-least-squares steps, each a QP of ``qpsolvers``.

    Each iteration solves, at the current ``q`` with task error ``e`` (from
    :meth:`IKQuery.error_vector`: position (m) then orientation (rad) rows)::

        min  1/2 ||J dq - e||^2 + 1/2 lambda^2 ||dq||^2
        s.t. max(lower - q, -r) <= dq <= min(upper - q, r)

    with ``J`` the query's task rows and a trust radius
    ``r = min(trust_radius, trust_ratio ||e||)`` per joint (rad or m): a box far larger
    than the step slows interior-point backends (Clarabel stops with "insufficient
    progress" at 1e5 times the step). The damping ``lambda`` follows Levenberg-Marquardt:
    a step that lowers ``||e||`` is taken and ``lambda`` shrinks (to at least
    :attr:`min_damping`); a step that does not is refused and ``lambda`` grows tenfold.

    It stops when the position error is at most ``tol`` (m) and the orientation error at
    most ``tol`` (rad), at ``max_iter`` QP solves, at the deadline, or when ``lambda``
    exceeds :attr:`max_damping` (a local minimum). ``q`` never leaves the limits: every
    step is bounded by them.
    """

    kind = "qp"
    default_max_iter = 100
    plain_tasks_only = True
    #: Initial damping ``lambda`` (task units per joint unit).
    initial_damping: float = 1e-2
    #: Smallest damping (keeps the QP strictly convex for redundant arms).
    min_damping: float = 1e-6
    #: Largest damping before giving up (no descent step exists).
    max_damping: float = 1e6
    #: Largest joint step per iteration (rad or m).
    trust_radius: float = 0.5
    #: Largest joint step per iteration relative to the task error ``||e||``.
    trust_ratio: float = 1e3

    def __init__(self, backend: str) -> None:
        self.backend = backend
        self.name = f"qp:{backend}"

    def solve(self, query: IKQuery, q0: FloatArray, max_iter: int, deadline: float) -> SolverOutput:
        """Refine ``q0`` towards ``query.target`` (see the class docstring for the program)."""
        robot = query.robot
        q = np.clip(np.asarray(q0, dtype=np.float64), robot.lower, robot.upper)
        T = robot.fk(q)
        e = query.error_vector(T)
        lam = self.initial_damping
        iterations = 0
        while True:
            if _converged(e, query.tol):
                return SolverOutput(q, iterations, True, "converged")
            if iterations >= max_iter:
                return SolverOutput(q, iterations, False, "max_iter")
            if budget_now() > deadline:
                return SolverOutput(q, iterations, False, "timeout")
            if lam > self.max_damping:
                return SolverOutput(
                    q, iterations, False, "stalled: no descent step (local minimum or limit)"
                )
            rows = None if query.mode == "pose" else (0, 1, 2)
            radius = min(self.trust_radius, self.trust_ratio * float(np.linalg.norm(e)))
            try:
                program = build_program(
                    robot,
                    q,
                    e,
                    objective="least_squares",
                    damping=lam,
                    velocity_limits=np.full(robot.dof, radius),
                    dt=1.0,
                    rows=rows,
                )
            except Exception as exc:  # report, never raise from a backend run
                return SolverOutput(q, iterations, False, f"{type(exc).__name__}: {exc}", True)
            result = solve_program(program, self.backend)
            iterations += 1
            if result.x is None or not np.all(np.isfinite(result.x)):
                return SolverOutput(
                    q, iterations, False, f"{self.name} failed: {result.status}", True
                )
            dq = program.clip(result.x)
            q_new = np.clip(q + dq, robot.lower, robot.upper)
            e_new = query.error_vector(robot.fk(q_new))
            if float(e_new @ e_new) < float(e @ e):
                q, e = q_new, e_new
                lam = max(lam / 3.0, self.min_damping)
            else:
                lam *= 10.0


class QPStepBackend(StepBackend):
    """A differential-IK step program solved by a ``qpsolvers`` backend (:func:`solve_program`)."""

    def __init__(self, backend: str) -> None:
        self.backend = backend
        self.name = f"qp:{backend}"

    def solve(self, program: DiffIKProgram, initvals: FloatArray | None = None) -> QPSolution:
        """The backend's answer and claim, unchecked; never raises for a backend failure."""
        return solve_program(program, self.backend, initvals)


def _converged(e: FloatArray, tol: float) -> bool:
    """Position (m) and orientation (rad) errors both within ``tol``."""
    if float(np.linalg.norm(e[:3])) > tol:
        return False
    return e.shape[0] == 3 or float(np.linalg.norm(e[3:])) <= tol


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
