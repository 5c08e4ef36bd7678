"""The full nonlinear IK program in CasADi, built once per robot and reused per target.

Decision variable ``q`` (dof,), parameters ``p*`` (3,), ``R*`` (3, 3), ``w_rot``, ``mu``
and ``q_ref`` (dof,)::

    min   ||p(q) - p*||^2 + w_rot (3 - trace(R*^T R(q))) + mu ||q - q_ref||^2
    s.t.  lower <= q <= upper

``(p(q), R(q))`` is the tool pose from a symbolic copy of the robot's chain,
``T = K[0] M(t_1) K[1] ... M(t_n) K[n]`` with ``t = C q`` (the same constants
``robot.chain`` (:class:`optik.chain.Chain`) that the compiled kernels of
``Robot.fk`` use), so it cannot drift from ``Robot.fk``. In ``"position"`` mode the
orientation term is left out.

Orientation measure: ``3 - trace(R*^T R) = 2 (1 - cos theta)``, with ``theta`` the angle
of ``R*^T R`` (the error angle optik reports). It is a polynomial in the entries of ``R``,
so smooth everywhere; it behaves like ``theta^2`` near the target (the same scale as the
squared position error, hence ``w_rot`` in m^2 per rad^2), and its only stationary points
in ``theta`` are the target (minimum) and ``theta = pi`` (maximum). The squared vee of the
skew part, ``||vee(R*^T R - R^T R*)||^2 / 4 = sin^2 theta``, has a spurious minimum at
``theta = pi``; the squared log map is not smooth there. See ``docs/programs.md``.

The targets and weights are CasADi parameters, so the solver (``casadi.nlpsol``) is built
once per ``(robot, mode, plugin, max_iter)`` and cached on the robot (weakly: it goes
away with the robot) and every call only passes numbers; ``q0`` warm-starts it.
"""

from __future__ import annotations

import threading
import weakref
from dataclasses import dataclass, field
from typing import Any, Final, Literal

import casadi
import numpy as np

from optik._checks import FloatArray, finite_array
from optik.errors import OptikError
from optik.model import Robot
from optik.programs.nlp_codegen import CompileReport, compiled_nlpsol
from optik.spatial import as_pose

__all__ = [
    "NLP_OPTIONS",
    "NLPProgram",
    "NLPSolution",
    "build_nlp",
    "symbolic_fk",
]

Mode = Literal["pose", "position"]

#: Options of each nonlinear solver: quiet, tight. Ipopt keeps a warm start where it is
#: (tiny ``bound_push``/``bound_frac``, initial barrier parameter 1e-9); sqpmethod uses
#: CasADi's own active-set QP solver ``qrqp`` and reflects negative Hessian eigenvalues
#: (the objective is not convex; ``eigen-clip`` and ``regularize`` were measured to stall
#: far from the target, see ``docs/programs.md``).
NLP_OPTIONS: Final[dict[str, dict[str, Any]]] = {
    "ipopt": {
        "print_time": False,
        "ipopt.print_level": 0,
        "ipopt.sb": "yes",
        "ipopt.tol": 1e-12,
        "ipopt.acceptable_tol": 1e-10,
        "ipopt.acceptable_iter": 5,
        "ipopt.mu_init": 1e-9,
        "ipopt.bound_push": 1e-10,
        "ipopt.bound_frac": 1e-10,
        "ipopt.warm_start_init_point": "yes",
    },
    "sqpmethod": {
        "print_time": False,
        "print_header": False,
        "print_iteration": False,
        "print_status": False,
        "qpsol": "qrqp",
        "qpsol_options": {
            "print_iter": False,
            "print_header": False,
            "print_info": False,
            "error_on_fail": False,
        },
        "hessian_approximation": "exact",
        "convexify_strategy": "eigen-reflect",
        "tol_pr": 1e-10,
        "tol_du": 1e-10,
        "min_step_size": 1e-16,
    },
}

_MAX_ITER_OPTION: Final[dict[str, str]] = {"ipopt": "ipopt.max_iter", "sqpmethod": "max_iter"}


