"""What ``plan_path`` reports, held where a plausible slip would change it.

Each test pins a reported field or a rule a mutation audit found unchecked: the
near-singular flag, the hard ``limit_margin`` at upper limits, the reported margins, the
step after an unsolved waypoint, the choice's switch count (the largest single-joint
step, as flagged) and the tool's departure past a waypoint.
"""

from __future__ import annotations

import numpy as np

import optik
from optik.analytic import wrap_into_limits
from optik.path_departure import segment_departure
from optik.paths import line
from optik.plan_choice import SWITCH_PENALTY, Comfort, choose, step_cost
from optik.problems import load_problem

PUMA = load_problem("puma560").robot


def test_a_path_through_a_wrist_singularity_is_flagged_near_singular() -> None:
    q = np.array([0.3, -0.5, 0.4, 0.2, 0.0, 0.1])  # q5 = 0: axes 4 and 6 aligned
    path = PUMA.fk(np.linspace(q, q + np.array([0.05, 0.0, 0.0, 0.0, 0.0, 0.0]), 4))
    plan = optik.plan_path(PUMA, path, q_start=q)
    assert plan.status == ["near_singular"] * 4
    bent = q + np.array([0.0, 0.0, 0.0, 0.0, 0.8, 0.0])  # the wrist bent: far from it
    away = optik.plan_path(PUMA, PUMA.fk(np.linspace(bent, bent + 0.02, 4)), q_start=bent)
    assert away.status == ["ok"] * 4


def test_the_reported_margin_is_the_distance_to_the_nearer_limit() -> None:
    q = np.array([0.3, -0.5, 0.4, 0.2, 0.8, 0.1])
    q[0] = PUMA.upper[0] - 0.3
    plan = optik.plan_path(PUMA, PUMA.fk(np.linspace(q, q + 0.02, 3)), q_start=q)
    expected = np.minimum(plan.q - PUMA.lower, PUMA.upper - plan.q)
    np.testing.assert_allclose(plan.limit_margin, expected, atol=1e-12)


def test_the_hard_margin_holds_at_an_upper_limit() -> None:
    q = np.array([0.3, -0.5, 0.4, 0.2, 0.8, 0.1])
    q[0] = PUMA.upper[0] - 0.05  # the path starts inside the margin of j1's upper limit
    path = PUMA.fk(np.linspace(q, q + np.array([-0.02, 0.0, 0.0, 0.0, 0.0, 0.0]), 3))
    plan = optik.plan_path(PUMA, path, q_start=q, limit_margin=0.2)
    solved = ~np.isnan(plan.q).any(axis=1)
    assert solved.any()
    assert np.all(plan.q[solved, 0] <= PUMA.upper[0] - 0.2 + 1e-12)
    assert plan.limit_margin[solved].min() >= 0.2 - 1e-12


def test_a_waypoint_inside_the_limits_but_not_the_margin_is_outside_limits() -> None:
    # A closed form's arm boxed to 0.3 rad around a configuration whose first joint is
    # 0.05 rad from its upper limit: with a 0.2 rad margin no branch is inside the
    # margin, one is inside the limits. plan_path said not_found (its proof step found
    # that answer and took it for a near miss) where it documents outside_limits.
    q = np.array([0.3, -0.5, 0.4, 0.2, 0.8, 0.1])
    boxed = PUMA.with_limits(q - 0.3, q + 0.3)
    q[0] = boxed.upper[0] - 0.05
    path = boxed.fk(np.linspace(q, q + np.array([0.02, 0.0, 0.0, 0.0, 0.0, 0.0]), 3))
    assert optik.plan_path(boxed, path).status == ["ok"] * 3
    plan = optik.plan_path(boxed, path, limit_margin=0.2)
    assert plan.status == ["outside_limits"] * 3
    assert np.isnan(plan.q).all()


def test_the_step_after_an_unsolved_waypoint_is_not_measured_across_it() -> None:
    q = np.array([0.3, -0.5, 0.4, 0.2, 0.8, 0.1])
    jump = np.array([1.0, 0.5, 0.0, 0.0, 0.0, 0.0])
    T = PUMA.fk(np.array([q, q, q + jump, q + jump]))
    T[1, :3, 3] = [50.0, 0.0, 0.0]  # beyond reach, between two stretches far apart
    for greedy in (False, True):
        plan = optik.plan_path(PUMA, T, greedy=greedy)
        assert plan.status == ["ok", "unreachable", "ok", "ok"], plan.status
        assert np.isnan(plan.step[2])  # the first waypoint of a stretch has no step


def test_greedy_choice_starts_afresh_after_an_empty_layer() -> None:
    # After a waypoint without candidates a new stretch begins: the greedy choice takes
    # its first candidate, as at the path's start, not the one nearest the configuration
    # before the gap (the step across the gap is not measured either).
    a, first, near_a = np.zeros(2), np.array([5.0, 5.0]), np.array([0.1, 0.0])
    box = Comfort(np.full(2, -10.0), np.full(2, 10.0))
    chosen = choose([[a], [], [first, near_a]], 0.1, True, None, box)
    assert list(chosen) == [0, -1, 0]


