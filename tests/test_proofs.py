"""Sound proofs: no 'unreachable' or 'outside_limits' for the pose of an in-limit configuration.

Every closed-form family is swept over configurations with each joint pinned at the values
where closed forms degenerate (0, +-pi/2, +-pi and the limits, clipped into the limits):
wrists and elbows aligned or folded, shoulders over the base. ``solve_ik`` must solve the
pose of every such configuration (verified here from FK), whatever the closed form finds.
"""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

import optik
from optik.analytic import family_of
from optik.problems import builtin_problems, load_problem
from optik.spatial import pose_error

ANALYTIC = [p.stem for p in builtin_problems() if family_of(load_problem(p).robot) is not None]
PINS = (0.0, math.pi / 2, -math.pi / 2, math.pi, -math.pi)


def _pinned_configurations(robot: optik.Robot, rng: np.random.Generator) -> list[np.ndarray]:
    lower = np.where(np.isfinite(robot.lower), robot.lower, -math.pi)
    upper = np.where(np.isfinite(robot.upper), robot.upper, math.pi)
    configs = []
    for i, j in itertools.combinations_with_replacement(range(robot.dof), 2):
        values_i = [*PINS, robot.lower[i], robot.upper[i]]
        for vi in values_i:
            q = rng.uniform(lower, upper)
            q[i] = vi
            if j != i:
                q[j] = PINS[int(rng.integers(len(PINS)))]
            configs.append(np.clip(q, robot.lower, robot.upper))
    return configs


@pytest.mark.parametrize("name", ANALYTIC)
def test_no_false_proof_at_pinned_joints(name: str) -> None:
    robot = load_problem(name).robot
    rng = np.random.default_rng(2024)
    failures = []
    for q in _pinned_configurations(robot, rng):
        T = robot.fk(q)
        res = optik.solve_ik(robot, T)
        p, r = pose_error(robot.fk(res.q), T)
        ok = p <= 1e-6 and r <= 1e-6 and float(robot.limit_violation(res.q)) <= 1e-12
        if not ok or not res.success:
            failures.append((q.round(6).tolist(), res.status, res.message))
    assert not failures, (
        f"{len(failures)} poses of in-limit configurations unsolved: {failures[:3]}"
    )


def test_ur5_wrist_singularity_is_solved() -> None:
    ur5 = load_problem("ur5").robot
    T = ur5.fk(np.array([0.0, 0.0, 0.0, -1.0, 0.0, 1.0]))
    assert optik.analytic_ik(ur5, T)  # the free q6 of the reference (0) leaves no elbow
    res = optik.solve_ik(ur5, T)
    assert res.success and res.status == "converged" and res.solver == "analytic"


def test_ur5_closed_form_alone_answers_at_the_wrist_singularity() -> None:
    # q5 in {0, +-pi} leaves q6 free; the closed form takes it from the reference, or,
    # when the elbow cannot reach with that q6, the q6 that puts the elbow mid-range.
    ur5 = load_problem("ur5").robot
    rng = np.random.default_rng(21)
    for k in range(400):
        q = rng.uniform(ur5.lower, ur5.upper)
        q[4] = (0.0, math.pi, -math.pi)[k % 3]
        if k % 4 == 0:
            q[2] = 0.0  # elbow stretched as well
        T = ur5.fk(q)
        branches = optik.analytic_ik(ur5, T)
        assert branches, f"no branch for q = {q.tolist()}"
        for b in branches:
            p, o = pose_error(ur5.fk(b), T)
            assert p < 1e-9 and o < 1e-9 and ur5.within_limits(b)


def test_folded_planar_elbow_is_solved() -> None:
    robot = load_problem("planar_2r").robot
    for q1 in np.linspace(-2.0, 2.0, 9):
        q = np.clip(np.array([q1, math.pi]), robot.lower, robot.upper)
        res = optik.solve_ik(robot, robot.fk(q)[:3, 3], mode="position")
        assert res.success, (q, res.status)


def test_locked_joint_is_solved() -> None:
    puma = load_problem("puma560").robot
    q = puma.mid_limits + 0.3
    locked = puma.with_limits(
        np.where(np.arange(6) == 3, q, puma.lower), np.where(np.arange(6) == 3, q, puma.upper)
    )
    res = optik.solve_ik(locked, locked.fk(q))
    assert res.success and abs(res.q[3] - q[3]) <= 1e-12


def test_unreachable_is_still_proved() -> None:
    puma = load_problem("puma560").robot
    centre, radius = puma.reach_sphere
    far = puma.fk(puma.mid_limits)
    far[:3, 3] = centre + np.array([2.0 * radius, 0.0, 0.0])
    res = optik.solve_ik(puma, far)
    assert res.status == "unreachable" and not res.success


