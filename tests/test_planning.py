"""plan_path and reachability: continuity, flags, verification, files."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from conftest import out_of_reach_and_back

from optik import DHJoint, Robot, solve_ik, solve_ik_batch
from optik.errors import OptikError, ShapeError
from optik.paths import PathFileError, arc, circle, line, read_path
from optik.planning import PLAN_STATUSES, plan_path
from optik.problems import load_problem
from optik.reachability import reachability
from optik.spatial import pose_error, transform

# A Puma 560 line (found by search) on which the nearest-branch choice jumps.
PUMA_Q0 = np.array([-0.333, 3.713, -1.5713, 0.1582, 0.4196, 4.597])
PUMA_Q1 = np.array([-0.7299, 3.927, -1.5419, 1.3596, 0.5327, 4.2171])


def _verify_plan(robot, plan, tol=1e-6) -> None:  # type: ignore[no-untyped-def]
    assert len(plan.status) == len(plan.poses) == len(plan.q)
    assert all(s in PLAN_STATUSES for s in plan.status)
    for k in np.flatnonzero(plan.solved):
        position, orientation = pose_error(robot.fk(plan.q[k]), plan.poses[k])
        assert position <= tol
        if plan.mode == "pose":
            assert orientation <= tol
        assert np.all(plan.q[k] >= robot.lower - 1e-12) and np.all(plan.q[k] <= robot.upper + 1e-12)


def test_plan_avoids_the_branch_jump_of_the_greedy_choice() -> None:
    robot = load_problem("puma560").robot
    poses = line(robot.fk(PUMA_Q0), robot.fk(PUMA_Q1), 0.01)
    greedy = plan_path(robot, poses, max_joint_step=0.2, greedy=True, q_start=PUMA_Q0)
    plan = plan_path(robot, poses, max_joint_step=0.2, q_start=PUMA_Q0)
    _verify_plan(robot, plan)
    _verify_plan(robot, greedy)
    assert plan.largest_step <= 0.2 < greedy.largest_step
    assert "discontinuity" in greedy.status and "discontinuity" not in plan.status
    assert greedy.largest_step / plan.largest_step > 3.0  # measured: 0.67 vs 0.116 rad
    assert plan.summary()["solved"] == len(poses)


def test_a_step_that_must_be_flagged_is_no_licence_to_switch_branch() -> None:
    """A UR5 joint path with one 0.25 rad step on joint 1, near the limits: that step
    must be flagged whatever the choice, and the plan took it as a 3.13 rad switch into
    the comfort box (the margin it saved outweighed the motion)."""
    robot = load_problem("ur5").robot
    q0 = np.array([-5.1923, 0.6836, 0.7168, -5.3733, 4.464, 5.4107])
    dq = np.array([-0.01126, -0.03115, -0.03667, 0.02772, 0.00072, 0.01396])
    Q = q0 + np.arange(20)[:, None] * dq
    Q[10:, 0] += 0.25
    assert np.all((robot.lower <= Q) & (robot.upper >= Q))  # the source path is a choice
    plan = plan_path(robot, robot.fk(Q), max_joint_step=0.2, q_start=Q[0])
    assert plan.summary()["discontinuity"] == 1 and plan.status[10] == "discontinuity"
    steps = np.max(np.abs(np.diff(plan.q, axis=0)), axis=1)
    assert steps[9] <= 0.25 + 1e-6  # the source's own step (0.239 rad), not a switch
    assert np.all(np.delete(steps, 9) <= 0.2)


def test_unreachable_stretch_is_flagged_and_nothing_is_dropped() -> None:
    robot = load_problem("puma560").robot
    poses = out_of_reach_and_back(robot)
    plan = plan_path(robot, poses, max_joint_step=0.3)
    _verify_plan(robot, plan)
    assert len(plan.status) == len(poses)
    unreachable = np.array([s == "unreachable" for s in plan.status])
    assert unreachable.any() and plan.solved.any()
    assert np.all(unreachable == ~plan.solved)
    distance = np.linalg.norm(poses[:, :3, 3], axis=1)
    assert np.all(distance[unreachable] > distance[~unreachable].max() - 1e-9)


def test_outside_default_limits_is_flagged_not_solved() -> None:
    """The boom swings +-135 deg (arm default, 270 deg range): 170 deg is out of reach.

    With the full pose the spherical arm has one branch, so nothing else can stand in.
    """
    robot = load_problem("jumbo_spherical_arm").robot
    angles = np.radians(np.linspace(120.0, 170.0, 11))
    q = np.stack([angles, np.full(11, 0.4), np.full(11, 4.0)], axis=1)
    poses = robot.fk(q)
    plan = plan_path(robot, poses, max_joint_step=0.2)
    _verify_plan(robot, plan)
    beyond = q[:, 0] > math.radians(135.0) + 1e-9
    assert all(plan.status[k] == "outside_limits" for k in np.flatnonzero(beyond))
    assert all(plan.status[k] in ("ok", "near_singular") for k in np.flatnonzero(~beyond))


def test_numeric_robot_plan_and_margin(rng: np.random.Generator) -> None:
    robot = load_problem("panda").robot
    q0 = robot.mid_limits
    T0 = robot.fk(q0)
    T1 = T0.copy()
    T1[:3, 3] += [0.1, 0.15, -0.1]
    poses = line(T0, T1, 0.01)
    plan = plan_path(robot, poses, max_joint_step=0.1, limit_margin=0.05, q_start=q0)
    _verify_plan(robot, plan)
    assert all(s == "ok" for s in plan.status)
    assert np.nanmin(plan.limit_margin) >= 0.05 - 1e-9
    assert plan.largest_step <= 0.1


def test_plan_files_round_trip(tmp_path) -> None:  # type: ignore[no-untyped-def]
    robot = load_problem("ur5").robot
    q = np.array([0.3, -1.2, 1.4, -0.4, 1.2, 0.2])
    T0 = robot.fk(q)
    T1 = T0 @ transform(None, [0.05, 0.1, 0.0])
    plan = plan_path(robot, line(T0, T1, 0.02), q_start=q)
    plan.save(tmp_path / "plan.npz")
    plan.save(tmp_path / "plan.csv")
    plan.save(tmp_path / "plan.json")
    with np.load(tmp_path / "plan.npz") as data:
        assert np.array_equal(data["q"], plan.q)
        assert list(data["status"]) == plan.status
    rows = (tmp_path / "plan.csv").read_text().strip().splitlines()
    assert len(rows) == len(plan.status) + 1 and rows[0].startswith("index,status")
    loaded = json.loads((tmp_path / "plan.json").read_text())
    assert loaded["summary"]["waypoints"] == len(plan.status)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["plan.csv", "plan.json", "plan.npz"]
    with pytest.raises(OptikError, match="unknown plan format"):
        plan.save(tmp_path / "plan.xlsx")


def test_path_primitives_and_files(tmp_path) -> None:  # type: ignore[no-untyped-def]
    T0 = transform(None, [1.0, 0.0, 0.5])
    T1 = transform(None, [0.0, 1.0, 0.5])
    poses = arc(T0, T1, [0.0, 0.0, 0.5], 0.01)
    radii = np.linalg.norm(poses[:, :3, 3] - [0.0, 0.0, 0.5], axis=1)
    assert np.allclose(radii, 1.0, atol=1e-12) and len(poses) == math.ceil(math.pi / 2 / 0.01) + 1
    full = circle(T0, [0.0, 0.0, 0.5], [0.0, 0.0, 1.0], 0.05)
    assert np.allclose(full[0, :3, 3], full[-1, :3, 3], atol=1e-12)
    straight = line(T0, T1, 0.1)
    steps = np.linalg.norm(np.diff(straight[:, :3, 3], axis=0), axis=1)
    assert np.all(steps <= 0.1 + 1e-12) and np.allclose(steps, steps[0])
    (tmp_path / "p.csv").write_text("x,y,z\n0.1,0.2,0.3\n0.2,0.2,0.3\n")
    read, mode = read_path(tmp_path / "p.csv")
    assert mode == "position" and read.shape == (2, 4, 4) and read[1, 0, 3] == 0.2
    (tmp_path / "bad.csv").write_text("x,y,z\n0.1,0.2\n")
    with pytest.raises(PathFileError, match="line 2"):
        read_path(tmp_path / "bad.csv")
    (tmp_path / "p.toml").write_text('length_unit = "mm"\npositions = [[100, 0, 0]]\n')
    assert read_path(tmp_path / "p.toml")[0][0, 0, 3] == pytest.approx(0.1)
    np.savez(tmp_path / "p.npz", poses=straight)
    assert read_path(tmp_path / "p.npz")[1] == "pose"
    with pytest.raises(PathFileError, match="not found"):
        read_path(tmp_path / "missing.csv")


def test_reachability_batch(rng: np.random.Generator) -> None:
    robot = load_problem("panda").robot
    inside = robot.fk(rng.uniform(robot.lower, robot.upper, (200, 7)))[:, :3, 3]
    far = rng.normal(size=(50, 3))
    far = 3.0 * far / np.linalg.norm(far, axis=1, keepdims=True)
    result = reachability(robot, np.vstack([inside, far]))
    assert result.reachable[:200].mean() >= 0.99
    assert not result.reachable[200:].any() and result.proven_unreachable[200:].all()
    for k in np.flatnonzero(result.reachable):
        assert np.linalg.norm(robot.fk(result.q[k])[:3, 3] - result.points[k]) <= 1e-6


def test_bad_plan_input() -> None:
    robot = load_problem("puma560").robot
    with pytest.raises(ShapeError):
        plan_path(robot, np.zeros((3, 2)))
    with pytest.raises(OptikError, match="max_joint_step"):
        plan_path(robot, np.zeros((3, 3)), max_joint_step=0.0)
    with pytest.raises(OptikError, match="limit_margin"):
        plan_path(robot, np.zeros((3, 3)), limit_margin=10.0)
    with pytest.raises(ShapeError):
        reachability(robot, np.zeros(3))


def test_plots_render(tmp_path) -> None:  # type: ignore[no-untyped-def]
    robot = load_problem("puma560").robot
    poses = line(robot.fk(PUMA_Q0), robot.fk(PUMA_Q1), 0.02)
    plan = plan_path(robot, poses, max_joint_step=0.2)
    out = plan.plot(tmp_path / "plan.png", robot)
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and out.stat().st_size > 20_000
    result = reachability(robot, np.array([[0.5, 0.1, 0.6], [0.3, -0.2, 0.9], [5.0, 0.0, 0.0]]))
    out = result.plot_slice(tmp_path / "slice.png", "z")
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    with pytest.raises(OptikError, match="axis"):
        result.plot_slice(tmp_path / "bad.png", "w")
    # written whole or not at all, with the reason as an OptikError (not matplotlib's)
    (tmp_path / "folder.png").mkdir()
    (tmp_path / "afile").write_text("")
    for bad, reason in (
        ("slice.xyz", "cannot write 'xyz' images"),
        ("folder.png", "it is a folder"),
        ("afile/slice.png", "is a file, not a folder"),
    ):
        with pytest.raises(OptikError, match=reason):
            result.plot_slice(tmp_path / bad)
    assert not (tmp_path / "slice.xyz").exists()


@pytest.mark.parametrize(
    "name", ["panda", "puma560", "ur5", "stanford_arm", "jumbo_drill_6dof", "dobot_magician"]
)
def test_reach_sphere_contains_every_tool_position(name: str, rng: np.random.Generator) -> None:
    robot = load_problem(name).robot
    center, radius = robot.reach_sphere
    lower = np.where(np.isfinite(robot.lower), robot.lower, -math.pi)
    upper = np.where(np.isfinite(robot.upper), robot.upper, math.pi)
    Q = rng.uniform(lower, upper, (5000, robot.dof))
    Q[:50] = np.where(rng.random((50, robot.dof)) < 0.5, lower, upper)  # corners of the box
    distance = np.linalg.norm(robot.fk(Q)[:, :3, 3] - center, axis=1)
    assert distance.max() <= radius + 1e-12
    assert distance.max() >= 0.75 * radius  # tight enough to prune, not a vacuous bound


def test_a_stretched_arms_own_position_is_never_proven_unreachable() -> None:
    """The tool position of a stretched planar arm lies 8.9e-16 m beyond its reach
    sphere's radius (the rounding of its FK); reachability, plan_path and solve_ik
    proved it unreachable (each compared the distance with the bare radius). Every
    proof by the sphere now allows for FK rounding (``REACH_SLACK``); a point 1e-6 of
    the radius beyond is still proven unreachable by each of them."""
    links = [0.8682033505476444, 0.7457427954593243, 0.6217322753706368]
    robot = Robot.from_dh([DHJoint(a=a, alpha=0.0, role="arm") for a in links])
    q = np.array([-1.7567159551060498, 0.0, 0.0])
    p = robot.fk(q)[:3, 3]
    centre, radius = robot.reach_sphere
    assert np.linalg.norm(p - centre) > radius  # the rounding this is about
    beyond = centre + (p - centre) * (1 + 1e-6)
    for point, proven in ((p, False), (beyond, True)):
        assert bool(reachability(robot, point[None]).proven_unreachable[0]) is proven
        assert (plan_path(robot, point[None], tol=1e-12).status[0] == "unreachable") is proven
        single = solve_ik(robot, point, mode="position", tol=1e-16)
        assert (single.status == "unreachable") is proven
        batch = solve_ik_batch(robot, point[None], mode="position", tol=1e-16)
        assert (batch.status[0] == "unreachable") is proven
    assert solve_ik(robot, p, mode="position").success


def test_unproven_failure_is_not_found_not_unreachable() -> None:
    # A point inside the Panda's reach sphere that the arm cannot reach: no proof exists
    # (no closed form, the sphere contains it), so the flag is not_found.
    panda = load_problem("panda").robot
    start = panda.fk(panda.mid_limits + 0.2)
    beyond = start.copy()
    beyond[:3, 3] = [0.0, 0.0, 1.33]
    centre, radius = panda.reach_sphere
    assert np.linalg.norm(beyond[:3, 3] - centre) < radius
    plan = plan_path(panda, np.stack([start, beyond]), max_joint_step=3.0)
    assert plan.status[0] == "ok"
    assert plan.status[1] == "not_found"


@pytest.mark.parametrize(
    ("q", "mode"),
    [
        ([-1.5, 0.0, math.pi / 2, -1.5], "pose"),  # the flange on the base axis
        ([-1.5707963, 0.0, 1.5707963, -1.5707963], "pose"),  # next to it
        ([-1.5707963, 0.0, 1.5707963, -1.5707963], "position"),
    ],
)
def test_a_closed_forms_missed_branch_is_found_not_called_outside_limits(
    q: list[float], mode: str
) -> None:
    """The DOBOT's closed form holds J1 at its reference when the flange is over the base
    axis (J4 then out of its limits) and rounds by 3e-7 beside it (J2 below 0): no branch
    inside the limits, and plan_path reported ``outside_limits``, a proof, for poses of
    in-limit configurations. The numeric search now follows, as in solve_ik."""
    robot = load_problem("dobot_magician").robot
    q_source = np.array(q)
    assert robot.within_limits(q_source)
    T = robot.fk(q_source)
    plan = plan_path(robot, T[None] if mode == "pose" else T[None, :3, 3], mode=mode)
    assert plan.status[0] in ("ok", "near_singular")
    reached = robot.fk(plan.q[0])
    assert np.linalg.norm(reached[:3, 3] - T[:3, 3]) < 1e-6
    assert robot.within_limits(plan.q[0])


def test_an_axis_waypoint_with_joints_on_their_limits_is_planned() -> None:
    """A Puma configuration with joints 2-6 on a limit: the steered numeric searches
    failed on its axis task and the waypoint was called ``outside_limits`` although
    solve_ik answers it inside the limits; planning now ends with solve_ik's own policy."""
    robot = load_problem("puma560").robot
    q = np.array([2.792526803190927, -0.7853981633974483, -3.9269908169872414,
                  -1.9198621771937625, -1.7453292519943295, -4.642575810304916])  # fmt: skip
    assert robot.within_limits(q)
    T = robot.fk(q)
    plan = plan_path(robot, T[None], mode="axis")
    assert plan.status[0] == "ok"
    reached = robot.fk(plan.q[0])
    assert np.linalg.norm(reached[:3, 3] - T[:3, 3]) < 1e-6
    assert float(reached[:3, 2] @ T[:3, 2]) > 1 - 1e-9
    assert robot.within_limits(plan.q[0])


