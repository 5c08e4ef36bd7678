"""plan_path with the task keywords: tool axis (5-D), weights, frozen joints, posture.

Every solved waypoint is re-verified here from forward kinematics: the position error and
the angle between the tool axis and the waypoint's, computed in the test, not read from
the plan.
"""

from __future__ import annotations

import importlib.util
import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import optik
from optik.errors import OptikError
from optik.model import Robot
from optik.paths import line
from optik.planning import PathPlan, plan_path
from optik.problems import load_problem
from optik.spatial import rot_z

TOL = 1e-6
COLUMN = {"x": 0, "y": 1, "z": 2}


def _axis_angle(a: np.ndarray, b: np.ndarray) -> float:
    return math.atan2(float(np.linalg.norm(np.cross(a, b))), float(a @ b))


def _check_axis_plan(robot: Robot, plan: PathPlan, axis: str = "z") -> None:
    """Every solved waypoint: tool point on the waypoint, tool axis along its axis."""
    c = COLUMN[axis]
    assert plan.mode == "axis"
    for k in np.flatnonzero(plan.solved):
        F = robot.fk(plan.q[k])
        T = plan.poses[k]
        assert np.linalg.norm(F[:3, 3] - T[:3, 3]) <= TOL, k
        assert _axis_angle(F[:3, c], T[:3, c]) <= TOL, k
        assert np.all(plan.q[k] >= robot.lower - 1e-12) and np.all(plan.q[k] <= robot.upper + 1e-12)


def _spinning_line(robot: Robot, q: np.ndarray, spin: float, step: float = 0.01) -> np.ndarray:
    """A drilling line: the tool z fixed, the roll about it turning ``spin`` rad per waypoint."""
    T0 = robot.fk(q)
    T1 = T0.copy()
    T1[:3, 3] += [0.0, 0.2, -0.05]
    poses = line(T0, T1, step)
    for k in range(len(poses)):
        poses[k, :3, :3] = poses[k, :3, :3] @ rot_z(spin * k)
    return poses


def test_axis_path_plans_where_the_full_pose_jumps() -> None:
    """The Panda: a roll of 0.35 rad per waypoint is a wrist spin in 6-D, free in 5-D."""
    panda = load_problem("panda").robot
    q0 = panda.mid_limits
    poses = _spinning_line(panda, q0, 0.35)
    full = plan_path(panda, poses, max_joint_step=0.2, q_start=q0)
    five = plan_path(panda, poses, mode="axis", max_joint_step=0.2, q_start=q0)
    assert full.mode == "pose" and "discontinuity" in full.status  # measured: 21 of 22
    assert full.largest_step > 0.2
    assert five.status == ["ok"] * len(poses)
    assert five.largest_step <= 0.2
    _check_axis_plan(panda, five)
    # The rolls really differ: the full pose of the 5-D answers misses them.
    rolls = [_axis_angle(panda.fk(five.q[k])[:3, 0], poses[k, :3, 0]) for k in range(len(poses))]
    assert max(rolls) > 1.0


def test_axis_mode_solves_waypoints_the_full_pose_cannot() -> None:
    """The Stanford arm (j4, j6 within +-170 deg): the requested roll lies in the gap.

    Every full pose of the line is reachable only outside the limits (the closed form's
    branches are checked here by FK), so the 6-D plan flags every waypoint
    ``outside_limits``; the 5-D plan solves every one.
    """
    robot = load_problem("stanford_arm").robot
    q = np.array([-0.45, 0.8, 0.8, 0.0, 0.6, math.radians(150.0)])
    T = robot.fk(q)
    T[:3, :3] = T[:3, :3] @ rot_z(math.radians(28.0))  # j6 would need 178 deg
    T0, T1 = T.copy(), T.copy()
    T0[:3, 3] -= 0.05 * T[:3, 0]
    T1[:3, 3] += 0.05 * T[:3, 0]
    poses = line(T0, T1, 0.01)
    for P in poses:  # reachable, but not inside the limits
        loose = optik.analytic_ik(robot, P, "pose", within_limits=False)
        assert loose and not optik.analytic_ik(robot, P, "pose")
        F = robot.fk(loose[0])
        assert np.linalg.norm(F[:3, 3] - P[:3, 3]) <= 1e-9
        assert not np.any(robot.within_limits(np.array(loose)))
    full = plan_path(robot, poses, max_joint_step=0.2)
    assert full.status == ["outside_limits"] * len(poses) and not full.solved.any()
    five = plan_path(robot, poses, mode="axis", max_joint_step=0.2)
    assert five.solved.all() and "discontinuity" not in five.status
    _check_axis_plan(robot, five)


