"""The ``qp:<backend>`` family: IK by bounded differential-IK steps, one QP per step.

Every backend that ``qpsolvers`` knows is registered as ``qp:<name>``; those not installed
here stay registered (so asking for one gives an install hint) but are not listed by
``available_solvers()``. The step program is :func:`optik.programs.diff_qp.build_program`;
:func:`solve_program` hands it to the backend with the tolerances of
:data:`BACKEND_OPTIONS` and never lets a backend exception escape.
"""

from __future__ import annotations

import math
import threading
import warnings
from typing import Any, Final

import numba as nb
import numpy as np
import qpsolvers
import qpsolvers.solvers
import scipy.sparse as spa

from optik._checks import MAX_LENGTH_M, FloatArray
from optik.limits import Q_CLIP_TOLERANCE
from optik.programs.diff_qp import DiffIKProgram, QPSolution
from optik.programs.step_arrays import (
    FILL_OK,
    ScaledProgram,
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
from optik.task import Task

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


# ---------------------------------------------------------------------- direct backends
#: What a direct backend returns: the point (or None), the backend's claim, its status
#: text, its iteration count (-1 when unknown).
DirectAnswer = tuple[FloatArray | None, bool, str, int]


class DirectBackend:
    """A backend's own API for step programs of one shape, its state reused across steps.

    ``solve(P, c, A, b, lb, ub, warm)`` takes the equilibrated arrays (``A``/``b`` with
    ``m`` rows, ``m = 0`` for least squares; ``lb``/``ub`` with ``-inf``/``inf`` where
    unbounded) and never raises for a backend failure. With ``warm`` the backend starts
    from its previous answer (its active set, or its primal-dual point) where it can;
    without it every call is independent of the previous ones. One instance per thread:
    the backends' workspaces are not shared between threads.
    """

    def __init__(self, backend: str, n: int, m: int) -> None:
        self.backend = backend
        self.n = n
        self.m = m

    def solve(
        self,
        P: FloatArray,
        c: FloatArray,
        A: FloatArray,
        b: FloatArray,
        lb: FloatArray,
        ub: FloatArray,
        warm: bool = False,
        lower_stack: FloatArray | None = None,
        upper_stack: FloatArray | None = None,
    ) -> DirectAnswer:
        """The backend's answer for the equilibrated program, unchecked.

        ``lower_stack``/``upper_stack``, when given, are ``[lb; b]`` and ``[ub; b]``
        (:class:`~optik.programs.step_arrays.StepArrays` keeps them so): backends that
        take bounds and rows stacked use them without a copy.
        """
        return self.solve_scaled(ScaledProgram(P, c, A, b, lb, ub, lower_stack, upper_stack), warm)

    def solve_scaled(self, qp: ScaledProgram, warm: bool = False) -> DirectAnswer:
        """:meth:`solve` of a program held as one tuple (e.g. ``StepArrays.scaled``)."""
        try:
            return self._solve(qp, warm)
        except Exception as exc:  # a backend may raise anything; keep its text
            return None, False, f"{type(exc).__name__}: {exc}", -1

    def _solve(self, qp: ScaledProgram, warm: bool) -> DirectAnswer:
        """Through ``qpsolvers.solve_problem`` (the backends without an own-API path)."""
        P, c, A, b, lb, ub = qp.P, qp.c, qp.A, qp.b, qp.lb, qp.ub
        Pm: Any = P
        Am: Any = A if self.m else None
        if self.backend in qpsolvers.sparse_solvers and self.backend not in qpsolvers.dense_solvers:
            Pm = spa.csc_matrix(P)
            Am = None if Am is None else spa.csc_matrix(Am)
        bounded = bool(np.any(np.isfinite(lb)) or np.any(np.isfinite(ub)))
        problem = qpsolvers.Problem(
            Pm,
            c,
            A=Am,
            b=b if self.m else None,
            lb=lb if bounded else None,
            ub=ub if bounded else None,
        )
        start = self._last if warm and self._last is not None else None
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            solution = qpsolvers.solve_problem(
                problem, self.backend, initvals=start, **BACKEND_OPTIONS.get(self.backend, {})
            )
        x = solution.x
        if x is not None:
            x = np.asarray(x, dtype=np.float64).reshape(-1)
            if x.shape != (self.n,):
                return None, False, f"returned x of shape {x.shape}", -1
            if self.backend in POLISHED_BACKENDS and np.all(np.isfinite(x)):
                polished = polish(P, c, A if self.m else None, b, lb, ub, x)
                x = x if polished is None else polished
        self._last = x
        status = "; ".join(str(w.message) for w in caught) or ("solved" if solution.found else "")
        return x, bool(solution.found and x is not None), status, _iterations(solution)

    _last: FloatArray | None = None


#: Interior-point backends whose answer is polished (:func:`polish`): Clarabel stopped
#: up to 1.3e-8 (1.1e-7 relative) from the closed form on DOBOT least-squares steps
#: (1 in 3,000 sampled; tests/test_qp_solvers.py keeps it), 5e-13 after polishing.
POLISHED_BACKENDS: Final[frozenset[str]] = frozenset({"clarabel"})

#: How close (in the equilibrated program's units) a bound must be to count as active in
#: :func:`polish`, and the tolerance of its feasibility and sign checks.
POLISH_TOL: Final[float] = 1e-7


def polish(
    P: FloatArray,
    c: FloatArray,
    A: FloatArray | None,
    b: FloatArray,
    lb: FloatArray,
    ub: FloatArray,
    x: FloatArray,
) -> FloatArray | None:
    """The exact minimizer on the active set of an approximate point, or ``None``.

    The bounds within :data:`POLISH_TOL` of ``x`` are fixed at their values; the free
    joints ``F`` and the multipliers ``y`` of ``A x = b`` then solve the KKT system
    ``[[P_FF, A_F^T], [A_F, 0]] [x_F; y] = [-(c_F + P_FA x_A); b - A_A x_A]``. The answer
    is returned only if it is inside the bounds (to :data:`POLISH_TOL`) and the bound
    multipliers ``g = P x + c + A^T y`` have the signs of an optimum (``g_i >= 0`` at a
    lower bound, ``<= 0`` at an upper one): then it satisfies the KKT conditions of the
    convex program exactly, up to rounding.
    """
    tol = POLISH_TOL
    at_lower = np.isfinite(lb) & (x - lb <= tol)
    at_upper = np.isfinite(ub) & (ub - x <= tol) & ~at_lower
    fixed = at_lower | at_upper
    free = ~fixed
    out = x.copy()
    out[at_lower] = lb[at_lower]
    out[at_upper] = ub[at_upper]
    nf = int(free.sum())
    m = 0 if A is None else A.shape[0]
    if nf == 0 or nf < m:
        return None
    K = np.zeros((nf + m, nf + m))
    K[:nf, :nf] = P[np.ix_(free, free)]
    rhs = np.empty(nf + m)
    rhs[:nf] = -(c[free] + P[np.ix_(free, fixed)] @ out[fixed])
    if A is not None and m:
        AF = A[:, free]
        K[:nf, nf:] = AF.T
        K[nf:, :nf] = AF
        rhs[nf:] = b - A[:, fixed] @ out[fixed]
    try:
        solution = np.linalg.solve(K, rhs)
    except np.linalg.LinAlgError:
        return None
    if not np.all(np.isfinite(solution)):
        return None
    out[free] = solution[:nf]
    if np.any(out < lb - tol) or np.any(out > ub + tol):
        return None
    g = P @ out + c
    if A is not None and m:
        g += A.T @ solution[nf:]
    if np.any(g[at_lower] < -tol) or np.any(g[at_upper] > tol):
        return None
    result: FloatArray = np.clip(out, lb, ub)
    return result


@nb.njit(cache=True, nogil=True)
def _active_set(lam: np.ndarray, sense: np.ndarray, n: int) -> None:
    """DAQP's warm start from its multipliers: bit 1 active, bit 2 the lower side."""
    for i in range(n):
        sense[i] = 1 if lam[i] > 0.0 else (3 if lam[i] < 0.0 else 0)


class _Daqp(DirectBackend):
    """DAQP: the bounds as its simple bounds, the task rows as equalities.

    A cold solve is one ``daqp.solve`` call, independent of the others (one step of
    :func:`optik.diff_ik`). Warm solves (the ``qp:daqp`` IK loop) share a ``daqp.Model``
    workspace, set up once and updated in place, which starts each solve from the
    previous one's active set, or from that of the cold solve just before. Measured on
    the Panda's least-squares steps (CPU time, one process): a warm update and solve 15
    µs against 18 µs for ``daqp.solve`` with the active set passed as constraint senses;
    a cold update and solve 0.8 µs slower than ``daqp.solve``, hence the two paths.
    """

    def __init__(self, backend: str, n: int, m: int) -> None:
        import daqp

        super().__init__(backend, n, m)
        self._solve_daqp = daqp.solve
        self._model = daqp.Model()
        self._ready = False
        self._options = BACKEND_OPTIONS["daqp"]
        self._upper = np.empty(n + m)
        self._lower = np.empty(n + m)
        self._sense = np.zeros(n + m, dtype=np.intc)
        self._sense[n:] = 5  # equality constraints
        self._cold = self._sense.copy()
        self._no_rows = np.zeros((0, n))
        #: The multipliers of the last cold solve, for the next warm one (else None).
        self._cold_lam: np.ndarray | None = None

    def _solve(self, qp: ScaledProgram, warm: bool) -> DirectAnswer:
        n = self.n
        lower, upper = qp.lower_stack, qp.upper_stack
        if lower is None or upper is None:
            upper, lower = self._upper, self._lower
            upper[:n] = qp.ub
            lower[:n] = qp.lb
            if self.m:
                upper[n:] = qp.b
                lower[n:] = qp.b
        A = qp.A if self.m else self._no_rows
        if not warm:
            x, _, flag, info = self._solve_daqp(
                qp.P, qp.c, A, upper, lower, self._cold, **self._options
            )
            self._cold_lam = info["lam"]
        else:
            sense = None  # the model's own state: the previous warm solve's active set
            if self._cold_lam is not None:
                # DAQP's sense bit 1 marks a constraint active, bit 2 its lower side.
                _active_set(self._cold_lam, self._sense, n)
                sense, self._cold_lam = self._sense, None
            model = self._model
            if self._ready:
                model.update(
                    H=qp.P, f=qp.c, A=A if self.m else None, bupper=upper, blower=lower,
                    sense=sense,
                )  # fmt: skip
            else:
                flag, _ = model.setup(
                    qp.P, qp.c, A, upper, lower, self._cold if sense is None else sense
                )
                if flag < 0:
                    return None, False, f"daqp setup exit flag {flag}", -1
                model.settings = self._options
                self._ready = True
            x, _, flag, info = model.solve()
        found = flag > 0
        return (
            (np.asarray(x) if found else None),
            found,
            f"daqp exit flag {flag}",
            int(info.get("iterations", -1)),
        )


class _Proxqp(DirectBackend):
    """ProxQP's dense ``QP`` object: the bounds as its box constraints, updated per step."""

    def __init__(self, backend: str, n: int, m: int) -> None:
        from proxsuite import proxqp

        super().__init__(backend, n, m)
        self._proxqp = proxqp
        options = BACKEND_OPTIONS["proxqp"]
        qp = proxqp.dense.QP(n, m, 0, True)
        qp.settings.eps_abs = options["eps_abs"]
        qp.settings.eps_rel = options["eps_rel"]
        qp.settings.max_iter = options["max_iter"]
        qp.settings.verbose = False
        self._qp = qp
        self._initialized = False
        self._P = np.zeros((n, n))

    def _solve(self, qp: ScaledProgram, warm: bool) -> DirectAnswer:
        P, c, lb, ub = qp.P, qp.c, qp.lb, qp.ub
        A_eq = qp.A if self.m else None
        b_eq = qp.b if self.m else None
        solver = self._qp
        # Always cold: warm-starting from the previous result (or from its x and z) made
        # the qp:proxqp IK loop 10-15x slower on the Panda (30 targets: median 0.86 ms cold,
        # 12.7 ms warm), the step programs of successive iterations being too different.
        solver.settings.initial_guess = self._proxqp.InitialGuess.NO_INITIAL_GUESS
        if self._initialized:
            # The preconditioner of the first program is kept (recomputing it doubles the
            # cost; the programs come equilibrated, and ProxQP's stopping test is on the
            # unscaled residuals), and an unchanged H (least norm: I) is not passed again,
            # which spares its factorization setup.
            H = None if np.array_equal(P, self._P) else P
            if H is not None:
                self._P[:] = P
            solver.update(H, c, A_eq, b_eq, None, None, None, lb, ub, update_preconditioner=False)
        else:
            solver.init(P, c, A_eq, b_eq, None, None, None, lb, ub)
            self._P[:] = P
            self._initialized = True
        solver.solve()
        info = solver.results.info
        found = info.status == self._proxqp.QPSolverOutput.PROXQP_SOLVED
        x = np.array(solver.results.x)
        return x, bool(found), str(info.status), int(info.iter)


class _Osqp(DirectBackend):
    """OSQP's own ``OSQP`` object: set up once on the dense pattern, updated per step.

    Rows of its constraint matrix: the task rows (equalities, ``l = u = b``), then the
    identity for the bounds. Its cost matrix is the upper triangle of ``P``.
    """

    def __init__(self, backend: str, n: int, m: int) -> None:
        import osqp

        super().__init__(backend, n, m)
        self._osqp = osqp
        self._solver: Any = None
        rows, cols = np.triu_indices(n)
        order = np.lexsort((rows, cols))  # CSC: column by column, rows ascending
        self._p_rows, self._p_cols = rows[order], cols[order]
        self._p_indptr = np.concatenate([[0], np.cumsum(np.arange(1, n + 1))])
        self._a_data = np.empty((n, m + 1))
        self._a_data[:, m] = 1.0
        self._a_indices = np.concatenate([np.append(np.arange(m), m + j) for j in range(n)])
        self._a_indptr = np.arange(0, n * (m + 1) + 1, m + 1)
        self._l = np.empty(m + n)
        self._u = np.empty(m + n)
        self._zeros_x = np.zeros(n)
        self._zeros_y = np.zeros(m + n)

    def _solve(self, qp: ScaledProgram, warm: bool) -> DirectAnswer:
        n, m = self.n, self.m
        Px = qp.P[self._p_rows, self._p_cols]
        if m:
            self._a_data[:, :m] = qp.A.T
        Ax = self._a_data.ravel()
        if m:
            self._l[:m] = qp.b
            self._u[:m] = qp.b
        self._l[m:] = qp.lb
        self._u[m:] = qp.ub
        if self._solver is None:
            solver = self._osqp.OSQP()
            solver.setup(
                spa.csc_matrix((Px, self._p_rows, self._p_indptr), shape=(n, n)),
                qp.c,
                spa.csc_matrix((Ax, self._a_indices, self._a_indptr), shape=(m + n, n)),
                self._l,
                self._u,
                verbose=False,
                **BACKEND_OPTIONS["osqp"],
            )
            self._solver = solver
        else:
            self._solver.update(Px=Px, Ax=Ax, q=qp.c, l=self._l, u=self._u)
            if not warm:
                self._solver.warm_start(x=self._zeros_x, y=self._zeros_y)
        result = self._solver.solve(raise_error=False)
        status = str(result.info.status)
        x = None if result.x is None else np.asarray(result.x, dtype=np.float64)
        found = result.info.status_val == 1 and x is not None
        return x, bool(found), status, int(result.info.iter)


#: Backends called through their own API (the others through ``qpsolvers``): measured in
#: ``benchmarks/bench_programs.py``.
_OWN_API: Final[dict[str, type[DirectBackend]]] = {
    "daqp": _Daqp,
    "proxqp": _Proxqp,
    "osqp": _Osqp,
}

_local = threading.local()


def direct_backend(backend: str, n: int, m: int) -> DirectBackend:
    """The calling thread's direct backend for programs of ``n`` joints and ``m`` rows."""
    cache: dict[tuple[str, int, int], DirectBackend] | None = getattr(_local, "solvers", None)
    if cache is None:
        cache = _local.solvers = {}
    key = (backend, n, m)
    solver = cache.get(key)
    if solver is None:
        solver = cache[key] = _OWN_API.get(backend, DirectBackend)(backend, n, m)
    return solver


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
        lm = np.array(
            [np.inf, 0.0, 0.0, self.initial_scale, self.w_bias, self.trust_radius,
             self.trust_ratio, self.min_scale]
        )  # fmt: skip
        buffers = arrays.buffers
        code = _lm_move(*buffers, arrays.zero_step, q, e, q_new, e_new, vmax, lm)
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
            code = _lm_move(*buffers, x, q, e, q_new, e_new, vmax, lm)
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


@nb.njit(cache=True, nogil=True, error_model="numpy")
def _lm_fill(
    buffers: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, bool],
    q: np.ndarray,
    e: np.ndarray,
    vmax: np.ndarray,
    lm: np.ndarray,
) -> int:
    """Fill the step program at ``q`` for the residual ``e`` with the loop's damping.

    ``buffers`` is :attr:`~optik.programs.step_arrays.StepArrays.buffers`. The trust
    radius ``min(trust_radius, trust_ratio ||e||)`` goes into ``vmax`` (dof,), the damping
    is ``sqrt(s (||e||^2 / 2 + w_bias))`` (see :class:`QPStepSolver`); ``lm`` is the
    loop's state. Returns the code of :func:`~optik.programs.step_arrays.fill_step`.
    """
    err2 = lm[_ERR2]
    radius = min(lm[_RADIUS], lm[_RATIO] * math.sqrt(err2))
    for i in range(vmax.shape[0]):
        vmax[i] = radius
    damping = math.sqrt(lm[_SCALE] * (0.5 * err2 + lm[_W_BIAS]))
    const, const_layout, ints, buf, layout, identity = buffers
    return fill_step(
        const, const_layout, ints, q, e, vmax, buf, layout, 1.0, True, Q_CLIP_TOLERANCE,
        MAX_LENGTH_M, 1.0, True, True, damping, identity,
    )  # fmt: skip


