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
