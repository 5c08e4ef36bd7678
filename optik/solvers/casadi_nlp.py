"""The ``casadi:<nlpsol>`` family (``casadi:ipopt``, ``casadi:sqpmethod``): IK as one NLP.

The program is :func:`optik.programs.nlp.build_nlp` (data: the task's weighted
least-squares residual, its Gauss–Newton Hessian, the target and weights as parameters),
built once per robot and task shape; :func:`nlp_backend` builds the ``casadi.nlpsol``
solver on it once per plugin and iteration limit, compiled to C and cached on disk
(``sqpmethod`` whole, :func:`optik.programs.nlp_codegen.compiled_solver`; Ipopt on its
compiled functions, :func:`optik.programs.nlp_codegen.compiled_nlpsol`), and every query
only passes numbers: the target, the weights and the query's bounds (the joint limits
narrowed by ``limit_margin``, closed on frozen joints). Those numbers go through
preallocated arrays that a ``casadi.FunctionBuffer`` reads and writes (one per thread
at a time), not through ``Function.__call__``'s dictionaries of ``casadi.DM``.

Each attempt is warm-started from a start of the one start policy
(:mod:`optik.solvers._starts`: the closed-form branches or ``q0``, then the seed-table
entries nearest the target) and runs solves of at most :data:`SOLVE_ITER` iterations:
when one stops short of the task's tolerances the next starts where it stopped, as long
as the squared residual fell to :data:`PROGRESS_RATIO` of what it was (or is already
small); otherwise the attempt ends and the next start is tried. Success is judged from FK
(:mod:`optik.verify`), not by the solver's claim, so the solvers stop as soon as the
answer is well inside the tolerances (Ipopt: at the first iterate whose objective changes
by less than :data:`OBJECTIVE_CHANGE_TOL`).
"""

from __future__ import annotations

import functools
import math
import threading
import weakref
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Final

import casadi
import numpy as np

from optik import _kernels
from optik._checks import FloatArray, as_float_array, check_int, finite_array
from optik._clock import one_time_setup
from optik._interrupts import reraise_interrupt
from optik.errors import OptikError
from optik.model import Robot
from optik.programs.nlp import NLPProgram, NLPSolution, build_nlp, task_shape
from optik.programs.nlp_codegen import (
    MAX_THREADS,
    CompiledSolver,
    CompileReport,
    Monitor,
    compiled_monitor,
    compiled_nlpsol,
    compiled_solver,
)
from optik.solvers._base import (
    IKQuery,
    IKSolver,
    SolverOutput,
    budget_now,
    register_solver,
    search_length,
)
from optik.task import BALANCE_BAND, Task, task_error

__all__ = [
    "NLP_OPTIONS",
    "OBJECTIVE_CHANGE_TOL",
    "PROGRESS_RATIO",
    "SOLVE_ITER",
    "STOP_FRACTION",
    "CasadiNLPSolver",
    "NLPBackend",
    "nlp_backend",
    "stop_objective",
]

#: Ipopt stops at the first iterate whose objective (the squared residual) changed by
#: less than this: ``(1e-7)^2``, a tenth of the default tolerance squared.
OBJECTIVE_CHANGE_TOL: Final[float] = 1e-14

