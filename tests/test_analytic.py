"""Closed-form IK: every family, property tests over random, singular and limit configurations."""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import assert_close

import optik
from optik.analytic import (
    FAMILIES,
    analytic_ik,
    analytic_ik_batch,
    detect_family,
    wrap_into_limits,
)
from optik.errors import AnalyticIKError, NonFiniteError, ShapeError
from optik.model import Robot
from optik.problems import load_problem

CASES = [
    ("planar_2r", "position"),
    ("jumbo_spherical_arm", "position"),
    ("jumbo_spherical_arm", "pose"),
    ("dobot_magician", "position"),
    ("dobot_magician", "pose"),
    ("puma560", "pose"),
    ("stanford_arm", "pose"),
    ("jumbo_drill_6dof", "pose"),
    ("ur5", "pose"),
]
N_RANDOM = 1000


def _finite_limits(robot: Robot) -> tuple[np.ndarray, np.ndarray]:
    lower = np.where(np.isfinite(robot.lower), robot.lower, -math.pi)
    upper = np.where(np.isfinite(robot.upper), robot.upper, math.pi)
    return lower, upper


def _special_configurations(robot: Robot, rng: np.random.Generator) -> np.ndarray:
    """Configurations at the limits and at the structure's singularities, on purpose."""
    lower, upper = _finite_limits(robot)
    out = []
    for i in range(robot.dof):
        for bound in (lower[i], upper[i]):
            q = rng.uniform(lower, upper)
            q[i] = bound
            out.append(q)
    singular_values = {
        "puma560": [(4, 0.0), (2, -math.pi / 2), (2, math.atan2(0.0203, 0.4318) - math.pi / 2)],
        "ur5": [(4, 0.0), (2, 0.0), (4, math.pi)],
        "stanford_arm": [(4, 0.0)],
        "jumbo_drill_6dof": [(4, 0.0)],
        "jumbo_spherical_arm": [(1, 0.0)],
        "planar_2r": [(1, 0.0)],
        "dobot_magician": [(1, 0.0), (2, 0.0)],
    }.get(robot.name, [])
    for joint, value in singular_values:
        for _ in range(20):
            q = rng.uniform(lower, upper)
            q[joint] = value + rng.choice([0.0, 1e-9, -1e-9, 1e-6])
            out.append(np.clip(q, lower, upper))
    return np.array(out)


@pytest.mark.parametrize(("name", "mode"), CASES)
def test_family_round_trip(name: str, mode: str, rng: np.random.Generator) -> None:
    """The configuration that made the target is among the branches; every branch reaches it."""
    robot = load_problem(name).robot
    lower, upper = _finite_limits(robot)
    random = rng.uniform(lower, upper, (N_RANDOM, robot.dof))
    special = _special_configurations(robot, rng)
    configs = np.vstack([random, special])
    missing = 0
    for k, q in enumerate(configs):
        T = robot.fk(q)
        target = T if mode == "pose" else T[:3, 3]
        branches = analytic_ik(robot, target, mode=mode, q_ref=q)
        assert branches, f"{name}: no branch for an in-limit configuration {q}"
        for b in branches:
            assert np.all(np.isfinite(b))
            assert robot.within_limits(b)
            T_b = robot.fk(b)
            assert np.linalg.norm(T_b[:3, 3] - T[:3, 3]) <= 1e-9
            if mode == "pose":
                assert optik.spatial.pose_error(T_b, T)[1] <= 1e-9
        compare = slice(0, 3) if (name == "dobot_magician" and mode == "position") else slice(None)
        # Within 1e-6 of a singularity two branches merge into a double root between them,
        # so the original is recovered only to about the distance from the singularity,
        # times the conditioning of the joints that follow (the Puma 1e-6 rad from its
        # stretched elbow: 1.5e-5 rad off in the shoulder, before and after the elbow's
        # equation was made relative; every branch still reaches the pose to 1e-9).
        tolerance = 1e-6 if k < N_RANDOM else 3e-5
        if np.max(np.abs(branches[0][compare] - q[compare])) > tolerance:
            missing += 1
    assert missing == 0, (
        f"{name}/{mode}: original configuration not the nearest branch {missing} times"
    )


