"""``solve_ik_batch`` proves what ``solve_ik`` proves: ``unreachable`` and ``outside_limits``.

Where the robot's closed form proves (the plain limits) and neither it nor the search
finds an answer, a batch row gets the single call's proof: a cross-check search from the
branches beyond the limits, clipped into them, then ``outside_limits`` (branches only
beyond the limits) or ``unreachable`` (no branch at all).
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import optik
from optik.errors import ArgumentError
from optik.ik import CROSS_CHECK_RESTARTS
from optik.ik_batch import BATCH_STATUSES
from optik.problems import load_problem


def _mixed_targets(robot: optik.Robot, n: int, seed: int) -> np.ndarray:
    """Poses of configurations up to 40 % of the range beyond the limits, and points
    drawn inside the reach sphere with the first pose's rotation: (2 n, 4, 4)."""
    rng = np.random.default_rng(seed)
    Q = robot.lower + rng.uniform(-0.4, 1.4, size=(n, robot.dof)) * (robot.upper - robot.lower)
    T = robot.fk(Q)
    centre, radius = robot.reach_sphere
    points = centre + radius * rng.uniform(-0.9, 0.9, size=(n, 3)) / np.sqrt(3.0)
    held = np.repeat(T[:1], n, axis=0)
    held[:, :3, 3] = points
    return np.concatenate([T, held])


@pytest.mark.parametrize(
    ("name", "mode"),
    [
        ("puma560", "pose"),  # compiled closed form
        ("stanford_arm", "pose"),
        ("jumbo_spherical_arm", "position"),  # a closed form run in Python
        ("dobot_magician", "position"),
        ("planar_2r", "position"),
    ],
)
def test_each_row_has_solve_ik_s_status_and_outside_limits_q(name: str, mode: str) -> None:
    robot = load_problem(name).robot
    T = _mixed_targets(robot, 12, 3)
    batch = optik.solve_ik_batch(robot, T, mode=mode, restarts=10)
    assert set(batch.status) <= set(BATCH_STATUSES)
    single = [optik.solve_ik(robot, t, mode=mode) for t in T]
    assert batch.status.tolist() == [r.status for r in single]
    # The sample holds answers, and proofs inside the reach sphere (which the batch
    # left as max_iter before it proved them).
    centre, radius = robot.reach_sphere
    inside = np.linalg.norm(T[:, :3, 3] - centre, axis=1) < radius
    assert np.any(batch.success)
    assert np.any(np.isin(batch.status, ["outside_limits", "unreachable"]) & inside)
    for k in np.flatnonzero(batch.status == "outside_limits"):
        # The branch nearest the middle of the limits, beyond them, reaching the target.
        np.testing.assert_allclose(batch.q[k], single[k].q, atol=1e-12)
        reached = robot.fk(batch.q[k])[:3, 3]
        assert np.linalg.norm(reached - T[k, :3, 3]) < 1e-9
        assert batch.limit_violation[k] == pytest.approx(single[k].limit_violation, abs=1e-12)
        assert batch.limit_violation[k] > 1e-6 and not batch.success[k]


def test_a_point_needing_a_short_stroke_is_outside_the_limits_in_both() -> None:
    # The boom slides 2 to 6 m; the point needs 1.5 m, inside the reach sphere. The batch
    # said max_iter (no proof) where solve_ik said outside_limits.
    arm = load_problem("jumbo_spherical_arm").robot
    p = arm.fk(np.array([0.2, 0.4, 1.5]))[:3, 3]
    restarts = 4
    batch = optik.solve_ik_batch(arm, p[None], mode="position", restarts=restarts)
    assert batch.status.tolist() == ["outside_limits"]
    assert batch.limit_violation[0] == pytest.approx(0.5, abs=1e-9)
    np.testing.assert_allclose(batch.q[0], [0.2, 0.4, 1.5], atol=1e-9)
    # Every attempt of the search, then of the cross-check (its first one included).
    assert batch.restarts[0] == restarts + 1 + CROSS_CHECK_RESTARTS
    assert optik.solve_ik(arm, p, mode="position").status == "outside_limits"


def test_graded_weights_keep_their_compromise_inside_the_limits() -> None:
    arm = load_problem("jumbo_spherical_arm").robot
    p = arm.fk(np.array([0.2, 0.4, 1.5]))[:3, 3]
    weights = [1.0, 1.0, 3.0, 0.0, 0.0, 0.0]
    batch = optik.solve_ik_batch(arm, p[None], mode="position", weights=weights, restarts=2)
    single = optik.solve_ik(arm, p, mode="position", weights=weights)
    assert batch.status[0] == single.status == "outside_limits"
    assert arm.within_limits(batch.q[0]) and batch.limit_violation[0] == 0.0
    assert batch.position_error[0] == pytest.approx(single.position_error, rel=1e-6)


