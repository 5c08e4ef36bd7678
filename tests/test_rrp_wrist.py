"""The RRP arm with a spherical wrist found from the joint axes: URDF and modified DH."""

from __future__ import annotations

import json
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
from scipy.spatial.transform import Rotation

from optik import Robot, analytic_ik, load_problem, solve_ik
from optik.analytic import FAMILIES, family_of
from optik.errors import AnalyticIKError

WRIST = FAMILIES["rrp_wrist"]
PROBLEMS = ("stanford_arm", "jumbo_drill_6dof")


def _origin(T: np.ndarray) -> str:
    xyz = " ".join(repr(float(v)) for v in T[:3, 3])
    rpy = " ".join(repr(float(v)) for v in Rotation.from_matrix(T[:3, :3]).as_euler("xyz"))
    return f"<origin xyz='{xyz}' rpy='{rpy}'/>"


def _dh(theta: float, d: float, a: float, alpha: float) -> np.ndarray:
    c, s, ca, sa = math.cos(theta), math.sin(theta), math.cos(alpha), math.sin(alpha)
    return np.array(
        [[c, -s * ca, s * sa, a * c], [s, c * ca, -c * sa, a * s], [0, sa, ca, d], [0, 0, 0, 1.0]]
    )


def _random_urdf(
    tmp_path: Path, problem: str, seed: int, wrist_offset: float = 0.0
) -> tuple[Path, Robot]:
    """A built-in DH arm as a URDF with random link frames: link ``i``'s frame is the DH
    frame after joint ``i``'s motion times a random rigid ``G_i`` (origin on the joint's
    axis), so each axis is a random direction in its frame and the prismatic joint slides
    along its own. ``wrist_offset`` (m) shifts axis 6 sideways, off the wrist centre."""
    dh = load_problem(problem).robot
    assert dh.dh is not None
    rng = np.random.default_rng(seed)
    links = ["<link name='l0'/>"]
    joints = []
    G_prev, X_prev = np.eye(4), dh.T_world_base
    for i, r in enumerate(dh.dh):
        G = np.eye(4)
        G[:3, :3] = Rotation.random(random_state=rng).as_matrix()
        G[2, 3] = rng.uniform(-0.2, 0.2)
        shift = np.eye(4)
        if i == 5:
            shift[0, 3] = wrist_offset
        origin = np.linalg.inv(G_prev) @ X_prev @ shift @ _dh(r.theta, 0.0, 0.0, 0.0) @ G
        axis = " ".join(repr(float(v)) for v in G[:3, :3].T @ np.array([0.0, 0.0, 1.0]))
        kind = "prismatic" if r.kind == "prismatic" else "revolute"
        joints.append(
            f"<joint name='j{i + 1}' type='{kind}'><parent link='l{i}'/>"
            f"<child link='l{i + 1}'/>{_origin(origin)}<axis xyz='{axis}'/>"
            f"<limit lower='{float(dh.lower[i])!r}' upper='{float(dh.upper[i])!r}' "
            "effort='1' velocity='1'/>"
            "</joint>"
        )
        links.append(f"<link name='l{i + 1}'/>")
        G_prev = G
        X_prev = _dh(0.0, r.d, r.a, r.alpha)
    tip = np.linalg.inv(G_prev) @ X_prev @ dh.T_flange_tool
    joints.append(
        f"<joint name='tip' type='fixed'><parent link='l6'/><child link='tip'/>{_origin(tip)}"
        "</joint>"
    )
    links.append("<link name='tip'/>")
    path = tmp_path / f"{problem}.urdf"
    path.write_text(f"<robot name='{problem}_urdf'>{''.join(links + joints)}</robot>", "utf-8")
    return path, dh


@pytest.mark.parametrize("problem", PROBLEMS)
def test_urdf_arm_gets_the_branches_of_the_dh_family(tmp_path: Path, problem: str) -> None:
    """Against the compiled ``spherical_wrist`` family on the same arm's DH rows: the same
    branches, pose by pose."""
    path, dh = _random_urdf(tmp_path, problem, seed=1)
    robot = Robot.from_urdf(path, "l0", "tip")
    q = dh.mid_limits + 0.1
    assert np.allclose(robot.fk(q), dh.fk(q), atol=1e-12)
    assert family_of(dh) is FAMILIES["spherical_wrist"]
    assert family_of(robot) is WRIST
    rng = np.random.default_rng(2)
    for q in rng.uniform(dh.lower, dh.upper, (100, 6)):
        T = dh.fk(q)
        reference = analytic_ik(dh, T, within_limits=False)
        ours = analytic_ik(robot, T, within_limits=False)
        assert len(ours) == len(reference) >= 1
        for b in ours:
            assert min(joint_distance(robot, b, r) for r in reference) < 1e-9
    assert_closed_form_round_trips(robot, WRIST, 100, seed=3, most={"pose": 8})
    _check_raw_branches_reach_the_pose(robot, 100, seed=8)
    q = dh.mid_limits + 0.2
    res = solve_ik(robot, robot.fk(q), solver="auto")
    assert res.success and res.solver == "analytic"


