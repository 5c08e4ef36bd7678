"""The ``spherical_axes`` family: three axes through one point and an arm of subproblems.

Arms the DH families do not take (twists other than 0 and +-90 deg, offsets anywhere,
the spherical joint first or last), built from DH rows, from modified DH rows and from
URDF text. References independent of the closed form: EAIK's solver on the same axes (its
kinematic class and its exact branches), forward kinematics written out here (numpy DH
products, scipy's rotation angle), the configuration each pose came from, and the
numeric solver.
"""

from __future__ import annotations

import math
import os
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
from conftest import newton_reference
from eaik.IK_HP import HPRobot
from scipy.spatial.transform import Rotation

from optik import Robot, load_problem, solve_ik
from optik.analytic import _finish, analytic_ik, analytic_ik_batch, family_of
from optik.analytic.geometry import joint_axes
from optik.analytic.parallel_arm import PARALLEL_12, PARALLEL_23
from optik.analytic.spherical_axes import (
    GENERAL,
    INTERSECTING,
    SECOND_PAIR,
    axes_plan,
    kind_pipeline,
    pack_axes_params,
)
from optik.errors import AnalyticIKError, OptikError
from optik.problems import builtin_problems

FK_TOL = 1e-10
LIMITS = np.array([[-2.5, 2.5], [-2.0, 2.0], [-2.8, 2.8], [-3.0, 3.0], [-2.0, 2.0], [-3.0, 3.0]])
"""Limits narrower than a turn (rad), so that the limit filter and the wrapping act."""
SOURCE_TOL = 1e-8
WRIST = [(0.0, -90.0, 0.45, 0.0), (0.0, 90.0, 0.0, 0.3), (0.0, 0.0, 0.1, 0.0)]
"""A spherical wrist: standard DH rows (a, alpha deg, d, theta) of joints 4 to 6."""
ARMS = {
    "second two parallel": (
        [(0.1, 60.0, 0.4, 0.2), (0.5, 0.0, 0.1, 0.1), (0.05, 75.0, 0.0, -0.3), *WRIST],
        PARALLEL_23,
        False,
        "6R-SPHERICAL_SECOND_TWO_PARALLEL",
    ),
    "first two parallel": (
        [(0.4, 0.0, 0.3, 0.2), (0.3, 70.0, 0.1, 0.0), (0.05, 80.0, 0.0, 0.4), *WRIST],
        PARALLEL_12,
        False,
        "6R-SPHERICAL_FIRST_TWO_PARALLEL",
    ),
    "first two intersecting": (
        [(0.0, 70.0, 0.3, 0.1), (0.4, 50.0, 0.05, 0.2), (0.05, 80.0, 0.0, 0.0), *WRIST],
        INTERSECTING,
        False,
        "6R-SPHERICAL_FIRST_TWO_INTERSECTING",
    ),
    "general arm": (
        [(0.1, 60.0, 0.4, 0.2), (0.5, 40.0, 0.1, 0.1), (0.05, 75.0, 0.0, -0.3), *WRIST],
        GENERAL,
        False,
        "6R-SPHERICAL_NO_PARALLEL_NO_INTERSECTING",
    ),
    "second two intersecting": (
        [(0.1, 60.0, 0.4, 0.2), (0.0, 40.0, 0.1, 0.1), (0.05, 75.0, 0.0, -0.3), *WRIST],
        SECOND_PAIR,
        False,
        "6R-SPHERICAL_SECOND_TWO_INTERSECTING",
    ),
    "spherical shoulder, general arm": (
        [
            (0.0, 90.0, 0.3, 0.0),
            (0.0, -90.0, 0.0, 0.2),
            (0.3, 70.0, 0.4, 0.1),
            (0.4, 35.0, 0.1, 0.3),
            (0.2, 50.0, 0.05, 0.0),
            (0.0, 0.0, 0.1, 0.0),
        ],
        GENERAL,
        True,
        "6R-SPHERICAL_NO_PARALLEL_NO_INTERSECTING",
    ),
    "spherical shoulder": (
        [
            (0.0, 90.0, 0.3, 0.0),
            (0.0, -90.0, 0.0, 0.2),
            (0.3, 70.0, 0.4, 0.1),
            (0.4, 0.0, 0.1, 0.3),
            (0.2, 50.0, 0.05, 0.0),
            (0.0, 0.0, 0.1, 0.0),
        ],
        PARALLEL_23,
        True,
        "6R-SPHERICAL_SECOND_TWO_PARALLEL",
    ),
}