@pytest.mark.parametrize("name", ["ur5", "jumbo_drill_6dof"])
def test_axis_paths_of_six_joint_arms(name: str) -> None:
    """A drilling line with a random roll per waypoint on a UR5 and the jumbo drill."""
    robot = load_problem(name).robot
    rng = np.random.default_rng(11)
    q = robot.mid_limits + 0.2
    T0 = robot.fk(q)
    T1 = T0.copy()
    T1[:3, 3] += 0.1 * T0[:3, 0]  # along the face, the drill axis kept
    poses = line(T0, T1, 0.02)
    for P in poses:
        P[:3, :3] = P[:3, :3] @ rot_z(rng.uniform(-math.pi, math.pi))
    plan = plan_path(robot, poses, mode="axis", max_joint_step=0.3, q_start=q)
    assert plan.solved.all() and "discontinuity" not in plan.status
    _check_axis_plan(robot, plan)


def test_other_tool_axis() -> None:
    panda = load_problem("panda").robot
    q0 = panda.mid_limits + 0.1
    T0 = panda.fk(q0)
    T1 = T0.copy()
    T1[:3, 3] += [0.05, 0.05, 0.0]
    poses = line(T0, T1, 0.01)
    for k, P in enumerate(poses):
        P[:3, :3] = P[:3, :3] @ optik.spatial.rot_x(0.3 * k)  # roll about the tool x
    plan = plan_path(panda, poses, mode="axis", axis="x", max_joint_step=0.2, q_start=q0)
    assert plan.status == ["ok"] * len(poses)
    _check_axis_plan(panda, plan, axis="x")


def test_weights_free_the_depth_and_the_roll() -> None:
    """weights [1, 1, 0, 1, 1, 0]: the waypoint's z (depth) and the roll about it free."""
    panda = load_problem("panda").robot
    q0 = panda.mid_limits
    poses = _spinning_line(panda, q0, 0.35, step=0.02)
    depth = np.linspace(0.0, 0.05, len(poses))
    deep = poses.copy()
    deep[:, :3, 3] += depth[:, None] * poses[:, :3, 2]  # deeper along each waypoint's z
    plan = plan_path(
        panda, deep, weights=[1, 1, 0, 1, 1, 0], max_joint_step=0.2, q_start=q0, tol=(1e-6, 1e-7)
    )
    assert plan.mode == "axis" and plan.status == ["ok"] * len(deep)
    for k in range(len(deep)):
        F = panda.fk(plan.q[k])
        d = deep[k, :3, :3].T @ (F[:3, 3] - deep[k, :3, 3])  # in the waypoint's frame
        assert math.hypot(d[0], d[1]) <= 1e-6
        assert _axis_angle(F[:3, 2], deep[k, :3, 2]) <= 1e-7
    # The depth is really free: the answers do not all sit at the pushed-in points.
    gaps = [np.linalg.norm(panda.fk(plan.q[k])[:3, 3] - deep[k, :3, 3]) for k in range(len(deep))]
    assert max(gaps) > 1e-3