#: Options of each nonlinear solver: quiet, tight. Ipopt keeps a warm start where it is:
#: initial barrier parameter 1e-12 and, since ``warm_start_init_point`` is on, the
#: ``warm_start_*`` pushes (Ipopt's defaults of 1e-3 put the bound multipliers at 1e-3,
#: a million times the barrier parameter, which held answers near a limit at errors of
#: 1e-6 for many iterations). It stops when converged (``tol``) or at the first iterate
#: whose objective changes by less than :data:`OBJECTIVE_CHANGE_TOL` (the ``acceptable``
#: test with every other part switched off): converged to well inside the verification's
#: tolerances, or stalled, which the next start handles (or earlier, at the task's
#: tolerances, by its monitor: :data:`MONITORED`). Each Ipopt iteration does the least
#: work that still solves these small, well-posed systems: one MUMPS solve, without
#: iterative refinement or the residual check (``fast_step_computation``), and no
#: second-order corrections (bounds only, no constraint to correct): 25 % fewer
#: instructions per Panda solve, the same iterates on 391 recorded solves (measured).
#: sqpmethod uses CasADi's own active-set QP solver ``qrqp``. Both take the program's
#: Gauss–Newton Hessian; neither computes the parameters' multipliers (``lam_p``, unused).
NLP_OPTIONS: Final[dict[str, dict[str, Any]]] = {
    "ipopt": {
        "print_time": False,
        "calc_lam_p": False,
        "ipopt.print_level": 0,
        "ipopt.sb": "yes",
        "ipopt.tol": 1e-12,
        "ipopt.mu_init": 1e-12,
        "ipopt.warm_start_init_point": "yes",
        "ipopt.warm_start_bound_push": 1e-9,
        "ipopt.warm_start_bound_frac": 1e-9,
        "ipopt.warm_start_mult_bound_push": 1e-9,
        "ipopt.acceptable_iter": 1,
        "ipopt.acceptable_tol": 1e30,
        "ipopt.acceptable_dual_inf_tol": 1e30,
        "ipopt.acceptable_constr_viol_tol": 1e30,
        "ipopt.acceptable_compl_inf_tol": 1e30,
        "ipopt.acceptable_obj_change_tol": OBJECTIVE_CHANGE_TOL,
        "ipopt.fast_step_computation": "yes",
        "ipopt.min_refinement_steps": 0,
        "ipopt.max_refinement_steps": 0,
        "ipopt.max_soc": 0,
    },
    "sqpmethod": {
        "print_time": False,
        "calc_lam_p": False,
        "print_header": False,
        "print_iteration": False,
        "print_status": False,
        # DAQP (a dual active-set solver; the compiled solver links the library CasADi
        # ships): CasADi's qrqp corrupted the C heap on an unreachable Panda target (the
        # process aborted at a later free, with or without code generation). The same
        # iterations on 200 reachable Panda targets, 0.14 ms per solve against 0.19.
        "qpsol": "daqp",
        "qpsol_options": {
            "error_on_fail": False,
        },
        "tol_pr": 1e-10,
        "tol_du": 1e-10,
        "min_step_size": 1e-16,
    },
}

_MAX_ITER_OPTION: Final[dict[str, str]] = {"ipopt": "ipopt.max_iter", "sqpmethod": "max_iter"}

GAUSS_NEWTON_TRIU: Final[dict[str, bool]] = {"ipopt": True, "sqpmethod": False}
"""The plugins given the program's Gauss–Newton Hessian (the ``hess_lag`` option), and
whether they take its upper triangle (Ipopt) or the full matrix; other plugins get
CasADi's exact Hessian of the Lagrangian."""

WHOLE_SOLVER: Final[frozenset[str]] = frozenset({"sqpmethod"})
"""The plugins compiled to C whole (:func:`optik.programs.nlp_codegen.compiled_solver`);
the others run as ``casadi.nlpsol`` on their compiled functions. Ipopt compiled whole
(CasADi generates it on Ipopt's C interface) measured no faster: Ipopt's own work per
solve dominates."""

MONITORED: Final[frozenset[str]] = frozenset({"ipopt"})
"""The plugins given a compiled iteration callback
(:func:`optik.programs.nlp_codegen.compiled_monitor`): it counts the iterations (no
``stats()`` after a solve it stops) and stops the solve once the objective is within the
task's tolerances (:func:`stop_objective`)."""

STOP_FRACTION: Final[float] = 0.5
"""The monitor stops at ``||r||^2 <= STOP_FRACTION w_min tol^2`` (:func:`stop_objective`):
both judged errors are then at most ``sqrt(STOP_FRACTION) tol``, about 0.71 ``tol``."""

STOP_STATUS: Final[str] = "User_Requested_Stop (objective within the task's tolerances)"

SOLVE_ITER: Final[int] = 8
"""Iterations of one solve; an attempt that needs more continues in another solve while
it makes progress (:data:`PROGRESS_RATIO`)."""