def _rows(spec: list[tuple[float, float, float, float]]) -> list[dict[str, object]]:
    return [
        {
            "a": a,
            "alpha": math.radians(al),
            "d": d,
            "theta": th,
            "name": f"j{i + 1}",
            "lower": -math.pi,
            "upper": math.pi,
        }
        for i, (a, al, d, th) in enumerate(spec)
    ]


def _dh(a: float, alpha: float, d: float, theta: float) -> np.ndarray:
    """``Rz(theta) Tz(d) Tx(a) Rx(alpha)``, written out."""
    ct, st, ca, sa = math.cos(theta), math.sin(theta), math.cos(alpha), math.sin(alpha)
    return np.array(
        [
            [ct, -st * ca, st * sa, a * ct],
            [st, ct * ca, -ct * sa, a * st],
            [0.0, sa, ca, d],
            [0.0, 0.0, 0.0, 1.0],
        ]
    )


def _table_fk(
    spec: list[tuple[float, float, float, float]], base: np.ndarray, tool: np.ndarray
) -> Callable[[np.ndarray], np.ndarray]:
    def fk(q: np.ndarray) -> np.ndarray:
        T = base.copy()
        for (a, al, d, th), qi in zip(spec, q, strict=True):
            T = T @ _dh(a, math.radians(al), d, th + qi)
        return T @ tool

    return fk


def _moved() -> tuple[np.ndarray, np.ndarray]:
    """A tilted, shifted base and a turned, offset tool."""
    base = np.eye(4)
    base[:3, :3] = Rotation.from_euler("xyz", [0.2, -0.3, 0.9]).as_matrix()
    base[:3, 3] = (0.3, -0.2, 0.1)
    tool = np.eye(4)
    tool[:3, :3] = Rotation.from_euler("zx", [0.4, -0.7]).as_matrix()
    tool[:3, 3] = (0.02, 0.03, 0.12)
    return base, tool


def _check(fk: Callable[[np.ndarray], np.ndarray], T: np.ndarray, branches: list) -> None:
    for b in branches:
        F = fk(b)
        assert np.linalg.norm(F[:3, 3] - T[:3, 3]) < FK_TOL
        assert Rotation.from_matrix(F[:3, :3].T @ T[:3, :3]).magnitude() < FK_TOL


def _wrapped(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.max(np.abs(np.remainder(a - b + math.pi, 2 * math.pi) - math.pi)))


def _eaik(robot: Robot) -> tuple[HPRobot, np.ndarray]:
    """EAIK on ``robot``'s joint axes, and the tool's rotation at q = 0 (EAIK's end frame
    has the world's orientation there)."""
    axes = joint_axes(robot)
    points = np.vstack([np.zeros(3), axes.points, axes.tool[:3, 3]])
    return HPRobot(axes.directions, np.diff(points, axis=0)), axes.tool[:3, :3]


def _reaching(fk: Callable[[np.ndarray], np.ndarray], T: np.ndarray, Q: list) -> list[np.ndarray]:
    """The distinct rows of ``Q`` (1e-6 apart, wrapped) whose FK is within 1e-8 of ``T``."""
    found: list[np.ndarray] = []
    for x in map(np.asarray, Q):
        if np.abs(fk(x) - T).max() < 1e-8 and all(_wrapped(x, f) > 1e-6 for f in found):
            found.append(x)
    return found


