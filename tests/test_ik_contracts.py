"""What ``solve_ik`` and ``solve_ik_all`` promise about their results, held at the edges.

Each test pins a promise a plausible slip would break (a mutation audit of the call
paths): every attempt of the budget runs, only verified answers are returned, a status
never contradicts ``success``, counts are the attempts spent, and no answer off the
query's box (frozen joints, ``limit_margin``) counts as a success.
"""

from __future__ import annotations

import numpy as np
import pytest

import optik
from optik.ik_result import verified_result, without_run
from optik.problems import load_problem
from optik.solvers import IKQuery
from optik.task import make_task

PANDA = load_problem("panda").robot
PUMA = load_problem("puma560").robot


def test_restarts_zero_runs_the_one_attempt() -> None:
    # With no closed form, restarts=0 is one attempt: it must run (not "no IK attempt").
    T = PANDA.fk(PANDA.mid_limits + 0.1)
    answers = optik.solve_ik_all(PANDA, T, restarts=0, q0=PANDA.mid_limits)
    assert len(answers) == 1 and answers[0].success and answers[0].restarts == 0
    nearest = optik.solve_ik(PANDA, T, restarts=0, select="nearest", q0=PANDA.mid_limits)
    assert nearest.success and nearest.restarts == 0


def test_the_last_attempt_of_the_budget_runs() -> None:
    # Only the last of restarts + 1 attempts can answer: a budget of one iteration each,
    # the first attempts from far starts. The answer reports the attempt that found it.
    T = PANDA.fk(PANDA.mid_limits + 0.1)
    for restarts in (1, 3):
        found = optik.solve_ik_all(
            PANDA, T, restarts=restarts, q0=PANDA.mid_limits + 0.1, max_iter=1
        )
        assert found and found[0].restarts == 0  # the start at q0 is the answer itself
    nearest = optik.solve_ik(PANDA, T, restarts=2, select="nearest", q0=PANDA.mid_limits + 0.1)
    assert nearest.success and nearest.restarts == 2  # "nearest" spends the whole budget


def test_solve_ik_all_returns_only_verified_answers() -> None:
    # A tolerance below the closed form's rounding: no branch verifies, none is returned.
    T = PUMA.fk(PUMA.mid_limits + 0.2)
    answers = optik.solve_ik_all(PUMA, T, tol=1e-17)
    assert all(r.success for r in answers)


def test_a_failed_verification_never_says_converged() -> None:
    T = PUMA.fk(PUMA.mid_limits + 0.2)
    result = optik.solve_ik(PUMA, T, tol=1e-17)
    assert result.success == (result.status == "converged")
    assert not result.success and result.status == "max_iter"


@pytest.mark.parametrize("joint", [0, 3, 5])
def test_a_frozen_value_no_branch_holds_is_never_a_success(joint: int) -> None:
    # No configuration reaches these poses with the joint at the frozen value (a six-joint
    # arm has no redundancy): the answer fails, or holds the value exactly.
    rng = np.random.default_rng(8)
    name = PUMA.joint_names[joint]
    for q in rng.uniform(0.8 * PUMA.lower, 0.8 * PUMA.upper, (12, 6)):
        value = float(q[joint] + 0.5)
        result = optik.solve_ik(PUMA, PUMA.fk(q), frozen={name: value}, restarts=5)
        assert not result.success or result.q[joint] == value
        assert result.status != "outside_limits"  # the branches prove nothing about a box


def test_a_frozen_joint_near_a_wrist_singularity_is_held_by_the_closed_form() -> None:
    # Near q5 = 0 the closed form recovers a frozen joint to about 1e-10 only: within the
    # match tolerance (1e-9) its branch is taken and the joint set exactly. (With q6 frozen
    # at the singularity the branch splits q4 + q6 at q4's reference, and the search
    # answers: 39 of these 60 are the closed form's, 21 with a 1e-12 match.)
    rng = np.random.default_rng(2)
    closed = 0
    for i in range(60):
        q = rng.uniform(0.9 * PUMA.lower, 0.9 * PUMA.upper)
        q[4] = 10.0 ** rng.uniform(-9, -4) * rng.choice([-1.0, 1.0])  # wrist nearly aligned
        j = (3, 5, 0)[i % 3]
        result = optik.solve_ik(PUMA, PUMA.fk(q), frozen={PUMA.joint_names[j]: float(q[j])})
        assert result.success and result.q[j] == q[j]
        closed += result.solver == "analytic"
    assert closed >= 35, closed


def test_an_answer_off_the_query_s_box_is_no_success() -> None:
    # Whatever produced it, a configuration that reaches the pose but not the frozen value
    # (or lies inside a limit margin) fails verification, with the reason.
    q = PUMA.mid_limits + 0.3
    T = PUMA.fk(q)
    name = PUMA.joint_names[5]
    for bounds in (
        (
            np.where(np.arange(6) == 5, q[5] + 0.2, PUMA.lower),
            np.where(np.arange(6) == 5, q[5] + 0.2, PUMA.upper),
        ),
        (np.maximum(PUMA.lower, q + 0.01), PUMA.upper),
    ):
        query = IKQuery(PUMA, T, "pose", 1e-6, make_task("pose"), bounds)
        result = verified_result(query, 0.0, "dls", without_run(q, "max_iter"), None)
        assert result.position_error <= 1e-12  # the pose itself is reached
        assert not result.success and result.status == "max_iter"
        assert "box" in result.message
    assert optik.solve_ik(PUMA, T, frozen={name: float(q[5])}).success