@pytest.mark.parametrize(
    ("name", "expected"),
    [("puma560", 8), ("ur5", 8), ("stanford_arm", 8), ("jumbo_spherical_arm", 4), ("planar_2r", 2)],
)
def test_branch_count_without_limits(name: str, expected: int, rng: np.random.Generator) -> None:
    robot = load_problem(name).robot
    mode = "pose" if robot.dof == 6 else "position"
    lower, upper = _finite_limits(robot)
    counts = []
    for _ in range(50):
        T = robot.fk(rng.uniform(lower, upper))
        counts.append(
            len(
                analytic_ik(
                    robot, T if mode == "pose" else T[:3, 3], mode=mode, within_limits=False
                )
            )
        )
    assert max(counts) == expected
    assert np.median(counts) == expected


def test_branches_sorted_by_distance_to_reference(rng: np.random.Generator) -> None:
    robot = load_problem("puma560").robot
    q = rng.uniform(robot.lower, robot.upper)
    ref = rng.uniform(robot.lower, robot.upper)
    branches = analytic_ik(robot, robot.fk(q), q_ref=ref)
    distances = [np.linalg.norm(b - ref) for b in branches]
    assert distances == sorted(distances)
    assert len(branches) >= 2


def test_unreachable_target_gives_empty_list() -> None:
    for name in ("puma560", "ur5", "stanford_arm"):
        robot = load_problem(name).robot
        T = np.eye(4)
        T[:3, 3] = [10.0, 0.0, 0.0]
        assert analytic_ik(robot, T) == []
    robot = load_problem("planar_2r").robot
    assert analytic_ik(robot, [3.0, 0.0, 0.0], mode="position") == []
    assert analytic_ik(robot, [1.0, 1.0, 0.5], mode="position") == []  # out of the plane


def test_outside_limits_branches_are_dropped_unless_asked() -> None:
    robot = load_problem("jumbo_spherical_arm").robot
    # Stroke 7 m: reachable geometrically, but the prismatic joint stops at 6 m.
    q = np.array([0.3, 0.5, 7.0])
    p = robot.fk(q)[:3, 3]
    assert analytic_ik(robot, p, mode="position") == []
    loose = analytic_ik(robot, p, mode="position", within_limits=False, q_ref=q)
    assert_close(loose[0], q, atol=1e-9)


def test_the_limit_filter_and_the_verification_give_one_verdict() -> None:
    """``within_limits`` (the closed forms' filter) and ``limit_violation`` (every
    answer's verification) agree to the last bit at the tolerance: a value 1e-12 beyond
    a bound of about 3 passed the one (``q <= upper + tol`` rounds) and failed the other
    (``q - upper <= tol``), and ``solve_ik`` reported ``max_iter`` for a closed-form
    answer. Values spread over the rounding of ``bound +- tol``."""
    from optik.limits import LIMIT_TOLERANCE, limit_violation, within_limits

    rng = np.random.default_rng(3)
    bounds = rng.uniform(-4.0, 4.0, 2000)
    steps = rng.integers(-40, 41, bounds.shape) * np.spacing(bounds)
    for sign in (1.0, -1.0):
        q = bounds + sign * LIMIT_TOLERANCE + steps
        lower = np.where(sign < 0, bounds, -10.0)[:, None]
        upper = np.where(sign > 0, bounds, 10.0)[:, None]
        inside = within_limits(q[:, None], lower[:, 0], upper[:, 0])
        rows = [within_limits(q[i : i + 1], lower[i], upper[i]) for i in range(len(q))]
        violation = np.array(
            [limit_violation(q[i : i + 1], lower[i], upper[i]) for i in range(len(q))]
        )
        assert np.array_equal(np.asarray(rows), violation <= LIMIT_TOLERANCE)
        assert inside.shape == (len(q),)
        assert 0 < np.count_nonzero(violation <= LIMIT_TOLERANCE) < len(q)


