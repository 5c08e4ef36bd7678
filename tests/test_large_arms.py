"""Closed forms of very large arms: the FK check's position tolerance follows the arm's size.

An absolute 1e-9 m check sat below the rounding of a 1e7 m arm's forward kinematics: a
UR5 scaled to 1e8 m lost every branch of a pose made from an in-limit configuration, and
``solve_ik`` reported that pose ``unreachable`` (an unsound proof); a Puma at 1e7 m lost
every branch of half its poses.
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import scaled_dh

import optik
from optik.analytic import family_of
from optik.analytic._base import VERIFY_TOLERANCE, verify_position_tolerance

UR5_ROWS = (
    {"d": 0.089459, "alpha": np.pi / 2},
    {"a": -0.425},
    {"a": -0.39225},
    {"d": 0.10915, "alpha": np.pi / 2},
    {"d": 0.09465, "alpha": -np.pi / 2},
    {"d": 0.0823},
)


def _scaled(
    rows: tuple[dict[str, float], ...], scale: float, base: np.ndarray | None = None
) -> optik.Robot:
    return scaled_dh(rows, scale, 6.28, base)


def _wrapped_distance(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.max(np.abs((a - b + np.pi) % (2 * np.pi) - np.pi)))


def test_position_tolerance_is_relative_beyond_a_metre() -> None:
    ur5 = _scaled(UR5_ROWS, 1.0)
    assert 1.0 < ur5.reach_sphere[1] < 1.2  # a metre: the tolerance as before, 1e-9 m each
    assert verify_position_tolerance(ur5) == pytest.approx(
        VERIFY_TOLERANCE * ur5.reach_sphere[1], rel=1e-3
    )
    big = _scaled(UR5_ROWS, 1e8)
    _, radius = big.reach_sphere
    assert verify_position_tolerance(big) == pytest.approx(VERIFY_TOLERANCE * radius, rel=1e-3)
    # A small arm far from the world's origin: the coordinates' rounding, not its size.
    base = np.eye(4)
    base[:3, 3] = [1e7, 0.0, 0.0]
    far = _scaled(UR5_ROWS, 1.0, base)
    assert 1e-7 < verify_position_tolerance(far) < 1e-6  # 256 eps 1e7 m: 5.7e-7 m
    T = far.fk(np.full(6, 0.4))
    assert any(_wrapped_distance(b, np.full(6, 0.4)) < 1e-6 for b in optik.analytic_ik(far, T))


@pytest.mark.parametrize("scale", [1e6, 1e7, 1e8])
def test_huge_ur5_keeps_the_source_branch_and_solves(scale: float) -> None:
    robot = _scaled(UR5_ROWS, scale)
    assert family_of(robot).name == "ur"
    rng = np.random.default_rng(7)
    configurations = rng.uniform(-3.0, 3.0, (20, 6))
    targets = np.array([robot.fk(q) for q in configurations])
    batch = optik.analytic_ik_batch(robot, targets)
    for q, T, count in zip(configurations, targets, batch.counts, strict=True):
        branches = optik.analytic_ik(robot, T)
        assert len(branches) == count >= 1
        assert min(_wrapped_distance(b, q) for b in branches) < 1e-6
        for b in branches:  # each branch reaches the pose to 1e-9 of the arm's size
            error = np.linalg.norm(robot.fk(b)[:3, 3] - T[:3, 3])
            assert error <= verify_position_tolerance(robot)
    result = optik.solve_ik(robot, targets[0])
    assert result.status == "converged" and result.solver == "analytic"


def test_km_arm_with_nearly_meeting_wrist_keeps_every_branch() -> None:
    # A random 6R whose wrist axes miss by 3e-10 of its size (spherical_axes, refined by
    # Newton): at 1 km its raw branches sit 3.6e-7 m off, above an absolute 1e-9 m.
    rows = [
        (-0.09751774441727978, -3.0919307677016596, -0.3628701369335685, -0.23771001291661942),
        (-0.40346575691691977, 0.2782596557434469, -0.38061042234976084, -0.39121140684852973),
        (-0.1950237405567936, 2.580047174981912, -0.03244485827975163, -0.7724369660804027),
        (3e-10, 2.746795826010156, 0.213108186755273, -0.9904590549325452),
        (0.0, -1.8018330972739784, 0.0, 0.6448402885033688),
        (0.18394579754754636, -2.6585426912468964, -0.13114878293855448, -0.7466050124603627),
    ]
    q = np.array([0.6461566242950214, -0.6514056961334527, 2.784375640419581,
                  2.692677897146888, 1.0390351130918902, 0.842571947099771])  # fmt: skip
    counts = []
    for scale in (1.0, 1000.0):
        joints = [
            optik.DHJoint(a=a * scale, alpha=al, d=d * scale, theta=th, lower=-2.8, upper=2.8)
            for a, al, d, th in rows
        ]
        robot = optik.Robot.from_dh(joints)
        assert family_of(robot).name == "spherical_axes"
        branches = optik.analytic_ik(robot, robot.fk(q))
        assert min(_wrapped_distance(b, q) for b in branches) < 1e-6
        counts.append(len(branches))
    assert counts[0] == counts[1] == 4