def test_frozen_joint_is_held_along_the_path() -> None:
    panda = load_problem("panda").robot
    q0 = panda.mid_limits.copy()
    q0[2] = 0.4
    poses = _spinning_line(panda, q0, 0.2, step=0.02)
    plan = plan_path(
        panda, poses, mode="axis", frozen={"panda_joint3": 0.4}, max_joint_step=0.2, q_start=q0
    )
    assert plan.solved.all() and "discontinuity" not in plan.status
    assert np.all(plan.q[:, 2] == 0.4)
    _check_axis_plan(panda, plan)
    # The frozen column is left out of the task Jacobian the flags are judged by.
    for k in range(len(poses)):
        J = panda.jacobian(plan.q[k])
        R = poses[k, :3, :3]
        rows = np.vstack([R.T @ J[:3], (R.T @ J[3:])[:2]])[:, [0, 1, 3, 4, 5, 6]]
        s = np.linalg.svd(rows, compute_uv=False)
        assert plan.manipulability[k] == pytest.approx(float(np.prod(s)), rel=1e-9)


def test_frozen_joint_exempt_from_the_margin() -> None:
    """A joint frozen next to its limit is not pushed in by ``limit_margin``."""
    panda = load_problem("panda").robot
    q0 = panda.mid_limits.copy()
    q0[6] = panda.upper[6] - 0.01  # 0.01 rad from the limit, inside a 0.05 rad margin
    poses = _spinning_line(panda, q0, 0.1, step=0.05)
    plan = plan_path(
        panda,
        poses,
        mode="axis",
        frozen={"panda_joint7": float(q0[6])},
        limit_margin=0.05,
        max_joint_step=0.3,
        q_start=q0,
    )
    assert plan.solved.all()
    assert np.all(plan.q[:, 6] == q0[6])
    free = np.delete(plan.limit_margin, 6, axis=1)
    assert free.min() >= 0.05 - 1e-9
    _check_axis_plan(panda, plan)


def test_manipulability_of_the_axis_task_rows() -> None:
    """Five rows (the roll row dropped): the product of their singular values."""
    panda = load_problem("panda").robot
    q0 = panda.mid_limits
    poses = _spinning_line(panda, q0, 0.35, step=0.05)
    plan = plan_path(panda, poses, mode="axis", max_joint_step=0.3, q_start=q0)
    for k in range(len(poses)):
        J = panda.jacobian(plan.q[k])
        R = poses[k, :3, :3]
        rows = np.vstack([R.T @ J[:3], (R.T @ J[3:])[:2]])
        s = np.linalg.svd(rows, compute_uv=False)
        assert plan.manipulability[k] == pytest.approx(float(np.prod(s)), rel=1e-9)
        assert s[-1] > 1e-3  # none flagged near_singular, rightly


def test_posture_candidates_are_first_order_optimal() -> None:
    """With a posture, each waypoint's answer is a local optimum of its distance to q_ref.

    First-order optimality (limits inactive): ``q - q_ref`` lies in the row space of the
    task Jacobian (5 rows in the waypoint's frame, computed here). Measured: 2e-15 to
    6e-6 relative on this line.
    """
    panda = load_problem("panda").robot
    q0 = panda.mid_limits
    poses = _spinning_line(panda, q0, 0.35, step=0.02)
    q_ref = q0 + np.array([0.4, -0.3, 0.5, -0.3, 0.4, 0.3, -0.5])
    plain = plan_path(panda, poses, mode="axis", max_joint_step=0.3, q_start=q0)
    near = plan_path(panda, poses, mode="axis", max_joint_step=0.3, q_start=q0, posture=q_ref)
    # The first answer, near q_ref, is a move from q_start, flagged when it is long.
    assert near.step[0] == pytest.approx(np.max(np.abs(near.q[0] - q0)), abs=0.0)
    assert near.status[0] == ("discontinuity" if near.step[0] > 0.3 else "ok")
    assert near.status[1:] == ["ok"] * (len(poses) - 1)
    _check_axis_plan(panda, near)
    for k in range(len(poses)):
        q = near.q[k]
        assert np.min(near.limit_margin[k]) > 1e-3  # limits inactive
        J = panda.jacobian(q)
        R = poses[k, :3, :3]
        A = np.vstack([R.T @ J[:3], (R.T @ J[3:])[:2]])
        g = q - q_ref
        off = g - np.linalg.pinv(A) @ (A @ g)
        assert np.linalg.norm(off) <= 1e-4 * np.linalg.norm(g), k
    distance = np.linalg.norm(near.q - q_ref, axis=1)
    assert np.all(distance < np.linalg.norm(plain.q - q_ref, axis=1))