@pytest.mark.parametrize("name", ["stanford_arm", "puma560", "ur5", "jumbo_drill_6dof"])
def test_branches_at_their_limits_come_back_inside_them(name: str) -> None:
    """A configuration with joints on their bounds: every branch returned lies inside the
    limits exactly (a row off by rounding is put on the bound) and ``solve_ik`` answers
    with a verified in-limit configuration (the Stanford arm's case found by a fuzz:
    ``max_iter`` from the closed form, at a limit violation of 1.00009e-12)."""
    robot = load_problem(name).robot
    lower, upper = _finite_limits(robot)
    rng = np.random.default_rng(11)
    configurations = [
        np.array([-math.pi / 2, 1e-12, 0.3048, -math.pi / 2, -math.pi / 2, -math.pi / 2])
    ]
    for _ in range(40):
        q = rng.uniform(lower, upper)
        on = rng.random(robot.dof) < 0.5
        q[on] = np.where(rng.random(robot.dof) < 0.5, lower, upper)[on]
        configurations.append(q)
    for q in configurations:
        if not robot.within_limits(q):
            continue
        T = robot.fk(q)
        branches = analytic_ik(robot, T)
        for branch in branches:
            assert np.all(branch >= robot.lower) and np.all(branch <= robot.upper)
        if name == "stanford_arm" and q is configurations[0]:
            # 1.00009e-12 beyond its bound by rounding: put on it, not dropped.
            assert min(float(np.max(np.abs(b - q))) for b in branches) < 1e-9
        result = optik.solve_ik(robot, T)
        assert result.success, (q, result.status, result.limit_violation)
        assert result.limit_violation == 0.0


def test_an_aligned_wrist_splits_its_turn_inside_the_limits() -> None:
    """At the wrist singularity only ``q4 + q6`` is defined. Keeping ``q4`` at its
    reference put the whole turn into ``q6``, outside its +-170 deg for a Stanford arm at
    ``q4 = 1.98, q6 = 1.23`` (found by a hostile-input search: no branch within the
    limits). The split nearest the reference comes too: on 300 random aligned wrists
    (``q5 = 0``) every pose keeps an in-limit branch, each reaching the pose (the sum
    ``q4 + q6`` is the source's modulo 2 pi), and with the source as reference the
    source comes first."""
    robot = load_problem("stanford_arm").robot
    rng = np.random.default_rng(8)
    sources = [np.array([-0.744, 1.2, 0.389, 1.98, 0.0, 1.23])]
    for _ in range(300):
        q = rng.uniform(robot.lower, robot.upper)
        q[4] = 0.0
        sources.append(q)
    for q in sources:
        T = robot.fk(q)
        branches = analytic_ik(robot, T)
        assert branches, q
        for b in branches:
            assert np.all(b >= robot.lower) and np.all(b <= robot.upper)
            assert_close(robot.fk(b), T, atol=1e-9)
        aligned = [b for b in branches if abs(b[4]) < 1e-9 and np.allclose(b[:3], q[:3], atol=1e-9)]
        assert aligned, q
        turn = np.remainder(aligned[0][3] + aligned[0][5] - q[3] - q[5] + math.pi, 2 * math.pi)
        assert abs(turn - math.pi) < 1e-9
        first = analytic_ik(robot, T, q_ref=q)[0]
        assert_close(first, q, atol=1e-9)