@pytest.mark.parametrize("arm", sorted(ARMS))
def test_every_branch_of_eaik_and_the_source(arm: str) -> None:
    """200 random poses: EAIK's class and branch count, each branch one of EAIK's (1e-9),
    every branch within 1e-10 of its pose by an independent FK, the source among them."""
    spec, kind, reverse, eaik_class = ARMS[arm]
    base, tool = _moved()
    robot = Robot.from_dh(_rows(spec), name=arm, base=base, tool=tool)
    family = family_of(robot)
    assert family is not None and family.name == "spherical_axes"
    plan = axes_plan(robot)
    assert (plan.kind, plan.reverse) == (kind, reverse)
    solver, R0 = _eaik(robot)
    assert solver.getKinematicFamily() == eaik_class
    fk = _table_fk(spec, base, tool)
    rng = np.random.default_rng(1)
    counts = []
    for q in rng.uniform(-math.pi, math.pi, (200, 6)):
        T = fk(q)
        branches = analytic_ik(robot, T, within_limits=False)
        _check(fk, T, branches)
        assert min(_wrapped(b, q) for b in branches) < SOURCE_TOL, q
        target = T.copy()
        target[:3, :3] = T[:3, :3] @ R0.T
        sol = solver.IK(target)
        if kind == GENERAL:
            # EAIK flags every branch of its quartic classes least-squares (is_LS), exact
            # or not: its reference there is the distinct branches that reach the pose.
            exact = _reaching(fk, T, sol.Q)
        else:
            exact = [np.asarray(x) for x, ls in zip(sol.Q, sol.is_LS, strict=True) if not ls]
        assert len(branches) == len(exact), q
        for b in branches:
            assert min(_wrapped(b, e) for e in exact) < 1e-9, q
        counts.append(len(branches))
    assert max(counts) == 8


def test_panda_with_its_last_joint_fixed() -> None:
    """The Panda's first six joints (modified DH, joint 7 fixed into the tool): a spherical
    shoulder read backwards, axes 6 and 5 meeting: EAIK's first two intersecting."""
    panda = load_problem(next(p for p in builtin_problems() if p.stem == "panda")).robot
    assert panda.dh is not None
    rows = panda.dh
    q7 = 0.4
    last = rows[6]
    ca, sa = math.cos(last.alpha), math.sin(last.alpha)
    ct, st = math.cos(q7), math.sin(q7)
    joint7 = np.array(  # Rx(alpha) Tx(a) Rz(q7) Tz(d)
        [
            [ct, -st, 0.0, last.a],
            [st * ca, ct * ca, -sa, -last.d * sa],
            [st * sa, ct * sa, ca, last.d * ca],
            [0.0, 0.0, 0.0, 1.0],
        ]
    )
    six = Robot.from_mdh(rows[:6], name="panda6", tool=joint7 @ panda.T_flange_tool)
    plan = axes_plan(six)
    assert (plan.kind, plan.reverse) == (INTERSECTING, True)
    assert _eaik(six)[0].getKinematicFamily() == "6R-SPHERICAL_FIRST_TWO_INTERSECTING"
    rng = np.random.default_rng(2)
    for q in rng.uniform(six.lower, six.upper, (200, 6)):
        T = six.fk(q)
        branches = analytic_ik(six, T)
        full = np.append(q, q7)
        assert np.max(np.abs(panda.fk(full) - T)) < 1e-12  # the same arm
        for b in branches:
            assert np.max(np.abs(panda.fk(np.append(b, q7)) - T)) < FK_TOL
        assert min(float(np.max(np.abs(b - q))) for b in branches) < SOURCE_TOL


def _origin(T: np.ndarray) -> str:
    """A URDF ``<origin>`` of the transform ``T`` (rpy: fixed-axis x, y, z)."""
    xyz = " ".join(repr(float(v)) for v in T[:3, 3])
    rpy = " ".join(repr(float(v)) for v in Rotation.from_matrix(T[:3, :3]).as_euler("xyz"))
    return f'<origin xyz="{xyz}" rpy="{rpy}"/>'


