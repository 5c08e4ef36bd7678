"""The QP backends' own APIs, set up once per program shape and then updated.

``diff_ik`` and the ``qp:<backend>`` IK loop (:mod:`optik.solvers.qp`) call DAQP, ProxQP
and OSQP through their own interfaces on the filled arrays of
:mod:`optik.programs.step_arrays`; the other backends go through ``qpsolvers``. Every
backend gets the tolerances of :data:`BACKEND_OPTIONS`.
"""

from __future__ import annotations

import threading
import warnings
from typing import Any, Final

import numpy as np
import qpsolvers
import qpsolvers.solvers
import scipy.sparse as spa
from scipy.linalg import cho_factor, cho_solve

from optik._checks import FloatArray
from optik._interrupts import reraise_interrupt
from optik._numba import jit
from optik.programs.step_arrays import (
    ScaledProgram,
)

__all__ = [
    "BACKEND_OPTIONS",
    "DirectBackend",
    "backend_iterations",
    "direct_backend",
    "polish",
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
    # Steps take at most 68 iterations (881 steps, Panda, UR5, Puma); 10,000 outer times
    # 1,500 inner let one stalled step run 15 million (45 s: a kilometre UR5 stretched,
    # past any timeout_s, which is checked between steps). The direct backend also caps
    # the inner loop (PROXQP_MAX_ITER_IN): 1e5 iterations, 0.3 s, at the most.
    "proxqp": {"eps_abs": 1e-12, "eps_rel": 0.0, "backend": "dense", "max_iter": 1_000},
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


def backend_iterations(solution: qpsolvers.Solution) -> int:
    """Iterations reported by the backend, when its extras hold them (else -1)."""
    info = solution.extras.get("info") if isinstance(solution.extras, dict) else None
    for attr in ("iter", "iter_ext", "iterations"):
        value = getattr(info, attr, None)
        if isinstance(value, int | np.integer):
            return int(value)
    return -1


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
            reraise_interrupt(exc)  # Ctrl-C is the caller's, not a failure
            return None, False, f"{type(exc).__name__}: {exc}", -1

    def _solve(self, qp: ScaledProgram, warm: bool) -> DirectAnswer:
        """Through ``qpsolvers.solve_problem`` (the backends without an own-API path).

        A program without constraints or bounds is solved here (:func:`_unconstrained`).
        """
        P, c, A, b, lb, ub = qp.P, qp.c, qp.A, qp.b, qp.lb, qp.ub
        fixed = np.isfinite(lb) & (lb == ub)
        if np.any(fixed):
            return self._solve_fixed(qp, fixed)
        Pm: Any = P
        Am: Any = A if self.m else None
        if self.backend in qpsolvers.sparse_solvers and self.backend not in qpsolvers.dense_solvers:
            Pm = spa.csc_matrix(P)
            Am = None if Am is None else spa.csc_matrix(Am)
        bounded = bool(np.any(np.isfinite(lb)) or np.any(np.isfinite(ub)))
        if not bounded and not self.m:
            unconstrained = _unconstrained(P, c)
            if unconstrained is not None:
                self._last = unconstrained
                return unconstrained, True, "solved (unconstrained: P x = -c by Cholesky)", 0
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
        return x, bool(solution.found and x is not None), status, backend_iterations(solution)

    _last: FloatArray | None = None

    def _solve_fixed(self, qp: ScaledProgram, fixed: np.ndarray) -> DirectAnswer:
        """The program with the variables of ``fixed`` (``lb == ub``) substituted out.

        quadprog turns each bound into an inequality, and a zero-width box into two
        opposite ones, which its dual active set may take for inconsistent (a Panda step
        with two joints at speed 0: "no point returned"); substituted, the backend sees
        only the free variables. The answer is the full point (n,), checked as any other.
        """
        free = ~fixed
        x = np.where(fixed, qp.lb, 0.0)
        nf = int(np.count_nonzero(free))
        if nf == 0:
            self._last = x
            return x, True, "every variable fixed by its bounds", 0
        xf = x[fixed]
        P_free = qp.P[np.ix_(free, free)]
        c_free = qp.c[free] + qp.P[np.ix_(free, fixed)] @ xf
        A_free = qp.A[:, free] if self.m else np.zeros((0, nf))
        b_free = qp.b - qp.A[:, fixed] @ xf if self.m else qp.b
        reduced = ScaledProgram(
            P_free, c_free, A_free, b_free, qp.lb[free], qp.ub[free], None, None
        )
        answer, found, status, iterations = DirectBackend(self.backend, nf, self.m)._solve(
            reduced, warm=False
        )
        if answer is not None:
            x[free] = answer
        self._last = None if answer is None else x
        return (None if answer is None else x), found, status, iterations


def _unconstrained(P: FloatArray, c: FloatArray) -> FloatArray | None:
    """``argmin ½ x^T P x + c^T x`` for a positive definite ``P``, else ``None``.

    qpsolvers hands a program without constraints to SciPy's LSQR instead of the backend
    (Clarabel's wrapper does), and LSQR's default tolerances leave a residual above the
    1e-8 it then accepts: it raised "unbounded below" on most well-conditioned damped
    least-squares steps. A Cholesky solve is exact to rounding.
    """
    try:
        factor = cho_factor(P)
    except np.linalg.LinAlgError:
        return None
    x = cho_solve(factor, -c)
    return x if np.all(np.isfinite(x)) else None


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


@jit
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


PROXQP_MAX_ITER_IN = 100
"""Iterations of ProxQP's inner loop per outer one (its default 1,500; ours take 1)."""


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
        qp.settings.max_iter_in = PROXQP_MAX_ITER_IN
        # Its infeasibility tests (1e-4) called feasible steps of a millimetre arm (rows
        # of 1e-3 m) infeasible; optik's own check judges an unsolved step anyway.
        qp.settings.eps_primal_inf = 1e-12
        qp.settings.eps_dual_inf = 1e-12
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
            # The step size rho adapts during a solve and would carry over: reset, so an
            # answer does not depend on what this thread solved before.
            self._solver.update_settings(rho=_OSQP_RHO)
            if not warm:
                self._solver.warm_start(x=self._zeros_x, y=self._zeros_y)
        result = self._solver.solve(raise_error=False)
        status = str(result.info.status)
        x = None if result.x is None else np.asarray(result.x, dtype=np.float64)
        found = result.info.status_val == 1 and x is not None
        return x, bool(found), status, int(result.info.iter)


#: OSQP's initial step size (its default), restored before every solve.
_OSQP_RHO: Final[float] = 0.1

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