def test_dobot_over_its_base_axis_keeps_the_reference() -> None:
    """The flange over the base axis (to 1e-17 m, rounding's azimuth): J1 is free and
    keeps its reference, not ``atan2`` of the rounding (which put J4 beyond -90 deg and
    lost the in-limit answer; found by a hostile-input search)."""
    robot = load_problem("dobot_magician").robot
    q = np.array([0.589, 0.0, math.pi / 2, -math.pi / 2])
    T = robot.fk(q)
    assert 0.0 < np.hypot(*T[:2, 3]) < 1e-15
    branches = analytic_ik(robot, T)
    assert branches
    for b in branches:
        assert b[0] == robot.mid_limits[0]
        assert np.all(b >= robot.lower) and np.all(b <= robot.upper)
        assert_close(robot.fk(b), T, atol=1e-9)
    ref = robot.mid_limits.copy()
    ref[0] = 0.4
    assert abs(analytic_ik(robot, T, q_ref=ref)[0][0] - 0.4) < 1e-12


def test_wrap_into_limits_picks_representative_nearest_reference() -> None:
    robot = load_problem("ur5").robot  # +-360 deg: two representatives for most angles
    Q = np.array([[0.5, -0.5, 1.0, 3.0, -3.0, 0.0]])
    ref = np.array([0.5 - 2 * math.pi, -0.5, 1.0 - 2 * math.pi, 3.0 + 2 * math.pi, -3.0, 6.0])
    wrapped = wrap_into_limits(Q, robot, ref)[0]
    expected = [0.5 - 2 * math.pi, -0.5, 1.0 - 2 * math.pi, 3.0, -3.0, 2 * math.pi]
    assert_close(wrapped, expected, atol=1e-12)  # 3 + 2 pi would exceed the 2 pi limit
    puma = load_problem("puma560").robot  # j2 in [-45, 225] deg: -100 deg lives at 260 (outside)
    wrapped = wrap_into_limits(
        np.array([[0.0, math.radians(200) - 2 * math.pi, 0, 0, 0, 0]]), puma, puma.mid_limits
    )
    assert_close(wrapped[0, 1], math.radians(200), atol=1e-12)


def test_a_joint_in_a_box_of_no_width_is_returned_to_the_bit() -> None:
    # The remainder's round trip moved 2 % of angles by an ulp: solve_ik_all returned
    # frozen joints 4.4e-16 off their value.
    robot = load_problem("puma560").robot
    values = np.random.default_rng(0).uniform(-2.5, 2.5, (10_000, robot.dof))
    ref = np.random.default_rng(1).uniform(-2.5, 2.5, (10_000, robot.dof))
    ref[:, 0] = values[:, 0]  # the answer's own value: v + pi - pi is not v for 2 % of v
    lower = np.hstack([values[:, :1], np.full((10_000, 5), -4.0)])
    upper = np.hstack([values[:, :1], np.full((10_000, 5), 4.0)])
    wrapped = wrap_into_limits(values, robot, ref, (lower, upper))
    assert np.array_equal(wrapped[:, 0], values[:, 0])
    twins = values.copy()
    twins[:, 0] -= 2 * math.pi  # a 2 pi twin of the box's value is put on it, exactly
    assert np.array_equal(wrap_into_limits(twins, robot, ref, (lower, upper))[:, 0], lower[:, 0])
    moved = np.abs(wrapped[:, 1:] - values[:, 1:])
    assert np.all((moved < 1e-12) | (np.abs(moved - 2 * math.pi) < 1e-12))
    rng = np.random.default_rng(4)
    q = robot.lower + (robot.upper - robot.lower) * rng.uniform(0.15, 0.85, robot.dof)
    value = float(q[0])  # 1.7321444701795161: the numeric path returned 4.4e-16 more
    results = optik.solve_ik_all(robot, robot.fk(q), frozen={"j1": value}, solver="dls", k=4)
    assert results and all(r.success and r.q[0] == value for r in results)


