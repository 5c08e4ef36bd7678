"""The ``casadi:<plugin>`` step backends: CasADi conic (QP) plugins solving step programs.

:func:`optik.programs.casadi_qp.build_conic` puts a step program into ``casadi.conic``'s
standard form; this module builds the conic solver for it and solves it. A conic solver
depends only on the plugin and the (dense) sparsity of ``H`` and ``A``, so it is built
once per ``(plugin, dof, rows of A)`` and reused for every step.
:func:`casadi_conic_plugins` lists the plugins of this CasADi build that solve a probe QP
correctly; :data:`CONIC_OPTIONS` holds the quiet, tight options used for each; each of
them is registered as a ``"step"`` solver ``casadi:<plugin>``.
"""

from __future__ import annotations

import contextlib
import functools
import os
import sys
import threading
from collections.abc import Iterator
from typing import Any, Final

import casadi
import numpy as np

from optik._checks import FloatArray
from optik._interrupts import reraise_interrupt
from optik.programs.casadi_qp import ConicProgram, build_conic
from optik.programs.diff_qp import DiffIKProgram, QPSolution
from optik.solvers._base import StepBackend, register_solver
from optik.solvers.qp import BACKEND_OPTIONS

__all__ = [
    "CANDIDATE_PLUGINS",
    "CONIC_OPTIONS",
    "EXCLUDED_PLUGINS",
    "ConicStepBackend",
    "casadi_conic_plugins",
    "solve_conic",
]

#: Options of each conic plugin: no output, tolerances as tight as the plugin reaches
#: reliably (measured accuracies in ``docs/programs.md``). ``error_on_fail`` is off
#: everywhere: a failure is read from ``stats()`` and reported, never raised.
CONIC_OPTIONS: Final[dict[str, dict[str, Any]]] = {
    # CasADi's own active-set QP solver (dense QR of the KKT system).
    "qrqp": {
        "print_iter": False,
        "print_header": False,
        "print_info": False,
        "constr_viol_tol": 1e-12,
        "dual_inf_tol": 1e-12,
    },
    # CasADi's own interior-point QP solver.
    "ipqp": {
        "print_iter": False,
        "print_header": False,
        "print_info": False,
        "constr_viol_tol": 1e-12,
        "dual_inf_tol": 1e-12,
    },
    # OSQP 1.0 inside CasADi, set as the qpsolvers backend (see optik.solvers.qp): 1e-10,
    # no Ruiz scaling (programs come equilibrated), no polishing (it prints to stdout).
    "osqp": {"osqp": {"verbose": False, **BACKEND_OPTIONS["osqp"]}},
    "proxqp": {"proxqp": {"eps_abs": 1e-12, "eps_rel": 0.0, "verbose": False, "max_iter": 10_000}},
    "qpoases": {"printLevel": "none", "terminationTolerance": 1e-12},
    "daqp": {"daqp": {"primal_tol": 1e-12, "dual_tol": 1e-12}},
    # Interior point: the duality-gap test must be on and tight too, else it stops 1e-9
    # from the closed forms (measured); bounds are approached to within ~4e-9.
    "piqp": {
        "piqp": {
            "verbose": False,
            "eps_abs": 1e-12,
            "eps_rel": 0.0,
            "check_duality_gap": True,
            "eps_duality_gap_abs": 1e-12,
            "eps_duality_gap_rel": 0.0,
        }
    },
    "superscs": {"superscs": {"verbose": 0, "eps": 1e-10, "max_iters": 100_000}},
}

#: Plugins probed by :func:`casadi_conic_plugins`: the open-source QP plugins that ship
#: with the CasADi wheel. ``fatrop`` and ``hpipm`` are left out (they expect an
#: optimal-control, stage-wise structure), and so are the commercial ones (``cplex``,
#: ``gurobi``, ``mosek``, ``xpress``), whose loaders print warnings when absent; add a
#: name here (and its options to :data:`CONIC_OPTIONS`) to probe it too.
CANDIDATE_PLUGINS: Final[tuple[str, ...]] = (
    "qrqp",
    "ipqp",
    "osqp",
    "proxqp",
    "qpoases",
    "daqp",
    "piqp",
    "superscs",
)

