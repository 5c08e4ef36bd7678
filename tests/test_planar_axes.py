"""The planar two-joint family found from the joint axes: URDF, modified DH and DH arms."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from conftest import assert_batch_equals_single, assert_closed_form_round_trips, joint_distance
from scipy.spatial.transform import Rotation

import optik
from optik import Robot, analytic_ik, load_problem, solve_ik
from optik.analytic import explain_family, family_of
from optik.analytic.geometry import joint_axes
from optik.errors import AnalyticIKError

LIMIT = math.radians(170.0)
PLANAR = optik.analytic.FAMILIES["planar_2r"]


def _origin(T: np.ndarray) -> str:
    xyz = " ".join(repr(float(v)) for v in T[:3, 3])
    rpy = " ".join(repr(float(v)) for v in Rotation.from_matrix(T[:3, :3]).as_euler("xyz"))
    return f'<origin xyz="{xyz}" rpy="{rpy}"/>'


def _pose(rotvec: tuple[float, float, float], xyz: tuple[float, float, float]) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = Rotation.from_rotvec(rotvec).as_matrix()
    T[:3, 3] = xyz
    return T


def _urdf(tmp_path: Path, second_axis: str = "0 -1 0", tilt: float = 0.0) -> Path:
    """A two-link arm in a tilted plane: the mount turned and shifted, both axes along the
    links' y (the second written reversed by default), the second joint offset along its
    axis and off the first link's line, the tip off the second link's line and along the
    axis. ``tilt`` (rad) turns the second joint's frame about x: its axis leaves parallel.
    """
    mount = _pose((0.3, -0.2, 0.5), (0.1, 0.2, 0.3))
    elbow = _pose((tilt, 0.0, 0.0), (0.45, 0.07, 0.02))
    tip = _pose((0.0, 0.4, 0.0), (0.3, -0.05, 0.04))
    limit = f'<limit lower="{-LIMIT!r}" upper="{LIMIT!r}" effort="1" velocity="1"/>'
    return _write(
        tmp_path,
        "<robot name='planar_urdf'>"
        "<link name='world'/><link name='base'/><link name='upper'/><link name='fore'/>"
        "<link name='tip'/>"
        f"<joint name='mount' type='fixed'><parent link='world'/><child link='base'/>"
        f"{_origin(mount)}</joint>"
        f"<joint name='shoulder' type='revolute'><parent link='base'/><child link='upper'/>"
        f"<origin xyz='0 0 0.1' rpy='0 0 0'/><axis xyz='0 1 0'/>{limit}</joint>"
        f"<joint name='elbow' type='revolute'><parent link='upper'/><child link='fore'/>"
        f"{_origin(elbow)}<axis xyz='{second_axis}'/>{limit}</joint>"
        f"<joint name='flange' type='fixed'><parent link='fore'/><child link='tip'/>"
        f"{_origin(tip)}</joint>"
        "</robot>",
    )


def _write(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "arm.urdf"
    path.write_text(text, encoding="utf-8")
    return path


def _check_round_trips(robot: Robot, n: int, seed: int) -> None:
    assert_closed_form_round_trips(robot, PLANAR, n, seed, {"pose": 2, "position": 2})


def test_urdf_arm_in_a_tilted_plane_gets_both_elbow_branches(tmp_path: Path) -> None:
    robot = Robot.from_urdf(_urdf(tmp_path), "world", "tip")
    assert family_of(robot) is optik.analytic.FAMILIES["planar_2r"]
    assert "family 'planar_2r' (detected)" in explain_family(robot)
    _check_round_trips(robot, 200, seed=1)
    # A generic position has two elbow branches (in position mode the orientation is
    # free): q2 mirrored about the straight arm.
    rng = np.random.default_rng(2)
    q = rng.uniform(0.3, 1.2, 2)
    assert len(analytic_ik(robot, robot.fk(q)[:3, 3], mode="position")) == 2
    assert len(analytic_ik(robot, robot.fk(q))) == 1
    res = solve_ik(robot, robot.fk(q), solver="auto")
    assert res.success and res.solver == "analytic"
    assert joint_distance(robot, res.q, q) < 1e-9


def test_second_axis_written_either_way(tmp_path: Path) -> None:
    same = Robot.from_urdf(_urdf(tmp_path, "0 1 0"), "world", "tip")
    assert family_of(same) is optik.analytic.FAMILIES["planar_2r"]
    _check_round_trips(same, 100, seed=3)


def test_unreachable_and_off_plane_targets_have_no_branch(tmp_path: Path) -> None:
    robot = Robot.from_urdf(_urdf(tmp_path), "world", "tip")
    T = robot.fk(np.array([0.4, -0.7]))
    far = T.copy()
    far[:3, 3] += 5.0 * T[:3, 0]
    assert analytic_ik(robot, far) == []
    off = T[:3, 3] + 1e-3 * joint_axes(robot).directions[0]  # off the plane by 1 mm
    assert analytic_ik(robot, off, mode="position") == []
    res = solve_ik(robot, far, solver="auto")
    assert not res.success and res.status == "unreachable"


def test_tilted_second_axis_is_not_planar_and_says_why(tmp_path: Path) -> None:
    robot = Robot.from_urdf(_urdf(tmp_path, tilt=1e-3), "world", "tip")
    assert family_of(robot) is None
    reason = optik.analytic.FAMILIES["planar_2r"].explain(robot)
    assert reason is not None and "not parallel" in reason and "(0.0572958 deg)" in reason
    with pytest.raises(AnalyticIKError, match="not parallel"):
        Robot.from_urdf(_urdf(tmp_path, tilt=1e-3), "world", "tip", analytic="planar_2r")


def test_coincident_axes_are_not_planar() -> None:
    robot = Robot.from_dh([{"a": 0.0, "d": 0.1, "role": "arm"}, {"a": 0.5, "role": "arm"}])
    assert optik.analytic.FAMILIES["planar_2r"].explain(robot) == "axes 1 and 2 coincide"


def test_modified_dh_arm_fits_with_its_offsets() -> None:
    rows = [
        {"a": 0.0, "alpha": 0.0, "d": 0.2, "theta": 0.3, "role": "arm"},
        {"a": 0.7, "alpha": 0.0, "d": -0.1, "theta": -0.5, "role": "arm"},
    ]
    tool = np.eye(4)
    tool[:3, 3] = (0.4, 0.1, 0.05)
    robot = Robot.from_mdh(rows, base=_pose((0.0, 0.0, 1.0), (1.0, 0.0, 0.5)), tool=tool)
    assert family_of(robot) is optik.analytic.FAMILIES["planar_2r"]
    _check_round_trips(robot, 200, seed=4)


def test_seed_003_arm_equals_the_textbook_formulas() -> None:
    """The DH arm of seed 003: the branches of ``q2 = +-acos(...)``, ``q1 = atan2 - atan2``
    computed here from the link lengths, independently of the family's vectors."""
    robot = load_problem("planar_2r").robot
    a1, a2 = (row.a for row in robot.dh or ())
    rng = np.random.default_rng(5)
    for _ in range(100):
        x, y = rng.uniform(-1.9, 1.9, 2)
        if not abs(a1 - a2) < math.hypot(x, y) < a1 + a2:
            continue
        c2 = (x * x + y * y - a1 * a1 - a2 * a2) / (2 * a1 * a2)
        expected = []
        for q2 in (-math.acos(c2), math.acos(c2)):
            q1 = math.atan2(y, x) - math.atan2(a2 * math.sin(q2), a1 + a2 * math.cos(q2))
            expected.append(np.array([q1, q2]))
        got = analytic_ik(robot, [x, y, 0.0], mode="position", within_limits=False)
        assert len(got) == 2
        for e in expected:
            assert min(joint_distance(robot, g, e) for g in got) < 1e-12