def test_a_switch_is_a_single_joint_step_beyond_the_bound() -> None:
    # What plan_path flags as a discontinuity: the largest single-joint step, not the norm.
    assert float(step_cost(np.full(6, 0.09), 0.1)) < 1.0
    assert float(step_cost(np.array([0.11, 0, 0, 0, 0, 0]), 0.1)) >= SWITCH_PENALTY


def test_a_tool_that_overshoots_a_waypoint_departs_from_the_path() -> None:
    # A joint path that runs three times as far as the waypoints: the tool passes B along
    # the segment's line and beyond; past B it departs from the path (which ends at B).
    qa = np.array([0.3, -0.5, 0.4, 0.2, 0.8, 0.1])
    qb = qa + np.array([0.01, 0.0, 0.0, 0.0, 0.0, 0.0])
    plan = optik.plan_path(PUMA, PUMA.fk(np.stack([qa, qb])), q_start=qa)
    path = lambda s: qa + 3.0 * np.asarray(s)[:, None] * (qb - qa)  # noqa: E731
    position, _ = segment_departure(PUMA, plan, 0, path, np.array([0.0, 1.0]))
    A, B = plan.poses[0, :3, 3], plan.poses[1, :3, 3]
    length = float(np.linalg.norm(B - A))
    # Reference: the distance of dense tool samples to the segment (an upper bound of the
    # samples' departure), and of the last eighth's samples (past B by about 1.6 |AB|).
    dense = PUMA.fk(path(np.linspace(0.0, 1.0, 401)))[:, :3, 3]
    lam = np.clip((dense - A) @ (B - A) / length**2, 0.0, 1.0)
    distance = np.linalg.norm(dense - (A + lam[:, None] * (B - A)), axis=1)
    assert position <= distance.max() + 1e-12
    assert position >= 1.2 * length


def test_a_tool_that_bulges_between_waypoints_departs_from_the_path() -> None:
    # A joint path through both waypoints that swings the shoulder out and back between
    # them (a full sine): its largest departure is inside the segment, not at its ends.
    qa = np.array([0.3, -0.5, 0.4, 0.2, 0.8, 0.1])
    qb = qa + np.array([0.01, 0.0, 0.0, 0.0, 0.0, 0.0])
    swing = np.array([0.0, 0.1, 0.0, 0.0, 0.0, 0.0])
    plan = optik.plan_path(PUMA, PUMA.fk(np.stack([qa, qb])), q_start=qa)

    def path(s: np.ndarray) -> np.ndarray:
        s = np.asarray(s)[:, None]
        return qa + s * (qb - qa) + np.sin(2.0 * np.pi * s) * swing

    position, _ = segment_departure(PUMA, plan, 0, path, np.array([0.0, 1.0]))
    A, B = plan.poses[0, :3, 3], plan.poses[1, :3, 3]
    dense = PUMA.fk(path(np.linspace(0.0, 1.0, 401)))[:, :3, 3]
    lam = np.clip((dense - A) @ (B - A) / float((B - A) @ (B - A)), 0.0, 1.0)
    distance = np.linalg.norm(dense - (A + lam[:, None] * (B - A)), axis=1)
    assert distance.max() > 0.03  # the swing moves the tool by centimetres
    # The peak is sought between the 8 samples: at least the dense samples' largest (the
    # 8 alone read below it), and near it.
    assert distance.max() - 1e-12 <= position <= (1.0 + 1e-4) * distance.max()


def test_a_numeric_arm_s_waypoints_get_fresh_candidates_by_default() -> None:
    # Without a closed form, each waypoint's candidates are the continuation of the
    # previous ones and fresh restarts (2 by default): more than one where they differ.
    panda = load_problem("panda").robot
    q = panda.mid_limits + 0.2
    path = panda.fk(np.linspace(q, q + 0.1, 5))
    plan = optik.plan_path(panda, path, q_start=q)
    assert plan.status == ["ok"] * 5
    assert plan.candidates.max() > 1
    assert optik.plan_path(panda, path, q_start=q, restarts=0).candidates.max() == 1


def test_a_jump_takes_the_representative_nearest_the_previous_waypoint() -> None:
    # Joint 6 of the Puma spans more than a turn. Where no branch continues the path, the
    # branches came wrapped nearest mid-limits: the plan jumped 6.27 rad (joint 6 a turn
    # away) where the same branch lies 0.21 rad from the previous waypoint.
    puma = load_problem("puma560").robot
    q_now = np.array([-0.333, 3.713, -1.5713, 0.1582, 0.4196, 4.597])
    q_far = np.array([-0.7299, 3.927, -1.5419, 1.3596, 0.5327, 4.2171])
    path = line(puma.fk(q_now), puma.fk(q_far), 0.05)
    branches = np.array(optik.analytic_ik(puma, path[1]))
    turned = wrap_into_limits(branches, puma, q_now[None])
    nearest = float(np.abs(turned - q_now).max(axis=1).min())  # 0.21 rad
    greedy = optik.plan_path(puma, path[:2], q_start=q_now, max_joint_step=0.1, greedy=True)
    assert greedy.status[1] == "discontinuity"
    assert abs(greedy.step[1] - nearest) <= 1e-9, (greedy.step, nearest)
    for plan in (greedy, optik.plan_path(puma, path, q_start=q_now, max_joint_step=0.1)):
        assert plan.largest_step < 1.0, plan.step