#: Plugins that load but give wrong answers on these programs, with the reason; they are
#: never listed. Measured with CasADi 3.8.2.
EXCLUDED_PLUGINS: Final[dict[str, str]] = {
    "highs": (
        "HiGHS 1.13 reports 'Optimal' after 0 QP iterations on a QP without constraint rows "
        "(every least-squares step) at points whose gradient is far from zero (relative "
        "errors 1e-4 to 1 on Jacobian programs with condition numbers 5e2-1e6)"
    ),
}

#: Plugins that print a banner when a solver is created, whatever their options; their
#: construction and first call run with the process's stdout sent to /dev/null.
_BANNER_PLUGINS: Final[frozenset[str]] = frozenset({"qpoases"})

# Creation under one lock: a banner plugin's redirects the whole process's stdout.
_lock = threading.Lock()
# One solver per thread and shape: a casadi.Function's call and its stats() share one
# memory, and the plugins (daqp, proxqp, qrqp) crashed the process when two threads
# called the same Function.
_local = threading.local()


@contextlib.contextmanager
def _silenced_stdout() -> Iterator[None]:
    """Send file descriptor 1 to /dev/null (C libraries print there, not via ``sys``)."""
    try:
        sys.stdout.flush()
        fd = sys.stdout.fileno()
    except (AttributeError, OSError, ValueError):
        fd = 1
    saved = os.dup(fd)
    try:
        with open(os.devnull, "w") as null:
            os.dup2(null.fileno(), fd)
            try:
                yield
            finally:
                os.dup2(saved, fd)
    finally:
        os.close(saved)


def _new_solver(plugin: str, n: int, m: int) -> casadi.Function:
    """A conic solver for dense ``H`` (n, n) and ``A`` (m, n), quiet and tight."""
    options = {"error_on_fail": False, **CONIC_OPTIONS.get(plugin, {})}
    sparsity = {"h": casadi.Sparsity.dense(n, n), "a": casadi.Sparsity.dense(m, n)}
    name = f"optik_{plugin}_{n}x{m}"
    if plugin not in _BANNER_PLUGINS:
        return casadi.conic(name, plugin, sparsity, options)
    with _silenced_stdout():
        solver = casadi.conic(name, plugin, sparsity, options)
        solver(h=np.eye(n), g=np.zeros(n), a=np.zeros((m, n)), lba=0.0, uba=0.0)
    return solver


def _solver(plugin: str, n: int, m: int) -> casadi.Function:
    """The calling thread's conic solver for ``(plugin, n, m)``, built on its first use."""
    solvers: dict[tuple[str, int, int], casadi.Function] | None = getattr(_local, "solvers", None)
    if solvers is None:
        solvers = _local.solvers = {}
    key = (plugin, n, m)
    solver = solvers.get(key)
    if solver is None:
        with _lock:
            solver = solvers[key] = _new_solver(plugin, n, m)
    return solver


