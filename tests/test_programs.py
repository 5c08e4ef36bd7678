"""The differential-IK step programs, inspected before they are solved (optik.programs)."""

from __future__ import annotations

import math

import numpy as np
import pytest
import qpsolvers
from conftest import assert_close, robot_of

from optik.errors import NonFiniteError, OptikError, ShapeError
from optik.model import DHJoint, Robot
from optik.programs import DEFAULT_DAMPING, build_program, build_qp, step_bounds
from optik.programs.diff_qp import ALL_ROWS, POSITION_ROWS

Q_PUMA = np.array([0.1, 0.5, -1.0, 0.3, 0.6, 0.2])


def continuous_arm() -> Robot:
    """A 3R arm whose first joint is continuous (infinite limits), built inline."""
    return Robot.from_dh(
        [
            DHJoint(a=0.0, alpha=math.pi / 2, d=0.4, continuous=True),
            DHJoint(a=0.5, role="arm"),
            DHJoint(a=0.4, role="arm"),
        ],
        name="continuous_3r",
    )


# ---------------------------------------------------------------------- the matrices
def test_least_norm_program_matrices() -> None:
    robot = robot_of("puma560")
    v = np.array([1e-3, -2e-3, 5e-4, 1e-3, 0.0, -1e-3])
    qp = build_qp(robot, Q_PUMA, v)
    assert isinstance(qp, qpsolvers.Problem)
    J = robot.jacobian(Q_PUMA)
    assert_close(qp.P, np.eye(6), what="P = W = I")
    assert_close(qp.q, np.zeros(6), what="c = 0")
    assert_close(qp.A, J, what="A = J")
    assert_close(qp.b, v, what="b = v")
    assert qp.G is None and qp.h is None
    assert_close(qp.lb, robot.lower - Q_PUMA, what="lb")
    assert_close(qp.ub, robot.upper - Q_PUMA, what="ub")


def test_least_squares_program_matrices() -> None:
    robot = robot_of("panda")
    q = robot.mid_limits
    v = np.linspace(-1e-3, 1e-3, 6)
    Wt = np.array([1.0, 1.0, 1.0, 0.5, 0.5, 0.5])
    prog = build_program(robot, q, v, objective="least_squares", Wt=Wt, damping=0.01)
    J = robot.jacobian(q)
    P = J.T @ np.diag(Wt) @ J + 1e-4 * np.eye(7)
    assert_close(prog.P, P, atol=1e-15, what="P = J^T Wt J + lambda^2 I")
    assert_close(prog.c, -J.T @ (Wt * v), atol=1e-18, what="c = -J^T Wt v")
    assert prog.qp.A is None and prog.qp.b is None
    assert prog.damping == 0.01
    default = build_program(robot, q, v, objective="least_squares")
    assert default.damping == DEFAULT_DAMPING
    # The unconstrained minimizer of the built cost is the damped closed form.
    x = np.linalg.solve(prog.P, -prog.c)
    closed = np.linalg.solve(J.T @ np.diag(Wt) @ J + 1e-4 * np.eye(7), J.T @ (Wt * v))
    assert_close(x, closed, atol=1e-15)


def test_rows_select_the_task() -> None:
    robot = robot_of("puma560")
    J = robot.jacobian(Q_PUMA)
    prog3 = build_program(robot, Q_PUMA, np.ones(3) * 1e-3)
    assert prog3.rows == POSITION_ROWS
    assert_close(prog3.J, J[:3])
    prog6 = build_program(robot, Q_PUMA, np.arange(6.0), rows=(0, 1, 5))
    assert prog6.rows == (0, 1, 5)
    assert_close(prog6.J, J[[0, 1, 5]])
    assert_close(prog6.v, np.array([0.0, 1.0, 5.0]))
    assert build_program(robot, Q_PUMA, np.zeros(6)).rows == ALL_ROWS


def test_weight_w_enters_least_norm() -> None:
    robot = robot_of("panda")
    W = np.array([1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0])
    prog = build_program(robot, robot.mid_limits, np.zeros(6), W=W)
    assert_close(prog.P, np.diag(W))


# ---------------------------------------------------------------------- bounds
def test_bounds_gain_and_velocity_limits() -> None:
    robot = robot_of("puma560")
    vmax = np.array([1.0, 1.0, 1.0, 2.0, 2.0, np.inf])
    lb, ub = step_bounds(robot, Q_PUMA, limit_gain=0.5, velocity_limits=vmax, dt=0.01)
    assert_close(lb, np.maximum(0.5 * (robot.lower - Q_PUMA), -vmax * 0.01))
    assert_close(ub, np.minimum(0.5 * (robot.upper - Q_PUMA), vmax * 0.01))
    assert np.all(np.isfinite(lb)) and np.all(lb < 0) and np.all(ub > 0)
    lb0, ub0 = step_bounds(robot, Q_PUMA, limits=False)
    assert np.all(lb0 == -np.inf) and np.all(ub0 == np.inf)


def test_infinite_limits_stay_infinite() -> None:
    robot = continuous_arm()
    q = np.array([10.0, 0.2, -0.3])
    prog = build_program(robot, q, np.zeros(6))
    assert prog.lower[0] == -np.inf and prog.upper[0] == np.inf
    assert np.all(np.isfinite(prog.lower[1:])) and np.all(np.isfinite(prog.upper[1:]))
    assert np.max(np.abs(prog.qp.lb[1:])) < 10.0  # no 1e20 sentinels anywhere
    free = build_program(robot, q, np.zeros(6), limits=False)
    assert free.qp.lb is None and free.qp.ub is None  # no bounds at all


