"""The RRP family found from the joint axes: URDF, modified DH and DH arms."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from conftest import (
    as_modified_dh,
    assert_batch_equals_single,
    assert_closed_form_round_trips,
    joint_distance,
)

import optik
from optik import Robot, analytic_ik, load_problem, solve_ik
from optik.analytic import FAMILIES, family_of
from optik.errors import AnalyticIKError

RRP = FAMILIES["spherical_rrp"]


def _joint(name: str, kind: str, parent: str, child: str, origin: str, axis: str) -> str:
    lower, upper = (0.2, 1.5) if kind == "prismatic" else (-2.8, 2.8)
    return (
        f"<joint name='{name}' type='{kind}'><parent link='{parent}'/><child link='{child}'/>"
        f"{origin}<axis xyz='{axis}'/>"
        f"<limit lower='{lower}' upper='{upper}' effort='1' velocity='1'/></joint>"
    )


def _urdf(
    tmp_path: Path, slide_axis: str = "1 0 0", kinds: tuple[str, str] = ("revolute", "prismatic")
) -> Path:
    """An RRP arm: axis 2 turned 1.2 rad from axis 1 and off it (skew), the slide normal to
    axis 2 (its frame turned about axis 2 only) but not through it, a mount and a tool."""
    second, third = kinds
    text = (
        "<robot name='rrp_urdf'>"
        + "".join(f"<link name='{n}'/>" for n in ("world", "base", "l1", "l2", "l3", "tip"))
        + "<joint name='mount' type='fixed'><parent link='world'/><child link='base'/>"
        "<origin xyz='0.1 -0.2 0.05' rpy='0.2 -0.1 0.4'/></joint>"
        + _joint("swing", "revolute", "base", "l1", "<origin xyz='0 0 0.3'/>", "0 0 1")
        + _joint("lift", second, "l1", "l2", "<origin xyz='0.2 0.1 0.25' rpy='1.2 0 0'/>", "0 0 1")
        + _joint("boom", third, "l2", "l3", "<origin xyz='0.05 0 0.07' rpy='0 0 0.5'/>", slide_axis)
        + "<joint name='flange' type='fixed'><parent link='l3'/><child link='tip'/>"
        "<origin xyz='0.1 0.03 -0.02' rpy='0.3 0.2 0.1'/></joint>"
        "</robot>"
    )
    path = tmp_path / "rrp.urdf"
    path.write_text(text, encoding="utf-8")
    return path


def _check_round_trips(robot: Robot, n: int, seed: int) -> None:
    assert_closed_form_round_trips(robot, RRP, n, seed, {"pose": 1, "position": 4})


def test_urdf_arm_with_skew_axes_and_an_offset_slide(tmp_path: Path) -> None:
    robot = Robot.from_urdf(_urdf(tmp_path), "world", "tip")
    assert family_of(robot) is RRP
    _check_round_trips(robot, 200, seed=1)
    q = np.array([0.4, -0.9, 0.8])
    res = solve_ik(robot, robot.fk(q), solver="auto")
    assert res.success and res.solver == "analytic" and joint_distance(robot, res.q, q) < 1e-9
    # Position only: two first-joint angles, two slide positions each, with the limits off.
    found = analytic_ik(robot, robot.fk(q)[:3, 3], mode="position", within_limits=False)
    assert len(found) == 4


def test_jumbo_arm_equals_seed_000_formulas() -> None:
    """Seed 000's eq. 27, 33, 34 (position) and corrected eq. 35-42 (pose), computed here
    from a1 alone, against the family's branches."""
    robot = load_problem("jumbo_spherical_arm").robot
    assert robot.dh is not None
    a1 = robot.dh[0].a
    rng = np.random.default_rng(2)
    for q in rng.uniform(robot.lower, robot.upper, (100, 3)):
        T = robot.fk(q)
        px, py, pz = T[:3, 3]
        expected = []
        for t1 in (math.atan2(py, px), math.atan2(-py, -px)):  # eq. 27: atan2(-px, py) +- pi/2
            c1, s1 = math.cos(t1), math.sin(t1)
            for t2 in (
                math.atan2(-(c1 * px + s1 * py - a1), pz),
                math.atan2(c1 * px + s1 * py - a1, -pz),
            ):
                d3 = (a1 - c1 * px - s1 * py) * math.sin(t2) + pz * math.cos(t2)
                expected.append(np.array([t1, t2, d3]))
        got = analytic_ik(robot, T[:3, 3], mode="position", within_limits=False)
        assert len(got) == 4
        for e in expected:
            assert min(joint_distance(robot, g, e) for g in got) < 1e-9
        R = T[:3, :3]
        t1 = math.atan2(R[0, 2], -R[1, 2])
        t2 = math.atan2(R[2, 0], R[2, 1])
        d3 = (a1 - math.cos(t1) * px - math.sin(t1) * py) * math.sin(t2) + pz * math.cos(t2)
        (pose,) = analytic_ik(robot, T)
        assert joint_distance(robot, pose, np.array([t1, t2, d3])) < 1e-9