def test_a_path_with_every_joint_frozen() -> None:
    """Every joint frozen at the waypoint's configuration: solved, manipulability 0
    (before: an IndexError from the singular values of a Jacobian with no column)."""
    robot = load_problem("puma560").robot
    q = robot.mid_limits + 0.2
    frozen = dict(zip(robot.joint_names, q.tolist(), strict=True))
    plan = plan_path(robot, robot.fk(q)[None], frozen=frozen)
    assert plan.status == ["ok"]
    np.testing.assert_array_equal(plan.q[0], q)
    assert plan.manipulability[0] == 0.0


def test_a_start_outside_the_limits_is_refused_and_an_empty_plan_is_not_drawn(
    tmp_path: Path,
) -> None:
    robot = load_problem("puma560").robot
    empty = plan_path(robot, np.zeros((0, 4, 4)))  # an empty batch plans to nothing
    with pytest.raises(OptikError, match="no waypoint to draw"):
        empty.plot(tmp_path / "empty.png", robot)
    assert not (tmp_path / "empty.png").exists()
    T = robot.fk(robot.mid_limits)[None]
    with pytest.raises(OptikError, match="outside its limits"):
        plan_path(robot, T, q_start=robot.upper + 1.0)
    # A hair outside (a measured configuration) is clipped onto the limits.
    plan = plan_path(robot, robot.fk(robot.upper - 0.1)[None], q_start=robot.upper + 1e-9)
    assert plan.status[0] != "not_found" and robot.within_limits(plan.q[0])


