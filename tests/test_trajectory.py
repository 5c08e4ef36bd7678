"""PathPlan.to_trajectory: limits, the path, the Cartesian path, optimality, segments, files."""

from __future__ import annotations

import json
import math
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest
import toppra
import toppra.algorithm
import toppra.constraint
from conftest import out_of_reach_and_back, plan_from_q
from scipy.interpolate import CubicSpline
from scipy.spatial.transform import Rotation, Slerp

from optik.errors import OptikError
from optik.model import Robot
from optik.paths import line
from optik.planning import PathPlan, plan_path
from optik.problems import load_problem
from optik.trajectory import Trajectory

ROOT = Path(__file__).resolve().parent.parent
PUMA_Q0 = np.array([-0.333, 3.713, -1.5713, 0.1582, 0.4196, 4.597])
PUMA_Q1 = np.array([-0.7299, 3.927, -1.5419, 1.3596, 0.5327, 4.2171])
VLIM = np.array([1.0, 0.8, 1.2, 1.5, 1.5, 2.0])  # rad/s
ALIM = np.array([2.0, 1.5, 2.5, 4.0, 4.0, 5.0])  # rad/s^2
TOLERANCE = 2e-3  # m and rad: accepted departure from the Cartesian path
REL = 1e-6


@pytest.fixture(scope="module")
def puma() -> Robot:
    return load_problem("puma560").robot


@pytest.fixture(scope="module")
def puma_plan(puma: Robot) -> PathPlan:
    poses = line(puma.fk(PUMA_Q0), puma.fk(PUMA_Q1), 0.01)
    plan = plan_path(puma, poses, max_joint_step=0.2, q_start=PUMA_Q0)
    assert all(s == "ok" for s in plan.status)
    return plan


@pytest.fixture(scope="module")
def puma_trajectory(puma: Robot, puma_plan: PathPlan) -> Trajectory:
    return puma_plan.to_trajectory(VLIM, ALIM, robot=puma, path_tolerance=TOLERANCE)


def _times(trajectory: Trajectory, k: int, n: int = 1000) -> np.ndarray:
    rng = np.random.default_rng(17 + k)
    duration = trajectory.segments[k].duration
    return np.sort(np.concatenate([[0.0, duration], rng.uniform(0.0, duration, n - 2)]))


def _spline(Q: np.ndarray) -> tuple[CubicSpline, np.ndarray]:
    """The documented joint path, built here from the plan: natural cubic in chord length."""
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(Q, axis=0), axis=1))])
    return CubicSpline(s, Q, bc_type="natural"), s


def _nearest_s(spline: CubicSpline, s_end: float, q: np.ndarray) -> tuple[float, float]:
    """The path parameter nearest ``q`` and the distance there (dense search, Gauss-Newton)."""
    grid = np.linspace(0.0, s_end, 4001)
    x = float(grid[np.argmin(np.linalg.norm(spline(grid) - q, axis=1))])
    for _ in range(8):
        d1 = spline(x, 1)
        x = float(np.clip(x - (spline(x) - q) @ d1 / (d1 @ d1), 0.0, s_end))
    return x, float(np.linalg.norm(spline(x) - q))


# ----------------------------------------------------------------------- limits
def test_velocity_and_acceleration_within_limits_at_1000_times(
    puma_trajectory: Trajectory,
) -> None:
    assert len(puma_trajectory.segments) == 1
    t = _times(puma_trajectory, 0)
    _, qd, qdd = puma_trajectory.at(0, t)
    assert np.all(np.abs(qd) <= VLIM * (1 + REL))
    assert np.all(np.abs(qdd) <= ALIM * (1 + REL))
    # Time-optimal: some joint runs at its limit somewhere.
    assert np.max(np.abs(qd) / VLIM) > 0.99 or np.max(np.abs(qdd) / ALIM) > 0.99
    # The sampled arrays too.
    assert np.all(np.abs(puma_trajectory.qd) <= VLIM * (1 + REL))
    assert np.all(np.abs(puma_trajectory.qdd) <= ALIM * (1 + REL))
    # At rest at both ends.
    np.testing.assert_allclose(qd[[0, -1]], 0.0, atol=1e-12)