def test_weighted_posture_and_weights_reach_the_solves() -> None:
    """joint_weights change the answer: a heavy joint 1 moves less from q_ref."""
    panda = load_problem("panda").robot
    q0 = panda.mid_limits
    poses = _spinning_line(panda, q0, 0.35, step=0.1)
    q_ref = q0 + np.array([0.4, -0.3, 0.5, -0.3, 0.4, 0.3, -0.5])
    w = np.ones(7)
    w[0] = 100.0
    plain = plan_path(panda, poses, mode="axis", max_joint_step=0.5, q_start=q0, posture=q_ref)
    heavy = plan_path(
        panda, poses, mode="axis", max_joint_step=0.5, q_start=q0, posture=q_ref, joint_weights=w
    )
    _check_axis_plan(panda, heavy)
    assert np.all(np.abs(heavy.q[:, 0] - q_ref[0]) < np.abs(plain.q[:, 0] - q_ref[0]))


def test_orientation_path_ignores_the_positions() -> None:
    panda = load_problem("panda").robot
    rng = np.random.default_rng(2)
    q = rng.uniform(panda.lower, panda.upper)
    T0 = panda.fk(q)
    T0[:3, 3] += 10.0  # far beyond the reach: only the rotation counts
    T1 = T0 @ optik.spatial.transform(rot_z(0.2), [0.0, 0.0, 0.0])
    poses = line(T0, T1, 0.01)
    plan = plan_path(panda, poses, mode="orientation", max_joint_step=0.3)
    assert plan.mode == "orientation" and plan.solved.all()
    for k in range(len(poses)):
        R = panda.fk(plan.q[k])[:3, :3]
        assert optik.spatial.rotation_angle(poses[k, :3, :3].T @ R) <= TOL


def test_axis_plan_files_name_the_mode(tmp_path: Path) -> None:
    panda = load_problem("panda").robot
    poses = _spinning_line(panda, panda.mid_limits, 0.35, step=0.1)
    plan = plan_path(panda, poses, mode="axis", q_start=panda.mid_limits)
    plan.save(tmp_path / "plan.json")
    assert json.loads((tmp_path / "plan.json").read_text())["mode"] == "axis"


POSES = line(np.eye(4), np.eye(4), 1.0)


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [
        ({"mode": "drill"}, "mode"),
        ({"mode": "axis", "axis": "w"}, "axis"),
        ({"weights": [1, 1, 1, 1, math.nan, 1]}, "weights"),
        ({"weights": [1, 1, 1, -1, 1, 1]}, "weights"),
        ({"weights": [1, 1, 1, 0, 0, 1]}, "weights"),
        ({"weights": [1, 1, 1]}, "weights"),
        ({"mode": "position", "weights": [1, 1, 1, 1, 1, 0]}, "weights"),
        ({"tol": (1e-6, 0.0)}, "tol"),
        ({"tol": (1e-6,)}, "tol"),
        ({"frozen": {"no_such_joint": 0.0}}, "frozen"),
        ({"frozen": {"panda_joint4": 0.5}}, "panda_joint4"),
        ({"frozen": {"panda_joint1": math.nan}}, "panda_joint1"),
        ({"frozen": [("panda_joint1", 0.0)]}, "frozen"),
        ({"posture": np.zeros(6)}, "posture"),
        ({"posture": np.full(7, math.nan)}, "posture"),
        ({"posture": np.zeros(7), "joint_weights": np.zeros(7)}, "joint_weights"),
        ({"joint_weights": np.ones(7)}, "joint_weights"),
    ],
)
def test_bad_task_input(kwargs: dict[str, Any], field: str) -> None:
    panda = load_problem("panda").robot
    with pytest.raises(OptikError, match=field):
        plan_path(panda, POSES, **kwargs)