def _check_raw_branches_reach_the_pose(robot: Robot, n: int, seed: int) -> None:
    """The closed form itself, before wrap, filter or polish: every raw branch reaches the
    whole pose (the helper of conftest checks positions only)."""
    rng = np.random.default_rng(seed)
    for q in rng.uniform(robot.lower, robot.upper, (n, 6)):
        T = robot.fk(q)
        T_0 = np.linalg.inv(robot.T_world_base) @ T @ np.linalg.inv(robot.T_flange_tool)
        raw = WRIST.candidates(robot, T_0, "pose", robot.mid_limits)
        assert len(raw) in (2, 4, 6, 8)
        for b in raw:
            assert np.max(np.abs(robot.fk(b) - T)) < 1e-10, (q, b)


def test_modified_dh_stanford_arm_fits() -> None:
    dh = load_problem("stanford_arm").robot
    mdh = as_modified_dh(dh)
    q = dh.mid_limits + 0.3
    assert np.allclose(mdh.fk(q), dh.fk(q), atol=1e-12)
    assert family_of(mdh) is WRIST
    assert_closed_form_round_trips(mdh, WRIST, 100, seed=4, most={"pose": 8})
    _check_raw_branches_reach_the_pose(mdh, 100, seed=9)


def test_axis_off_the_wrist_centre_is_declined_with_the_distance(tmp_path: Path) -> None:
    path, _ = _random_urdf(tmp_path, "stanford_arm", seed=5, wrist_offset=0.01)
    robot = Robot.from_urdf(path, "l0", "tip")
    assert WRIST.explain(robot) == "axis 6 misses the wrist centre by 0.01 m"
    with pytest.raises(AnalyticIKError, match="misses the wrist centre"):
        Robot.from_urdf(path, "l0", "tip", analytic="rrp_wrist")


def test_other_joint_kinds_are_declined() -> None:
    puma = load_problem("puma560").robot
    assert WRIST.explain(puma) == "joints RRRRRR: the family takes RRPRRR"
    assert WRIST.explain(load_problem("panda").robot) == "7 joints (the family takes 6)"


def test_batch_equals_single_calls(tmp_path: Path) -> None:
    path, dh = _random_urdf(tmp_path, "jumbo_drill_6dof", seed=6)
    robot = Robot.from_urdf(path, "l0", "tip")
    rng = np.random.default_rng(7)
    assert_batch_equals_single(robot, robot.fk(rng.uniform(dh.lower, dh.upper, (40, 6))), "pose")


def test_random_rrp_arms_with_any_spherical_wrist_reach_every_pose() -> None:
    """Random DH arms: an RRP arm, then three wrist axes through one point at any twists
    (which the DH family's right angles do not take): each fits, each pose gets its
    branch, and every raw branch reaches the whole pose."""
    rng = np.random.default_rng(6)
    for _ in range(8):
        twist = [float(rng.uniform(0.2, 2.9) * rng.choice([-1, 1])) for _ in range(3)]
        rows = [
            {"a": rng.uniform(-0.5, 0.5), "alpha": twist[0], "d": rng.uniform(-0.5, 0.5),
             "theta": rng.uniform(-3, 3), "role": "arm"},
            {"a": rng.uniform(-0.5, 0.5), "alpha": rng.choice([-1, 1]) * math.pi / 2,
             "d": rng.uniform(-0.5, 0.5), "theta": rng.uniform(-3, 3), "role": "arm"},
            {"kind": "prismatic", "alpha": twist[1], "theta": rng.uniform(-3, 3),
             "lower": 0.1, "upper": 2.0},
            {"alpha": twist[2], "theta": rng.uniform(-3, 3), "role": "wrist"},
            {"alpha": rng.uniform(0.2, 2.9), "theta": rng.uniform(-3, 3), "role": "wrist"},
            {"a": rng.uniform(-0.1, 0.1), "alpha": rng.uniform(-3, 3),
             "d": rng.uniform(0, 0.2), "theta": rng.uniform(-3, 3), "role": "wrist"},
        ]  # fmt: skip
        robot = Robot.from_dh(rows)
        assert family_of(robot) is WRIST
        assert_closed_form_round_trips(robot, WRIST, 20, seed=7, most={"pose": 8})
        _check_raw_branches_reach_the_pose(robot, 20, seed=8)


def test_cli_names_the_family_and_solves_with_it(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """`optik robot` prints the family found from the axes; `optik solve` answers with it."""
    from optik.cli import main

    path, dh = _random_urdf(tmp_path, "stanford_arm", seed=1)
    assert main(["robot", str(path)]) == 0
    assert capsys.readouterr().out.rstrip().endswith("closed-form family: rrp_wrist")
    q = dh.mid_limits + 0.2
    T = dh.fk(q)
    rpy = Rotation.from_matrix(T[:3, :3]).as_euler("xyz")
    argv = ["solve", "--urdf", str(path), "--base", "l0", "--tip", "tip", "--position"]
    argv += [repr(float(v)) for v in T[:3, 3]] + ["--rpy"] + [repr(float(v)) for v in rpy]
    assert main([*argv, "--json"]) == 0
    result = json.loads(capsys.readouterr().out)
    assert result["solver"] == "analytic" and result["success"]
    assert joint_distance(dh, np.array(result["q"]), q) < 1e-6
