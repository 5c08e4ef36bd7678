"""PathPlan.to_trajectory on hostile input: near-duplicate waypoints, huge sample counts."""

from __future__ import annotations

import csv
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from conftest import plan_from_q
from scipy.optimize import minimize_scalar
from scipy.spatial.transform import Rotation, Slerp

import optik.trajectory
from optik.errors import OptikError, OutputFileError
from optik.model import Robot
from optik.paths import line
from optik.planning import plan_path
from optik.problems import load_problem
from optik.spatial import rot_z
from optik.trajectory import MAX_TRAJECTORY_SAMPLES, MERGE_TOLERANCE, Trajectory

QA = np.array([0.3, 0.5, -1.0, 0.4, 0.6, 0.2])
QB = QA + 0.3  # every joint moves 0.3 rad
REL = 1e-6
# A curved Puma path (rad) found by a hostile-input search ...
DISTINCT = np.array(
    [
        [
            0.12694799857,
            -0.30325637818,
            -0.25650728797,
            -0.00599424467,
            0.02222002795,
            -0.0209664846,
        ],
        [0.21312141779, -0.32101987508, -0.22965730103, 0.05893574170, 0.10955595781, 0.0369849745],
        [0.29531262023, -0.34276558876, -0.20678953087, 0.11988351128, 0.19290967088, 0.0909542168],
        [0.36983375565, -0.37218136945, -0.19159182772, 0.17316121385, 0.26859331695, 0.1372533921],
        [0.43356394728, -0.41238809395, -0.18718506838, 0.21564797262, 0.33348601921, 0.1727616237],
        [0.48417998782, -0.46570896952, -0.19589246011, 0.24502058031, 0.38526457039, 0.1951557041],
        [0.52032807164, -0.53349780182, -0.21906780857, 0.25992523127, 0.42257516484, 0.2030818278],
        [0.54172386838, -0.61603892120, -0.25699544411, 0.26007759516, 0.44513347222, 0.1962556644],
        [0.54917354078, -0.71252616492, -0.30886920398, 0.24628383471, 0.45374565526, 0.1754833767],
        [0.54451415290, -0.78539816340, -0.37285202413, 0.22038101398, 0.45024877802, 0.1426020287],
        [0.53047787384, -0.78539816340, -0.44621173548, 0.18510130206, 0.43737500959, 0.1003437895],
        [0.51049001503, -0.78539816340, -0.52552302656, 0.14387001040, 0.41854966142, 0.0521339706],
    ]
)
# ... whose IK repeated waypoints 3, 4 and 5 about 2e-11 rad off the path (these offsets).
OFFSETS = np.array(
    [
        [1.255e-11, -6.195e-12, 1.851e-12, 8.719e-12, 1.276e-11, 7.460e-12],
        [1.037e-11, -8.378e-12, -3.317e-13, 6.536e-12, 1.058e-11, 5.278e-12],
        [7.849e-12, -1.090e-11, -2.850e-12, 4.018e-12, 8.059e-12, 2.759e-12],
    ]
)
CURVED = np.insert(DISTINCT, [4, 5, 6], DISTINCT[3:6] + OFFSETS, axis=0)
DUPLICATES = [4, 6, 8]  # rows of CURVED that repeat the row before them


@pytest.fixture(scope="module")
def puma() -> Robot:
    return load_problem("puma560").robot


def _line(*extra: float) -> np.ndarray:
    """Five waypoints from QA to QB, plus waypoints at the given fractions of the way."""
    s = np.sort(np.concatenate([np.linspace(0.0, 1.0, 5), extra]))
    return QA + s[:, None] * (QB - QA)


def _within_limits(trajectory: Trajectory, vlim: float, alim: float) -> None:
    """Exact samples at 2,000 times of each segment keep both limits."""
    for k, seg in enumerate(trajectory.segments):
        _, qd, qdd = trajectory.at(k, np.linspace(0.0, seg.duration, 2000))
        assert np.all(np.isfinite(qd)) and np.all(np.isfinite(qdd))
        assert np.max(np.abs(qd)) <= vlim * (1 + REL)
        assert np.max(np.abs(qdd)) <= alim * (1 + REL)


def _chord_length(Q: np.ndarray) -> float:
    return float(np.sum(np.linalg.norm(np.diff(Q, axis=0), axis=1)))