PROGRESS_RATIO: Final[float] = 0.25
"""A solve that stops short of the tolerances is continued when the squared residual fell
to this fraction of its value at the solve's start, or below :data:`PROGRESS_FLOOR`."""

PROGRESS_FLOOR: Final[float] = 1e-8
"""Squared residual (about 1e-4 m or rad) below which a solve is always continued while
it decreases (next to a singularity the last digits converge slowly, but converge)."""


class _Slot:
    """One caller's ``casadi.FunctionBuffer`` of a solver and the arrays it reads and writes.

    The buffer holds pointers into the arrays: they live as long as the slot.
    """

    def __init__(self, solver: casadi.Function, dof: int, n_parameters: int) -> None:
        self.x0 = np.zeros(dof)
        self.p = np.zeros(n_parameters)
        self.lbx = np.zeros(dof)
        self.ubx = np.zeros(dof)
        self.x = np.zeros(dof)
        self.f = np.zeros(1)
        # CasADi's stubs declare set_arg(i, pointer, size); from Python it takes a buffer.
        buffer: Any
        buffer, self.trigger = solver.buffer()
        for name in ("x0", "p", "lbx", "ubx"):
            buffer.set_arg(solver.index_in(name), memoryview(getattr(self, name)))
        buffer.set_res(solver.index_out("x"), memoryview(self.x))  # type: ignore[arg-type]
        buffer.set_res(solver.index_out("f"), memoryview(self.f))  # type: ignore[arg-type]
        self.buffer = buffer


class _SlotPool:
    """The slots of one solver: taken by a solve, given back after it; at most ``limit``.

    A whole compiled solver has :data:`~optik.programs.nlp_codegen.MAX_THREADS` memory
    slots and a buffer holds one for its lifetime, so a caller beyond the limit waits.
    """

    def __init__(self, make: Callable[[], _Slot], limit: int) -> None:
        self._make = make
        self._limit = limit
        self._made = 0
        self._free: list[_Slot] = []
        self._lock = threading.Lock()
        self._given = threading.Condition(self._lock)

    def take(self) -> _Slot:
        with self._lock:
            while not self._free and self._made >= self._limit:
                self._given.wait()
            if self._free:
                return self._free.pop()
            # Made under the lock: a buffer checks out a memory slot of the generated
            # code, whose checkout is not thread-safe.
            slot = self._make()
            self._made += 1
            return slot

    def give(self, slot: _Slot) -> None:
        with self._lock:
            self._free.append(slot)
            self._given.notify()


#: Buffers of one ``casadi.nlpsol`` solver alive at a time (CasADi's own memory pool grows).
_NLPSOL_SLOTS: Final[int] = 1024