def test_the_plan_starts_at_q_start_and_a_needed_jump_is_flagged_on_the_path() -> None:
    """The move from ``q_start`` is a step like the others (a hostile search's find).

    Waypoint 0 is ``fk(q_now)`` and the path crosses the wrist's singular range, where
    the branch must switch. The plan had started on another branch 1.25 rad from
    ``q_now``, status ``ok``, 0 flagged: the jump hidden before waypoint 0. Now it starts
    at ``q_now`` and the jump is flagged where it happens.
    """
    robot = load_problem("puma560").robot
    q_now = np.array([0.3, 0.6, -0.9, 0.4, 0.3, 0.2])
    q_end = np.array([0.5, 0.6, -0.9, 0.4, -0.3, 0.2])
    poses = line(robot.fk(q_now), robot.fk(q_end), 0.005)
    plan = plan_path(robot, poses, max_joint_step=0.1, q_start=q_now)
    _verify_plan(robot, plan)
    assert np.max(np.abs(plan.q[0] - q_now)) < 1e-9
    assert plan.status[0] == "ok" and plan.step[0] < 1e-9
    assert plan.status.count("discontinuity") == 1  # the switch, on the path
    greedy = plan_path(robot, poses, max_joint_step=0.1, q_start=q_now, greedy=True)
    assert greedy.status.count("discontinuity") >= 1  # measured 3: a switch is needed