def test_modified_dh_jumbo_arm_fits() -> None:
    jumbo = load_problem("jumbo_spherical_arm").robot
    mdh = as_modified_dh(jumbo)
    q = np.array([0.3, -0.4, 3.0])
    assert np.allclose(mdh.fk(q), jumbo.fk(q), atol=1e-12)
    assert family_of(mdh) is RRP
    _check_round_trips(mdh, 100, seed=3)


@pytest.mark.parametrize(
    ("slide_axis", "kinds", "reason"),
    [
        (
            "0.6 0 0.8",
            ("revolute", "prismatic"),
            "the prismatic direction is 53.1301 deg off the normal of axis 2",
        ),
        ("1 0 0", ("revolute", "revolute"), "joints RRR: the family takes RRP"),
        ("1 0 0", ("prismatic", "revolute"), "joints RPR: the family takes RRP"),
    ],
)
def test_arms_without_the_structure_say_why(
    tmp_path: Path, slide_axis: str, kinds: tuple[str, str], reason: str
) -> None:
    robot = Robot.from_urdf(_urdf(tmp_path, slide_axis, kinds), "world", "tip")
    assert RRP.explain(robot) == reason
    assert family_of(robot) is None or family_of(robot) is not RRP
    with pytest.raises(AnalyticIKError, match="does not fit"):
        Robot.from_urdf(
            _urdf(tmp_path, slide_axis, kinds), "world", "tip", analytic="spherical_rrp"
        )


def test_parallel_first_axes_are_not_rrp() -> None:
    rows = [
        {"a": 0.3, "role": "arm"},
        {"a": 0.2, "alpha": math.pi / 2, "role": "arm"},
        {"kind": "prismatic", "lower": 0.0, "upper": 1.0},
    ]
    robot = Robot.from_dh(rows)
    assert "axes 1 and 2 are parallel" in (RRP.explain(robot) or "")


def test_batch_equals_single_calls(tmp_path: Path) -> None:
    robot = Robot.from_urdf(_urdf(tmp_path), "world", "tip")
    rng = np.random.default_rng(4)
    T = robot.fk(rng.uniform(robot.lower, robot.upper, (50, 3)))
    assert_batch_equals_single(robot, T, "pose")
    assert_batch_equals_single(robot, T[:, :3, 3], "position")


def test_off_reach_target_has_no_branch(tmp_path: Path) -> None:
    robot = Robot.from_urdf(_urdf(tmp_path), "world", "tip")
    T = robot.fk(np.array([0.4, -0.9, 0.8]))
    T[:3, 3] += 10.0
    assert analytic_ik(robot, T[:3, 3], mode="position") == []
    assert optik.solve_ik(robot, T, solver="auto").status == "unreachable"


def test_random_rrp_arms_reach_every_pose() -> None:
    """Random DH arms of the structure (any first twist, the slide normal to axis 2, any
    offsets and tool point): each fits, and each in-limit pose gets its branch."""
    rng = np.random.default_rng(5)
    for _ in range(10):
        rows = [
            {
                "a": rng.uniform(-0.5, 0.5),
                "alpha": rng.uniform(0.2, 2.9) * rng.choice([-1, 1]),
                "d": rng.uniform(-0.5, 0.5),
                "theta": rng.uniform(-3, 3),
                "role": "arm",
            },
            {
                "a": rng.uniform(-0.5, 0.5),
                "alpha": rng.choice([-1, 1]) * math.pi / 2,
                "d": rng.uniform(-0.5, 0.5),
                "theta": rng.uniform(-3, 3),
                "role": "arm",
            },
            {
                "kind": "prismatic",
                "a": rng.uniform(-0.3, 0.3),
                "alpha": rng.uniform(-3, 3),
                "theta": rng.uniform(-3, 3),
                "lower": 0.1,
                "upper": 2.0,
            },
        ]
        tool = np.eye(4)
        tool[:3, 3] = rng.uniform(-0.2, 0.2, 3)
        robot = Robot.from_dh(rows, tool=tool)
        assert family_of(robot) is RRP
        assert_closed_form_round_trips(robot, RRP, 20, seed=6, most={"pose": 1, "position": 4})