def _urdf(spec: list[tuple[float, float, float, float]]) -> str:
    """URDF text of the DH chain: joint ``i + 1`` at the end of row ``i``'s transform."""
    parts = ['<robot name="urdf_arm">', '<link name="l0"/>']
    origin = np.eye(4)
    for i, (a, al, d, th) in enumerate(spec):
        parts += [
            f'<link name="l{i + 1}"/>',
            f'<joint name="j{i + 1}" type="revolute"><parent link="l{i}"/>'
            f'<child link="l{i + 1}"/>{_origin(origin)}<axis xyz="0 0 1"/>'
            '<limit lower="-3.14" upper="3.14" effort="1" velocity="1"/></joint>',
        ]
        origin = _dh(a, math.radians(al), d, th)
    parts += [
        '<link name="tip"/>',
        f'<joint name="tip_joint" type="fixed"><parent link="l{len(spec)}"/>'
        f'<child link="tip"/>{_origin(origin)}</joint>',
        "</robot>",
    ]
    return "\n".join(parts)


@pytest.mark.parametrize("arm", ["second two parallel", "spherical shoulder"])
def test_found_from_a_urdf(arm: str) -> None:
    """The same arms written as URDF (frames of the URDF's choosing): found, solved."""
    spec, kind, reverse, _ = ARMS[arm]
    robot = Robot.from_urdf(_urdf(spec), "l0", "tip")
    plan = axes_plan(robot)
    assert (plan.kind, plan.reverse) == (kind, reverse)
    fk = _table_fk(spec, np.eye(4), np.eye(4))
    rng = np.random.default_rng(3)
    for q in rng.uniform(robot.lower, robot.upper, (100, 6)):
        T = fk(q)
        branches = analytic_ik(robot, T)
        _check(fk, T, branches)
        assert min(_wrapped(b, q) for b in branches) < SOURCE_TOL


@pytest.mark.parametrize("arm", sorted(ARMS))
def test_wrist_singularity_takes_the_reference(arm: str) -> None:
    """q5 = 0 aligns axes 4 and 6 (the wrist's +-90 deg twists; for the spherical
    shoulder, q2 = 0 aligns axes 1 and 3): the free angle takes ``q_ref``'s value."""
    spec, _, reverse, _ = ARMS[arm]
    robot = Robot.from_dh(_rows(spec), name=arm)
    fk = _table_fk(spec, np.eye(4), np.eye(4))
    rng = np.random.default_rng(4)
    for q in rng.uniform(-math.pi, math.pi, (50, 6)):
        q[1 if reverse else 4] = 0.0
        T = fk(q)
        branches = analytic_ik(robot, T, q_ref=q, within_limits=False)
        _check(fk, T, branches)
        assert min(_wrapped(b, q) for b in branches) < SOURCE_TOL, q


def test_solve_ik_answers_with_the_closed_form() -> None:
    spec = ARMS["first two parallel"][0]
    robot = Robot.from_dh(_rows(spec), name="arm")
    rng = np.random.default_rng(5)
    for q in rng.uniform(robot.lower, robot.upper, (5, 6)):
        res = solve_ik(robot, robot.fk(q), solver="auto")
        assert res.success and res.solver == "analytic"


def test_what_does_not_fit_says_why() -> None:
    """An elbow axis through the wrist centre (general or meeting shoulder), no spherical
    joint, seven joints; a declared family that does not fit fails when it is built."""
    stuck = [
        (0.1, 60.0, 0.4, 0.0),
        (0.5, 30.0, 0.1, 0.0),
        (0.0, 75.0, 0.0, 0.0),  # axis 3 through o3, and the wrist centre is o3 (d4 = 0)
        (0.0, -90.0, 0.0, 0.0),
        *WRIST[1:],
    ]
    robot = Robot.from_dh(_rows(stuck), name="stuck")
    assert family_of(robot) is None
    reason = axes_plan(robot).reason
    assert reason.startswith("axis 3 (j3) passes through the wrist centre")
    assert "read backwards" in reason
    with pytest.raises(AnalyticIKError, match="does not fit family 'spherical_axes'"):
        Robot.from_dh(_rows(stuck), name="stuck", analytic="spherical_axes")
    meeting = [(0.0, 60.0, 0.4, 0.0), (0.0, 30.0, 0.0, 0.0), (0.05, 75.0, 0.0, 0.0), *WRIST]
    reason = axes_plan(Robot.from_dh(_rows(meeting))).reason
    assert "passes through the point of axes 1 and 2" in reason
    assert "neither axes 1 (j1), 2 (j2) nor 2 (j2), 3 (j3) are parallel" in reason
    ur5 = load_problem(next(p for p in builtin_problems() if p.stem == "ur5")).robot
    assert "misses the point of axes 4" in axes_plan(ur5).reason
    panda = load_problem(next(p for p in builtin_problems() if p.stem == "panda")).robot
    assert axes_plan(panda).reason == "7 joints (the family takes 6)"
    three = [(0.4, 0.0, 0.3, 0.0), (0.3, 0.0, 0.1, 0.0), (0.05, 80.0, 0.0, 0.0), *WRIST]
    assert "axes 1-3 are parallel" in axes_plan(Robot.from_dh(_rows(three))).reason


