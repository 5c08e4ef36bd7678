"""The ``three_parallel`` family: three parallel axes, any other twists.

Inner: axes 2, 3 and 4 (or 3, 4 and 5) parallel; outer: axes 1, 2 and 3 parallel with axes
5 and 6 meeting (or the same read backwards).

Arms written as URDF text from joint axes and offsets (EAIK's ``H``, ``P`` form), with
random directions, so that no DH family fits. References independent of the closed form:
EAIK on the same ``H``, ``P`` (its class, and its distinct branches that reach the pose),
a product-of-exponentials FK written here with scipy's rotations, and the configuration
each pose came from.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from conftest import (
    assert_batch_equals_single,
    assert_closed_form_round_trips,
    axes_urdf_robot,
    poe_fk,
)
from eaik.IK_HP import HPRobot
from scipy.spatial.transform import Rotation

from optik import load_problem, solve_ik
from optik.analytic import analytic_ik, family_of
from optik.analytic.spherical_axes import THREE_INNER, THREE_OUTER, parallel_plan


def _arm(
    seed: int, first: int, sense: float = 1.0, meet: int | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Random ``H`` (6, 3) and ``P`` (7, 3): axes ``first .. first + 2`` (0-based) parallel,
    the middle one written with ``sense``; axes ``meet`` and ``meet + 1`` meeting."""
    rng = np.random.default_rng(seed)
    H = rng.normal(size=(6, 3))
    H /= np.linalg.norm(H, axis=1, keepdims=True)
    H[first + 1] = sense * H[first]
    H[first + 2] = H[first]
    P = rng.normal(size=(7, 3)) * 0.3
    if meet is not None:
        P[meet + 1] = 0.0  # the next axis starts at this one's point
    return H, P


def _wrapped(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.max(np.abs(np.remainder(a - b + math.pi, 2 * math.pi) - math.pi)))


ARMS = {
    "inner": (1, 1, None, THREE_INNER, False, "6R-THREE_INNER_PARALLEL"),
    "inner, other geometry": (2, 1, None, THREE_INNER, False, "6R-THREE_INNER_PARALLEL"),
    "inner 3-5": (3, 2, None, THREE_INNER, True, "6R-THREE_INNER_PARALLEL"),
    "inner 3-5, other geometry": (4, 2, None, THREE_INNER, True, "6R-THREE_INNER_PARALLEL"),
    "outer": (11, 0, 4, THREE_OUTER, False, "6R-THREE_PARALLEL_TWO_INTERSECTING"),
    "outer 4-6": (12, 3, 0, THREE_OUTER, True, "6R-THREE_PARALLEL_TWO_INTERSECTING"),
}
"""seed, first parallel axis (0-based), meeting pair's first axis, kind, read backwards,
EAIK's class."""


@pytest.mark.parametrize("arm", sorted(ARMS))
def test_every_branch_of_eaik_and_the_source(arm: str, tmp_path: Path) -> None:
    """100 random poses: EAIK's class, the same number of branches as EAIK's that reach the
    pose, each within 1e-9 of one of them (1e-7 where EAIK's misses its pose by more than
    1e-13), each within 1e-10 of its pose by the FK written here, the source among them.
    Axes 3, 4, 5 (or 4, 5, 6) parallel are solved read backwards."""
    seed, first, meet, kind, reverse, eaik_class = ARMS[arm]
    H, P = _arm(seed, first, meet=meet)
    robot = axes_urdf_robot(H, P, tmp_path / "arm.urdf")
    family = family_of(robot)
    assert family is not None and family.name == "three_parallel"
    plan = parallel_plan(robot)
    assert (plan.kind, plan.reverse) == (kind, reverse)
    eaik = HPRobot(H, P)
    assert eaik.getKinematicFamily() == eaik_class
    rng = np.random.default_rng(seed)
    counts = []
    for q in rng.uniform(-math.pi, math.pi, (100, 6)):
        T = poe_fk(H, P, q)
        branches = analytic_ik(robot, T, within_limits=False)
        for b in branches:
            assert np.abs(poe_fk(H, P, b) - T).max() < 1e-10
        assert min(_wrapped(b, q) for b in branches) < 1e-8, q
        reaching: list[np.ndarray] = []
        for x in map(np.asarray, eaik.IK(T).Q):
            if np.abs(poe_fk(H, P, x) - T).max() < 1e-8 and all(
                _wrapped(x, r) > 1e-6 for r in reaching
            ):
                reaching.append(x)
        assert len(branches) == len(reaching), q
        for b in branches:
            distance, r = min((_wrapped(b, r), i) for i, r in enumerate(reaching))
            # Near a singularity EAIK's own branch misses the pose (5e-13 to 1e-11, ours
            # 1e-15), which moves its angles by up to a few 1e-9: then 1e-7.
            eaik_miss = np.abs(poe_fk(H, P, reaching[r]) - T).max()
            assert distance < (1e-9 if eaik_miss < 1e-13 else 1e-7), q
        counts.append(len(branches))
    assert max(counts) >= 4  # more than one root of the quartic