# ----------------------------------------------------------------------- near duplicates
def test_a_near_duplicate_waypoint_leaves_a_straight_line_time_optimal(puma: Robot) -> None:
    # Every joint moves 0.3 rad at once from rest to rest, so with limits of 1 the
    # optimum is the triangular profile 2 sqrt(0.3 / 1) s. It took 115 s with the
    # duplicate.
    optimum = 2.0 * math.sqrt(0.3)
    plan = plan_from_q(puma, _line(0.5 + 3e-11))
    trajectory = plan.to_trajectory(1.0, 1.0, robot=puma)
    assert trajectory.duration == pytest.approx(optimum, rel=1e-5)
    _within_limits(trajectory, 1.0, 1.0)


def test_near_duplicates_on_a_curved_path_give_a_trajectory_through_every_waypoint(
    puma: Robot,
) -> None:
    plan = plan_from_q(puma, CURVED)
    trajectory = plan.to_trajectory(1.0, 1.0, robot=puma)  # a bare ValueError before
    _within_limits(trajectory, 1.0, 1.0)
    # The same path without the near duplicates takes the same time.
    alone = plan_from_q(puma, DISTINCT).to_trajectory(1.0, 1.0, robot=puma)
    assert trajectory.duration == pytest.approx(alone.duration, rel=1e-6)
    # Each waypoint is held at its stated time to within the documented merge distance.
    (segment,) = trajectory.segments
    assert np.all(np.diff(segment.waypoint_times) >= 0.0)
    q_way, _, _ = trajectory.at(0, segment.waypoint_times)
    tol = MERGE_TOLERANCE * _chord_length(CURVED)
    assert np.max(np.linalg.norm(q_way - CURVED, axis=1)) <= tol
    # A merged waypoint is passed when the one it duplicates is.
    times = segment.waypoint_times
    np.testing.assert_array_equal(times[DUPLICATES], times[np.subtract(DUPLICATES, 1)])
    np.testing.assert_allclose(np.delete(q_way, DUPLICATES, axis=0), DISTINCT, atol=1e-9)


def test_a_merged_waypoint_counts_in_the_measured_departure(puma: Robot) -> None:
    # Two waypoints 3e-13 rad apart are one point: the segment holds at the first, and
    # the tool's move to the second is the departure recorded.
    Q = np.array([QA, QA + 3e-13])
    trajectory = plan_from_q(puma, Q).to_trajectory(1.0, 1.0, robot=puma)
    (segment,) = trajectory.segments
    assert segment.interpolation == "hold"
    T = puma.fk(Q)
    moved = float(np.linalg.norm(T[1, :3, 3] - T[0, :3, 3]))
    assert moved > 0.0
    assert segment.position_deviation == pytest.approx(moved, rel=1e-3, abs=0.0)


def test_close_waypoints_with_fast_limits_are_timed_exactly(puma: Robot) -> None:
    # Waypoints 7e-6 rad apart (not merged), solved by IK, under limits of 1e3: TOPP-RA's
    # absolute tolerances reported "no parameterisation; check the limits". The optimum
    # is 2 sqrt(0.3 / 1e3) s, as above.
    plan = plan_path(puma, puma.fk(_line(0.5 + 1e-5)), max_joint_step=0.5, q_start=QA)
    assert all(status == "ok" for status in plan.status)
    trajectory = plan.to_trajectory(1e3, 1e3, robot=puma)
    assert trajectory.duration == pytest.approx(2.0 * math.sqrt(0.3 / 1e3), rel=1e-5)
    _within_limits(trajectory, 1e3, 1e3)


def test_a_short_knot_interval_is_not_split_as_finely_as_a_long_one(puma: Robot) -> None:
    trajectory = plan_from_q(puma, np.array([QA, QA + 1e-4, QB])).to_trajectory(1.0, 1.0)
    ss = trajectory._timings[0].ss
    length = _chord_length(np.array([QA, QA + 1e-4, QB]))
    # At least 200 intervals (the default grid), none longer than an even share.
    assert 200 <= len(ss) - 1 <= 202
    assert np.max(np.diff(ss)) <= length / 200 * (1 + 1e-9)