def test_the_batch_refuses_a_row_off_the_query_s_box(monkeypatch: pytest.MonkeyPatch) -> None:
    # A closed form that handed back branches off the frozen value (as if unclipped):
    # the batch's verification refuses them.
    rng = np.random.default_rng(9)
    Q = rng.uniform(0.8 * PUMA.lower, 0.8 * PUMA.upper, (6, 6))
    T = PUMA.fk(Q)
    monkeypatch.setattr("optik.ik_batch._branches", lambda *args: Q.copy())
    value = 0.123
    batch = optik.solve_ik_batch(PUMA, T, frozen={PUMA.joint_names[5]: value}, restarts=0)
    assert np.all(np.abs(Q[:, 5] - value) > 1e-3)
    assert not batch.success.any()


def test_a_batch_row_s_stream_is_its_index_whatever_precedes_it() -> None:
    # Target k draws from the stream seed + k: a row beyond reach before it (not searched)
    # must not shift the streams of the rows after it. A short budget per attempt, so
    # that the random starts decide the answers (the Panda: no closed form).
    rng = np.random.default_rng(3)
    T = PANDA.fk(rng.uniform(PANDA.lower, PANDA.upper, (8, PANDA.dof)))
    far = np.eye(4)
    far[:3, 3] = [100.0, 0.0, 0.0]
    options = {"max_iter": 4, "restarts": 300, "seed": 7}
    after_far = optik.solve_ik_batch(PANDA, np.concatenate([far[None], T]), **options)
    after_near = optik.solve_ik_batch(PANDA, np.concatenate([T[:1], T]), **options)
    assert after_far.status[0] == "unreachable"
    np.testing.assert_array_equal(after_far.q[1:], after_near.q[1:])
    np.testing.assert_array_equal(after_far.restarts[1:], after_near.restarts[1:])
    assert np.any(after_far.restarts[1:] > 0)  # the draws mattered


@pytest.mark.parametrize("tol", [(1e-2, 1e-6), (1e-6, 1e-2)])
def test_split_tolerances_judge_each_error_by_its_own(tol: tuple[float, float]) -> None:
    # A turn of the base by 1e-3 rad (the tool point moves ~5e-4 m): within the loose
    # tolerance of the one error, beyond the tight one of the other.
    from optik.verify import verify_one

    q = PUMA.mid_limits + 0.3
    turned = q + np.array([1e-3, 0.0, 0.0, 0.0, 0.0, 0.0])
    position, orientation, _, success = verify_one(PUMA, turned, PUMA.fk(q), make_task(tol=tol))
    assert orientation > 5e-4 and position > 1e-4
    assert success == (position <= tol[0] and orientation <= tol[1])
    assert not success


def test_a_point_within_tol_of_the_reach_sphere_is_not_proved_unreachable() -> None:
    # 5 mm beyond full stretch with tol 1 cm: an answer within the tolerance exists.
    planar = load_problem("planar_2r").robot
    centre, radius = planar.reach_sphere
    point = centre + np.array([radius + 0.005, 0.0, 0.0])
    single = optik.solve_ik(planar, point, mode="position", tol=0.01)
    batch = optik.solve_ik_batch(planar, point[None], mode="position", tol=0.01)
    assert single.success and batch.success.tolist() == [True]
    far = centre + np.array([radius + 0.02, 0.0, 0.0])
    assert optik.solve_ik_batch(planar, far[None], mode="position", tol=0.01).status[0] == (
        "unreachable"
    )


def test_uniform_weights_are_the_plain_task() -> None:
    # Weights are divided by the largest: equal ones, whatever their size, are the plain
    # pose (its proofs and its closed form), not a graded compromise.
    task = make_task(weights=[2.0] * 6)
    assert task.weights.max() == 1.0 and task.is_pose_or_position and not task.is_graded
    far = np.eye(4)
    far[:3, 3] = [10.0, 0.0, 0.0]
    result = optik.solve_ik(PANDA, far, weights=[1e-10] * 6)
    assert (result.status, result.solver, result.iterations) == ("unreachable", "reach", 0)
    T = PUMA.fk(PUMA.mid_limits + 0.2)
    assert optik.solve_ik(PUMA, T, weights=[3.0] * 6).solver == "analytic"


def test_solve_ik_all_s_answers_are_a_tenth_of_a_radian_apart_by_default() -> None:
    T = PANDA.fk(PANDA.mid_limits + 0.2)
    answers = optik.solve_ik_all(PANDA, T, k=8)
    assert len(answers) >= 2
    Q = np.array([r.q for r in answers])
    gaps = np.linalg.norm(Q[:, None] - Q[None], axis=2)[np.triu_indices(len(Q), 1)]
    assert gaps.min() >= 0.1