def test_velocity_and_acceleration_are_the_derivatives_of_position(
    puma_trajectory: Trajectory,
) -> None:
    h = 1e-6
    t = _times(puma_trajectory, 0, 200)[1:-1]
    q_plus, qd_plus, _ = puma_trajectory.at(0, t + h)
    q_minus, qd_minus, _ = puma_trajectory.at(0, t - h)
    _, qd, qdd = puma_trajectory.at(0, t)
    np.testing.assert_allclose((q_plus - q_minus) / (2 * h), qd, atol=1e-6)
    # Path acceleration is piecewise constant: compare away from the grid's switch points.
    fd = (qd_plus - qd_minus) / (2 * h)
    close = np.abs(fd - qdd) <= 1e-4 * (1 + np.abs(qdd))
    assert close.mean() > 0.95


def test_positions_on_the_planned_joint_path_and_through_every_waypoint(
    puma: Robot, puma_plan: PathPlan, puma_trajectory: Trajectory
) -> None:
    segment = puma_trajectory.segments[0]
    assert segment.interpolation == "cubic"
    spline, s = _spline(puma_plan.q)
    t = _times(puma_trajectory, 0)
    q, _, _ = puma_trajectory.at(0, t)
    found = [_nearest_s(spline, s[-1], row) for row in q]
    assert max(d for _, d in found) < 1e-9
    s_of_t = np.array([v for v, _ in found])
    assert np.all(np.diff(s_of_t) >= -1e-9)  # forward along the path, never back
    np.testing.assert_allclose(s_of_t[[0, -1]], [0.0, s[-1]], atol=1e-9)
    # Each waypoint is passed at its stated time.
    q_way, _, _ = puma_trajectory.at(0, segment.waypoint_times)
    np.testing.assert_allclose(q_way, puma_plan.q, atol=1e-9)
    assert np.all(puma.within_limits(q))


def _distance_to_polyline(points: np.ndarray, vertices: np.ndarray) -> np.ndarray:
    a, b = vertices[:-1], vertices[1:]
    ab = b - a
    lam = np.einsum("pkj,kj->pk", points[:, None, :] - a, ab) / np.einsum("kj,kj->k", ab, ab)
    nearest = a + np.clip(lam, 0.0, 1.0)[..., None] * ab
    return np.min(np.linalg.norm(points[:, None, :] - nearest, axis=2), axis=1)


def test_fk_of_samples_within_tolerance_of_the_cartesian_path(
    puma: Robot, puma_plan: PathPlan, puma_trajectory: Trajectory
) -> None:
    q, _, _ = puma_trajectory.at(0, _times(puma_trajectory, 0))
    T = puma.fk(q)
    distance = _distance_to_polyline(T[:, :3, 3], puma_plan.poses[:, :3, 3])
    assert distance.max() <= TOLERANCE
    # Orientation: the angle to the nearest rotation of the path's geodesic (slerp).
    key = Rotation.from_matrix(puma_plan.poses[:, :3, :3])
    slerp = Slerp(np.arange(len(key)), key)
    path_rotations = slerp(np.linspace(0, len(key) - 1, 20 * len(key)))
    angles = np.array(
        [np.min((path_rotations.inv() * Rotation.from_matrix(R)).magnitude()) for R in T[:, :3, :3]]
    )
    assert angles.max() <= TOLERANCE
    segment = puma_trajectory.segments[0]
    assert segment.position_deviation <= TOLERANCE
    assert segment.position_deviation >= 0.5 * distance.max()  # it measures, not guesses