@dataclass(frozen=True, eq=False)
class NLPBackend:
    """A ``casadi.nlpsol`` solver built on one :class:`~optik.programs.nlp.NLPProgram`.

    Built by :func:`nlp_backend` (cached) and reused for every target.

    Attributes:
        program: the program it solves.
        plugin: the ``casadi.nlpsol`` plugin.
        max_iter: the iteration limit of one solve.
        options: the options the solver was built with (``hess_lag`` and the monitor's
            ``iteration_callback`` excepted).
        solver: the solver as a ``casadi.Function`` with ``casadi.nlpsol``'s inputs and
            outputs: the nlpsol itself, or the whole solver compiled to C
            (``compiled``).
        gauss_newton: whether it uses the program's Gauss–Newton Hessian.
        compile_report: whether ``solver`` runs compiled C and what building it cost
            (:class:`~optik.programs.nlp_codegen.CompileReport`).
        compiled: the whole solver compiled (``sqpmethod``), else ``None``.
        monitor: the compiled iteration callback the solver calls (``ipopt``), else
            ``None``.
    """

    program: NLPProgram
    plugin: str
    max_iter: int
    options: dict[str, Any]
    solver: casadi.Function
    gauss_newton: bool
    compile_report: CompileReport
    compiled: CompiledSolver | None = None
    monitor: Monitor | None = None
    _slots: _SlotPool = field(init=False, repr=False)

    def __post_init__(self) -> None:
        n_parameters = int(self.program.parameters.shape[0])
        limit = MAX_THREADS - 1 if self.compiled is not None else _NLPSOL_SLOTS

        def make() -> _Slot:
            return _Slot(self.solver, self.program.dof, n_parameters)

        object.__setattr__(self, "_slots", _SlotPool(make, limit))

    def solve(
        self,
        target: Any,
        q0: Any,
        *,
        weights: Any = None,
        mu: float = 0.0,
        q_ref: Any = None,
        bounds: tuple[Any, Any] | None = None,
    ) -> NLPSolution:
        """Solve for one target from the warm start ``q0`` (dof,) (clipped into the bounds).

        Args:
            target: see :meth:`NLPProgram.parameter_vector`; so are ``weights``, ``mu``
                and ``q_ref``.
            q0: warm start (dof,).
            weights: see :meth:`NLPProgram.parameter_vector`.
            mu: see :meth:`NLPProgram.parameter_vector`.
            q_ref: see :meth:`NLPProgram.parameter_vector`.
            bounds: ``(lower, upper)`` (dof,) each inside the joint limits, default the
                limits.

        A solver failure comes back as ``success=False`` with its text in ``status``.

        Raises:
            OptikError: bad arguments (see :meth:`NLPProgram.parameter_vector`), bounds
                outside the limits or crossed.
        """
        program = self.program
        params = program.parameter_vector(target, weights=weights, mu=mu, q_ref=q_ref)
        if bounds is None:
            lower, upper = program.lbx, program.ubx
        else:
            if not isinstance(bounds, tuple | list) or len(bounds) != 2:
                raise OptikError(f"bounds must be a pair (lower, upper), got {bounds!r}")
            lower = as_float_array("bounds[0]", bounds[0])
            upper = as_float_array("bounds[1]", bounds[1])
            if lower.shape != (program.dof,) or upper.shape != (program.dof,):
                raise OptikError(f"bounds must be two arrays of shape ({program.dof},)")
            if np.any(np.isnan(lower) | np.isnan(upper)) or np.any(lower > upper):
                raise OptikError("bounds: NaN or lower > upper")
            if np.any(lower < program.lbx) or np.any(upper > program.ubx):
                raise OptikError("bounds must lie inside the joint limits")
        x0 = np.clip(finite_array("q0", q0, (program.dof,)), lower, upper)
        return self.solve_parameters(params, x0, lower, upper)

    def solve_parameters(
        self,
        params: FloatArray,
        x0: FloatArray,
        lower: FloatArray | None = None,
        upper: FloatArray | None = None,
        stop: float = -1.0,
    ) -> NLPSolution:
        """Solve for a parameter vector of :meth:`NLPProgram.parameter_vector`, unchecked.

        The inner call of :meth:`solve` for callers that validated their inputs once
        (``x0`` finite and inside the bounds, ``params`` from ``parameter_vector``);
        ``lower`` / ``upper`` (dof,) default to the joint limits. With a ``monitor``, the
        solve stops at the first iterate whose objective is at most ``stop``
        (:func:`stop_objective`; negative: never), which counts as converged.
        """
        slot = self._slots.take()
        try:
            if self.monitor is not None:
                self.monitor.start(stop)
            slot.x0[:] = x0
            slot.p[:] = params
            slot.lbx[:] = self.program.lbx if lower is None else lower
            slot.ubx[:] = self.program.ubx if upper is None else upper
            slot.trigger()
            code = slot.buffer.ret()
            iterations, success, status = self._exit(slot)
            if code != 0:
                text = f"solver failed (return code {code}: {status})"
                return NLPSolution(np.array(x0), False, text, iterations, float("nan"), True)
            objective = float(slot.f[0])
            if not math.isfinite(objective):
                # The compiled code has no NaN checks: a NaN gradient passes its test.
                success, status = False, f"non-finite objective ({status})"
            return NLPSolution(slot.x.copy(), success, status, iterations, objective)
        finally:
            self._slots.give(slot)

    def _exit(self, slot: _Slot) -> tuple[int, bool, str]:
        """``(iterations, success, status)`` of the solve that just ran in ``slot``."""
        if self.monitor is not None:
            iterations, stopped = self.monitor.last_solve()
            if stopped:
                return iterations, True, STOP_STATUS
        if self.compiled is None:
            stats = slot.buffer.stats()
            return (
                int(stats.get("iter_count", -1)),
                bool(stats.get("success", False)),
                str(stats.get("return_status", "")),
            )
        # The compiled SQP loop ends converged, at its iteration limit, or (below it)
        # on a step shorter than min_step_size: sqpmethod's own three statuses.
        iterations, converged = self.compiled.last_solve()
        if converged:
            return iterations, True, "Solve_Succeeded"
        if iterations >= self.max_iter:
            return iterations, False, "Maximum_Iterations_Exceeded"
        return iterations, False, "Search_Direction_Becomes_Too_Small"


