"""Closed-form IK of a seven-joint arm with one joint held (``analytic_ik(free_joint=...)``).

The KUKA iiwa of pybullet's ``pybullet_data`` (a test dependency), read from its URDF:
axes 1-3 meet (spherical shoulder), axes 5-7 meet (spherical wrist). References are
independent of the closed form: the robot's own FK (round trips), the configuration a
pose came from, and the numeric solver with the joint frozen.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pybullet_data  # the test extra: its absence is a failure, not a skip
import pytest
from conftest import frozen_answers_among_branches

from optik import Robot, load_problem
from optik.analytic import analytic_ik
from optik.errors import AnalyticIKError, OptikError
from optik.problems import builtin_problems

IIWA_URDF = Path(pybullet_data.getDataPath()) / "kuka_iiwa" / "model.urdf"
FK_TOL = 1e-10
SOURCE_TOL = 1e-8


@pytest.fixture(scope="module")
def iiwa() -> Robot:
    return Robot.from_urdf(IIWA_URDF, "lbr_iiwa_link_0", "lbr_iiwa_link_7")


def _wrapped(a: np.ndarray, b: np.ndarray) -> float:
    """Max-abs angle difference after wrapping into (-pi, pi]."""
    return float(np.max(np.abs(np.remainder(a - b + math.pi, 2 * math.pi) - math.pi)))


def _check(robot: Robot, target: np.ndarray, branches: list[np.ndarray], k: int, value: float):
    """Every branch round-trips through FK, lies inside the limits, holds joint ``k``."""
    for b in branches:
        assert b.shape == (7,)
        assert b[k] == value
        assert robot.within_limits(b)
        assert np.max(np.abs(robot.fk(b) - target)) < FK_TOL


def _singular_sample(robot: Robot, rng: np.random.Generator, zero: int) -> np.ndarray:
    """An in-limit configuration with ``q[zero] = 0`` and the other singular joints
    (q2, q4, q6) at least 0.1 rad from 0: one singularity at a time."""
    while True:
        q = rng.uniform(robot.lower, robot.upper)
        q[zero] = 0.0
        if all(abs(q[j]) > 0.1 for j in (1, 3, 5) if j != zero):
            return q


def _source_distance(branches: list[np.ndarray], q: np.ndarray) -> float:
    return min((_wrapped(b, q) for b in branches), default=math.inf)


def test_elbow_side_joint_held_returns_every_branch(iiwa: Robot) -> None:
    """Joint 3 held: 500 random in-limit configurations come back among the branches."""
    rng = np.random.default_rng(14)
    name = iiwa.joint_names[2]
    counts = []
    for q in rng.uniform(iiwa.lower, iiwa.upper, (500, 7)):
        target = iiwa.fk(q)
        branches = analytic_ik(iiwa, target, free_joint=name, free_value=q[2])
        _check(iiwa, target, branches, 2, q[2])
        assert _source_distance(branches, q) < SOURCE_TOL, q
        counts.append(len(branches))
    # Up to two elbows x two shoulders x two wrists; most in-limit poses keep all eight.
    assert max(counts) == 8 and min(counts) >= 1


@pytest.mark.parametrize("k", [0, 4, 6])
def test_other_held_joints(iiwa: Robot, k: int) -> None:
    """Joint 1 held (direct form), joints 5 and 7 held (the chain read backwards)."""
    rng = np.random.default_rng(k)
    name = iiwa.joint_names[k]
    for q in rng.uniform(iiwa.lower, iiwa.upper, (150, 7)):
        target = iiwa.fk(q)
        branches = analytic_ik(iiwa, target, free_joint=name, free_value=q[k])
        _check(iiwa, target, branches, k, q[k])
        assert _source_distance(branches, q) < SOURCE_TOL, q


def test_branches_sorted_by_distance_to_q_ref(iiwa: Robot) -> None:
    rng = np.random.default_rng(3)
    q = rng.uniform(iiwa.lower, iiwa.upper)
    ref = rng.uniform(iiwa.lower, iiwa.upper)
    name = iiwa.joint_names[2]
    branches = analytic_ik(iiwa, iiwa.fk(q), q_ref=ref, free_joint=name, free_value=q[2])
    ref_held = ref.copy()
    ref_held[2] = q[2]
    distances = [float(np.linalg.norm(b - ref_held)) for b in branches]
    assert len(branches) > 1 and distances == sorted(distances)


# ---------------------------------------------------------------------- singular poses
@pytest.mark.parametrize("k", [2, 0, 6])
def test_shoulder_singularity(iiwa: Robot, k: int) -> None:
    """q2 = 0 (axes 1 and 3 aligned): the source is found, any reference gives branches."""
    rng = np.random.default_rng(20 + k)
    name = iiwa.joint_names[k]
    for _ in range(40):
        q = _singular_sample(iiwa, rng, 1)
        target = iiwa.fk(q)
        branches = analytic_ik(iiwa, target, q_ref=q, free_joint=name, free_value=q[k])
        _check(iiwa, target, branches, k, q[k])
        assert _source_distance(branches, q) < SOURCE_TOL
        ref = rng.uniform(iiwa.lower, iiwa.upper)
        others = analytic_ik(iiwa, target, q_ref=ref, free_joint=name, free_value=q[k])
        assert others
        _check(iiwa, target, others, k, q[k])


@pytest.mark.parametrize("k", [2, 0, 4, 6])
def test_wrist_singularity_free_angle_takes_the_reference(iiwa: Robot, k: int) -> None:
    """q6 = 0 (axes 5 and 7 aligned): only q5 + q7 is defined; q5 takes the reference."""
    rng = np.random.default_rng(30 + k)
    name = iiwa.joint_names[k]
    for _ in range(40):
        q = _singular_sample(iiwa, rng, 5)
        target = iiwa.fk(q)
        branches = analytic_ik(iiwa, target, q_ref=q, free_joint=name, free_value=q[k])
        _check(iiwa, target, branches, k, q[k])
        assert _source_distance(branches, q) < SOURCE_TOL
        if k in (0, 2):  # the direct form: the wrist's first joint (q5) is the free one
            ref = q.copy()
            ref[4] = rng.uniform(-1.0, 1.0)
            moved = analytic_ik(iiwa, target, q_ref=ref, free_joint=name, free_value=q[k])
            _check(iiwa, target, moved, k, q[k])
            assert any(abs(b[4] - ref[4]) < SOURCE_TOL for b in moved)


@pytest.mark.parametrize("k", [2, 0, 4, 6])
def test_stretched_elbow_is_never_a_false_no_branch(iiwa: Robot, k: int) -> None:
    """q4 = 0: the elbow equation's double root (tangent), found despite rounding.

    The URDF's axes meet only to about 1e-12 m (angles written to 11 digits), and at a
    double root that moves the joints by its square root: the source is found to 1e-5.
    Holding joint 1 or 7, a stretched elbow also puts axes 3 and 5 on one line (q3 + q5
    alone is defined); that rounding then decides the split, so only the round trip and
    a non-empty answer are required there.
    """
    rng = np.random.default_rng(40 + k)
    name = iiwa.joint_names[k]
    for _ in range(40):
        q = _singular_sample(iiwa, rng, 3)
        target = iiwa.fk(q)
        branches = analytic_ik(iiwa, target, q_ref=q, free_joint=name, free_value=q[k])
        _check(iiwa, target, branches, k, q[k])
        if k in (2, 4):
            assert _source_distance(branches, q) < 1e-5
        ref = rng.uniform(iiwa.lower, iiwa.upper)
        others = analytic_ik(iiwa, target, q_ref=ref, free_joint=name, free_value=q[k])
        assert others
        _check(iiwa, target, others, k, q[k])


@pytest.mark.parametrize("k", [0, 4])
def test_every_singularity_at_once(iiwa: Robot, k: int) -> None:
    """q2 = q4 = q6 = 0 (a straight arm): free angles chosen so the branch stays in limits."""
    rng = np.random.default_rng(50 + k)
    name = iiwa.joint_names[k]
    for _ in range(40):
        q = rng.uniform(iiwa.lower, iiwa.upper)
        q[[1, 3, 5]] = 0.0
        target = iiwa.fk(q)
        ref = rng.uniform(iiwa.lower, iiwa.upper)
        branches = analytic_ik(iiwa, target, q_ref=ref, free_joint=name, free_value=q[k])
        assert branches
        _check(iiwa, target, branches, k, q[k])


# ---------------------------------------------------------------------- an independent reference
def test_numeric_solutions_with_the_joint_frozen_are_among_the_branches(iiwa: Robot) -> None:
    """``solve_ik(frozen=...)`` from random starts finds nothing the closed form lacks."""
    rng = np.random.default_rng(99)
    assert frozen_answers_among_branches(iiwa, iiwa.fk, 2, rng, _source_distance) >= 10


# ---------------------------------------------------------------------- bad input
def test_bad_free_joint_inputs(iiwa: Robot) -> None:
    target = iiwa.fk(np.full(7, 0.3))
    with pytest.raises(OptikError, match=r"free_joint must name a joint.*lbr_iiwa_joint_1"):
        analytic_ik(iiwa, target, free_joint="elbow", free_value=0.1)
    with pytest.raises(OptikError, match="free_value is required"):
        analytic_ik(iiwa, target, free_joint="lbr_iiwa_joint_3")
    with pytest.raises(OptikError, match="free_value is given without free_joint"):
        analytic_ik(iiwa, target, free_value=0.1)
    with pytest.raises(OptikError, match="outside the limits of joint 'lbr_iiwa_joint_3'"):
        analytic_ik(iiwa, target, free_joint="lbr_iiwa_joint_3", free_value=3.0)
    with pytest.raises(OptikError, match="free_value"):
        analytic_ik(iiwa, target, free_joint="lbr_iiwa_joint_3", free_value=math.nan)
    with pytest.raises(AnalyticIKError, match="mode must be 'pose'"):
        analytic_ik(iiwa, target, mode="position", free_joint="lbr_iiwa_joint_3", free_value=0.1)


def test_held_elbow_has_no_closed_form_and_says_why(iiwa: Robot) -> None:
    target = iiwa.fk(np.full(7, 0.3))
    with pytest.raises(AnalyticIKError, match="does not change the distance"):
        analytic_ik(iiwa, target, free_joint="lbr_iiwa_joint_4", free_value=0.1)
    # Joint 2 held at 0 puts axes 1 and 3 on one line: no meeting point to solve about.
    with pytest.raises(AnalyticIKError, match=r"are parallel.*at 0 rad"):
        analytic_ik(iiwa, target, free_joint="lbr_iiwa_joint_2", free_value=0.1)


def test_six_joint_robot_with_free_joint_is_declined() -> None:
    ur5 = load_problem(next(p for p in builtin_problems() if p.stem == "ur5")).robot
    target = ur5.fk(np.full(6, 0.3))
    with pytest.raises(AnalyticIKError, match="6 joints"):
        analytic_ik(ur5, target, free_joint=ur5.joint_names[0], free_value=0.3)


def test_unreachable_target_gives_no_branch(iiwa: Robot) -> None:
    target = np.eye(4)
    target[:3, 3] = (5.0, 0.0, 0.5)
    assert analytic_ik(iiwa, target, free_joint="lbr_iiwa_joint_3", free_value=0.2) == []


@pytest.mark.parametrize("held", [0, 2])
def test_a_held_arm_joint_leaves_the_newton_step_at_the_wrist_centre(
    tmp_path: Path, held: int
) -> None:
    """Holding joint 1 or 3 of an iiwa leaves three arm joints before the wrist (axes 5,
    6, 7 meet): a branch's Newton step is referred to the wrist centre, two 3 x 3
    solves. Here axis 6 is moved 3e-10 m off axis 5 (inside the geometry's tolerance:
    the closed form solves the ideal arm), so every branch misses by about that much and
    takes the step. The centre does not move with the wrist joints; away from the
    singularities (q2, q4, q6 at least 0.1 rad from 0) the branches equal those of the
    damped step (the centre NaN) and reach their poses to rounding. Nearer, the two
    steps part by what the conditioning allows (5.8e-5 rad at ``|q4| = 1e-4`` on the
    URDF's own iiwa, both within 5e-13 of the pose)."""
    from optik.analytic.free_joint import AT_WRIST, free_joint_plan, pack_free_params, solve

    text = IIWA_URDF.read_text()
    joint_6 = '<origin rpy="1.57079632679 0 0" xyz="0 0 0.2155"/>'
    assert text.count(joint_6) == 2  # joints 4 and 6: the second is joint 6's
    head, tail = text.rsplit(joint_6, 1)
    path = tmp_path / "iiwa.urdf"
    path.write_text(head + joint_6.replace('xyz="0 0', 'xyz="3e-10 0') + tail)
    iiwa = Robot.from_urdf(path, "lbr_iiwa_link_0", "lbr_iiwa_link_7")
    params = pack_free_params(iiwa, free_joint_plan(iiwa, held))
    centre = np.append(params[AT_WRIST : AT_WRIST + 3], 1.0)
    assert np.all(np.isfinite(centre))
    rng = np.random.default_rng(held)
    for q in rng.uniform(iiwa.lower, iiwa.upper, (10, 7)):
        moved = q.copy()
        moved[4:] = rng.uniform(iiwa.lower[4:], iiwa.upper[4:])
        np.testing.assert_allclose(iiwa.fk(moved) @ centre, iiwa.fk(q) @ centre, atol=1e-9)
    damped = params.copy()
    damped[AT_WRIST : AT_WRIST + 3] = np.nan
    ref = iiwa.mid_limits
    total = 0
    for q in rng.uniform(iiwa.lower, iiwa.upper, (200, 7)):
        if min(abs(q[1]), abs(q[3]), abs(q[5])) < 0.1:
            continue
        T = iiwa.fk(q)
        at_wrist, plain = np.empty((8, 7)), np.empty((8, 7))
        n = solve(params, T, ref, q[held], 0, at_wrist)
        assert solve(damped, T, ref, q[held], 0, plain) == n > 0
        np.testing.assert_allclose(at_wrist[:n], plain[:n], rtol=0.0, atol=1e-10)
        assert min(_wrapped(b, q) for b in at_wrist[:n]) < SOURCE_TOL
        for b in at_wrist[:n]:
            assert b[held] == q[held]
            assert np.max(np.abs(iiwa.fk(b) - T)) < 1e-14
        total += n
    assert total >= 400


def test_a_held_wrist_joint_keeps_the_damped_step(iiwa: Robot) -> None:
    # Holding joint 5 (or 7) leaves two wrist joints: no block structure, the damped
    # step (the same centre in the vector, unused: the branches equal the NaN's).
    from optik.analytic.free_joint import AT_WRIST, free_joint_plan, pack_free_params, solve

    params = pack_free_params(iiwa, free_joint_plan(iiwa, 4))
    damped = params.copy()
    damped[AT_WRIST : AT_WRIST + 3] = np.nan
    rng = np.random.default_rng(9)
    for q in rng.uniform(iiwa.lower, iiwa.upper, (20, 7)):
        T = iiwa.fk(q)
        a, b = np.empty((8, 7)), np.empty((8, 7))
        n = solve(params, T, iiwa.mid_limits, q[4], 0, a)
        assert solve(damped, T, iiwa.mid_limits, q[4], 0, b) == n > 0
        np.testing.assert_array_equal(a[:n], b[:n])


def _prefixes(robot: Robot, q: np.ndarray) -> np.ndarray:
    """The chain's prefix products (top three rows, row-major) as the Newton step reads
    them: ``pre[0] = K[0]``, ``pre[i + 1] = pre[i] Rz(q_i) K[i + 1]``, the pose last."""
    K = robot.chain.K
    pre = np.zeros((robot.dof + 2, 12))
    P = K[0].copy()
    pre[0] = P[:3].reshape(-1)
    for i, t in enumerate(q):
        c, s = math.cos(t), math.sin(t)
        P = P @ np.array([[c, -s, 0, 0], [s, c, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]) @ K[i + 1]
        pre[i + 1] = P[:3].reshape(-1)
    return pre


@pytest.mark.parametrize("held", [0, 2])
def test_the_wrist_centre_step_around_a_held_joint_is_the_newton_step(
    iiwa: Robot, held: int
) -> None:
    # The wrist-centre step itself (no damped fallback): it equals numpy's solve of the
    # Jacobian's six free columns for the pose residual, 1e-6 rad from the target.
    from optik.analytic._newton import RESIDUAL, _wrist_step, newton_work_size, pose_residual
    from optik.analytic.free_joint import AT_WRIST, FREE_LAYOUT, free_joint_plan, pack_free_params

    params = pack_free_params(iiwa, free_joint_plan(iiwa, held))
    free = [j for j in range(7) if j != held]
    rng = np.random.default_rng(4 + held)
    checked = 0
    for _ in range(40):
        q = rng.uniform(iiwa.lower, iiwa.upper)
        if min(abs(q[1]), abs(q[3]), abs(q[5])) < 0.1:
            continue  # away from the singularities, where the blocks are refused
        target = q.copy()
        target[free] += rng.uniform(-1e-6, 1e-6, 6)
        T = iiwa.fk(target)[None]
        pre = _prefixes(iiwa, q)
        work = np.zeros(newton_work_size(7))
        pose_residual(pre, 7, T, 0, work)
        step = RESIDUAL + 6 + 7
        assert _wrist_step(
            params, FREE_LAYOUT[0], FREE_LAYOUT[1], 7, held, AT_WRIST, pre, work, step, 1e-4
        )
        expected = np.linalg.solve(iiwa.jacobian(q)[:, free], work[RESIDUAL : RESIDUAL + 6])
        assert work[step + held] == 0.0
        np.testing.assert_allclose(work[step : step + 7][free], expected, rtol=0.0, atol=1e-15)
        checked += 1
    assert checked >= 15