def test_a_fine_plan_stays_within_its_ik_tolerance_of_the_cartesian_path() -> None:
    # The UR5 along a line planned every millimetre: between waypoints the tool stays within
    # the plan's own IK tolerance (1e-6 m, 1e-6 rad) of the Cartesian path.
    robot = load_problem("ur5").robot
    q0 = np.array([0.3, -1.2, 1.5, -1.0, -1.4, 0.2])
    T0 = robot.fk(q0)
    T1 = T0.copy()
    T1[:3, 3] += [0.0, 0.3, -0.1]
    tol = 1e-6
    plan = plan_path(robot, line(T0, T1, 0.001), q_start=q0, tol=tol)
    assert plan.solved.all()
    trajectory = plan.to_trajectory(1.0, 2.0, robot=robot, path_tolerance=tol)
    q, _, _ = trajectory.at(0, _times(trajectory, 0))
    T = robot.fk(q)
    assert _distance_to_polyline(T[:, :3, 3], plan.poses[:, :3, 3]).max() <= tol
    # The line keeps its orientation: every sample's rotation is the waypoints' one.
    rel = Rotation.from_matrix(T0[:3, :3]).inv() * Rotation.from_matrix(T[:, :3, :3])
    assert rel.magnitude().max() <= tol


def test_path_tolerance_is_enforced(puma: Robot, puma_plan: PathPlan) -> None:
    with pytest.raises(OptikError, match="path_tolerance"):
        puma_plan.to_trajectory(VLIM, ALIM, robot=puma, path_tolerance=1e-6)
    with pytest.raises(OptikError, match="needs robot"):
        puma_plan.to_trajectory(VLIM, ALIM, path_tolerance=1e-3)


# ----------------------------------------------------------------------- optimality
def _upper_bound_time(spline: CubicSpline, s_end: float) -> float:
    """Duration of a feasible bang-coast-bang path-speed profile (an upper bound)."""
    s = np.linspace(0.0, s_end, 20001)
    d1, d2 = np.abs(spline(s, 1)), np.abs(spline(s, 2))
    cruise = float(np.min(VLIM / np.maximum(d1, 1e-300)))
    cruise = min(cruise, float(np.min(np.sqrt(0.5 * ALIM / np.maximum(d2, 1e-300)))))
    accel = float(np.min((ALIM - d2 * cruise**2) / np.maximum(d1, 1e-300)))
    assert accel > 0
    if s_end >= cruise**2 / accel:
        return s_end / cruise + cruise / accel
    return 2.0 * math.sqrt(s_end / accel)


def _toppra_optimum(Q: np.ndarray, points: int) -> float:
    """TOPP-RA's duration on the same path, built here with toppra's own spline."""
    _, s = _spline(Q)
    path = toppra.SplineInterpolator(s, Q, bc_type="natural")
    constraints = [
        toppra.constraint.JointVelocityConstraint(VLIM),
        toppra.constraint.JointAccelerationConstraint(ALIM),
    ]
    grid = np.linspace(0.0, s[-1], points)
    instance = toppra.algorithm.TOPPRA(
        constraints, path, gridpoints=grid, parametrizer="ParametrizeConstAccel"
    )
    return float(instance.compute_trajectory(0.0, 0.0).duration)


def test_total_time_between_bounds_and_near_the_toppra_optimum(
    puma_plan: PathPlan, puma_trajectory: Trajectory
) -> None:
    spline, s = _spline(puma_plan.q)
    duration = puma_trajectory.duration
    dense = spline(np.linspace(0.0, s[-1], 20001))
    lower = float(np.max(np.sum(np.abs(np.diff(dense, axis=0)), axis=0) / VLIM))
    assert lower <= duration <= _upper_bound_time(spline, s[-1])
    optimum = _toppra_optimum(puma_plan.q, 4000)
    assert abs(duration - optimum) <= 0.05 * optimum
    assert duration == pytest.approx(puma_trajectory.t[-1])


