"""The full nonlinear IK program in CasADi, as data: built once per robot and task shape.

Decision variable ``q`` (dof,); parameters ``p*`` (3,), ``R*`` (3, 3), ``s`` (6,) the
square roots of the task's weights on ``[x, y, z, rx, ry, rz]`` (target frame), ``mu`` and
``q_ref`` (dof,)::

    min   ||r(q)||^2 + mu ||q - q_ref||^2
    s.t.  lower <= q <= upper

``r`` is the task's weighted residual (:mod:`optik.task`), in the target frame, with
``E = R*^T R(q)`` the rotation from the target to the tool:

- position rows (absent in ``"orientation"`` mode): ``s_i (R*^T (p(q) - p*))_i``, a zero
  weight frees that target axis;
- full orientation (``"pose"``, ``"orientation"``): the nine entries of ``E - I``, the
  off-diagonal ``E_lm`` weighted by ``s_k / sqrt(2)`` (``k`` the third index: near the
  target ``E ~ I + [phi]x`` with ``phi`` the target-frame rotation vector, so ``E_lm``
  and ``E_ml`` are ``-+phi_k``), the diagonal ``E_jj - 1`` (second order in ``phi``) by
  ``sqrt((s_k^2 + s_l^2) / 4)``;
- tool axis ``k`` (``"axis"``): column ``k`` of ``E`` less ``e_k``, ``E_lk`` weighted by
  ``s_m`` (``m`` the third index), ``E_kk - 1`` by ``sqrt((s_l^2 + s_m^2) / 2)``; the
  rotation about the axis does not enter.

To first order ``||r||^2`` is ``||sqrt(w) [R*^T dp; phi]||^2``, the residual of the compiled
``dls``; with unit weights its rotation part is exactly ``3 - trace(R*^T R) = 2 (1 - cos
theta)`` (``theta`` the error angle) for a full orientation and ``||a - a*||^2 = 2 (1 -
cos theta)`` for a tool axis: polynomials in ``R``, smooth everywhere, zero only at the
target (the diagonal rows rule out ``theta = pi``), with no other stationary point in
``theta`` but the maximum at ``pi``. See ``docs/programs.md``.

The program is a sum of squares, so it carries its Gauss–Newton Hessian
``2 (J_r^T J_r + (lambda + mu) I)`` (``J_r`` the residual's Jacobian, ``lambda`` =
:data:`GN_DAMPING`) next to the objective; the solvers (:mod:`optik.solvers.casadi_nlp`)
use it instead of the exact Hessian of the Lagrangian, which is indefinite away from the
target.

``(p(q), R(q))`` is the tool pose from a symbolic copy of the robot's chain,
``T = K[0] M(t_1) K[1] ... M(t_n) K[n]`` with ``t = C q`` (the same constants
``robot.chain`` (:class:`optik.chain.Chain`) that the compiled kernels of ``Robot.fk`` use),
so it cannot drift from ``Robot.fk``.

This module only describes the program: :func:`build_nlp` returns an inspectable
:class:`NLPProgram` (cached per robot and task shape); the ``casadi.nlpsol`` solvers built
on it, and their compiled functions, belong to :mod:`optik.solvers.casadi_nlp`.
"""

from __future__ import annotations

import math
import threading
import weakref
from dataclasses import dataclass
from typing import Any, Final

import casadi
import numpy as np

from optik._checks import FloatArray, finite_array
from optik.errors import OptikError
from optik.model import Robot
from optik.spatial import as_pose
from optik.task import AXES, MODES, Task, make_task

__all__ = [
    "GN_DAMPING",
    "NLPProgram",
    "NLPSolution",
    "build_nlp",
    "symbolic_fk",
    "task_shape",
]

#: ``lambda`` of the Gauss–Newton Hessian ``2 (J^T J + lambda I)``: keeps it positive
#: definite on a redundant task (its null space) without changing the answer (the
#: objective is not damped), and small enough that steps near the target are Gauss–Newton
#: steps (quadratic convergence at a zero residual).
GN_DAMPING: Final[float] = 1e-6