def _hessian_function(program: NLPProgram, upper_triangle: bool) -> casadi.Function:
    """``hess_lag(x, p, lam_f, lam_g)``: ``lam_f`` times the Gauss–Newton Hessian."""
    lam_f = casadi.SX.sym("lam_f")
    lam_g = casadi.SX.sym("lam_g", 0)
    H = lam_f * program.hessian
    name = "triu_hess_gamma_x_x" if upper_triangle else "hess_gamma_x_x"
    return casadi.Function(
        "nlp_hess_l",
        [program.q, program.parameters, lam_f, lam_g],
        [casadi.triu(H) if upper_triangle else H],
        ["x", "p", "lam_f", "lam_g"],
        [name],
    )


def _new_backend(
    program: NLPProgram, plugin: str, max_iter: int, options: dict[str, Any], codegen: bool
) -> NLPBackend:
    name = f"ik_{plugin}_{program.mode}" + (f"_{'xyz'[program.axis]}" if program.axis >= 0 else "")
    nlp = {"x": program.q, "p": program.parameters, "f": program.objective}
    gauss_newton = plugin in GAUSS_NEWTON_TRIU
    monitor = None
    extra: dict[str, Any] = {}
    if codegen and plugin in MONITORED and "iteration_callback" not in options:
        monitor, _ = compiled_monitor(program.dof, int(program.parameters.shape[0]))
        if monitor is not None:
            extra["iteration_callback"] = monitor.function
    build_options = {**options, **extra}
    if gauss_newton:
        build_options["hess_lag"] = _hessian_function(program, GAUSS_NEWTON_TRIU[plugin])
    solver = casadi.nlpsol(name, plugin, nlp, build_options)
    report = CompileReport(False, 0.0, False, "code generation not asked for")
    if codegen and plugin in WHOLE_SOLVER:
        # The whole solver as C (the SQP loop too); else its functions, as below.
        whole, report = compiled_solver(solver)
        if whole is not None:
            return NLPBackend(
                program, plugin, max_iter, options, whole.function, gauss_newton, report, whole
            )
    if codegen:
        # The library holds the Gauss–Newton nlp_hess_l; built from it without the
        # hess_lag option, the solver loads that compiled function by name (on failure
        # compiled_nlpsol returns the SX solver above, built with it).
        solver, report = compiled_nlpsol(name, plugin, solver, {**options, **extra})
    return NLPBackend(
        program, plugin, max_iter, options, solver, gauss_newton, report, None, monitor
    )


_lock = threading.Lock()
_BACKENDS: weakref.WeakKeyDictionary[Robot, dict[tuple[Any, ...], NLPBackend]] = (
    weakref.WeakKeyDictionary()
)
# The same backends keyed without their options (built with the defaults only).
_FAST: weakref.WeakKeyDictionary[Robot, dict[tuple[Any, ...], NLPBackend]] = (
    weakref.WeakKeyDictionary()
)