# ----------------------------------------------------------------------- segments
def test_an_unreachable_stretch_gives_two_segments(puma: Robot) -> None:
    plan = plan_path(puma, out_of_reach_and_back(puma), max_joint_step=0.3)
    solved = plan.solved
    assert solved.any() and not solved.all()
    trajectory = plan.to_trajectory(VLIM, ALIM, robot=puma)
    assert len(trajectory.segments) == 2
    runs = np.flatnonzero(np.diff(np.concatenate([[0], solved.astype(int), [0]])))
    expected = [(int(a), int(b) - 1) for a, b in zip(runs[::2], runs[1::2], strict=True)]
    assert [(seg.first, seg.last) for seg in trajectory.segments] == expected
    for k, seg in enumerate(trajectory.segments):
        assert not any(plan.status[i] == "unreachable" for i in range(seg.first, seg.last + 1))
        q_end, qd_end, _ = trajectory.at(k, [0.0, seg.duration])
        np.testing.assert_allclose(q_end, plan.q[[seg.first, seg.last]], atol=1e-9)
        np.testing.assert_allclose(qd_end, 0.0, atol=1e-12)
        samples = slice(seg.start, seg.stop)
        np.testing.assert_allclose(trajectory.t[samples][[0, -1]] - seg.t_start, [0, seg.duration])
    # End to end on one clock, and the arrays hold only the two segments' samples.
    first, second = trajectory.segments
    assert second.t_start == pytest.approx(first.t_start + first.duration)
    assert second.start == first.stop and second.stop == len(trajectory.t)


def test_a_discontinuity_splits_the_trajectory(puma: Robot) -> None:
    poses = line(puma.fk(PUMA_Q0), puma.fk(PUMA_Q1), 0.01)
    greedy = plan_path(puma, poses, max_joint_step=0.2, greedy=True, q_start=PUMA_Q0)
    jumps = [k for k, s in enumerate(greedy.status) if s == "discontinuity"]
    assert jumps
    trajectory = greedy.to_trajectory(VLIM, ALIM, robot=puma)
    assert len(trajectory.segments) == len(jumps) + 1
    assert [seg.first for seg in trajectory.segments[1:]] == jumps
    for k in range(len(trajectory.segments)):
        q, qd, qdd = trajectory.at(k, _times(trajectory, k, 300))
        assert np.all(np.abs(qd) <= VLIM * (1 + REL)) and np.all(np.abs(qdd) <= ALIM * (1 + REL))
        # Within a segment no step is larger than the plan's bound.
        assert np.max(np.abs(np.diff(q, axis=0))) <= 0.2


def test_a_spline_that_would_leave_the_limits_becomes_monotone(puma: Robot) -> None:
    upper = puma.upper[1]
    mid = puma.mid_limits
    Q = np.tile(mid, (6, 1))
    Q[:, 1] = [upper - 0.6, upper - 0.3, upper - 0.05, upper, upper - 0.02, upper - 0.4]
    Q[:, 0] += np.linspace(0.0, 0.3, 6)
    # The natural cubic through these values overshoots the limit (checked here).
    spline, s = _spline(Q)
    assert spline(np.linspace(0, s[-1], 5000))[:, 1].max() > upper + 1e-6
    plan = plan_from_q(puma, Q)
    trajectory = plan.to_trajectory(VLIM, ALIM, robot=puma)
    (segment,) = trajectory.segments
    assert segment.interpolation == "pchip"
    q, qd, qdd = trajectory.at(0, _times(trajectory, 0))
    assert np.all(q <= puma.upper + 1e-12) and np.all(q >= puma.lower - 1e-12)
    assert np.all(np.abs(qd) <= VLIM * (1 + REL)) and np.all(np.abs(qdd) <= ALIM * (1 + REL))
    q_way, _, _ = trajectory.at(0, segment.waypoint_times)
    np.testing.assert_allclose(q_way, Q, atol=1e-9)


def test_repeated_and_single_waypoints(puma: Robot) -> None:
    Q = np.array([PUMA_Q0, PUMA_Q0, PUMA_Q0 + 0.05, PUMA_Q0 + 0.1])
    trajectory = plan_from_q(puma, Q).to_trajectory(VLIM, ALIM, robot=puma)
    (segment,) = trajectory.segments
    q_way, _, _ = trajectory.at(0, segment.waypoint_times)
    np.testing.assert_allclose(q_way, Q, atol=1e-9)
    single = plan_from_q(puma, PUMA_Q0[None]).to_trajectory(VLIM, ALIM)
    (hold,) = single.segments
    assert hold.duration == 0.0 and hold.interpolation == "hold"
    np.testing.assert_allclose(single.q, PUMA_Q0[None])
    np.testing.assert_allclose(single.qd, 0.0)