@nb.njit(cache=True, nogil=True, error_model="numpy")
def _lm_move(
    const: np.ndarray,
    const_layout: np.ndarray,
    ints: np.ndarray,
    buf: np.ndarray,
    layout: np.ndarray,
    identity: bool,
    x: np.ndarray,
    q: np.ndarray,
    e: np.ndarray,
    q_new: np.ndarray,
    e_new: np.ndarray,
    vmax: np.ndarray,
    lm: np.ndarray,
) -> int:
    """Marquardt's move on the backend's point ``x``, then the next program (one call).

    The step is taken (``q``, ``e`` and the errors in ``lm`` replaced, the scale halved
    down to ``min_scale``) if it lowers ``||e||^2``, else refused (the scale quadrupled);
    then :func:`_lm_fill` at the resulting ``q``. Returns its code, or :data:`_NOT_FINITE`.

    An attempt starts with ``lm``'s squared error at ``inf`` and ``x`` zeros (nv,): the
    program is first filled at ``q`` with a zero residual (its bounds contain 0), the
    zero step measures the residual ``e`` and the errors at ``q``, the scale stays.
    """
    start = not lm[_ERR2] < np.inf
    if start:
        e[:] = 0.0
        fill_step(
            const, const_layout, ints, q, e, vmax, buf, layout, 1.0, True, Q_CLIP_TOLERANCE,
            MAX_LENGTH_M, 1.0, False, True, 0.0, identity,
        )  # fmt: skip
    err2, position, orientation = take_step(
        const, const_layout, ints, buf, layout, identity, x, q_new, e_new
    )
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
    return _lm_fill((const, const_layout, ints, buf, layout, identity), q, e, vmax, lm)


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