def _probe(plugin: str) -> bool:
    """Whether ``plugin`` loads and solves both shapes of step program correctly.

    1. ``min (x0 - 1)^2 + (x1 - 2)^2 + x2^2  s.t.  x0 + x1 + x2 = 1,  x1 <= 0.5`` (an
       equality row, an active bound, infinite bounds elsewhere): ``(0.75, 0.5, -0.25)``.
    2. a dense 7-variable QP without rows, ``H = M^T M + 1e-2 I`` (``M`` a fixed 6x7
       matrix, condition number about 2e3), infinite bounds: ``x = -H^-1 g``.

    Both must be met to 1e-6 (relative), whatever the plugin claims.
    """
    try:
        if not casadi.has_conic(plugin):
            return False
        first = _solver(plugin, 3, 1)(
            h=2.0 * np.eye(3),
            g=np.array([-2.0, -4.0, 0.0]),
            a=np.ones((1, 3)),
            lba=1.0,
            uba=1.0,
            lbx=np.full(3, -np.inf),
            ubx=np.array([np.inf, 0.5, np.inf]),
        )
        x1 = np.asarray(first["x"], dtype=np.float64).ravel()
        if not np.max(np.abs(x1 - np.array([0.75, 0.5, -0.25]))) < 1e-6:
            return False
        M = np.cos(np.arange(42.0).reshape(6, 7) * 1.3 + 0.2)
        H = M.T @ M + 1e-2 * np.eye(7)
        g = -M.T @ np.linspace(-1.0, 1.0, 6)
        second = _solver(plugin, 7, 0)(h=H, g=g, lbx=np.full(7, -np.inf), ubx=np.full(7, np.inf))
        x2 = np.asarray(second["x"], dtype=np.float64).ravel()
        expected = np.linalg.solve(H, -g)
        return bool(np.max(np.abs(x2 - expected)) < 1e-6 * np.max(np.abs(expected)))
    except Exception:  # a plugin that cannot load or run is not listed
        return False


@functools.cache
def casadi_conic_plugins() -> tuple[str, ...]:
    """Conic plugins of this CasADi build that load and solve a probe QP, in probe order.

    Each of :data:`CANDIDATE_PLUGINS` is loaded and must solve two probe QPs (one with an
    equality row and an active bound, one dense without rows) to 1e-6, whatever it
    claims; the result is cached for the process. In CasADi 3.8.2 this excludes ``ipqp``
    (NaN with infinite bounds) and ``superscs`` (a wrong point reported as success);
    ``highs`` is not probed at all (see :data:`EXCLUDED_PLUGINS`).
    """
    return tuple(plugin for plugin in CANDIDATE_PLUGINS if _probe(plugin))


def solve_built(conic: ConicProgram) -> QPSolution:
    """Run the plugin on a built conic program; a failure comes back as ``found=False``."""
    name = f"casadi:{conic.plugin}"
    if not conic.program.bounds_consistent:
        return QPSolution(None, False, "inconsistent bounds (lower > upper)", name)
    try:
        solver = _solver(conic.plugin, *conic.shape)
        result = solver(**conic.args)
        stats = solver.stats()
    except Exception as exc:  # keep the plugin's message
        reraise_interrupt(exc)  # Ctrl-C is the caller's, not a failure
        return QPSolution(None, False, f"{type(exc).__name__}: {exc}", name)
    x = np.asarray(result["x"], dtype=np.float64).ravel() / conic.scale
    status = str(stats.get("return_status", "") or ("success" if stats.get("success") else ""))
    iterations = int(stats.get("iter_count", -1) or -1)
    return QPSolution(x, bool(stats.get("success", False)), status, name, iterations)


def solve_conic(program: DiffIKProgram, plugin: str) -> QPSolution:
    """Build the conic form of ``program`` for ``plugin`` and solve it, unchecked."""
    return solve_built(build_conic(program, plugin))


class ConicStepBackend(StepBackend):
    """One step program solved by the CasADi conic plugin ``plugin``."""

    def __init__(self, plugin: str) -> None:
        self.plugin = plugin
        self.name = f"casadi:{plugin}"

    def solve(self, program: DiffIKProgram, initvals: FloatArray | None = None) -> QPSolution:
        """The plugin's answer and claim, unchecked (``initvals`` is not used)."""
        return solve_conic(program, self.plugin)


def _register_all() -> None:
    """Register ``casadi:<plugin>`` as a step backend for every candidate conic plugin."""
    for plugin in CANDIDATE_PLUGINS:

        def factory(plugin: str = plugin) -> StepBackend:
            return ConicStepBackend(plugin)

        def available(plugin: str = plugin) -> bool:
            return plugin in casadi_conic_plugins()

        register_solver(
            f"casadi:{plugin}",
            factory,
            available,
            f"The CasADi conic plugin {plugin!r} does not load or fails optik's probe QP "
            "in this CasADi build.",
            kind="step",
        )


_register_all()