# ----------------------------------------------------------------------- limits given
@pytest.mark.parametrize(
    ("velocity", "acceleration", "match"),
    [
        (-1.0, 2.0, "must lie in"),
        (np.array([1.0, 1.0, np.nan, 1.0, 1.0, 1.0]), 2.0, "must lie in"),
        (1.0, np.array([2.0, 0.0, 2.0, 2.0, 2.0, 2.0]), "must lie in"),
        (math.inf, 2.0, "must lie in"),
        # 1e-155: the time scale squared overflowed (a bare OverflowError)
        (1e-155, 1.0, r"velocity_limits: limits must lie in \[1e-09"),
        (1.0, 1e10, r"acceleration_limits: limits must lie in \[1e-09, 1e\+09\]"),
        (np.ones(5), 2.0, "one per joint"),
        (1.0, np.ones((6, 2)), "one per joint"),
        ("fast", 2.0, "velocity_limits"),
        (None, 2.0, "velocity_limits: none known"),
        (1.0, None, "acceleration_limits: none known"),
    ],
)
def test_bad_or_missing_limits_raise(
    puma: Robot, puma_plan: PathPlan, velocity: object, acceleration: object, match: str
) -> None:
    with pytest.raises(OptikError, match=match):
        puma_plan.to_trajectory(velocity, acceleration, robot=puma)


def test_no_robot_and_no_limits_says_so(puma_plan: PathPlan) -> None:
    with pytest.raises(OptikError, match="no robot was given"):
        puma_plan.to_trajectory(acceleration_limits=1.0)
    with pytest.raises(OptikError, match="dt"):
        puma_plan.to_trajectory(1.0, 1.0, dt=0.0)


def test_urdf_velocity_limits_are_the_default() -> None:
    urdf = ROOT / "problems" / "panda.urdf"
    robot = Robot.from_urdf(urdf, "panda_link0", "panda_hand")
    # The file's own numbers, read here with ElementTree.
    joints = {j.get("name"): j for j in ET.parse(urdf).getroot().findall("joint")}
    stated = [float(joints[n].find("limit").get("velocity")) for n in robot.joint_names]
    np.testing.assert_array_equal(robot.velocity_limits, stated)
    assert np.all(np.isinf(robot.acceleration_limits))  # URDF has no acceleration limits
    q0 = robot.mid_limits
    T0 = robot.fk(q0)
    T1 = T0.copy()
    T1[:3, 3] += [0.0, 0.25, -0.1]
    plan = plan_path(robot, line(T0, T1, 0.01), q_start=q0)
    assert plan.solved.all()
    trajectory = plan.to_trajectory(acceleration_limits=100.0, robot=robot)
    np.testing.assert_array_equal(trajectory.velocity_limits, stated)
    _, qd, _ = trajectory.at(0, _times(trajectory, 0))
    ratio = np.max(np.abs(qd), axis=0) / np.array(stated)
    assert ratio.max() <= 1 + REL and ratio.max() > 0.99


def test_problem_file_velocity_and_acceleration_fields(tmp_path: Path) -> None:
    text = (ROOT / "problems" / "planar_2r.toml").read_text()
    assert 'angle_unit = "deg"' in text and "velocity" not in text
    lines = []
    for row in text.splitlines():
        lines.append(row)
        if row.strip() == "[[robot.joints]]":
            lines.append("velocity = 90.0\nacceleration = 180.0")  # deg/s, deg/s^2
    file = tmp_path / "planar.toml"
    file.write_text("\n".join(lines))
    robot = load_problem(file).robot
    np.testing.assert_allclose(robot.velocity_limits, math.pi / 2)
    np.testing.assert_allclose(robot.acceleration_limits, math.pi)
    bad = tmp_path / "bad.toml"
    bad.write_text(file.read_text().replace("velocity = 90.0", "velocity = -1.0", 1))
    with pytest.raises(OptikError, match="velocity"):
        load_problem(bad)


