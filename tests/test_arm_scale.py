"""Numeric IK of arms far from a metre in size: the search balances its units.

A Puma 560 scaled to 1-3 mm (with a 1e-5 wrist offset, so that no fast closed form
answers first) failed 37 of 40 (1 mm) and 30 of 40 (3 mm) FK targets with ``dls``: its
position rows (m) were small beside its rotation rows (rad) and beside the damping's
bias; the jumbo drill at 1e3 (a 7 km arm with a 4 km slide) solved 8 of 200 batch
targets. The search now measures positions and slides in the arm's size
(:func:`optik.task.balanced_search`).
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import scaled_dh, scaled_problem
from scipy.spatial.transform import Rotation

import optik
from optik.errors import NoSolutionError
from optik.task import BALANCE_BAND, balanced_search, make_task


def _puma(scale: float) -> optik.Robot:
    rows = [
        {"d": 0.67183, "alpha": np.pi / 2},
        {"a": 0.4318},
        {"d": 0.15005, "a": 0.0203, "alpha": -np.pi / 2},
        {"d": 0.4318, "alpha": np.pi / 2},
        {"a": 1e-5, "alpha": -np.pi / 2},
        {},
    ]
    return scaled_dh(rows, scale, 2.5)


def test_balanced_search_weights_bias_and_length() -> None:
    task = make_task(weights=[1, 1, 1, 1e-6, 1e-6, 1e-6], tol=(1e-7, 1e-5))
    small = balanced_search(task, 1e-3)  # [dp / L; dtheta]: rotation rows times L^2
    np.testing.assert_allclose(small.weights, [1, 1, 1, 1e-6, 1e-6, 1e-6])
    assert small.packed[11] == pytest.approx(1e-6)  # the damping's bias, times L^2
    assert small.packed[12] == 1e-3  # slides damped over L^2
    assert (small.position_tol, small.orientation_tol) == (1e-7, 1e-5)
    large = balanced_search(task, 1e3)  # position rows over L^2, already the smaller
    np.testing.assert_allclose(large.weights, [1e-6, 1e-6, 1e-6, 1, 1, 1])
    assert large.packed[11] == 1.0 and large.packed[12] == 1e3
    for length in BALANCE_BAND:
        assert balanced_search(task, length) is task.search  # about a metre: unchanged
    orientation = make_task("orientation")
    assert balanced_search(orientation, 1e-3) is orientation  # no position rows
    point = balanced_search(make_task("position"), 1e-2)
    assert point.is_pose_or_position and point.packed[11] == pytest.approx(1e-4)


@pytest.mark.parametrize("scale", [2e-3, 1e-2])
def test_millimetre_arm_is_solved_by_dls_and_the_batch(scale: float) -> None:
    robot = _puma(scale)
    rng = np.random.default_rng(0)
    sources = rng.uniform(robot.lower, robot.upper, (20, 6))
    targets = np.array([robot.fk(q) for q in sources])
    tight = (1e-6 * scale, 1e-6)  # 1e-6 of the arm's size, not 1e-6 m
    for T in targets:
        result = optik.solve_ik(robot, T, solver="dls", warm_start="q0", tol=tight)
        assert result.success, (result.status, result.position_error)
        F = robot.fk(result.q)
        assert np.linalg.norm(F[:3, 3] - T[:3, 3]) <= tight[0]
        assert Rotation.from_matrix(T[:3, :3].T @ F[:3, :3]).magnitude() <= tight[1]
    batch = optik.solve_ik_batch(robot, targets, tol=tight)
    assert batch.success.all(), batch.status
    points = optik.solve_ik_batch(robot, targets[:, :3, 3], mode="position", tol=tight)
    assert points.success.all()
    reached = np.array([robot.fk(q)[:3, 3] for q in points.q])
    assert np.max(np.linalg.norm(reached - targets[:, :3, 3], axis=1)) <= tight[0]


@pytest.mark.parametrize(
    ("name", "scale"),
    [("panda", 1e-3), ("jumbo_drill_6dof", 1e3), ("stanford_arm", 1e3), ("ur5", 1e3)],
)
def test_batch_solves_arms_of_every_size(name: str, scale: float) -> None:
    # Before: 14 (Panda at 1e-3) and 8 (drill at 1e3) of 200; the UR5 at 1e3 took a
    # median of 177 iterations.
    robot = scaled_problem(name, scale)
    rng = np.random.default_rng(0)
    sources = rng.uniform(robot.lower, robot.upper, (40, robot.dof))
    targets = np.array([robot.fk(q) for q in sources])
    batch = optik.solve_ik_batch(robot, targets)
    assert batch.success.all(), batch.status
    for q, T in zip(batch.q, targets, strict=True):
        F = robot.fk(q)
        assert np.linalg.norm(F[:3, 3] - T[:3, 3]) <= 1e-6
        assert Rotation.from_matrix(T[:3, :3].T @ F[:3, :3]).magnitude() <= 1e-6


@pytest.mark.parametrize("name", ["puma560", "panda"])
def test_proxqp_steps_of_a_millimetre_arm_agree_with_an_active_set_solver(name: str) -> None:
    # ProxQP's infeasibility test (1e-4 by default) called feasible least-norm steps of
    # millimetre arms infeasible (7 of 12 here); quadprog, DAQP and Clarabel solved them.
    robot = scaled_problem(name, 1e-3)
    rng = np.random.default_rng(11)
    for _ in range(6):
        q = rng.uniform(robot.lower, robot.upper)
        twist = rng.standard_normal(6)
        twist[:3] *= 1e-3
        try:
            exact = optik.diff_ik(robot, q, twist, dt=0.01, solver="qp:quadprog")
        except NoSolutionError:  # the limits block it: both must say so
            with pytest.raises(NoSolutionError):
                optik.diff_ik(robot, q, twist, dt=0.01, solver="qp:proxqp")
            continue
        step = optik.diff_ik(robot, q, twist, dt=0.01, solver="qp:proxqp")
        J = robot.jacobian(q)
        np.testing.assert_allclose(J @ step, 0.01 * twist, atol=1e-9)
        np.testing.assert_allclose(step, exact, atol=1e-7)


def test_a_pure_wrist_has_no_size_to_balance() -> None:
    # Three axes through one point, the tool on it: reach radius 0 (a division by it
    # made the search's weights infinite).
    wrist = optik.Robot.from_dh(
        [
            {"alpha": np.pi / 2, "lower": -3.0, "upper": 3.0},
            {"alpha": -np.pi / 2, "lower": -3.0, "upper": 3.0},
            {"lower": -3.0, "upper": 3.0},
        ]
    )
    assert wrist.reach_sphere[1] == 0.0
    task = make_task()
    assert balanced_search(task, 0.0) is task
    T = wrist.fk(np.array([0.3, 0.2, 0.1]))
    assert optik.solve_ik(wrist, T, solver="dls", warm_start="q0").success
    assert optik.solve_ik_batch(wrist, T[None]).success[0]


@pytest.mark.parametrize("scale", [1e-3, 1e3])
@pytest.mark.parametrize("solver", ["qp:daqp", "qp:clarabel", "casadi:ipopt", "casadi:sqpmethod"])
def test_program_solvers_search_in_the_arms_units(solver: str, scale: float) -> None:
    # The qp:* loop's damping bias and trust ratio and the NLP's residual were in metres:
    # on the Panda at 1e-3 (1e3) they solved 1 (3) of these 6 targets with qp:*, 0 (6)
    # with casadi:*; their searches are now balanced as dls's is.
    robot = scaled_problem("panda", scale)
    rng = np.random.default_rng(3)
    sources = rng.uniform(robot.lower, robot.upper, (6, robot.dof))
    solved = 0
    for q in sources:
        T = robot.fk(q)
        result = optik.solve_ik(robot, T, solver=solver, restarts=8)
        if result.success:
            solved += 1
            F = robot.fk(result.q)
            assert np.linalg.norm(F[:3, 3] - T[:3, 3]) <= 1e-6
            assert Rotation.from_matrix(T[:3, :3].T @ F[:3, :3]).magnitude() <= 1e-6
    assert solved >= 5, solved


@pytest.mark.parametrize(
    ("name", "scale"), [("stanford_arm", 1e-3), ("stanford_arm", 1e3), ("jumbo_drill_6dof", 1e3)]
)
def test_qp_steps_move_a_slide_in_the_arms_size(name: str, scale: float) -> None:
    # Slides at 1e-3 / 1e3, searched numerically from the seed table (no closed form
    # first): qp:daqp solved 1 / 6 of the Stanford arm's 8 and 0 of the drill's before; a
    # slide's damping is now over L^2 and its trust radius times L in the qp:* steps.
    robot = scaled_problem(name, scale)
    rng = np.random.default_rng(3)
    for q in rng.uniform(robot.lower, robot.upper, (8, robot.dof)):
        T = robot.fk(q)
        result = optik.solve_ik(robot, T, solver="qp:daqp", restarts=8, warm_start="q0")
        assert result.success, (result.status, result.position_error)
        F = robot.fk(result.q)
        assert np.linalg.norm(F[:3, 3] - T[:3, 3]) <= 1e-6


@pytest.mark.parametrize("scale", [1e-3, 10.0, 1e3])
def test_seed_table_ranks_starts_in_the_arms_size(scale: float) -> None:
    # The table ranked (and clustered) poses by ||dp||^2 + 0.05 m^2 ||dR||_F^2: by
    # rotation alone on a millimetre arm, by position alone on a 10 m one. 30 Panda
    # targets with dls: 8 restarts in all at 1 m; 56 at 10 and 62 at 1e3 before.
    def restarts(robot: optik.Robot) -> int:
        rng = np.random.default_rng(5)
        sources = rng.uniform(robot.lower, robot.upper, (30, robot.dof))
        results = [optik.solve_ik(robot, robot.fk(q), solver="dls", restarts=20) for q in sources]
        assert all(r.success for r in results)
        return sum(r.restarts for r in results)

    assert restarts(scaled_problem("panda", scale)) <= restarts(scaled_problem("panda", 1.0)) + 10