def test_spherical_rrp_pose_uses_corrected_first_angle(rng: np.random.Generator) -> None:
    """Seed 000 eq. 36 prints q1 = atan2(-Ax, -Ay); the A-matrix product gives atan2(Ax, -Ay)."""
    robot = load_problem("jumbo_spherical_arm").robot
    wrong = 0
    for _ in range(100):
        q = rng.uniform(*_finite_limits(robot))
        R = robot.fk(q)[:3, :3]
        printed = math.atan2(-R[0, 2], -R[1, 2])
        corrected = math.atan2(R[0, 2], -R[1, 2])
        assert abs(math.remainder(corrected - q[0], 2 * math.pi)) < 1e-9
        wrong += abs(math.remainder(printed - q[0], 2 * math.pi)) > 1e-6
    assert wrong >= 95  # wrong except where sin(q1) = 0


def test_family_detection_and_errors() -> None:
    puma = load_problem("puma560").robot
    assert detect_family(puma) is FAMILIES["spherical_wrist"]
    assert detect_family(load_problem("ur5").robot) is FAMILIES["ur"]
    panda = load_problem("panda").robot
    assert detect_family(panda) is None
    with pytest.raises(AnalyticIKError, match="no closed-form"):
        analytic_ik(panda, panda.fk(panda.mid_limits))
    with pytest.raises(AnalyticIKError, match="solves mode"):
        analytic_ik(puma, [0.3, 0.2, 0.5], mode="position")
    # A declared family is checked when the robot is built, with the reason.
    with pytest.raises(AnalyticIKError, match=r"does not fit family 'ur': 2 joints"):
        Robot.from_dh([{"a": 1.0, "role": "arm"}, {"a": 1.0, "role": "arm"}], analytic="ur")
    with pytest.raises(AnalyticIKError, match="unknown analytic family"):
        Robot.from_dh([{"a": 1.0, "role": "arm"}], analytic="nope")


def test_bad_targets_raise_optik_errors() -> None:
    puma = load_problem("puma560").robot
    bad = np.eye(4)
    bad[0, 3] = np.nan
    with pytest.raises(NonFiniteError):
        analytic_ik(puma, bad)
    with pytest.raises(ShapeError):
        analytic_ik(puma, np.eye(3))
    skewed = np.eye(4)
    skewed[0, 1] = 0.1
    with pytest.raises(optik.errors.InvalidRotationError):
        analytic_ik(puma, skewed)


def _one_per_pipeline() -> list[tuple[Robot, dict[str, object]]]:
    """A robot of each compiled single call: the DH table, the axes, a held joint."""
    ur5 = load_problem("ur5").robot
    puma = load_problem("puma560").robot
    assert puma.dh is not None
    axes = Robot.from_dh(list(puma.dh), name="puma_axes", base=puma.T_world_base,
                         tool=puma.T_flange_tool, analytic="spherical_axes")  # fmt: skip
    panda = load_problem("panda").robot
    return [(ur5, {}), (axes, {}), (panda, {"free_joint": panda.joint_names[6], "free_value": 0.3})]


@pytest.mark.parametrize("size", [1e10, 1e300, np.inf, np.nan])
def test_a_q_ref_beyond_the_joint_bound_is_refused_by_every_path(size: float) -> None:
    # The compiled single call checked q_ref for NaN only: 1e300 was used (or raised an
    # error naming a value nobody passed, q[0] = 1e10 + 1.96), and the batch took it.
    for robot, free in _one_per_pipeline():
        q = robot.mid_limits + 0.2
        if free:
            q[robot.joint_names.index(str(free["free_joint"]))] = 0.3
        T = robot.fk(q)
        for ref in (np.full(robot.dof, size), [size] * robot.dof):
            with pytest.raises(optik.OptikError, match=r"^q_ref"):
                analytic_ik(robot, T, q_ref=ref, **free)  # type: ignore[arg-type]
            with pytest.raises(optik.OptikError, match=r"^q_ref"):
                analytic_ik_batch(robot, T[None], q_ref=ref, **free)  # type: ignore[arg-type]
        assert len(analytic_ik(robot, T, q_ref=q, **free)) > 0  # type: ignore[arg-type]


def _angle_gap(a: np.ndarray, b: np.ndarray) -> float:
    """Max-abs difference of two configurations, revolute angles wrapped (rad or m)."""
    return float(np.max(np.abs(np.remainder(a - b + math.pi, 2 * math.pi) - math.pi)))