def test_no_proof_without_the_plain_limits_or_when_not_asked() -> None:
    arm = load_problem("jumbo_spherical_arm").robot
    p = arm.fk(np.array([0.2, 0.4, 1.5]))[:3, 3]
    # A margin narrows the box: the branch set proves nothing about it (as in solve_ik).
    narrowed = optik.solve_ik_batch(arm, p[None], mode="position", restarts=2, limit_margin=0.01)
    assert narrowed.status.tolist() == ["max_iter"]
    unproved = optik.solve_ik_batch(arm, p[None], mode="position", restarts=2, proofs=False)
    assert unproved.status.tolist() == ["max_iter"] and arm.within_limits(unproved.q[0])
    assert unproved.restarts[0] == 2


def test_a_target_with_no_branch_at_all_is_unreachable_inside_the_sphere() -> None:
    # A fixed orientation the UR5's wrist cannot take at that point: no branch, limits or
    # not, although the point lies well inside the reach sphere.
    ur5 = load_problem("ur5").robot
    T = ur5.fk(ur5.mid_limits)
    centre, radius = ur5.reach_sphere
    rng = np.random.default_rng(0)
    T_all = np.repeat(T[None], 400, axis=0)
    T_all[:, :3, 3] = centre + radius * rng.uniform(-1.0, 1.0, (400, 3)) / np.sqrt(3.0)
    batch = optik.solve_ik_batch(ur5, T_all, restarts=5)
    inside = np.linalg.norm(T_all[:, :3, 3] - centre, axis=1) < radius
    proved = np.flatnonzero((batch.status == "unreachable") & inside)
    assert proved.size > 0
    for k in proved:
        assert optik.analytic_ik(ur5, T_all[k], within_limits=False) == []
        assert optik.solve_ik(ur5, T_all[k]).status == "unreachable"


@pytest.mark.parametrize("value", ["no", 0, None, 1.0])
def test_proofs_must_be_a_boolean(value: object) -> None:
    puma = load_problem("puma560").robot
    with pytest.raises(ArgumentError, match="proofs"):
        optik.solve_ik_batch(puma, puma.fk(puma.mid_limits)[None], proofs=value)


# Targets a closed form reaches by no branch, which an in-limit configuration meets within
# a loose tol (both errors below it): the search's least-squares minimum trades position
# for rotation and misses them. Witnesses found by a minimax search.
LOOSE_TOL_CASES = [
    (
        "ur5",
        0.05,
        [
            [1.0, 0.0, 0.0, 0.04735666780866799],
            [0.0, 6.123233995736766e-17, -1.0, -0.11685300269685252],
            [0.0, 1.0, 6.123233995736766e-17, 0.15456189556764965],
            [0.0, 0.0, 0.0, 1.0],
        ],
        [0.9763633989588054, -2.7463191729295335, -3.526929632454513,
         -0.009936249924747918, 1.0236542315196513, 2.0316352141017653e-06],
    ),
    (
        "puma560",
        0.1,
        [
            [0.8660254037844386, -0.5, 0.0, 0.22250243943872],
            [0.5, 0.8660254037844386, 0.0, -0.6152378885730886],
            [0.0, 0.0, 1.0, 0.18568346733299357],
            [0.0, 0.0, 0.0, 1.0],
        ],
        [-1.017329666346613, -0.7853981633974483, -1.0513212971525594,
         -6.763549674591244e-05, 1.7453292519943295, 1.540848783332782],
    ),
]  # fmt: skip


@pytest.mark.parametrize(("name", "tol", "target", "witness"), LOOSE_TOL_CASES, ids=["ur5", "puma"])
def test_a_loose_tol_met_near_the_target_is_no_proof(
    name: str, tol: float, target: list[list[float]], witness: list[float]
) -> None:
    robot = load_problem(name).robot
    T, q = np.array(target), np.array(witness)
    # The witness meets tol inside the limits (scipy's rotation angle, not optik's).
    F = robot.fk(q)
    assert robot.within_limits(q)
    assert np.linalg.norm(F[:3, 3] - T[:3, 3]) < tol
    assert Rotation.from_matrix(F[:3, :3].T @ T[:3, :3]).magnitude() < tol
    single = optik.solve_ik(robot, T, tol=tol)
    batch = optik.solve_ik_batch(robot, T[None], tol=tol)
    # Either found, or not found: never "unreachable" or "outside_limits" (they were).
    assert single.status in ("converged", "max_iter"), single.message
    assert batch.status[0] in ("converged", "max_iter")
    assert single.status == batch.status[0]
    # At the default tol the closed form's proof stands.
    assert optik.solve_ik(robot, T).status in ("unreachable", "outside_limits")
    assert optik.solve_ik_batch(robot, T[None]).status[0] in ("unreachable", "outside_limits")


def test_the_proofs_run_slice_by_slice_with_the_rows_of_one_slice(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    puma = load_problem("puma560").robot
    T = _mixed_targets(puma, 12, 4)
    whole = optik.solve_ik_batch(puma, T, restarts=3)
    monkeypatch.setattr(optik.ik_batch, "BATCH_SLICE", 3)
    sliced = optik.solve_ik_batch(puma, T, restarts=3)
    assert np.sum(np.isin(whole.status, ["outside_limits", "unreachable"])) > 3  # several slices
    assert sliced.status.tolist() == whole.status.tolist()
    np.testing.assert_array_equal(sliced.q, whole.q)
    np.testing.assert_array_equal(sliced.iterations, whole.iterations)
