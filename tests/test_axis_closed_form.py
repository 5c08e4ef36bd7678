"""The tool-axis task solved by the closed forms over the free roll (optik.analytic.roll).

Targets are reachable by construction: the FK pose of a random in-limit configuration,
turned by a random roll about its tool z axis. Every answer is re-verified here from
forward kinematics: the tool point's distance to the target point and the angle between
the tool z axis and the target's.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pytest
from conftest import general_arm

import optik
from optik.analytic import family_of
from optik.analytic.roll import axis_branches, grid_branches, rolled_poses
from optik.errors import AnalyticIKError
from optik.spatial import rot_x, rot_y, rot_z

ROBOTS = ("puma560", "ur5")
TARGETS = 25
EXACT = 1e-9  # the closed form's own check (VERIFY_TOLERANCE)


def _robot(name: str) -> optik.Robot:
    return optik.load_problem(name).robot


def _targets(robot: optik.Robot, seed: int, count: int = TARGETS):
    """(target, the configuration it came from, a q0 near it) triples."""
    rng = np.random.default_rng(seed)
    for _ in range(count):
        q = rng.uniform(robot.lower, robot.upper)
        T = robot.fk(q)
        T[:3, :3] = T[:3, :3] @ rot_z(rng.uniform(-math.pi, math.pi))
        q0 = np.clip(q + rng.normal(0.0, 0.5, robot.dof), robot.lower, robot.upper)
        yield T, q, q0


def _axis_errors(robot: optik.Robot, q: np.ndarray, T: np.ndarray, k: int = 2):
    """(position error m, angle between tool axis k and the target's, rad) from FK."""
    F = robot.fk(q)
    a, b = F[:3, k], T[:3, k]
    angle = math.atan2(float(np.linalg.norm(np.cross(a, b))), float(a @ b))
    return float(np.linalg.norm(F[:3, 3] - T[:3, 3])), angle


def _gap_to_exact(robot: optik.Robot, q: np.ndarray, T: np.ndarray) -> float:
    """Distance from ``q`` to the nearest full-pose branch of the target turned to
    ``q``'s own roll about z (the tool axis)."""
    R_rel = T[:3, :3].T @ robot.fk(q)[:3, :3]
    rolled = T.copy()
    rolled[:3, :3] = T[:3, :3] @ rot_z(math.atan2(R_rel[1, 0], R_rel[0, 0]))
    exact = optik.analytic_ik(robot, rolled, q_ref=q, within_limits=False)
    return float(np.linalg.norm(exact[0] - q))


def _in_limits(robot: optik.Robot, q: np.ndarray) -> bool:
    return bool(np.all(q >= robot.lower - 1e-12) and np.all(q <= robot.upper + 1e-12))


@pytest.mark.parametrize("axis", [0, 1, 2])
def test_rolled_poses_turn_about_the_target_axis(axis: int) -> None:
    T = _robot("puma560").fk(np.array([0.3, 0.2, -0.4, 0.5, 0.6, 0.7]))
    rolls = np.array([-2.0, 0.0, 0.7, 3.0])
    turn = (rot_x, rot_y, rot_z)[axis]
    for pose, theta in zip(rolled_poses(T, axis, rolls), rolls, strict=True):
        np.testing.assert_allclose(pose[:3, :3], T[:3, :3] @ turn(theta), atol=1e-15)
        np.testing.assert_array_equal(pose[:3, 3], T[:3, 3])
        np.testing.assert_allclose(pose[:3, axis], T[:3, axis], atol=1e-15)


@pytest.mark.parametrize("name", ROBOTS)
def test_every_branch_is_exact_in_limits_and_as_near_as_the_source(name: str) -> None:
    robot = _robot(name)
    for T, q_true, q0 in _targets(robot, seed=1):
        (found,) = axis_branches(robot, T, 2, q0[None])
        assert found.nearest, "a reachable target has branches on the grid"
        for q in [*found.nearest, *found.samples]:
            position, angle = _axis_errors(robot, q, T)
            assert position <= EXACT and angle <= EXACT
            assert _in_limits(robot, q)
        distances = [float(np.linalg.norm(q - q0)) for q in found.nearest]
        assert distances == sorted(distances)
        # The configuration the pose came from, or one at least as near q0.
        assert distances[0] <= float(np.linalg.norm(q_true - q0)) + 1e-9


def test_other_tool_axes() -> None:
    robot = _robot("puma560")
    rng = np.random.default_rng(3)
    for k, turn in ((0, rot_x), (1, rot_y)):
        for _ in range(5):
            q = rng.uniform(robot.lower, robot.upper)
            T = robot.fk(q)
            T[:3, :3] = T[:3, :3] @ turn(rng.uniform(-math.pi, math.pi))
            res = optik.solve_ik(robot, T, mode="axis", axis="xyz"[k], q0=q)
            assert res.success and res.solver == "analytic"
            position, angle = _axis_errors(robot, res.q, T, k)
            assert position <= EXACT and angle <= EXACT
            assert float(np.linalg.norm(res.q - q)) <= 1e-6  # q itself is an answer


@pytest.mark.parametrize("name", ROBOTS)
def test_solve_ik_axis_answers_with_the_closed_form(name: str) -> None:
    robot = _robot(name)
    farther = 0
    for T, _, q0 in _targets(robot, seed=2):
        res = optik.solve_ik(robot, T, mode="axis", q0=q0)
        assert res.success and res.status == "converged"
        assert res.solver == "analytic" and res.backend_converged is None
        position, angle = _axis_errors(robot, res.q, T)
        assert position <= EXACT and angle <= EXACT and _in_limits(robot, res.q)
        nearest = optik.solve_ik(robot, T, mode="axis", q0=q0, select="nearest")
        np.testing.assert_array_equal(nearest.q, res.q)
        dls = optik.solve_ik(robot, T, mode="axis", q0=q0, solver="dls", warm_start="q0")
        assert dls.success
        d_closed = float(np.linalg.norm(res.q - q0))
        d_dls = float(np.linalg.norm(dls.q - q0))
        # dls's answer is exact only to tol = 1e-6 in the task: near a wrist singularity
        # its q lies up to ~1e-3 rad off the exact answers, and can be that much nearer q0
        # than any of them. The gap: to the exact branch nearest it at its own roll.
        assert d_closed <= d_dls + _gap_to_exact(robot, dls.q, T) + 1e-9
        farther += d_closed > d_dls + 1e-9
    assert farther <= 3  # of TARGETS; each within dls's own gap


@pytest.mark.parametrize("name", ROBOTS)
def test_solve_ik_all_over_the_roll(name: str) -> None:
    robot = _robot(name)
    for T, _, q0 in list(_targets(robot, seed=4))[:8]:
        answers = optik.solve_ik_all(robot, T, mode="axis", q0=q0, k=6, min_separation=0.3)
        assert len(answers) == 6
        for res in answers:
            position, angle = _axis_errors(robot, res.q, T)
            assert res.success and position <= EXACT and angle <= EXACT
            assert _in_limits(robot, res.q)
        Q = np.array([res.q for res in answers])
        pairwise = np.linalg.norm(Q[:, None] - Q[None], axis=2)
        assert np.all(pairwise[~np.eye(len(Q), dtype=bool)] >= 0.3)
        distances = np.linalg.norm(Q - q0, axis=1)
        assert np.all(np.diff(distances) >= 0.0)
        first = optik.solve_ik(robot, T, mode="axis", q0=q0)
        np.testing.assert_allclose(answers[0].q, first.q, atol=1e-12)


def test_no_branch_on_the_grid_is_no_proof() -> None:
    """A frozen joint narrows the box to a plane the grid never hits: dls searches it."""
    robot = _robot("ur5")
    q = np.array([0.4, -1.2, 1.3, -0.6, 1.1, 0.3])
    T = robot.fk(q)
    T[:3, :3] = T[:3, :3] @ rot_z(0.8)
    res = optik.solve_ik(robot, T, mode="axis", frozen={robot.joint_names[0]: 0.4}, q0=q)
    assert res.success and res.solver == "dls"
    assert res.q[0] == 0.4
    position, angle = _axis_errors(robot, res.q, T)
    assert position <= 1e-6 and angle <= 1e-6


def test_unsolved_axis_target_is_not_called_unreachable_from_the_grid() -> None:
    # On the Puma's base axis, inside its reach sphere: the wrist centre cannot get there
    # (the shoulder offset), so neither the grid nor dls finds an answer, and nothing
    # proves it: the status is dls's, not "unreachable".
    robot = _robot("puma560")
    T = np.eye(4)
    T[:3, 3] = robot.T_world_base[:3, 3] + [0.0, 0.0, 0.3]
    (found,) = axis_branches(robot, T, 2, robot.mid_limits[None])
    assert not found.nearest
    res = optik.solve_ik(robot, T, mode="axis", restarts=3)
    assert not res.success and res.status != "unreachable"
    assert res.solver == "dls"


def test_an_axis_task_beyond_the_reach_sphere_is_proved_unreachable() -> None:
    robot = _robot("ur5")
    T = np.eye(4)
    T[:3, 3] = [5.0, 0.0, 0.0]
    res = optik.solve_ik(robot, T, mode="axis")
    assert res.status == "unreachable" and res.solver == "reach"


def test_drilling_path_on_the_ur5_is_continuous_with_the_closed_form(monkeypatch) -> None:
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "examples"))
    import drilling_pattern

    import optik.planning

    calls = []
    original = optik.planning.axis_branches

    def counted(*args, **kwargs):
        calls.append(1)
        return original(*args, **kwargs)

    monkeypatch.setattr(optik.planning, "axis_branches", counted)
    robot = _robot("ur5")
    holes = drilling_pattern.drilling_pattern()
    plan = optik.plan_path(robot, holes, mode="axis", max_joint_step=0.3)
    assert calls, "the closed form gives the candidates"
    assert plan.status == ["ok"] * len(holes)
    steps = np.max(np.abs(np.diff(plan.q, axis=0)), axis=1)
    assert np.all(steps <= 0.3)
    for q, T in zip(plan.q, holes, strict=True):
        position, angle = _axis_errors(robot, q, T)
        assert position <= EXACT and angle <= EXACT and _in_limits(robot, q)