def test_numeric_robot_outside_reach_sphere_is_unreachable() -> None:
    panda = load_problem("panda").robot
    centre, radius = panda.reach_sphere
    T = panda.fk(panda.mid_limits)
    T[:3, 3] = centre + np.array([0.0, radius + 0.1, 0.0])
    res = optik.solve_ik(panda, T)
    assert res.status == "unreachable" and res.iterations == 0


@pytest.mark.parametrize(
    ("name", "box"),
    [
        ("ur5", {}),
        ("puma560", {}),
        ("ur5", {"limit_margin": 0.01}),
        ("ur5", {"frozen": {"shoulder_pan": 0.1}}),
        ("puma560", {"limit_margin": 0.01}),
        ("panda", {"frozen": {"panda_joint7": 0.3}, "limit_margin": 0.01}),
    ],
)
def test_beyond_the_reach_sphere_is_unreachable_without_a_search(name: str, box: dict) -> None:
    # A closed form's branch set proves nothing about a narrowed box, so the search ran
    # and said "max_iter"; the reach sphere holds the narrowed box too (as in the batch).
    # With the plain limits the closed form's proof was cross-checked by a dls run that
    # the sphere makes needless.
    robot = load_problem(name).robot
    centre, radius = robot.reach_sphere
    T = robot.fk(robot.mid_limits)
    T[:3, 3] = centre + np.array([0.0, 0.0, 3.0 * radius])
    res = optik.solve_ik(robot, T, **box)
    assert (res.status, res.solver, res.iterations) == ("unreachable", "reach", 0)
    assert "beyond its radius" in res.message
    batch = optik.solve_ik_batch(robot, T[None], **box)
    assert batch.status.tolist() == ["unreachable"]
    assert optik.solve_ik_all(robot, T, **box) == []


def test_position_mode_with_a_tool_offset_falls_back_to_numeric() -> None:
    base = load_problem("jumbo_spherical_arm").robot
    family = family_of(base)
    assert family is not None and "position" in family.modes
    # A tool offset along the last link: the closed form (flange position) does not apply.
    rows = base.dh
    assert rows is not None
    tool = np.eye(4)
    tool[2, 3] = 0.1
    tooled = optik.Robot.from_dh(rows, tool=tool, limits=np.stack([base.lower, base.upper], 1))
    q = tooled.mid_limits + 0.1
    res = optik.solve_ik(tooled, tooled.fk(q)[:3, 3], mode="position")
    assert res.success


def test_the_sweep_reaches_singular_configurations() -> None:
    # The sweep must include configurations where the closed forms degenerate (a joint
    # free or a root doubled: the Jacobian loses rank), or it proves nothing there.
    singular = {}
    for name in ANALYTIC:
        robot = load_problem(name).robot
        singular[name] = 0
        for q in _pinned_configurations(robot, np.random.default_rng(2024)):
            s = np.linalg.svd(robot.jacobian(q), compute_uv=False)
            singular[name] += int(s[min(robot.dof, 6) - 1] < 1e-9 * max(s[0], 1.0))
    # The six-joint arms' wrists align at these pins (q5 = 0).
    assert sum(singular.values()) > 0, singular


def test_closed_form_recovers_a_branch_next_to_a_fold() -> None:
    # q2 a hair from pi: the trig equation's tangent rule rounds q2 to pi, 1e-9 m off the
    # target; the polish recovers the branch, verified here from FK.
    robot = load_problem("planar_2r").robot
    q = np.array([0.3, math.pi - 1e-9])
    p = robot.fk(q)[:3, 3]
    branches = optik.analytic_ik(robot, p, "position")
    assert branches
    for b in branches:  # 1e-9 of the arm's 2 m reach radius
        assert np.linalg.norm(robot.fk(b)[:3, 3] - p) <= 1e-9 * robot.reach_sphere[1]
    batch = optik.analytic_ik_batch(robot, p[None], "position")
    assert batch.counts[0] == len(branches)


def test_the_cross_check_answers_where_the_closed_form_misses(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    # A closed form that finds no branch (as one can at a degenerate pose) for a target
    # that is reachable: the dls cross-check's answer, never a proof.
    puma = load_problem("puma560").robot
    q = puma.mid_limits + 0.2
    T = puma.fk(q)
    monkeypatch.setattr("optik.ik.analytic_ik", lambda *args, **kwargs: [])
    res = optik.solve_ik(puma, T)
    assert (res.success, res.status, res.solver) == (True, "converged", "dls")
    position, angle = pose_error(puma.fk(res.q), T)
    assert position <= 1e-6 and angle <= 1e-6 and puma.within_limits(res.q)