@pytest.mark.parametrize("arm", sorted(ARMS))
def test_compiled_call_gives_the_numpy_steps_row_for_row(arm: str) -> None:
    """One compiled call (closed form, Newton step, wrap, limits, FK check, dedupe, sort)
    against the numpy steps (the step on ``Robot.jacobian``, then ``_finish``:
    ``Robot.fk``) on the same raw candidates."""
    spec = ARMS[arm][0]
    base, tool = _moved()
    robot = Robot.from_dh(_rows(spec), name=arm, base=base, tool=tool, limits=LIMITS)
    plan = axes_plan(robot)
    params = pack_axes_params(robot, plan)
    rng = np.random.default_rng(6)
    compared = 0
    for q in rng.uniform(-math.pi, math.pi, (120, 6)):
        T = robot.fk(q)
        for sort, within in ((True, True), (False, True), (True, False)):
            ref = rng.uniform(robot.lower, robot.upper) if sort else robot.mid_limits
            got = analytic_ik(robot, T, q_ref=ref if sort else None, within_limits=within)
            rows = np.empty((8, 6))
            n = kind_pipeline(plan.kind).candidates(params, T, ref, rows)
            stepped = newton_reference(robot, list(rows[:n]), T)
            expected = _finish(robot, stepped, T, "pose", ref, sort, within)
            if not expected:
                continue  # the polish's case, not the compiled steps'
            compared += 1
            assert len(got) == len(expected)
            for a, b in zip(got, expected, strict=True):
                # The Newton step formed twice (compiled, numpy) agrees to rounding times the
                # normal equations' condition: up to 2e-11 next to a singularity.
                np.testing.assert_allclose(a, b, rtol=0.0, atol=1e-9)
    assert compared >= 200


@pytest.mark.parametrize("arm", ["first two parallel", "spherical shoulder"])
def test_batch_equals_single_calls(arm: str) -> None:
    spec = ARMS[arm][0]
    robot = Robot.from_dh(_rows(spec), name=arm, limits=LIMITS)
    rng = np.random.default_rng(7)
    Q = rng.uniform(-math.pi, math.pi, (60, 6))
    Q[::5, 4] = 0.0  # wrist singularities
    T = robot.fk(Q)
    T[3, :3, 3] = (5.0, 0.0, 0.0)  # out of reach
    refs = rng.uniform(robot.lower, robot.upper, (60, 6))
    for q_ref in (None, refs[0], refs):
        for within in (True, False):
            batch = analytic_ik_batch(robot, T, q_ref=q_ref, within_limits=within)
            assert batch.counts[3] == 0
            for i in range(60):
                ref = None if q_ref is None else (q_ref[i] if np.ndim(q_ref) == 2 else q_ref)
                single = analytic_ik(robot, T[i], q_ref=ref, within_limits=within)
                assert batch.counts[i] == len(single)
                if single:
                    np.testing.assert_array_equal(batch.q[i, : len(single)], np.array(single))