# ----------------------------------------------------------------------- files
def test_csv_and_ros_json_files(tmp_path: Path, puma_trajectory: Trajectory) -> None:
    names = puma_trajectory.joint_names
    csv_file = puma_trajectory.save(tmp_path / "trajectory.csv")
    rows = csv_file.read_text().splitlines()
    assert rows[0].split(",")[:2] == ["segment", "t"] and len(rows) == len(puma_trajectory.t) + 1
    data = np.loadtxt(csv_file, delimiter=",", skiprows=1)
    np.testing.assert_allclose(data[:, 1], puma_trajectory.t, atol=1e-9)
    np.testing.assert_allclose(data[:, 2 : 2 + len(names)], puma_trajectory.q, rtol=1e-10)
    json_file = puma_trajectory.save(tmp_path / "trajectory.json")
    doc = json.loads(json_file.read_text())
    (message,) = doc["segments"]
    assert message["joint_names"] == list(names)
    assert len(message["points"]) == len(puma_trajectory.t)
    for k in (0, 7, len(message["points"]) - 1):
        point = message["points"][k]
        stamp = point["time_from_start"]
        assert 0 <= stamp["nanosec"] < 1_000_000_000 and isinstance(stamp["sec"], int)
        assert stamp["sec"] + 1e-9 * stamp["nanosec"] == pytest.approx(
            puma_trajectory.t[k], abs=1e-9
        )
        np.testing.assert_allclose(point["positions"], puma_trajectory.q[k])
        np.testing.assert_allclose(point["velocities"], puma_trajectory.qd[k])
        np.testing.assert_allclose(point["accelerations"], puma_trajectory.qdd[k])
    with pytest.raises(OptikError, match="unknown trajectory format"):
        puma_trajectory.save(tmp_path / "trajectory.txt")


def test_bad_velocity_in_a_urdf_or_a_dh_row_raises() -> None:
    text = (ROOT / "problems" / "panda.urdf").read_text()
    assert 'velocity="2.175"' in text
    with pytest.raises(OptikError, match="velocity limit"):
        Robot.from_urdf(
            text.replace('velocity="2.175"', 'velocity="-1"', 1), "panda_link0", "panda_hand"
        )
    with pytest.raises(OptikError, match="velocity"):
        Robot.from_urdf(
            text.replace('velocity="2.175"', 'velocity="fast"', 1), "panda_link0", "panda_hand"
        )
    with pytest.raises(OptikError, match="velocity"):
        Robot.from_dh([{"a": 1.0, "role": "arm", "velocity": -2.0}])
    with pytest.raises(OptikError, match="acceleration"):
        Robot.from_dh([{"a": 1.0, "role": "arm", "acceleration": math.nan}])
    robot = Robot.from_dh(
        [{"a": 1.0, "role": "arm", "velocity": 2.0, "acceleration": 3.0}, {"a": 1.0, "role": "arm"}]
    )
    np.testing.assert_array_equal(robot.velocity_limits, [2.0, math.inf])
    np.testing.assert_array_equal(robot.acceleration_limits, [3.0, math.inf])
    # with_limits keeps the rate limits.
    clone = robot.with_limits(robot.lower / 2, robot.upper / 2)
    np.testing.assert_array_equal(clone.velocity_limits, robot.velocity_limits)