def test_inconsistent_bounds_are_visible() -> None:
    robot = robot_of("puma560")
    q = Q_PUMA.copy()
    q[0] = robot.upper[0] + 0.1  # outside the limit, farther than vmax * dt
    prog = build_program(robot, q, np.zeros(6), velocity_limits=np.ones(6), dt=0.01)
    assert not prog.bounds_consistent
    assert prog.min_task_violation() == math.inf


# ---------------------------------------------------------------------- validation
@pytest.mark.parametrize(
    ("kwargs", "error"),
    [
        ({"q": np.zeros(5)}, ShapeError),
        ({"q": np.array([0, 0, np.nan, 0, 0, 0])}, NonFiniteError),
        ({"v": np.zeros(5)}, ShapeError),
        ({"v": np.array([0, 0, np.inf, 0, 0, 0])}, NonFiniteError),
        ({"limit_gain": 0.0}, OptikError),
        ({"limit_gain": 1.5}, OptikError),
        ({"limit_gain": -0.5}, OptikError),
        ({"dt": 0.0}, OptikError),
        ({"dt": -0.1}, OptikError),
        ({"objective": "least_cubes"}, OptikError),
        ({"damping": 1e-3}, OptikError),  # least norm takes no damping
        ({"objective": "least_squares", "damping": -1.0}, OptikError),
        ({"objective": "least_squares", "damping": np.nan}, NonFiniteError),
        ({"W": -np.ones(6)}, OptikError),
        ({"W": np.ones((6, 5))}, ShapeError),
        ({"W": np.diag([1.0, 1, 1, 1, 1, 0])}, OptikError),
        ({"W": np.triu(np.ones((6, 6)))}, OptikError),
        ({"rows": (0, 0, 1)}, OptikError),
        ({"rows": (0, 7)}, OptikError),
        ({"rows": ()}, OptikError),
        ({"velocity_limits": np.ones(6)}, OptikError),  # no dt
        ({"velocity_limits": -np.ones(6), "dt": 0.1}, OptikError),
        ({"velocity_limits": np.full(6, np.nan), "dt": 0.1}, NonFiniteError),
        ({"velocity_limits": np.ones(4), "dt": 0.1}, ShapeError),
    ],
)
def test_bad_inputs_raise_optik_errors(kwargs: dict, error: type[Exception]) -> None:
    robot = robot_of("puma560")
    args = {"q": Q_PUMA, "v": np.zeros(6)}
    args.update({k: kwargs.pop(k) for k in ("q", "v") if k in kwargs})
    with pytest.raises(error):
        build_program(robot, args["q"], args["v"], **kwargs)


def test_not_a_robot() -> None:
    with pytest.raises(OptikError):
        build_program("puma", Q_PUMA, np.zeros(6))  # type: ignore[arg-type]


# ---------------------------------------------------------------------- evaluation helpers
def test_min_task_violation_and_kkt_at_the_closed_form() -> None:
    robot = robot_of("puma560")
    v = np.array([1e-3, -2e-3, 5e-4, 1e-3, 0.0, -1e-3])
    prog = build_program(robot, Q_PUMA, v)
    assert prog.min_task_violation() < 1e-12
    dq = np.linalg.pinv(prog.J) @ v
    report = prog.kkt(dq)
    assert report.primal < 1e-15
    assert report.stationarity < 1e-15
    assert not report.active_lower.any() and not report.active_upper.any()
    # y = -(J J^T)^-1 v for min 1/2|dq|^2 + y^T (J dq - v): dq = -J^T y.
    assert_close(prog.J.T @ report.y, -dq, atol=1e-15)
    # J is square here: any other point is infeasible, not merely non-stationary.
    assert prog.kkt(dq + 1e-4).primal > 1e-5
    # Redundant arm: a feasible point off the minimum norm fails stationarity only.
    panda = robot_of("panda")
    prog7 = build_program(panda, panda.mid_limits + 0.1, v)
    dq7 = np.linalg.pinv(prog7.J) @ v
    null = np.linalg.svd(prog7.J)[2][-1]
    assert prog7.kkt(dq7).stationarity < 1e-15
    off = prog7.kkt(dq7 + 1e-4 * null)
    assert off.primal < 1e-15 and off.stationarity > 1e-5
    # Blocking the step: joint 0 may not move, and the task needs it.
    blocked = build_program(
        robot, Q_PUMA, prog.J[:, 0] * 1e-2, velocity_limits=[0, 9, 9, 9, 9, 9], dt=1.0
    )
    assert blocked.min_task_violation() > 1e-3


def test_equilibrated_program_has_the_same_minimizer() -> None:
    robot = robot_of("panda")
    v = np.array([3e-4, -1e-4, 2e-4, 0.0, 1e-3, 0.0])
    prog = build_program(robot, robot.mid_limits, v, objective="least_squares")
    eq = prog.equilibrated()
    assert eq.scale == pytest.approx(1e3)
    assert np.max(np.abs(eq.P)) == pytest.approx(1.0)
    x = np.linalg.solve(eq.P, -eq.c) / eq.scale
    assert_close(x, np.linalg.solve(prog.P, -prog.c), atol=1e-14)