def task_shape(task: str | Task) -> tuple[str, int]:
    """``(mode, axis)`` of a task: what the program's rows are (its weights are parameters).

    ``axis`` is the tool axis (0 x, 1 y, 2 z) of ``mode="axis"``, else -1.

    Raises:
        OptikError: an unknown mode.
    """
    if isinstance(task, Task):
        return task.mode, task.axis
    if task not in MODES:
        raise OptikError(f"mode must be one of {MODES} or an optik Task, got {task!r}")
    return str(task), (AXES.index("z") if task == "axis" else -1)


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
        failed: the solver raised (its text in ``status``; ``q`` is the start).
    """

    q: FloatArray
    success: bool
    status: str
    iterations: int
    objective: float
    failed: bool = False


@dataclass(frozen=True, eq=False)
class NLPProgram:
    """The nonlinear IK program of one robot and task shape: data, solved elsewhere.

    Attributes:
        robot_name: name of the robot it was built for (the robot is not kept).
        mode: the task's mode (``"pose"``, ``"position"``, ``"orientation"``, ``"axis"``).
        axis: the tool axis of ``"axis"`` mode (0 x, 1 y, 2 z), else -1.
        q: decision variable, SX (dof,).
        p_target: parameter, target position (3,), m (unused in orientation mode).
        R_target: parameter, target rotation (3, 3) (unused in position mode).
        sqrt_weights: parameter, the square roots of the task's weights (6,).
        mu: parameter, weight of the regularisation ``||q - q_ref||^2``.
        q_ref: parameter, regularisation reference (dof,).
        parameters: all parameters stacked, ``[p*, vec(R*) (column-major), sqrt(w), mu,
            q_ref]``, in the order :meth:`parameter_vector` fills them.
        T: symbolic tool pose (4, 4).
        position_error: ``p(q) - p*`` (3,), world frame.
        residual: the task's weighted residual ``r`` (see the module).
        orientation_measure: the rotation rows' part of ``||r||^2`` (0 without orientation).
        objective: ``||r||^2 + mu ||q - q_ref||^2``.
        hessian: its Gauss–Newton Hessian ``2 (J_r^T J_r + (GN_DAMPING + mu) I)``.
        fk: ``casadi.Function`` ``q -> T``.
        lbx: lower bounds (dof,), the joint limits (``-inf`` allowed).
        ubx: upper bounds (dof,).
    """

    robot_name: str
    mode: str
    axis: int
    q: casadi.SX
    p_target: casadi.SX
    R_target: casadi.SX
    sqrt_weights: casadi.SX
    mu: casadi.SX
    q_ref: casadi.SX
    parameters: casadi.SX
    T: casadi.SX
    position_error: casadi.SX
    residual: casadi.SX
    orientation_measure: casadi.SX
    objective: casadi.SX
    hessian: casadi.SX
    fk: casadi.Function
    lbx: FloatArray
    ubx: FloatArray

    @property
    def dof(self) -> int:
        """Number of joint coordinates."""
        return int(self.q.shape[0])

    @property
    def shape(self) -> tuple[str, int]:
        """``(mode, axis)``: what identifies the program for a robot (:func:`task_shape`)."""
        return self.mode, self.axis

    def default_task(self) -> Task:
        """The task of this shape with unit weights (tolerance 1e-6)."""
        return make_task(self.mode, axis=AXES[max(self.axis, 0)])

    def parameter_vector(
        self,
        target: Any,
        *,
        weights: Any = None,
        mu: float = 0.0,
        q_ref: Any = None,
    ) -> FloatArray:
        """The numeric parameter vector for a target.

        Args:
            target: 4x4 pose; in position mode a 3-vector or a 4x4 (translation used).
            weights: (6,) task weights on ``[x, y, z, rx, ry, rz]`` (target frame), a
                :class:`~optik.task.Task` of this shape, or ``None`` (the shape's unit
                weights). Their pattern must be this program's shape.
            mu: regularisation weight (>= 0).
            q_ref: regularisation reference (dof,), default the middle of the limits.

        Raises:
            ShapeError, NonFiniteError, InvalidRotationError: a bad target or ``q_ref``.
            OptikError: bad weights, or weights of another task shape; a negative or
                non-finite ``mu``.
        """
        if weights is None:
            task = self.default_task()
        elif isinstance(weights, Task):
            task = weights
        else:
            task = make_task(self.mode, axis=AXES[max(self.axis, 0)], weights=weights)
        p, R = _target(task, target)
        if task_shape(task) != self.shape:
            raise OptikError(
                f"weights: task {task_shape(task)} does not match the program's {self.shape}"
            )
        # A real number, not a string float() would parse ("1") nor a bool.
        if isinstance(mu, str | bytes | bool | np.bool_) or not isinstance(
            mu, int | float | np.integer | np.floating
        ):
            raise OptikError(f"mu must be a number, got {mu!r}")
        number = float(mu)
        if not math.isfinite(number) or number < 0.0:
            raise OptikError(f"mu must be finite and >= 0, got {mu!r}")
        if q_ref is None:
            finite = np.isfinite(self.lbx) & np.isfinite(self.ubx)
            ref = np.where(
                finite,
                0.5 * (np.where(finite, self.lbx, 0.0) + np.where(finite, self.ubx, 0.0)),
                0.0,
            )
        else:
            ref = finite_array("q_ref", q_ref, (self.dof,))
        return np.concatenate([p, R.ravel(order="F"), np.sqrt(task.weights), [number], ref])


def _target(task: Task, target: Any) -> tuple[FloatArray, FloatArray]:
    """Target position (3,) and rotation (3, 3).

    In position mode the rotation is the identity, unless the weights differ between the
    axes and the target has one: then they are on its axes (:attr:`Task.needs_target_frame`,
    as every solver and the verification read them).
    """
    if task.mode == "position" and np.shape(target) == (3,):
        return finite_array("target", target, (3,)), np.eye(3)
    T = as_pose("target", target)
    framed = task.mode != "position" or task.needs_target_frame
    return T[:3, 3].copy(), np.array(T[:3, :3] if framed else np.eye(3))


def _rotation_rows(E: casadi.SX, s: casadi.SX, mode: str, axis: int) -> list[casadi.SX]:
    """The weighted rotation rows of the residual (see the module) for ``E = R*^T R``."""
    if mode in ("pose", "orientation"):
        rows = []
        for m in range(3):
            for l in range(3):  # noqa: E741 - the index names of the module docstring
                k = 3 - l - m
                if l == m:
                    weight = casadi.sqrt((s[(l + 1) % 3] ** 2 + s[(l + 2) % 3] ** 2) / 4.0)
                    rows.append(weight * (E[l, l] - 1.0))
                else:
                    rows.append(s[k] / math.sqrt(2.0) * E[l, m])
        return rows
    if mode == "axis":
        k = axis
        rows = []
        for l in range(3):  # noqa: E741
            if l == k:
                others = [i for i in range(3) if i != k]
                weight = casadi.sqrt((s[others[0]] ** 2 + s[others[1]] ** 2) / 2.0)
                rows.append(weight * (E[k, k] - 1.0))
            else:
                rows.append(s[3 - l - k] * E[l, k])
        return rows
    return []


def _new_program(robot: Robot, mode: str, axis: int) -> NLPProgram:
    n = robot.dof
    q = casadi.SX.sym("q", n)
    p_target = casadi.SX.sym("p_target", 3)
    R_target = casadi.SX.sym("R_target", 3, 3)
    sqrt_weights = casadi.SX.sym("sqrt_weights", 6)
    mu = casadi.SX.sym("mu")
    q_ref = casadi.SX.sym("q_ref", n)
    T = _fk_expression(robot, q)
    position_error = T[:3, 3] - p_target
    rows: list[casadi.SX] = []
    if mode != "orientation":
        local = casadi.mtimes(R_target.T, position_error)
        rows += [sqrt_weights[i] * local[i] for i in range(3)]
    rotation = _rotation_rows(casadi.mtimes(R_target.T, T[:3, :3]), sqrt_weights[3:], mode, axis)
    residual = casadi.vertcat(*rows, *rotation)
    orientation = casadi.sumsqr(casadi.vertcat(*rotation)) if rotation else casadi.SX(0.0)
    objective = casadi.sumsqr(residual) + mu * casadi.sumsqr(q - q_ref)
    J = casadi.jacobian(residual, q)
    hessian = 2.0 * (casadi.mtimes(J.T, J) + (GN_DAMPING + mu) * casadi.SX.eye(n))
    parameters = casadi.vertcat(p_target, casadi.vec(R_target), sqrt_weights, mu, q_ref)
    return NLPProgram(
        robot_name=robot.name,
        mode=mode,
        axis=axis,
        q=q,
        p_target=p_target,
        R_target=R_target,
        sqrt_weights=sqrt_weights,
        mu=mu,
        q_ref=q_ref,
        parameters=parameters,
        T=T,
        position_error=position_error,
        residual=residual,
        orientation_measure=orientation,
        objective=objective,
        hessian=hessian,
        fk=casadi.Function("fk", [q], [T], ["q"], ["T"]),
        lbx=robot.lower.copy(),
        ubx=robot.upper.copy(),
    )


_lock = threading.Lock()
_CACHE: weakref.WeakKeyDictionary[Robot, dict[tuple[str, int], NLPProgram]] = (
    weakref.WeakKeyDictionary()
)


def build_nlp(robot: Robot, task: str | Task = "pose") -> NLPProgram:
    """The nonlinear IK program of ``robot`` for a task shape (cached per robot and shape).

    Args:
        robot: the robot.
        task: a mode (``"pose"``, ``"position"``, ``"orientation"``, ``"axis"`` with the
            tool's z axis) or a :class:`~optik.task.Task`; only its shape (mode and tool
            axis, :func:`task_shape`) matters, its weights are parameters.

    Raises:
        OptikError: not a robot, or an unknown mode.
    """
    if not isinstance(robot, Robot):
        raise OptikError(f"robot must be an optik.Robot, got {type(robot).__name__}")
    shape = task_shape(task)
    per_robot = _CACHE.get(robot)
    program = None if per_robot is None else per_robot.get(shape)
    if program is not None:
        return program
    with _lock:
        per_robot = _CACHE.setdefault(robot, {})
        program = per_robot.get(shape)
        if program is None:
            program = _new_program(robot, *shape)
            per_robot[shape] = program
    return program