def test_a_start_far_from_every_branch_flags_the_first_waypoint() -> None:
    """A planar 2R: the first branch nearest ``q_start`` is taken, and the move is flagged."""
    robot = load_problem("planar_2r").robot
    path = line(robot.fk(np.array([-2.31, 1.1668])), robot.fk(np.array([-2.0, 1.2])), 0.02)
    near = plan_path(robot, path[:, :3, 3], max_joint_step=0.2, q_start=[-2.31, 1.166])
    assert np.max(np.abs(near.q[0] - [-2.31, 1.1668])) < 1e-3  # not the other elbow
    assert "discontinuity" not in near.status
    start = np.array([1.0, 1.0])  # 2 rad and more from both branches of waypoint 0
    far = plan_path(robot, path[:, :3, 3], max_joint_step=0.2, q_start=start)
    _verify_plan(robot, far)
    assert far.step[0] == np.max(np.abs(far.q[0] - start)) > 0.2
    assert far.status[0] == "discontinuity" and far.status[1:] == ["ok"] * (len(path) - 1)


def test_a_start_away_from_a_frozen_value_is_the_first_step() -> None:
    """``q_start`` off a frozen joint's value: refused as the solves' seed before (naming
    neither ``q_start`` nor ``frozen``); now the move to that value is the first step."""
    robot = load_problem("puma560").robot
    q_now = np.array([0.3, 0.5, -0.5, 0.2, 0.4, 0.1])
    held = q_now.copy()
    held[2] = -0.2
    poses = robot.fk(held + np.outer(np.linspace(0.0, 0.05, 6), [1, 0, 0, 0, 0, 0]))
    plan = plan_path(robot, poses, q_start=q_now, frozen={"j3": -0.2}, max_joint_step=0.2)
    _verify_plan(robot, plan)
    assert plan.solved.all() and np.all(plan.q[:, 2] == -0.2)
    assert plan.step[0] == pytest.approx(np.max(np.abs(plan.q[0] - q_now)), abs=0.0)
    assert plan.step[0] >= 0.3 and plan.status[0] == "discontinuity"
    assert plan.status[1:] == ["ok"] * (len(poses) - 1)