def nlp_backend(
    robot: Robot,
    task: str | Task = "pose",
    *,
    plugin: str = "ipopt",
    max_iter: int = 100,
    options: dict[str, Any] | None = None,
    codegen: bool = True,
) -> NLPBackend:
    """The solver of ``build_nlp(robot, task)`` (cached per robot, task shape and settings).

    Args:
        robot: the robot.
        task: a mode or a :class:`~optik.task.Task` (its shape chooses the program).
        plugin: ``casadi.nlpsol`` plugin, ``"ipopt"`` or ``"sqpmethod"`` (options from
            :data:`NLP_OPTIONS`, the program's Gauss–Newton Hessian); any other plugin
            gets only ``options`` and CasADi's exact Hessian.
        max_iter: iteration limit of one solve.
        options: extra ``nlpsol`` options, merged over the defaults (part of the cache key).
        codegen: run the solver compiled to C, cached on disk: ``sqpmethod`` whole
            (:func:`optik.programs.nlp_codegen.compiled_solver`), others on their
            compiled functions (:func:`optik.programs.nlp_codegen.compiled_nlpsol`),
            Ipopt with its compiled monitor (:data:`MONITORED`); the SX functions when no
            C compiler is found. ``backend.compile_report`` says which and what it cost.

    Raises:
        OptikError: not a robot, an unknown mode, a ``max_iter`` not an integer >= 1
            (``ArgumentError``), ``options`` not a dict with str keys, or a plugin CasADi
            cannot load.
    """
    if not isinstance(robot, Robot):
        raise OptikError(f"robot must be an optik.Robot, got {type(robot).__name__}")
    shape = task_shape(task)
    if options is None and type(max_iter) is int and max_iter >= 1:
        # The common call (the casadi:<plugin> solvers): no options to merge and key.
        fast = _FAST.get(robot)
        backend = None if fast is None else fast.get((shape, plugin, max_iter, bool(codegen)))
        if backend is not None:
            return backend
    max_iter = check_int("max_iter", max_iter, minimum=1)
    if options is not None and not (
        isinstance(options, dict) and all(isinstance(key, str) for key in options)
    ):
        raise OptikError(f"options must be a dict with str keys (nlpsol options), got {options!r}")
    merged = {**NLP_OPTIONS.get(plugin, {}), **(options or {})}
    merged[_MAX_ITER_OPTION.get(plugin, "max_iter")] = int(max_iter)
    key = (shape, plugin, repr(sorted(merged.items())), bool(codegen))
    # Building (and compiling) a solver is paid once: a timeout_s does not count it.
    with _lock, one_time_setup():
        program = build_nlp(robot, task)
        per_robot = _BACKENDS.setdefault(robot, {})
        backend = per_robot.get(key)
        if backend is None:
            try:
                backend = _new_backend(program, plugin, int(max_iter), merged, bool(codegen))
            except RuntimeError as exc:
                raise OptikError(f"cannot build the CasADi {plugin!r} solver: {exc}") from exc
            per_robot[key] = backend
        if options is None and type(max_iter) is int:
            _FAST.setdefault(robot, {})[(shape, plugin, max_iter, bool(codegen))] = backend
    return backend


def stop_objective(task: Task) -> float:
    """The objective ``||r||^2`` below which both judged errors of ``task`` are met.

    ``STOP_FRACTION * w_min * tol^2``, with ``w_min`` the smallest positive weight and
    ``tol`` the smaller tolerance of the rows the task has (position, rotation). With
    ``E = R*^T R`` every rotation row's weight is at least ``w_min / 2`` per entry of
    ``E - I`` (full orientation) or ``w_min`` per entry of ``E e_k - e_k`` (tool axis
    ``k``), so the rotation part of ``||r||^2`` is at least ``w_min (3 - trace E) = 4
    w_min sin^2(theta / 2)`` (full) or ``w_min ||E e_k - e_k||^2 = 4 w_min sin^2(alpha /
    2)`` (axis); the position part is at least ``w_min`` times the squared judged
    position error. Below the threshold each judged error is at most
    ``sqrt(STOP_FRACTION) tol`` (``mu = 0``).
    """
    w = task.weights.tolist()
    tolerances = []
    if max(w[:3]) > 0.0:
        tolerances.append(task.position_tol)
    if max(w[3:]) > 0.0:
        tolerances.append(task.orientation_tol)
    w_min = min(x for x in w if x > 0.0)
    return STOP_FRACTION * w_min * min(tolerances) ** 2