def _motion(prismatic: bool, t: casadi.SX) -> casadi.SX:
    """``M(t)``: rotation about z by ``t`` (revolute) or translation along z (prismatic)."""
    M = casadi.SX.eye(4)
    if prismatic:
        M[2, 3] = t
    else:
        c, s = casadi.cos(t), casadi.sin(t)
        M[0, 0], M[0, 1], M[1, 0], M[1, 1] = c, -s, s, c
    return M


def _fk_expression(robot: Robot, q: casadi.SX) -> casadi.SX:
    """Symbolic tool pose (4, 4) of ``robot`` at ``q`` from its chain form."""
    chain = robot.chain
    K = chain.K
    t = casadi.mtimes(casadi.DM(chain.C), q)
    T = casadi.SX(casadi.DM(K[0]))
    for i, prismatic in enumerate(chain.prismatic):
        T = casadi.mtimes(casadi.mtimes(T, _motion(bool(prismatic), t[i])), casadi.DM(K[i + 1]))
    return T


def symbolic_fk(robot: Robot) -> casadi.Function:
    """``fk(q) -> T``: the robot's forward kinematics as a CasADi function (SX graph).

    Built from the same chain constants as ``Robot.fk``; ``q`` is (dof,), ``T`` (4, 4).
    """
    q = casadi.SX.sym("q", robot.dof)
    return casadi.Function(f"fk_{robot.name}", [q], [_fk_expression(robot, q)], ["q"], ["T"])


@dataclass(frozen=True)
class NLPSolution:
    """What the nonlinear solver returned (unchecked; optik verifies by FK elsewhere).

    Attributes:
        q: final joint vector (dof,).
        success: the solver's own claim (``stats()["success"]``).
        status: its return status text.
        iterations: iterations it reports.
        objective: the objective value at ``q``.
    """

    q: FloatArray
    success: bool
    status: str
    iterations: int
    objective: float


_NOT_COMPILED: Final = CompileReport(False, 0.0, False, "code generation not asked for")