@pytest.mark.parametrize(
    ("name", "q_mid"),
    [("ur5", [0.5, -1.2, 1.0, 0.4, 0.0, 0.3]), ("puma560", [0.3, 0.5, -1.0, 2.0, 0.0, 0.7])],
)
def test_a_path_through_an_aligned_wrist_is_not_broken_at_it(name: str, q_mid: list) -> None:
    # A joint-space line through q5 = 0, 0.005 rad a waypoint: its poses have a continuous
    # answer in the limits. At q5 = 0 the closed form holds the wrist's free turn at its
    # reference; from mid-limits no branch continued the path there, and a discontinuity
    # (a proof, for a robot with a closed form) was flagged where none is.
    robot = load_problem(name).robot
    direction = np.array([0.2, -0.1, 0.15, 0.3, 0.5, -0.25])
    Q = np.array(q_mid) + np.linspace(-0.1, 0.1, 21)[:, None] * direction
    assert robot.within_limits(Q).all()
    assert np.linalg.svd(robot.jacobian(Q[10]), compute_uv=False)[-1] < 1e-12
    plan = plan_path(robot, robot.fk(Q), max_joint_step=0.1, q_start=Q[0])
    assert "discontinuity" not in plan.status
    assert plan.largest_step <= 0.1
    _verify_plan(robot, plan)