_ONE_KIND_SCRIPT = """
import math, sys
import numpy as np
import optik
from optik.analytic.general_arm import general_arm_candidates
from optik.analytic.pair_wrist import pair_wrist_candidates, second_pair_candidates
from optik.analytic.parallel_arm import parallel_arm_candidates
from optik.analytic.spherical_axes import (
    INTERSECTING, axes_plan, kind_pipeline, pack_axes_params, postprocess_axes,
)
from optik.analytic.three_parallel import three_inner_candidates, three_outer_candidates

rows = [dict(a=a, alpha=math.radians(al), d=d, lower=-3.0, upper=3.0) for a, al, d in ROWS]
robot = optik.Robot.from_dh(rows)
plan = axes_plan(robot)
assert plan.kind == INTERSECTING, plan
out = np.empty((8, 6))
T = robot.fk(np.full(6, 0.3))
n = kind_pipeline(INTERSECTING).candidates(pack_axes_params(robot, plan), T, np.zeros(6), out)
others = (general_arm_candidates, second_pair_candidates, parallel_arm_candidates,
          three_inner_candidates, three_outer_candidates)
print(n, len(pair_wrist_candidates.signatures), [len(f.signatures) for f in others])
single = optik.analytic_ik(robot, T)
Q, counts = optik.analytic_ik_batch(robot, np.stack([T, T]))
print(len(single), *counts.tolist(), len(postprocess_axes.signatures))
"""


def test_a_kind_pipeline_compiles_its_own_arm_alone(tmp_path: Path) -> None:
    """Each arm kind's kernels hold its closed form alone (numba prunes the others on the
    constant kind), so a robot's first call compiles one arm's kernel, not seven: in a
    fresh cache, the ``candidates`` of the meeting-pair kind compile ``pair_wrist``'s
    kernel and no other arm's. The post-processing is one kernel, not inlined into each
    pipeline: the single call and the batch compile it once, with one signature, and a
    second kind's pipeline links that kernel (``postprocess_axes``)."""
    rows = [(a, al, d) for a, al, d, _ in ARMS["first two intersecting"][0]]
    script = _ONE_KIND_SCRIPT.replace("ROWS", repr(rows))
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path)}
    done = subprocess.run(
        [sys.executable, "-c", script], env=env, capture_output=True, text=True, check=False
    )
    assert done.returncode == 0, done.stderr
    first, second = done.stdout.splitlines()
    assert first.split() == ["8", "1", "[0,", "0,", "0,", "0,", "0]"]
    single, batch_0, batch_1, signatures = (int(x) for x in second.split())
    assert single >= 1 and batch_0 == batch_1 == single
    assert signatures == 1


def test_kind_pipeline_refuses_an_unknown_kind() -> None:
    with pytest.raises(OptikError, match=r"unknown arm kind 99; known: \[1, 2, 3, 4, 5, 6, 7\]"):
        kind_pipeline(99)


def test_an_aligned_wrist_splits_its_turn_inside_narrow_limits() -> None:
    """Axes 4 and 6 aligned (``q5 = -0.3`` against the wrist's DH offset): only the turn
    ``q4 + q6`` is defined. With the wrist's joints limited to +-1.2 rad, keeping ``q4``
    at its reference (0) put turns beyond 1.2 rad into ``q6``, outside its limits: no
    branch. The split nearest the reference comes too: every pose of 200 random aligned
    wrists keeps an in-limit branch reaching it (the turn the source's)."""
    spec = ARMS["second two parallel"][0]
    limits = np.array([[-3.0, 3.0]] * 3 + [[-1.2, 1.2], [-2.0, 2.0], [-1.2, 1.2]])
    robot = Robot.from_dh(_rows(spec), limits=limits)
    assert axes_plan(robot).kind == PARALLEL_23
    rng = np.random.default_rng(21)
    for _ in range(200):
        q = rng.uniform(robot.lower, robot.upper)
        q[4] = -0.3
        T = robot.fk(q)
        branches = analytic_ik(robot, T)
        aligned = [b for b in branches if abs(b[4] + 0.3) < 1e-9]
        assert aligned, q
        for b in branches:
            assert np.all(b >= robot.lower) and np.all(b <= robot.upper)
            np.testing.assert_allclose(robot.fk(b), T, atol=1e-9)
        assert any(abs(b[3] + b[5] - q[3] - q[5]) < 1e-9 for b in aligned)