def _general_arm() -> optik.Robot:
    """A spherical wrist after a general arm (the quartic of ``spherical_axes``) with a
    turned, offset tool: the wrist centre moves with the roll, so some rolls are out of
    reach, and the branches' wrists pass singularities along the roll."""
    tool = np.eye(4)
    tool[:3, :3] = rot_z(0.4) @ rot_x(-0.7)
    tool[:3, 3] = (0.02, 0.03, 0.12)
    return general_arm(limit=3.2, tool=tool)


def test_a_general_arm_with_an_offset_tool_solves_the_axis_task() -> None:
    """Every answer exact and inside the limits; the source or one as near q0."""
    robot = _general_arm()
    assert family_of(robot).name == "spherical_axes"
    for T, q_true, q0 in _targets(robot, seed=6, count=8):
        (found,) = axis_branches(robot, T, 2, q0[None])
        assert found.nearest
        for q in [*found.nearest, *found.samples]:
            position, angle = _axis_errors(robot, q, T)
            assert position <= EXACT and angle <= EXACT and _in_limits(robot, q)
        distances = [float(np.linalg.norm(q - q0)) for q in found.nearest]
        assert distances == sorted(distances)
        assert distances[0] <= float(np.linalg.norm(q_true - q0)) + 1e-9


def test_the_roll_samples_skip_the_polish_the_batch_gives() -> None:
    """Rolls out of reach have no branch: the batch of ``analytic_ik_batch`` polishes
    each such pose (and finds none), the roll's own batch does not; on the others both
    give the same branches."""
    from optik.analytic import checked_batch

    robot = _general_arm()
    family = family_of(robot)
    T = robot.fk(np.array([0.3, -0.5, 0.8, 0.2, 1.1, -0.4]))
    poses = rolled_poses(T, 0, np.linspace(-math.pi, math.pi, 48, endpoint=False))
    public = optik.analytic_ik_batch(robot, poses, within_limits=False)
    fast = checked_batch(robot, family, poses, "pose", None, False, polish=False)
    assert 0 < int(np.sum(public.counts == 0)) < len(poses)  # some rolls out of reach
    np.testing.assert_array_equal(fast.counts, public.counts)
    np.testing.assert_array_equal(fast.q, public.q)