@dataclass(frozen=True, eq=False)
class NLPProgram:
    """The nonlinear IK program of one robot and mode, inspectable and reusable.

    Attributes:
        robot_name: name of the robot it was built for (the robot is not kept).
        mode: ``"pose"`` or ``"position"``.
        plugin: the ``casadi.nlpsol`` plugin (``"ipopt"`` or ``"sqpmethod"``).
        q: decision variable, SX (dof,).
        p_target: parameter, target position (3,), m.
        R_target: parameter, target rotation (3, 3) (unused in position mode).
        w_rot: parameter, weight of the orientation term (m^2 per unit of ``3 - trace``).
        mu: parameter, weight of the regularisation ``||q - q_ref||^2``.
        q_ref: parameter, regularisation reference (dof,).
        parameters: all parameters stacked, ``[p*, vec(R*) (column-major), w_rot, mu,
            q_ref]``, in the order :meth:`parameter_vector` fills them.
        T: symbolic tool pose (4, 4).
        position_error: ``p(q) - p*`` (3,).
        orientation_measure: ``3 - trace(R*^T R(q))`` (0 in position mode).
        objective: the objective expression.
        fk: ``casadi.Function`` ``q -> T``.
        solver: the ``casadi.nlpsol`` function.
        lbx: lower bounds (dof,), the joint limits (``-inf`` allowed).
        ubx: upper bounds (dof,).
        options: the options the solver was built with.
        compile_report: whether ``solver`` runs compiled C and what building it cost
            (:class:`~optik.programs.nlp_codegen.CompileReport`).
    """

    robot_name: str
    mode: Mode
    plugin: str
    q: casadi.SX
    p_target: casadi.SX
    R_target: casadi.SX
    w_rot: casadi.SX
    mu: casadi.SX
    q_ref: casadi.SX
    parameters: casadi.SX
    T: casadi.SX
    position_error: casadi.SX
    orientation_measure: casadi.SX
    objective: casadi.SX
    fk: casadi.Function
    solver: casadi.Function
    lbx: FloatArray
    ubx: FloatArray
    options: dict[str, Any]
    compile_report: CompileReport = _NOT_COMPILED
    _bounds: tuple[Any, Any] = field(init=False, repr=False)

    def __post_init__(self) -> None:
        # The bounds as CasADi matrices once (a conversion per solve costs a few µs each).
        object.__setattr__(self, "_bounds", (casadi.DM(self.lbx), casadi.DM(self.ubx)))

    @property
    def dof(self) -> int:
        """Number of joint coordinates."""
        return int(self.q.shape[0])

    def parameter_vector(
        self, target: Any, *, w_rot: float = 1.0, mu: float = 0.0, q_ref: Any = None
    ) -> FloatArray:
        """The numeric parameter vector for a target.

        Args:
            target: 4x4 pose; in position mode a 3-vector or a 4x4 (translation used).
            w_rot: orientation weight (>= 0).
            mu: regularisation weight (>= 0).
            q_ref: regularisation reference (dof,), default the middle of the limits.

        Raises:
            ShapeError, NonFiniteError, InvalidRotationError: a bad target or ``q_ref``.
            OptikError: a negative or non-finite weight.
        """
        p, R = _target(self.mode, target)
        for name, value in (("w_rot", w_rot), ("mu", mu)):
            try:
                number = float(value)
            except (TypeError, ValueError) as exc:
                raise OptikError(f"{name} must be a number, got {value!r}") from exc
            if not np.isfinite(number) or number < 0.0:
                raise OptikError(f"{name} must be finite and >= 0, got {value!r}")
        if q_ref is None:
            finite = np.isfinite(self.lbx) & np.isfinite(self.ubx)
            ref = np.where(
                finite,
                0.5 * (np.where(finite, self.lbx, 0.0) + np.where(finite, self.ubx, 0.0)),
                0.0,
            )
        else:
            ref = finite_array("q_ref", q_ref, (self.dof,))
        return np.concatenate([p, R.ravel(order="F"), [float(w_rot), float(mu)], ref])

    def solve(
        self,
        target: Any,
        q0: Any,
        *,
        w_rot: float = 1.0,
        mu: float = 0.0,
        q_ref: Any = None,
    ) -> NLPSolution:
        """Solve for one target from the warm start ``q0`` (dof,) (clipped into the limits).

        Arguments as in :meth:`parameter_vector`. A solver exception comes back as
        ``success=False`` with its text in ``status`` (and ``q0`` as ``q``).
        """
        params = self.parameter_vector(target, w_rot=w_rot, mu=mu, q_ref=q_ref)
        x0 = np.clip(finite_array("q0", q0, (self.dof,)), self.lbx, self.ubx)
        return self.solve_parameters(params, x0)

    def solve_parameters(self, params: FloatArray, x0: FloatArray) -> NLPSolution:
        """Solve for a parameter vector of :meth:`parameter_vector` from ``x0``, unchecked.

        The inner call of :meth:`solve` for callers that validated their inputs once
        (``x0`` finite and inside the bounds, ``params`` from :meth:`parameter_vector`).
        """
        try:
            result = self.solver(x0=x0, p=params, lbx=self._bounds[0], ubx=self._bounds[1])
            stats = self.solver.stats()
        except Exception as exc:  # keep the backend's message
            return NLPSolution(x0, False, f"{type(exc).__name__}: {exc}", 0, float("nan"))
        q = result["x"].full().ravel()
        return NLPSolution(
            q=q,
            success=bool(stats.get("success", False)),
            status=str(stats.get("return_status", "")),
            iterations=int(stats.get("iter_count", -1)),
            objective=float(result["f"]),
        )


def _target(mode: str, target: Any) -> tuple[FloatArray, FloatArray]:
    """Target position (3,) and rotation (3, 3) (identity in position mode)."""
    if mode == "position" and np.shape(target) == (3,):
        return finite_array("target", target, (3,)), np.eye(3)
    T = as_pose("target", target)
    R = np.eye(3) if mode == "position" else T[:3, :3]
    return T[:3, 3].copy(), np.array(R)


_lock = threading.Lock()
_CACHE: weakref.WeakKeyDictionary[Robot, dict[tuple[Any, ...], NLPProgram]] = (
    weakref.WeakKeyDictionary()
)
# The same programs keyed without their options (built with the defaults only).
_FAST: weakref.WeakKeyDictionary[Robot, dict[tuple[Any, ...], NLPProgram]] = (
    weakref.WeakKeyDictionary()
)