def test_batch_equals_single_calls(tmp_path: Path) -> None:
    robot = Robot.from_urdf(_urdf(tmp_path), "world", "tip")
    rng = np.random.default_rng(6)
    T = robot.fk(rng.uniform(robot.lower, robot.upper, (50, 2)))
    assert_batch_equals_single(robot, T, "pose")
    assert_batch_equals_single(robot, T[:, :3, 3], "position")


@pytest.mark.parametrize(
    ("rows", "q2"),
    [
        ([{"a": 0.5, "role": "arm"}, {"a": 0.5, "role": "arm"}], math.pi),  # folded
        ([{"a": 0.5, "role": "arm"}, {"a": 0.5, "role": "arm"}], math.pi - 1e-9),
        ([{"a": 0.5, "role": "arm"}, {"a": 0.5, "role": "arm"}], 1e-7),  # stretched
        ([{"a": 0.5, "role": "arm"}, {"a": 0.0, "d": 0.1, "role": "arm"}], None),  # tool on axis 2
    ],
)
def test_pose_mode_sets_the_joint_the_position_leaves_free(rows: list, q2: float | None) -> None:
    """Folded (joint 1 free), a hair from folded or stretched (ill-conditioned) or with the
    tool on axis 2 (joint 2 free): the orientation sets the joint, so every pose of the
    sweep gets its branch, and the raw closed form reaches the whole pose."""
    robot = Robot.from_dh(rows)
    rng = np.random.default_rng(7)
    Q = rng.uniform(robot.lower, robot.upper, (40, 2))
    if q2 is not None:
        Q[:, 1] = q2
    for q in Q:
        T = robot.fk(q)
        branches = analytic_ik(robot, T, within_limits=False)
        assert any(np.max(np.abs(robot.fk(b) - T)) < 1e-9 for b in branches), q
        raw = PLANAR.candidates(robot, T, "pose", robot.mid_limits)
        assert min(float(np.max(np.abs(robot.fk(b) - T)[:3, :3])) for b in raw) < 1e-12