class CasadiNLPSolver(IKSolver):
    """IK as one nonlinear program solved by a ``casadi.nlpsol`` plugin.

    The program (see :mod:`optik.programs.nlp`), with ``r`` the task's weighted residual
    in the target frame (position rows over the constrained axes; a full orientation, a
    tool axis, or none)::

        min  ||r(q)||^2
        s.t. lower <= q <= upper    (the query's bounds: limits, limit_margin, frozen)

    Stops when both judged errors are within the task's tolerances, when a solve makes
    too little progress (:data:`PROGRESS_RATIO`), at ``max_iter`` solver iterations in
    total, or at the deadline (checked between solves: a running solve is not
    interrupted, it is bounded by :data:`SOLVE_ITER`). ``converged`` is the last solve's
    own claim (its convergence test: ``stats()["success"]``, or the compiled loop's).
    """

    plain_tasks_only = False  # every task, frozen joints and limit margins
    kind = "nlp"
    default_max_iter = 60

    def __init__(self, plugin: str) -> None:
        self.plugin = plugin
        self.name = f"casadi:{plugin}"
        # The last query's setup: its attempts (solve calls) share it. Replaced whole,
        # so a thread reading it sees one query's setup or another's, never a mix.
        self._last: tuple[IKQuery, int, _Setup] | None = None

    def searched(self, query: IKQuery) -> IKQuery:
        """The search twin, balanced for an arm smaller than :data:`BALANCE_BAND`.

        The backends' tolerances are absolute: a millimetre arm's residual in metres
        meets them 1e-6-2e-4 m short of the target. A large arm's program is left in
        metres: balanced, its slides' columns shrink by ``1 / L`` beside the revolute
        joints' (the NLP has no damping to even them), and the Stanford arm at 1e3 took
        ten times the iterations.
        """
        return query.searching(balanced=search_length(query.robot) < BALANCE_BAND[0])

    def backend(self, query: IKQuery, max_iter: int) -> NLPBackend:
        """The solver of the query's task shape (one solve of at most ``max_iter``)."""
        return nlp_backend(
            query.robot, query.spec, plugin=self.plugin, max_iter=min(max_iter, SOLVE_ITER)
        )

    def solve(self, query: IKQuery, q0: FloatArray, max_iter: int, deadline: float) -> SolverOutput:
        """Refine ``q0`` towards ``query.target`` (see the class docstring)."""
        budget = max(1, int(max_iter))
        try:
            setup = self._setup(query, budget)
        except Exception as exc:  # report, never raise from a backend run
            reraise_interrupt(exc)  # Ctrl-C is the caller's, not a failure
            q = np.clip(np.asarray(q0, dtype=np.float64), query.lower, query.upper)
            return SolverOutput(q, 0, False, f"{type(exc).__name__}: {exc}", True)
        backend, params, lbx, ubx, stop, measure = setup
        q, converged, e2 = measure(np.asarray(q0, dtype=np.float64))
        iterations = 0
        claim, status = False, "not started"
        while True:
            if converged:
                return SolverOutput(q, iterations, claim if iterations else True, status)
            if iterations >= budget:
                return SolverOutput(q, iterations, claim, f"max_iter ({status})")
            if budget_now() > deadline:
                return SolverOutput(q, iterations, claim, f"timeout ({status})")
            result = backend.solve_parameters(params, q, lbx, ubx, stop)
            if result.failed:
                return SolverOutput(q, iterations, False, result.status, True)
            iterations += max(result.iterations, 1)
            claim, status = result.success, result.status
            q_new, converged, e2_new = measure(result.q)
            if not math.isfinite(e2_new):
                return SolverOutput(q, iterations, False, f"non-finite answer ({status})", True)
            if e2_new >= e2:
                return SolverOutput(q, iterations, claim, f"no progress ({status})")
            progressed = e2_new <= PROGRESS_RATIO * e2 or e2_new <= PROGRESS_FLOOR
            q, e2 = q_new, e2_new
            if not progressed and not converged:
                return SolverOutput(q, iterations, claim, f"slow progress ({status})")

    def _setup(self, query: IKQuery, budget: int) -> _Setup:
        """The backend, parameters, bounds and measure of a query (kept for its attempts)."""
        last = self._last
        if last is not None and last[0] is query and last[1] == budget:
            return last[2]
        task = query.spec
        backend = self.backend(query, budget)
        target = query.target
        # The parameters [p*, vec(R*), sqrt(w), mu, q_ref] (NLPProgram.parameter_vector)
        # of the query's target and task, validated by the query already; mu = 0, so
        # q_ref does not enter. Position weights that differ between the axes are on the
        # target's axes (Task.needs_target_frame), as the verification reads them.
        framed = task.mode != "position" or task.needs_target_frame
        rotation = target[:3, :3] if framed else np.eye(3)
        # A balanced search's residual in the arm's units (optik.task.balanced_search:
        # its weights are those times the bias), where the backends' absolute
        # tolerances mean the same on a millimetre arm as on a metre one.
        bias = task.damping_bias
        params = np.concatenate(
            [
                target[:3, 3],
                rotation.ravel(order="F"),
                np.sqrt(task.weights / bias),
                np.zeros(1 + query.robot.dof),
            ]
        )
        bounds = query.bounds
        setup: _Setup = (
            backend,
            params,
            None if bounds is None else bounds[0],
            None if bounds is None else bounds[1],
            stop_objective(task) / bias,
            _Measure(query),
        )
        self._last = (query, budget, setup)
        return setup