def _new_program(
    robot: Robot, mode: Mode, plugin: str, options: dict[str, Any], codegen: bool
) -> NLPProgram:
    n = robot.dof
    q = casadi.SX.sym("q", n)
    p_target = casadi.SX.sym("p_target", 3)
    R_target = casadi.SX.sym("R_target", 3, 3)
    w_rot = casadi.SX.sym("w_rot")
    mu = casadi.SX.sym("mu")
    q_ref = casadi.SX.sym("q_ref", n)
    T = _fk_expression(robot, q)
    position_error = T[:3, 3] - p_target
    if mode == "pose":
        orientation = 3.0 - casadi.sum1(casadi.sum2(R_target * T[:3, :3]))
    else:
        orientation = casadi.SX(0.0)
    objective = casadi.sumsqr(position_error) + w_rot * orientation + mu * casadi.sumsqr(q - q_ref)
    parameters = casadi.vertcat(p_target, casadi.vec(R_target), w_rot, mu, q_ref)
    name = f"ik_{plugin}_{mode}"
    solver = casadi.nlpsol(name, plugin, {"x": q, "p": parameters, "f": objective}, options)
    report = _NOT_COMPILED
    if codegen:
        solver, report = compiled_nlpsol(name, plugin, solver, options)
    return NLPProgram(
        robot_name=robot.name,
        mode=mode,
        plugin=plugin,
        q=q,
        p_target=p_target,
        R_target=R_target,
        w_rot=w_rot,
        mu=mu,
        q_ref=q_ref,
        parameters=parameters,
        T=T,
        position_error=position_error,
        orientation_measure=orientation,
        objective=objective,
        fk=casadi.Function("fk", [q], [T], ["q"], ["T"]),
        solver=solver,
        lbx=robot.lower.copy(),
        ubx=robot.upper.copy(),
        options=options,
        compile_report=report,
    )


def build_nlp(
    robot: Robot,
    mode: Mode = "pose",
    *,
    plugin: str = "ipopt",
    max_iter: int = 100,
    options: dict[str, Any] | None = None,
    codegen: bool = True,
) -> NLPProgram:
    """The nonlinear IK program of ``robot`` (cached: built once per robot and settings).

    Args:
        robot: the robot.
        mode: ``"pose"`` or ``"position"``.
        plugin: ``casadi.nlpsol`` plugin, ``"ipopt"`` or ``"sqpmethod"`` (options from
            :data:`NLP_OPTIONS`); any other plugin gets only ``options``.
        max_iter: iteration limit of the solver.
        options: extra ``nlpsol`` options, merged over the defaults (part of the cache key).
        codegen: run the solver on its functions compiled to C
            (:func:`optik.programs.nlp_codegen.compiled_nlpsol`, cached on disk; the SX
            functions when no C compiler is found). ``program.compile_report`` says which
            and what it cost.

    Raises:
        OptikError: an unknown mode, a ``max_iter`` below 1, or a plugin CasADi cannot load.
    """
    if not isinstance(robot, Robot):
        raise OptikError(f"robot must be an optik.Robot, got {type(robot).__name__}")
    if mode not in ("pose", "position"):
        raise OptikError(f"mode must be 'pose' or 'position', got {mode!r}")
    if int(max_iter) != max_iter or max_iter < 1:
        raise OptikError(f"max_iter must be an integer >= 1, got {max_iter!r}")
    if options is None and type(max_iter) is int:
        # The common call (the casadi:<plugin> solvers): no options to merge and key.
        fast = _FAST.get(robot)
        program = None if fast is None else fast.get((mode, plugin, max_iter, bool(codegen)))
        if program is not None:
            return program
    merged = {**NLP_OPTIONS.get(plugin, {}), **(options or {})}
    merged[_MAX_ITER_OPTION.get(plugin, "max_iter")] = int(max_iter)
    key = (mode, plugin, repr(sorted(merged.items())), bool(codegen))
    with _lock:
        per_robot = _CACHE.setdefault(robot, {})
        program = per_robot.get(key)
        if program is None:
            try:
                program = _new_program(robot, mode, plugin, merged, bool(codegen))
            except RuntimeError as exc:
                raise OptikError(f"cannot build the CasADi {plugin!r} solver: {exc}") from exc
            per_robot[key] = program
        if options is None and type(max_iter) is int:
            _FAST.setdefault(robot, {})[(mode, plugin, max_iter, bool(codegen))] = program
    return program