# ----------------------------------------------------------------------- command line
def test_optik_plan_trajectory_writes_csv_and_ros_json(tmp_path: Path) -> None:
    from optik.cli import main

    out = tmp_path / "plan"
    urdf = ROOT / "problems" / "panda.urdf"
    args = ["plan", "--urdf", str(urdf), "--base", "panda_link0", "--tip", "panda_hand"]
    args += ["--line", "0.4", "-0.2", "0.5", "0.4", "0.2", "0.5", "--rpy-deg", "180", "0", "0"]
    assert main([*args, "--trajectory", "--acceleration-limits", "5", "--out", str(out)]) == 0
    doc = json.loads((out / "trajectory.json").read_text())
    plan = json.loads((out / "plan.json").read_text())
    (message,) = doc["segments"]
    assert doc["velocity_limits"] == [2.175] * 7 and doc["acceleration_limits"] == [5.0] * 7
    times = [
        p["time_from_start"]["sec"] + 1e-9 * p["time_from_start"]["nanosec"]
        for p in message["points"]
    ]
    assert np.all(np.diff(times) > 0) and times[-1] == pytest.approx(doc["duration"], abs=1e-9)
    positions = np.array([p["positions"] for p in message["points"]])
    np.testing.assert_allclose(positions[[0, -1]], np.array(plan["q"])[[0, -1]], atol=1e-9)
    velocities = np.array([p["velocities"] for p in message["points"]])
    assert np.all(np.abs(velocities) <= 2.175 * (1 + REL))
    rows = (out / "trajectory.csv").read_text().splitlines()
    assert len(rows) == len(message["points"]) + 1
    # Missing or malformed limits: exit 2 before any planning, with the flag named.
    assert (
        main(
            [
                "plan",
                "puma560",
                "--line",
                "0.5",
                "-0.2",
                "0.3",
                "0.5",
                "0.2",
                "0.3",
                "--trajectory",
                "--out",
                str(tmp_path / "x"),
            ]
        )
        == 2
    )
    assert not (tmp_path / "x" / "plan.csv").exists()
    assert main([*args, "--trajectory", "--acceleration-limits", "1", "2", "--out", str(out)]) == 2
    assert main([*args, "--velocity-limits", "1", "--out", str(out)]) == 2
    # Limits the trajectory cannot meet (more than MAX_TRAJECTORY_SAMPLES samples): exit
    # 2 before any file is written, not after the plan's files.
    slow = tmp_path / "slow"
    limits = ["--velocity-limits", "1e-6", "--acceleration-limits", "1e-6"]
    assert main([*args, "--trajectory", *limits, "--out", str(slow)]) == 2
    assert not slow.exists() or not any(slow.iterdir())


def test_at_checks_its_arguments(puma_trajectory: Trajectory) -> None:
    with pytest.raises(OptikError, match="segment"):
        puma_trajectory.at(1, 0.0)
    with pytest.raises(OptikError, match="finite"):
        puma_trajectory.at(0, [0.0, math.nan])
    q, qd, qdd = puma_trajectory.at(0, 0.25)  # a scalar time gives one row
    assert q.shape == qd.shape == qdd.shape == (1, 6)


def test_the_exact_range_of_a_cubic_spline_matches_dense_sampling() -> None:
    from optik.trajectory import _cubic_range

    rng = np.random.default_rng(5)
    for _ in range(20):
        s = np.concatenate([[0.0], np.cumsum(rng.uniform(0.05, 0.3, 8))])
        spline = CubicSpline(s, rng.normal(size=(9, 3)), bc_type="natural")
        low, high = _cubic_range(spline.c, np.diff(s))
        dense = spline(np.linspace(0.0, s[-1], 200_001))
        np.testing.assert_allclose(low, dense.min(axis=0), atol=1e-9)
        np.testing.assert_allclose(high, dense.max(axis=0), atol=1e-9)


def test_optik_plan_dt_sets_the_trajectory_sampling(tmp_path: Path) -> None:
    from optik.cli import main

    args = ["plan", "planar_2r", "--line", "1.5", "-0.5", "0", "1.5", "0.5", "0", "--step", "0.1"]
    limits = ["--velocity-limits", "1", "--acceleration-limits", "2"]
    out = tmp_path / "dt"
    assert main([*args, "--trajectory", *limits, "--dt", "0.05", "--out", str(out)]) == 0
    t = np.loadtxt(out / "trajectory.csv", delimiter=",", skiprows=1)[:, 1]
    np.testing.assert_allclose(np.diff(t)[:-1], 0.05, atol=1e-9)  # the last: to the end
    assert 0.0 < t[-1] - t[-2] <= 0.05 + 1e-9
    # --dt samples a trajectory: without --trajectory it is an error, before planning
    assert main([*args, "--dt", "0.05", "--out", str(tmp_path / "no")]) == 2
    assert not (tmp_path / "no").exists()