_Setup = tuple[NLPBackend, FloatArray, "FloatArray | None", "FloatArray | None", float, "_Measure"]
"""What a query's attempts share: backend, parameters, bounds (``None``: the limits), the
objective a monitored solve stops at (:func:`stop_objective`) and the query's
:class:`_Measure`."""


class _Measure:
    """``x -> (q, converged, e^T e)``: ``x`` clipped into the query's bounds and judged.

    ``converged``: both judged errors within the task's tolerances; ``e`` the task
    residual of :meth:`IKQuery.error_vector` (:func:`optik.task.task_error`), from the
    compiled FK, unvalidated (a non-finite ``x`` gives a NaN ``e^T e``).
    """

    def __init__(self, query: IKQuery) -> None:
        chain = query.robot.chain
        self.lower, self.upper = query.lower, query.upper
        self.K, self.prismatic, self.C = chain.K, chain.prismatic, chain.C
        self.identity = chain.identity
        self.target, self.packed = query.target, query.spec.packed
        self.position_tol, self.orientation_tol = float(self.packed[8]), float(self.packed[9])
        self.T = np.empty((4, 4))
        self.e = np.zeros(6)  # a point's residual fills e[:3]: e[3:] stays 0
        self.M = np.empty((3, 4))

    def __call__(self, x: FloatArray) -> tuple[FloatArray, bool, float]:
        q = np.minimum(np.maximum(x, self.lower), self.upper)
        theta = q if self.identity else np.ascontiguousarray(self.C @ q)
        _kernels.fk_into(self.K, self.prismatic, theta, self.T)
        position, orientation = task_error(self.T, self.target, self.packed, self.e, self.M)
        converged = position <= self.position_tol and orientation <= self.orientation_tol
        return q, converged, float(self.e @ self.e)


@functools.cache
def _has_nlpsol(plugin: str) -> bool:
    try:
        return bool(casadi.has_nlpsol(plugin))
    except Exception:  # a plugin that cannot load is not available
        return False


def _register_all() -> None:
    """Register ``casadi:ipopt`` and ``casadi:sqpmethod``."""
    for plugin in ("ipopt", "sqpmethod"):

        def factory(plugin: str = plugin) -> IKSolver:
            return CasadiNLPSolver(plugin)

        def available(plugin: str = plugin) -> bool:
            return _has_nlpsol(plugin)

        register_solver(
            f"casadi:{plugin}",
            factory,
            available,
            f"CasADi was built without the {plugin!r} nlpsol plugin; install the casadi "
            "wheel from PyPI (`pip install casadi`), which ships it.",
        )


_register_all()