def test_an_axis_written_the_other_way(tmp_path: Path) -> None:
    """Axis 3 written opposite to axes 2 and 4 (EAIK finds no branch there): every pose
    still gets branches that reach it, the source among them."""
    H, P = _arm(5, 1, sense=-1.0)
    robot = axes_urdf_robot(H, P, tmp_path / "arm.urdf")
    assert family_of(robot) is not None and family_of(robot).name == "three_parallel"
    rng = np.random.default_rng(5)
    for q in rng.uniform(-math.pi, math.pi, (100, 6)):
        T = poe_fk(H, P, q)
        branches = analytic_ik(robot, T, within_limits=False)
        for b in branches:
            assert np.abs(poe_fk(H, P, b) - T).max() < 1e-10
        assert min(_wrapped(b, q) for b in branches) < 1e-8, q


@pytest.mark.parametrize(("first", "meet"), [(1, None), (0, 4), (3, 0)])
def test_round_trips_batches_and_solve_ik(first: int, meet: int | None, tmp_path: Path) -> None:
    """In-limit poses: the shared round-trip check (raw closed form included), batches equal
    single calls, and ``solve_ik`` answers with the closed form."""
    H, P = _arm(6, first, meet=meet)
    robot = axes_urdf_robot(H, P, tmp_path / "arm.urdf")
    family = family_of(robot)
    assert family is not None
    assert_closed_form_round_trips(robot, family, 40, seed=6, most={"pose": 8})
    rng = np.random.default_rng(7)
    Q = rng.uniform(robot.lower, robot.upper, (30, 6))
    assert_batch_equals_single(robot, np.stack([robot.fk(q) for q in Q]), "pose")
    result = solve_ik(robot, robot.fk(Q[0]))
    assert result.success and result.solver == "analytic"
    assert np.abs(robot.fk(result.q) - robot.fk(Q[0])).max() < 1e-9


def test_the_ur_keeps_its_family_and_what_does_not_fit_says_why(tmp_path: Path) -> None:
    """The UR5's right angles keep ``ur`` (detected first); four parallel axes, or axes 2
    and 3 on one line, do not fit, with the reason, in order and read backwards."""
    ur5 = load_problem("ur5").robot
    assert family_of(ur5) is not None and family_of(ur5).name == "ur"
    assert parallel_plan(ur5).kind == THREE_INNER
    H, P = _arm(8, 1)
    H[0] = H[1]
    reason = parallel_plan(axes_urdf_robot(H, P, tmp_path / "four.urdf")).reason
    assert reason.startswith("axis 1 (j1) is parallel to axes 2-4 too; read backwards")
    assert "as outer axes" in reason
    H, P = _arm(9, 1)
    P[2] = H[1] * 0.2  # axis 3 on axis 2's line
    reason = parallel_plan(axes_urdf_robot(H, P, tmp_path / "line.urdf")).reason
    assert reason.startswith("axes 2 (j2) and 3 (j3) are one line")
    H, P = _arm(10, 0)  # axes 1-3 parallel, but axes 5 and 6 do not meet
    reason = parallel_plan(axes_urdf_robot(H, P, tmp_path / "apart.urdf")).reason
    assert "as outer axes: axes 5 (j5) and 6 (j6) do not meet" in reason


@pytest.mark.parametrize(("first", "meet"), [(1, None), (2, None), (0, 4), (3, 0)])
def test_axes_parallel_only_to_the_tolerance(first: int, meet: int | None, tmp_path: Path) -> None:
    """The middle parallel axis tilted by 3e-10 rad (inside ANGLE_TOL, as a URDF angle
    written to ten digits): the closed form of the ideal arm (3e-10 off), then the Newton
    step on the robot's chain, gives branches within 1e-12 of their pose (by the FK written
    here), the source among them."""
    H, P = _arm(40 + first, first, meet=meet)
    tilt = Rotation.from_rotvec(3e-10 * np.array([0.6, -0.64, 0.48])).as_matrix()
    H[first + 1] = tilt @ H[first + 1]
    robot = axes_urdf_robot(H, P, tmp_path / "arm.urdf")
    assert family_of(robot) is not None and family_of(robot).name == "three_parallel"
    rng = np.random.default_rng(first)
    for q in rng.uniform(-math.pi, math.pi, (40, 6)):
        T = poe_fk(H, P, q)
        branches = analytic_ik(robot, T, within_limits=False)
        for b in branches:
            assert np.abs(poe_fk(H, P, b) - T).max() < 1e-12
        assert min(_wrapped(b, q) for b in branches) < 1e-6, q


def test_cli_names_the_family_and_solves_with_it(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """`optik robot` prints ``three_parallel`` for such a URDF; `optik solve` answers with
    the closed form, and the answer reaches the pose (FK written here)."""
    from optik.cli import main

    H, P = _arm(11, 0, meet=4)
    path = tmp_path / "arm.urdf"
    axes_urdf_robot(H, P, path)
    assert main(["robot", str(path)]) == 0
    assert capsys.readouterr().out.rstrip().endswith("closed-form family: three_parallel")
    q = np.array([0.3, -0.5, 1.0, 0.4, -0.8, 0.2])
    T = poe_fk(H, P, q)
    rpy = Rotation.from_matrix(T[:3, :3]).as_euler("xyz")
    argv = ["solve", "--urdf", str(path), "--base", "l0", "--tip", "l7", "--position"]
    argv += [repr(float(v)) for v in T[:3, 3]] + ["--rpy"] + [repr(float(v)) for v in rpy]
    assert main([*argv, "--json"]) == 0
    result = json.loads(capsys.readouterr().out)
    assert result["solver"] == "analytic" and result["success"]
    assert np.abs(poe_fk(H, P, np.array(result["q"])) - T).max() < 1e-9