class _LineRoll:
    """A one-joint stand-in for the roll: the configuration is the roll itself."""

    def __init__(self, cost) -> None:
        self.cost_of, self.calls = cost, 0

    def branches(self, rolls: np.ndarray, refs: np.ndarray) -> np.ndarray:
        self.calls += 1
        return np.asarray(rolls, dtype=float)[:, None, None]

    def cost(self, Q: np.ndarray, refs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return Q, self.cost_of(Q[:, 0])


def _refined(cost, x0: float) -> tuple[float, float, int]:
    from optik.analytic.roll import ROLL_GRID, _refine

    h = 2 * math.pi / ROLL_GRID
    line = _LineRoll(cost)
    x = np.array([x0])
    qx, fx = _refine(line, np.zeros((1, 1)), x, x[:, None], cost(x), cost(x - h), cost(x + h), h)
    return float(qx[0, 0]), float(fx[0]), line.calls


@pytest.mark.parametrize(
    "cost",
    [
        lambda t: np.where(t < 0.3371, 5.0 + 10.0 * (0.3371 - t), 30.0),  # a jump
        lambda t: np.where(t > 0.3371, 5.0 + 3.0 * np.sqrt(np.abs(t - 0.3371)), 30.0),
    ],
    ids=["linear then a jump", "a square-root cusp then a jump"],
)
def test_the_roll_search_finds_a_minimum_at_a_jump(cost) -> None:
    """Where a branch's continuation ends (its wrist at a singularity) the distance falls
    steeply to a jump. Golden sections find the jump to the roll tolerance within the
    round limit (parabolas through the jump crept towards it and ran out of rounds,
    3.7e-7 rad short); a smooth minimum still takes a few parabolic steps."""
    from optik.analytic.roll import MAX_REFINE_ROUNDS, ROLL_TOLERANCE

    x, fx, calls = _refined(cost, 0.3 if cost(np.array([0.3]))[0] < 30 else 0.36)
    assert abs(x - 0.3371) <= ROLL_TOLERANCE and calls < MAX_REFINE_ROUNDS
    assert fx == float(cost(np.array([x]))[0]) and fx < 5.01
    x, fx, calls = _refined(lambda t: (t - 0.31) ** 2 + 0.1 * (t - 0.31) ** 4, 0.25)
    assert abs(x - 0.31) < 1e-7 and fx < 1e-14 and calls <= 10


def test_a_branch_born_between_two_grid_rolls_is_found() -> None:
    """Where the branch count changes between two grid rolls (a fold: a pair of branches
    is born or dies) the interval is sampled more finely, so a branch that lives on less
    than a grid step is searched too. On the general arm's second target of seed 6 the
    nearest answer lies on such a branch: without the fold's samples the answer was 0.878
    rad from q0 against the 0.808 of ``dls`` with ``select="nearest"`` (the reference
    here, independent of the roll); on these targets the closed form is never farther
    than that reference."""
    robot = _general_arm()
    for T, _, q0 in _targets(robot, seed=6, count=4):
        closed = optik.solve_ik(robot, T, mode="axis", q0=q0)
        reference = optik.solve_ik(
            robot, T, mode="axis", q0=q0, solver="dls", warm_start="q0", select="nearest"
        )
        assert closed.success and closed.solver == "analytic" and reference.success
        position, angle = _axis_errors(robot, closed.q, T)
        assert position <= EXACT and angle <= EXACT and _in_limits(robot, closed.q)
        assert np.linalg.norm(closed.q - q0) <= np.linalg.norm(reference.q - q0) + 1e-6


def test_the_roll_refuses_a_robot_without_a_pose_closed_form() -> None:
    """Called directly on the Panda (no closed form), the roll says why, not an assert."""
    panda = _robot("panda")
    T = panda.fk(panda.mid_limits)
    with pytest.raises(AnalyticIKError, match="'none'"):
        axis_branches(panda, T, 2, panda.mid_limits[None])
    with pytest.raises(AnalyticIKError, match="full poses"):
        grid_branches(panda, T, 2, panda.mid_limits)