def test_a_loose_tol_met_near_a_waypoint_is_no_proof() -> None:
    """The closed form has no branch for this pose, but an in-limit configuration meets it
    within tol=0.05 (0.047 m and 0.047 rad): not found, never proved unreachable (it was).
    At the default tol the proof stands."""
    ur5 = load_problem("ur5").robot
    T = np.array([
        [1.0, 0.0, 0.0, 0.04735666780866799],
        [0.0, 6.123233995736766e-17, -1.0, -0.11685300269685252],
        [0.0, 1.0, 6.123233995736766e-17, 0.15456189556764965],
        [0.0, 0.0, 0.0, 1.0],
    ])  # fmt: skip
    witness = np.array([
        0.9763633989588054, -2.7463191729295335, -3.526929632454513,
        -0.009936249924747918, 1.0236542315196513, 2.0316352141017653e-06,
    ])  # fmt: skip
    F = ur5.fk(witness)
    assert ur5.within_limits(witness) and np.linalg.norm(F[:3, 3] - T[:3, 3]) < 0.05
    assert np.arccos(np.clip((np.trace(F[:3, :3].T @ T[:3, :3]) - 1.0) / 2.0, -1.0, 1.0)) < 0.05
    assert plan_path(ur5, T[None], tol=0.05).status[0] in ("not_found", "ok")
    assert plan_path(ur5, T[None]).status[0] == "unreachable"