@pytest.mark.parametrize("mode", ["axis", "orientation"])
def test_axis_and_orientation_need_poses(mode: str) -> None:
    panda = load_problem("panda").robot
    with pytest.raises(OptikError, match="path"):
        plan_path(panda, np.zeros((3, 3)), mode=mode)


def test_bad_input_is_refused_before_any_solve() -> None:
    """An empty path is still validated (nothing is solved, nothing is skipped)."""
    panda = load_problem("panda").robot
    with pytest.raises(OptikError, match="frozen"):
        plan_path(panda, np.zeros((0, 3)), frozen={"nope": 0.0})


def test_drilling_pattern_example() -> None:
    """examples/drilling_pattern.py: every hole drilled in 5-D, the 6-D plans jump."""
    file = Path(__file__).resolve().parent.parent / "examples" / "drilling_pattern.py"
    spec = importlib.util.spec_from_file_location("drilling_pattern", file)
    assert spec is not None and spec.loader is not None
    example = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(example)
    holes = example.drilling_pattern()
    # The holes lie on the tilted plate, 6 cm apart, each drilling along minus its normal.
    normal = np.array([math.sin(math.radians(30.0)), 0.0, math.cos(math.radians(30.0))])
    assert np.allclose((holes[:, :3, 3] - [0.45, 0.0, 0.25]) @ normal, 0.0, atol=1e-12)
    assert np.allclose(holes[:, :3, 2], -normal, atol=1e-12)
    gaps = np.linalg.norm(np.diff(holes[:, :3, 3], axis=0), axis=1)
    assert np.allclose(gaps, 0.06, atol=1e-12)
    results = example.main()
    for name in ("panda", "ur5"):
        robot = load_problem(name).robot
        five = results[name]
        assert five["status"] == ["ok"] * len(holes)
        for q, T in zip(five["q"], holes, strict=True):
            F = robot.fk(q)
            assert np.linalg.norm(F[:3, 3] - T[:3, 3]) <= TOL
            assert _axis_angle(F[:3, 2], T[:3, 2]) <= TOL
        assert results[name + "_pose"]["largest_step"] > 0.6  # the full poses spin the wrist


def test_an_axis_path_through_a_wrist_singularity_stays_continuous() -> None:
    # At q5 = 0 every roll of the tool is singular: the roll's grid of closed-form answers
    # held the free wrist joint at mid-limits (q6 = 0), and the plan flagged a 0.5 rad
    # jump there although the path's own configurations move 0.03 rad a waypoint.
    ur5 = load_problem("ur5").robot
    Q = np.array([[0.3, 0.6, -1.0, 0.4, q5, 0.5] for q5 in (0.06, 0.03, 0.0, -0.03, -0.06)])
    plan = plan_path(ur5, ur5.fk(Q), mode="axis", max_joint_step=0.1, q_start=Q[0])
    assert "discontinuity" not in plan.status, (plan.status, plan.step)
    assert plan.largest_step <= 0.03 + 1e-6
    # One answer: the nearest to q0 at the singular pose is q0's own configuration.
    res = optik.solve_ik(ur5, ur5.fk(Q[2]), mode="axis", q0=Q[2])
    assert res.success and np.max(np.abs(res.q - Q[2])) <= 1e-6, res.q