# A joint exactly on its limit next to a singularity: the closed form splits the two
# nearly parallel joints only to eps / sin(q5) and put this joint 1.5e-9 .. 3e-8 beyond
# its limit; the branch was dropped (the nearest one returned was 1.9 rad away).
ON_A_LIMIT_NEAR_SINGULAR = [
    ("puma560", [-2.1199709690340063, -0.5386266287082703, -1.0213114479966383,
                 -1.9198621771937625, 1e-06, -3.382203476513454]),
    ("puma560", [-2.3127504328352764, 2.173228466797553, -3.1638913023821296,
                 -1.9198621771937625, 1e-08, -2.270774384257755]),
    ("stanford_arm", [-2.9670597281570106, -2.24109041269382e-09, 0.3048000013784227,
                      2.9670597283189997, -0.5622718489639161, 2.9670597274556]),
]  # fmt: skip


@pytest.mark.parametrize(("name", "q_list"), ON_A_LIMIT_NEAR_SINGULAR)
def test_a_branch_on_its_limit_next_to_a_singularity_is_kept(
    name: str, q_list: list[float]
) -> None:
    robot = load_problem(name).robot
    q = np.array(q_list)
    assert robot.within_limits(q)
    T = robot.fk(q)
    branches = analytic_ik(robot, T, q_ref=q)
    nearest = min(branches, key=lambda b: _angle_gap(b, q))
    assert _angle_gap(nearest, q) < 1e-6
    assert np.max(np.abs(robot.fk(nearest) - T)) < 1e-12  # an exact answer, not a compromise
    for b in branches:
        assert robot.within_limits(b)
        assert np.max(np.abs(robot.fk(b) - T)) < 1e-10
    batch = analytic_ik_batch(robot, T[None], q_ref=q)
    assert int(batch.counts[0]) == len(branches)
    assert np.array_equal(batch.q[0, : len(branches)], np.array(branches))


def test_joints_on_their_limits_next_to_the_wrist_singularity_keep_the_source() -> None:
    # Random Puma poses with q4 or q6 exactly on a limit and q5 at 1e-10 .. 1e-6: the
    # source configuration among the branches in every one (29 of 150 lost it: the
    # nearest branch a turn of q4 and q6 away). Near the singularity the q4 / q6 split
    # is conditioned as 1 / q5: the source is found to 1e-4, not to rounding.
    puma = load_problem("puma560").robot
    rng = np.random.default_rng(11)
    for _ in range(60):
        q = rng.uniform(puma.lower, puma.upper)
        j = int(rng.choice([3, 5]))
        q[j] = puma.lower[j] if rng.random() < 0.5 else puma.upper[j]
        q[4] = float(rng.choice([-1.0, 1.0]) * 10 ** rng.uniform(-10, -6))
        T = puma.fk(q)
        branches = analytic_ik(puma, T, q_ref=q)
        assert min(_angle_gap(b, q) for b in branches) < 1e-4, q.tolist()
        assert all(np.max(np.abs(puma.fk(b) - T)) < 1e-10 for b in branches)


def test_python_family_has_no_compiled_table() -> None:
    planar = load_problem("planar_2r").robot
    with pytest.raises(AnalyticIKError, match="no compiled kernel"):
        FAMILIES["planar_2r"].model(planar)


def test_row_views_list_the_first_rows_as_views_for_every_count() -> None:
    from optik.analytic._arguments import ROW_VIEWS

    out = np.arange(48.0).reshape(8, 6)
    assert len(ROW_VIEWS) == 9
    for n, row_views in enumerate(ROW_VIEWS):
        rows = row_views(out)
        assert isinstance(rows, list) and len(rows) == n
        for i, row in enumerate(rows):
            assert row.shape == (6,) and np.shares_memory(row, out[i])
            np.testing.assert_array_equal(row, out[i])