def test_a_zero_speed_inside_the_path_raises(puma: Robot, monkeypatch: pytest.MonkeyPatch) -> None:
    real = optik.trajectory._toppra_speed

    def stalled(*args: object) -> np.ndarray:
        sd = real(*args)  # type: ignore[arg-type]
        sd[len(sd) // 2 : len(sd) // 2 + 2] = 0.0
        return sd

    monkeypatch.setattr(optik.trajectory, "_toppra_speed", stalled)
    with pytest.raises(OptikError, match="not finite"):
        plan_from_q(puma, _line()).to_trajectory(1.0, 1.0)


# ----------------------------------------------------------------------- sample count
@pytest.mark.parametrize(
    ("limit", "dt"),
    [(1e-6, 0.01), (1.0, 1e-10)],  # 303,000 s every 10 ms; 1.1 s every 0.1 ns
)
def test_more_than_the_sample_cap_raises_before_allocating(
    puma: Robot, limit: float, dt: float
) -> None:
    plan = plan_from_q(puma, _line())
    with pytest.raises(OptikError, match="MAX_TRAJECTORY_SAMPLES") as info:
        plan.to_trajectory(limit, limit, dt=dt)
    assert "dt" in str(info.value) and f"{MAX_TRAJECTORY_SAMPLES:,}" in str(info.value)


# ------------------------------------------------- departures measured by the task
def _turning_line() -> tuple[Robot, np.ndarray, np.ndarray]:
    """A Puma line whose tool turns 0.35 rad about its z axis per waypoint (a search's)."""
    robot = load_problem("puma560").robot
    q = np.array([0.2, 0.8, -0.6, 0.3, 0.7, 0.1])
    T0 = robot.fk(q)
    T1 = T0.copy()
    T1[:3, 3] += [0.0, 0.1, -0.05]
    path = line(T0, T1, 0.01)
    for k, P in enumerate(path):
        P[:3, :3] = P[:3, :3] @ rot_z(0.35 * k)
    return robot, path, q


def _rotation_departure(robot: Robot, trajectory: Any, path: np.ndarray, axis: int | None) -> float:
    """Largest angle of the tool (or its tool axis) from the path's geodesic, measured densely.

    41 times per interval; per time the least angle over the interval's slerp by a grid
    and a bounded scalar search (scipy), independent of optik's measure.
    """
    segment = trajectory.segments[0]
    worst = 0.0
    for i in range(segment.first, segment.last):
        t0, t1 = segment.waypoint_times[i], segment.waypoint_times[i + 1]
        q, _, _ = trajectory.at(0, np.linspace(t0, t1, 43)[1:-1])
        slerp = Slerp([0.0, 1.0], Rotation.from_matrix(path[[i, i + 1], :3, :3]))
        grid = np.linspace(0.0, 1.0, 101)
        frames = slerp(grid).as_matrix()  # (101, 3, 3): the path's rotation on the grid
        for T in robot.fk(q):

            def angle(u: float, T: np.ndarray = T, slerp: Slerp = slerp) -> float:
                R = slerp(u).as_matrix()
                if axis is None:
                    return float(Rotation.from_matrix(R.T @ T[:3, :3]).magnitude())
                c = np.clip(R[:, axis] @ T[:3, axis], -1.0, 1.0)
                return float(np.arccos(c))

            if axis is None:
                on_grid = Rotation.from_matrix(frames.transpose(0, 2, 1) @ T[:3, :3]).magnitude()
            else:
                on_grid = np.arccos(np.clip(frames[:, :, axis] @ T[:3, axis], -1.0, 1.0))
            u = grid[int(np.argmin(on_grid))]
            found = minimize_scalar(
                angle, bounds=(max(0.0, u - 0.01), min(1.0, u + 0.01)), method="bounded",
                options={"xatol": 1e-12},
            )  # fmt: skip
            worst = max(worst, float(found.fun))
    return worst


@pytest.mark.parametrize("mode", ["orientation", "axis"])
def test_departures_measure_what_the_task_constrains(mode: str) -> None:
    # Orientation plans had their free position measured (0.376 m, and path_tolerance
    # refused a good plan for it) and their rotation not at all (0 rad); axis plans
    # reported 0 rad for a tool axis 4.3e-5 rad off the path's.
    robot, path, q = _turning_line()
    plan = plan_path(robot, path, mode=mode, max_joint_step=0.3, q_start=q)
    assert plan.status == ["ok"] * len(path)
    trajectory = plan.to_trajectory(1.0, 2.0, robot=robot)
    segment = trajectory.segments[0]
    dense = _rotation_departure(robot, trajectory, path, 2 if mode == "axis" else None)
    # The peak between samples is sought: at least the dense measure (8 samples alone read
    # 98.7 % of it), and near it (the dense grid's own shortfall)
    assert dense - 1e-12 <= segment.orientation_deviation <= 1.001 * dense
    if mode == "orientation":
        assert segment.position_deviation == 0.0
    else:
        assert segment.position_deviation > 0.0
    largest = max(segment.position_deviation, segment.orientation_deviation)
    plan.to_trajectory(1.0, 2.0, robot=robot, path_tolerance=1.01 * largest)
    with pytest.raises(OptikError, match="path_tolerance"):
        plan.to_trajectory(1.0, 2.0, robot=robot, path_tolerance=0.99 * largest)


def _puma_turning_line() -> tuple[Robot, np.ndarray, np.ndarray]:
    """The Puma 560 along 7.1 cm that turns its tool 0.37 rad, every 2 cm: robot, path, q0."""
    robot = load_problem("puma560").robot
    q0 = np.array([0.3, 0.6, -0.4, 0.5, 0.7, -0.3])
    T0 = robot.fk(q0)
    T1 = T0.copy()
    T1[:3, 3] += [0.05, -0.04, 0.03]
    T1[:3, :3] = T1[:3, :3] @ Rotation.from_rotvec([0.2, -0.3, 0.1]).as_matrix()
    return robot, line(T0, T1, 0.02), q0


def _position_departure(trajectory: Any, robot: Robot, path: np.ndarray, per: int) -> float:
    """Largest distance of the tool from each interval's straight segment, at ``per``
    times per interval (an independent dense measure of a pose plan's departure)."""
    segment = trajectory.segments[0]
    worst = 0.0
    for i in range(segment.first, segment.last):
        t0, t1 = segment.waypoint_times[i], segment.waypoint_times[i + 1]
        q, _, _ = trajectory.at(0, np.linspace(t0, t1, per))
        p = robot.fk(q)[:, :3, 3]
        a, b = path[i, :3, 3], path[i + 1, :3, 3]
        lam = np.clip((p - a) @ (b - a) / ((b - a) @ (b - a)), 0.0, 1.0)
        worst = max(worst, float(np.max(np.linalg.norm(p - a - lam[:, None] * (b - a), axis=1))))
    return worst


def test_the_position_departure_is_the_peak_between_samples() -> None:
    """The tool's largest distance from the path: its 8 samples per interval read below
    the peak (path_tolerance could pass a trajectory beyond it); the peak is sought."""
    robot, path, q0 = _puma_turning_line()
    plan = plan_path(robot, path, max_joint_step=0.3, q_start=q0)
    assert plan.status == ["ok"] * len(path)
    trajectory = plan.to_trajectory(1.0, 2.0, robot=robot)
    dense = _position_departure(trajectory, robot, path, 401)
    assert dense > 1e-5
    measured = trajectory.segments[0].position_deviation
    assert dense - 1e-12 <= measured <= (1.0 + 1e-4) * dense


def test_joint_names_with_commas_keep_the_csv_columns(tmp_path: Path) -> None:
    robot = Robot.from_dh(
        [
            {"name": "sh,oulder", "a": 1.0, "alpha": 0.0, "d": 0.0},
            {"name": 'el"bow', "a": 1.0, "alpha": 0.0, "d": 0.0},
        ],
        limits=[[-3.0, 3.0], [-3.0, 3.0]],
    )
    plan = plan_path(robot, np.array([[1.5, -0.2, 0.0], [1.5, 0.2, 0.0]]), max_joint_step=0.5)
    trajectory = plan.to_trajectory(1.0, 2.0, robot=robot)
    for saved in (plan.save(tmp_path / "plan.csv"), trajectory.save(tmp_path / "t.csv")):
        rows = list(csv.reader(saved.read_text().splitlines()))
        assert {len(row) for row in rows} == {len(rows[0])}
        assert "sh,oulder" in rows[0] and 'el"bow' in rows[0]


def test_a_free_position_axis_does_not_count_in_the_departure() -> None:
    # With weights [1, 1, 0, ...] the waypoints' answers lie up to 7 cm along their free
    # axis; the departure was measured from the path's nearest point in 3-D, then that
    # axis dropped: 1.06e-2 m reported for 3.2e-4 m (a hostile search's case).
    robot, path, q0 = _puma_turning_line()
    plan = plan_path(robot, path, max_joint_step=0.3, q_start=q0, weights=[1, 1, 0, 1, 1, 1])
    trajectory = plan.to_trajectory(1.0, 2.0, robot=robot)
    segment = trajectory.segments[0]

    def slerp(A: np.ndarray, B: np.ndarray, u: float) -> np.ndarray:
        turn = Rotation.from_matrix(A[:3, :3].T @ B[:3, :3]).as_rotvec()
        return A[:3, :3] @ Rotation.from_rotvec(u * turn).as_matrix()

    dense = 0.0  # the largest x-y distance (in the path's frame) to the path, 80 samples
    grid = np.linspace(0.0, 1.0, 401)
    for i in range(segment.first, segment.last):
        A, B = plan.poses[i], plan.poses[i + 1]
        # The path's frame and point at each grid value, for every sample of the segment.
        turn = Rotation.from_matrix(A[:3, :3].T @ B[:3, :3]).as_rotvec()
        frames = A[:3, :3] @ Rotation.from_rotvec(grid[:, None] * turn).as_matrix()
        points = A[:3, 3] + grid[:, None] * (B[:3, 3] - A[:3, 3])
        t = np.linspace(segment.waypoint_times[i], segment.waypoint_times[i + 1], 80)
        for q in trajectory.at(0, t)[0]:
            p = robot.fk(q)[:3, 3]

            def off(u: float, A: np.ndarray = A, B: np.ndarray = B, p: np.ndarray = p) -> float:
                d = p - A[:3, 3] - u * (B[:3, 3] - A[:3, 3])
                return float(np.linalg.norm((slerp(A, B, u).T @ d)[:2]))

            local = np.einsum("uji,uj->ui", frames, p - points)[:, :2]
            j = int(np.argmin(np.linalg.norm(local, axis=1)))
            found = minimize_scalar(off, bounds=(grid[max(j - 1, 0)], grid[min(j + 1, 400)]),
                                    method="bounded")  # fmt: skip
            dense = max(dense, min(float(found.fun), off(grid[j])))
    # At least the dense measure (the 8 samples alone read 3.19 for 3.24), and near it:
    # the nearest point along the constrained axes comes from a fixed point that leaves out
    # the path frame's turn, whose distance is never below the least (0.12 % above here)
    assert dense - 1e-12 <= segment.position_deviation <= 1.005 * dense
    plan.to_trajectory(1.0, 2.0, robot=robot, path_tolerance=1.5 * dense)


def test_a_motion_below_a_nanoradian_holds_still(puma: Robot) -> None:
    # TOPP-RA finds no parameterisation of a motion of 1e-11 to 1e-10 rad in all: the plan
    # was refused with "check the limits" (and 30 lines of toppra's warnings).
    direction = np.array([1.0, 0.5, -0.3, 0.2, 0.7, 1.0])
    Q = QA + np.array([0.0, 1e-10, 2e-10])[:, None] * direction
    trajectory = plan_from_q(puma, Q).to_trajectory(1.0, 2.0)
    (segment,) = trajectory.segments
    assert segment.interpolation == "hold" and trajectory.duration == 0.0
    assert np.max(np.abs(trajectory.q[:, None, :] - Q[None])) <= 1e-9


def test_a_grid_beyond_its_cap_is_refused(puma: Robot) -> None:
    # A million intervals (the old cap) took a minute on a ten-waypoint plan.
    plan = plan_from_q(puma, np.stack([QA, QB]))
    with pytest.raises(OptikError, match=r"grid.*20000|grid.*20,000"):
        plan.to_trajectory(1.0, 2.0, grid=optik.trajectory.MAX_GRID + 1)


def test_a_plan_that_is_not_a_plan_is_an_error() -> None:
    with pytest.raises(OptikError, match=r"plan: expected an optik\.PathPlan .* got list"):
        optik.trajectory.plan_trajectory([1, 2, 3], 1.0, 2.0)  # type: ignore[arg-type]


@pytest.mark.parametrize("path", [None, b"plan.csv", 3])
def test_writing_to_a_value_that_is_no_path_is_an_error(
    puma: Robot, tmp_path: Path, path: Any
) -> None:
    # pathlib's TypeError escaped before the path was checked.
    plan = plan_from_q(puma, np.stack([QA, QB]))
    trajectory = plan.to_trajectory(1.0, 2.0)
    for write in (plan.save, trajectory.save, plan.plot):
        with pytest.raises(OutputFileError, match=r"expected a path|not bytes"):
            write(path)


def test_a_file_name_too_long_for_the_system_is_an_error_naming_it(
    puma: Robot, tmp_path: Path
) -> None:
    # The folder check (is_dir) raised a raw OSError (ENAMETOOLONG).
    plan = plan_from_q(puma, np.stack([QA, QB]))
    target = tmp_path / ("a" * 300 + ".csv")
    with pytest.raises(OutputFileError, match="a" * 300):
        plan.save(target)
    assert list(tmp_path.iterdir()) == []


def test_toppra_retries_print_nothing_and_leave_its_logger_as_it_was(
    puma: Robot, capfd: pytest.CaptureFixture[str]
) -> None:
    """A segment 1e-8 rad long: TOPP-RA's retry warnings filled stderr (198 lines), and
    each call added one more console handler to toppra's logger."""
    import logging

    import toppra  # its import adds its own (null) handler

    from optik.planning import plan_path

    logger = logging.getLogger(toppra.__name__)
    handlers, level = list(logger.handlers), logger.level
    q = np.array([-0.333, 3.713, -1.5713, 0.1582, 0.4196, 4.597])
    plan = plan_path(puma, np.array([puma.fk(q), puma.fk(q + 1e-8)]), q_start=q)
    for _ in range(2):
        trajectory = plan.to_trajectory(1.0, 1.0, robot=puma)
        assert trajectory.duration > 0.0
    assert capfd.readouterr().err == ""
    assert logger.handlers == handlers and logger.level == level


def test_an_infinite_joint_value_in_a_plan_is_an_error(puma: Robot) -> None:
    """NaN marks an unsolved waypoint; an infinity (a hand-edited plan) merged every
    waypoint into the first: a 0 s "hold" trajectory, without a word."""
    from optik.paths import line
    from optik.planning import plan_path

    q = np.array([-0.333, 3.713, -1.5713, 0.1582, 0.4196, 4.597])
    target = puma.fk(np.array([-0.7299, 3.927, -1.5419, 1.3596, 0.5327, 4.2171]))
    plan = plan_path(puma, line(puma.fk(q), target, 0.01), max_joint_step=0.2, q_start=q)
    plan.q[5, 2] = np.inf
    with pytest.raises(OptikError, match=r"plan: q\[5, 2\] is inf"):
        plan.to_trajectory(1.0, 1.0)
    plan.q[5, 2] = np.nan  # unsolved: the trajectory splits there
    segments = plan.to_trajectory(1.0, 1.0).segments
    assert [(s.first, s.last) for s in segments] == [(0, 4), (6, len(plan.q) - 1)]


def test_the_departure_is_the_same_whatever_the_block_of_intervals(
    puma: Robot, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The intervals are measured a block at a time (one at a time took 47 s on 20,000
    waypoints): blocks of 3 intervals or one block give the same departures."""
    import optik.path_departure as departure
    from optik.paths import line
    from optik.planning import plan_path

    q = np.array([-0.333, 3.713, -1.5713, 0.1582, 0.4196, 4.597])
    T0 = puma.fk(q)
    T1 = T0.copy()
    T1[:3, 3] += [0.05, 0.05, -0.05]
    for mode, weights in (("pose", None), ("pose", [1, 0, 1, 1, 1, 1]), ("axis", None)):
        plan = plan_path(puma, line(T0, T1, 0.004), mode=mode, weights=weights, q_start=q)
        whole = plan.to_trajectory(1.0, 2.0, robot=puma).segments
        monkeypatch.setattr(departure, "_INTERVALS_AT_ONCE", 3)
        blocks = plan.to_trajectory(1.0, 2.0, robot=puma).segments
        monkeypatch.undo()
        assert len(whole) == len(blocks) == 1 and whole[0].position_deviation > 0.0
        assert whole[0].position_deviation == blocks[0].position_deviation
        assert whole[0].orientation_deviation == blocks[0].orientation_deviation
