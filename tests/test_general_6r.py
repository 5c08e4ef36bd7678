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
        assert "singular for this geometry" in general_plan(robot).reason


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
