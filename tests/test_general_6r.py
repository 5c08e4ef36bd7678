"""Any six revolute joints (``general_6r``): every branch, against an independent search.

The reference for completeness is scipy's ``least_squares`` on ``Robot.fk`` from many
random starts (it knows nothing of the elimination): the distinct answers it finds must
all be among the family's branches. Arms: random standard-DH arms (no decomposition
fits them) and pybullet's xArm6 from its URDF (an offset wrist; EAIK finds no family).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pybullet_data  # the test extra: its absence is a failure, not a skip
import pytest
from conftest import (
    SEED,
    assert_batch_equals_single,
    assert_closed_form_round_trips,
    joint_distance,
    random_q,
    robot_of,
)
from scipy.optimize import least_squares

import optik
from optik.analytic import FAMILIES, analytic_ik, explain_family, family_of
from optik.analytic.general_6r import general_plan
from optik.robot_text import robot_text

XARM6_URDF = Path(pybullet_data.getDataPath()) / "xarm" / "xarm6_robot.urdf"


def _random_arm(rng: np.random.Generator, name: str) -> optik.Robot:
    """Six revolute joints of random lengths, offsets and twists, limits +-pi."""
    rows = [
        {
            "a": float(rng.uniform(-0.5, 0.5)),
            "d": float(rng.uniform(-0.5, 0.5)),
            "alpha": float(rng.uniform(-math.pi, math.pi)),
            "theta": float(rng.uniform(-1.0, 1.0)),
            "lower": -math.pi,
            "upper": math.pi,
        }
        for _ in range(6)
    ]
    return optik.Robot.from_dh(rows, name=name)


def _xarm6() -> optik.Robot:
    return optik.Robot.from_urdf(XARM6_URDF, "world", "link6")


def _searched_answers(robot: optik.Robot, T: np.ndarray, starts: int, seed: int) -> list:
    """Distinct configurations (wrapped to (-pi, pi]) reaching ``T``, by scipy from
    ``starts`` random starts, the joint limits lifted (the reference of completeness)."""
    rng = np.random.default_rng(seed)

    def residual(q: np.ndarray) -> np.ndarray:
        F = robot.fk(q)
        return np.concatenate([F[:3, 3] - T[:3, 3], (F[:3, :3] - T[:3, :3]).ravel()])

    found: list[np.ndarray] = []
    for q0 in rng.uniform(-math.pi, math.pi, (starts, 6)):
        fit = least_squares(residual, q0, xtol=1e-15, ftol=1e-15, gtol=1e-15)
        if np.max(np.abs(fit.fun)) > 1e-10:
            continue
        q = np.arctan2(np.sin(fit.x), np.cos(fit.x))
        if all(joint_distance(robot, q, other) > 1e-6 for other in found):
            found.append(q)
    return found


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_a_random_arm_gets_every_branch_the_search_finds(seed: int) -> None:
    rng = np.random.default_rng(SEED + seed)
    robot = _random_arm(rng, f"random_{seed}")
    family = family_of(robot)
    assert family is not None and family.name == "general_6r"
    assert_closed_form_round_trips(robot, family, n=10, seed=SEED + seed, most={"pose": 16})
    for q in random_q(robot, rng, 2):
        T = robot.fk(q)
        branches = analytic_ik(robot, T, within_limits=False)
        searched = _searched_answers(robot, T, starts=60, seed=seed)
        assert len(searched) >= 2  # the search itself works
        for answer in searched:
            assert min(joint_distance(robot, answer, b) for b in branches) < 1e-6


def test_the_xarm6_from_its_urdf_gets_every_branch() -> None:
    robot = _xarm6()
    family = family_of(robot)
    assert family is not None and family.name == "general_6r"
    assert "general_6r: fits" in explain_family(robot)
    assert_closed_form_round_trips(robot, family, n=25, seed=SEED, most={"pose": 16})
    rng = np.random.default_rng(SEED)
    for q in random_q(robot, rng, 2):
        T = robot.fk(q)
        branches = analytic_ik(robot, T, within_limits=False)
        searched = _searched_answers(robot, T, starts=60, seed=SEED)
        assert len(searched) >= 2
        for answer in searched:
            assert min(joint_distance(robot, answer, b) for b in branches) < 1e-6
    assert_batch_equals_single(robot, robot.fk(random_q(robot, rng, 6)), "pose")


def test_solve_ik_all_answers_the_xarm6_with_the_closed_form() -> None:
    """``solve_ik_all`` takes every branch; ``solve_ik`` keeps its faster numeric solver."""
    robot = _xarm6()
    rng = np.random.default_rng(SEED + 7)
    for q in random_q(robot, rng, 5):
        T = robot.fk(q)
        answers = optik.solve_ik_all(robot, T, k=16, min_separation=1e-6)
        assert answers and all(a.success and a.solver == "analytic" for a in answers)
        assert len(answers) == len(analytic_ik(robot, T))
        result = optik.solve_ik(robot, T)
        assert result.success and result.solver == "dls"


def test_an_axis_path_does_not_search_the_roll_with_the_numerical_family(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """plan_path(mode="axis") on the xArm6 searched the free roll with general_6r (hundreds
    of 2 ms solves a waypoint: 47 s for 8 waypoints, tool axis x): the roll's search is
    for the fast families; here the numeric candidates plan it, each waypoint verified."""
    robot = _xarm6()

    def no_closed_form(*args: object, **kwargs: object) -> None:
        raise AssertionError("the roll's search called general_6r")

    monkeypatch.setattr(FAMILIES["general_6r"], "candidates", no_closed_form)
    rng = np.random.default_rng(3)
    qa = robot.lower + (robot.upper - robot.lower) * rng.uniform(0.3, 0.7, robot.dof)
    qb = qa + rng.uniform(-0.3, 0.3, robot.dof)
    poses = robot.fk(np.array([qa + t * (qb - qa) for t in np.linspace(0.0, 1.0, 8)]))
    plan = optik.plan_path(robot, poses, mode="axis", axis="x", max_joint_step=0.5)
    assert list(plan.status) == ["ok"] * 8
    for q, T in zip(plan.q, poses, strict=True):
        F = robot.fk(q)
        assert np.linalg.norm(F[:3, 3] - T[:3, 3]) <= 1e-6
        assert float(F[:3, 0] @ T[:3, 0]) >= math.cos(1e-6)


def test_an_empty_branch_set_of_the_numerical_family_proves_nothing() -> None:
    """Inside the reach sphere but unreachable: no branch, yet never 'unreachable'."""
    robot = _xarm6()
    assert not FAMILIES["general_6r"].proves_unreachable
    centre, radius = robot.reach_sphere
    # Straight up at 99.9 % of the sphere's radius with the base's orientation: past what
    # the arm reaches (its sphere is a bound, not its reach), but not provably so by the
    # sphere. solve_ik does not use the family (not fast); plan_path does.
    T = np.eye(4)
    T[:3, 3] = centre + np.array([0.0, 0.0, 0.999 * radius])
    assert analytic_ik(robot, T, within_limits=False) == []
    result = optik.solve_ik(robot, T, restarts=2)
    assert not result.success
    assert result.status not in ("unreachable", "outside_limits")
    plan = optik.plan_path(robot, T[None], restarts=1)
    assert plan.status == ["not_found"]


def test_arms_with_an_exact_family_keep_it() -> None:
    """The Puma and the UR5 keep their exact families; the elimination is singular on
    both (their right angles and meeting axes), and says so."""
    for name, expected in (("puma560", "spherical_wrist"), ("ur5", "ur")):
        robot = robot_of(name)
        family = family_of(robot)
        assert family is not None and family.name == expected
        assert "elimination is singular" in general_plan(robot).reason


def test_arms_that_are_not_six_revolute_joints_are_declined_with_the_reason() -> None:
    assert general_plan(robot_of("panda")).reason == "7 joints (the family takes 6)"
    assert "revolute" in general_plan(robot_of("stanford_arm")).reason


def test_the_robot_text_of_an_arm_without_a_family_says_why_per_family() -> None:
    rng = np.random.default_rng(SEED)
    rows = [
        {"a": 0.3, "alpha": float(rng.uniform(0.2, 1.3)), "d": 0.1, "lower": -3, "upper": 3}
        for _ in range(4)
    ]
    robot = optik.Robot.from_dh(rows, name="four")
    assert family_of(robot) is None
    lines = robot_text(robot).splitlines()
    at = lines.index("closed-form family: none (numeric solvers)")
    reasons = lines[at + 1 :]
    assert [line.split(":")[0].strip() for line in reasons] == list(FAMILIES)
    assert "  general_6r: 4 joints (the family takes 6)" in reasons


# A generic arm (rows: a, d, alpha, theta) that a hostile search used.
_GENERIC = [
    [0.5622351776349419, 0.21169405914193606, 1.3182197570030034, -2.581774207544016],
    [0.2614288317478086, 0.9616214044489055, -0.4812594956351335, -2.4353432518200897],
    [0.9165328907316848, 0.3519643698434136, -1.9025941524179673, 1.081080192573351],
    [0.9854832554731858, -0.5810290519870096, 2.2233666868154787, 1.2497933231800404],
    [-0.5566499448464297, -0.6304565354894776, 2.8535527917488874, -1.002560582135763],
    [-0.11721100196109302, 0.3121747034888076, -0.3750942015290488, -3.1399307260661273],
]


def _arm(rows: list[list[float]], scale: float = 1.0) -> optik.Robot:
    return optik.Robot.from_dh(
        [
            {"a": a * scale, "d": d * scale, "alpha": al, "theta": th, "lower": -3.2, "upper": 3.2}
            for a, d, al, th in rows
        ]
    )


@pytest.mark.parametrize("scale", [1e-7, 1e-6, 1e3])
def test_the_same_geometry_at_another_size_gives_the_same_branches(scale: float) -> None:
    """Lengths in units of the arm's largest: at 1e-7 m the family did not fit, at 1e-6
    and 1e5 poses lost their configuration (at 1e5 m the absolute 1e-9 m FK check is at
    double precision itself: not tested)."""
    unit, scaled = _arm(_GENERIC), _arm(_GENERIC, scale)
    family = family_of(scaled)
    assert family is not None and family.name == "general_6r"
    rng = np.random.default_rng(SEED)
    for q in rng.uniform(-3.0, 3.0, (40, 6)):
        branches = analytic_ik(scaled, scaled.fk(q), within_limits=False)
        assert min(joint_distance(scaled, b, q) for b in branches) < 1e-6
        assert len(branches) == len(analytic_ik(unit, unit.fk(q), within_limits=False))


def test_a_singular_pose_of_a_generic_arm_keeps_its_configuration() -> None:
    """A double root of the pencil came out as a complex pair beyond the old tolerance
    (1e-6), and two Newton steps could not restore a kept one: no branch at all."""
    rows = [
        [0.5642275793748557, -0.12811278174034646, -0.06181227492980179, 2.1477303690912954],
        [0.6133111364855854, 0.4008020716633107, 0.22907760837750413, 1.2484192482408591],
        [-0.861049504334817, 0.6221388828061645, -2.925308063202994, -2.192055567137361],
        [-0.8336610380879239, 0.013245346297940719, 1.0658726624150177, 0.05819184179407033],
        [-0.28926504123434205, -0.4265788183305923, 2.624331489544465, 1.0779610798261352],
        [0.5663669748681226, 0.10518645337181654, 0.9816724827473138, 2.009018155378345],
    ]
    robot = _arm(rows)
    q = np.array(
        [
            2.0693827738997,
            1.3364588549271617,
            -2.8563019028318286,
            -1.18460076668208,
            2.71148946735892,
            -1.97138642556145,
        ]
    )
    assert np.linalg.svd(robot.jacobian(q), compute_uv=False)[-1] < 1e-6  # singular
    branches = analytic_ik(robot, robot.fk(q))
    assert branches
    for b in branches:
        assert np.max(np.abs(robot.fk(b) - robot.fk(q))) < 1e-9


def test_branches_at_singular_poses_are_distinct() -> None:
    """At a singular pose two roots of the pencil merge: the answers keep one of them.

    Random arms, each pose with one joint moved to where the Jacobian's smallest singular
    value vanishes; every pair of answers differs by at least the closed forms' duplicate
    tolerance, 1e-9 (without the de-duplication these arms give pairs closer than that).
    """
    rng = np.random.default_rng(1)

    def smallest_singular_value(robot: optik.Robot, q: np.ndarray) -> float:
        return float(np.linalg.svd(robot.jacobian(q), compute_uv=False)[-1])

    arms = [
        _arm([
            [rng.uniform(-0.5, 0.5), rng.uniform(-0.5, 0.5), rng.uniform(-math.pi, math.pi),
             rng.uniform(-1.0, 1.0)]
            for _ in range(6)
        ])
        for _ in range(2)
    ]  # fmt: skip
    rng.uniform(-3.0, 3.0, (12, 6))  # the draws of the search that found these poses
    checked = 0
    for robot in arms:
        assert family_of(robot) is FAMILIES["general_6r"]
        for k in range(12):
            q = rng.uniform(-3.0, 3.0, 6)
            j = k % 6

            def smallest(
                x: np.ndarray, robot: optik.Robot = robot, q: np.ndarray = q, j: int = j
            ) -> list[float]:
                return [smallest_singular_value(robot, np.r_[q[:j], x, q[j + 1 :]])]

            q[j] = least_squares(smallest, [q[j]], xtol=1e-15, ftol=1e-15, gtol=1e-15).x[0]
            branches = np.array(analytic_ik(robot, robot.fk(q), within_limits=False))
            assert len(branches) >= 1
            for a in range(len(branches)):
                for b in range(a):
                    assert np.max(np.abs(branches[a] - branches[b])) >= 1e-9  # documented
            checked += len(branches)
    assert checked >= 90
