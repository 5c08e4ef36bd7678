"""The Franka Panda in closed form with its last joint held (``free_joint="panda_joint7"``).

With q7 known the other six joints are the pair-elbow-wrist structure read backwards
(:mod:`optik.analytic.free_joint`): axes 6 and 5 meet at the wrist point, axis 4 is the
elbow (its two 0.0825 m offsets only change the shoulder-wrist distance), axes 3, 2, 1
meet at the shoulder; the 0.088 m wrist offset sits between axes 6 and 7, inside the held
joint's motion. The structure is found from the joint axes, whatever the robot was read
from: the modified DH table of ``problems/panda.toml``, pybullet's ``franka_panda/panda.urdf``
(angles written to 11 digits) and example-robot-data's ``panda.urdf``.

References are independent of the closed form: forward kinematics written out here from
the DH rows (numpy) or computed by pinocchio from the URDF, the rotation angle from
scipy's ``Rotation``, the configuration each pose came from, EAIK's solver for the same
axes with joint 7 locked, and ``solve_ik`` with the joint frozen.
"""

from __future__ import annotations

import importlib.metadata
import math
import os
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pinocchio as pin
import pybullet_data  # the test extra: its absence is a failure, not a skip
import pytest
from conftest import frozen_answers_among_branches
from eaik.IK_HP import HPRobot
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

from optik import Robot, load_problem, solve_ik
from optik.analytic import analytic_ik, analytic_ik_batch
from optik.analytic.free_joint import free_joint_plan
from optik.analytic.geometry import joint_axes
from optik.errors import AnalyticIKError, NonFiniteError, OptikError
from optik.problems import builtin_problems

PYBULLET_URDF = Path(pybullet_data.getDataPath()) / "franka_panda" / "panda.urdf"
Q7 = "panda_joint7"
FK_TOL = 1e-10
SOURCE_TOL = 1e-8
STRETCHED_Q4 = -(math.atan2(0.0825, 0.316) + math.atan2(0.0825, 0.384))
"""q4 of the stretched elbow: the shoulder-wrist distance at its largest (0.7194 m)."""
DOUBLE_ROOT_TOL = {"problems": 1e-6, "pybullet": 2e-4}
"""How near the source a branch is at a double root (q5 = +-pi/2, the stretched elbow).

Two branches meet there, and a pose error e moves a branch by about sqrt(e / curvature):
the exact DH table's rounding (1e-16) gives about 4e-7 rad, the URDF's axes, which meet
only to about 1e-12 m (angles written 1.57079632679), up to 8e-5 rad. Every branch still
reproduces the pose to 1e-12 (checked)."""


def _erd_urdf() -> Path | None:
    try:
        dist = importlib.metadata.distribution("example-robot-data")
    except importlib.metadata.PackageNotFoundError:
        return None
    path = dist.locate_file("cmeel.prefix/share/example-robot-data/robots")
    path = Path(str(path)) / "panda_description" / "urdf" / "panda.urdf"
    return path if path.is_file() else None


ERD_URDF = _erd_urdf()
# CI installs the test extra: there a missing package is a failure, never a skip.
needs_erd = pytest.mark.skipif(
    ERD_URDF is None and not os.environ.get("CI"),
    reason="example-robot-data is not installed (pip install 'optik[test]'): "
    "its panda.urdf is not available",
)


# ---------------------------------------------------------------------- independent FK
def _mdh(alpha: float, a: float, theta: float, d: float) -> np.ndarray:
    """``Rx(alpha) Tx(a) Rz(theta) Tz(d)``, written out."""
    ca, sa, ct, st = math.cos(alpha), math.sin(alpha), math.cos(theta), math.sin(theta)
    return np.array(
        [
            [ct, -st, 0.0, a],
            [st * ca, ct * ca, -sa, -d * sa],
            [st * sa, ct * sa, ca, d * ca],
            [0.0, 0.0, 0.0, 1.0],
        ]
    )


def _table_fk(robot: Robot) -> Callable[[np.ndarray], np.ndarray]:
    """The FK of a robot built from modified DH rows, from its rows (not its chain)."""
    rows = robot.dh
    assert rows is not None and robot.convention == "mdh"

    def fk(q: np.ndarray) -> np.ndarray:
        T = robot.T_world_base.copy()
        for row, qi in zip(rows, q, strict=True):
            T = T @ _mdh(row.alpha, row.a, row.theta + qi, row.d)
        return T @ robot.T_flange_tool

    return fk


def _pinocchio_fk(path: Path, frame: str) -> Callable[[np.ndarray], np.ndarray]:
    """The FK of ``frame`` by pinocchio from the URDF (fingers at 0)."""
    model = pin.buildModelFromUrdf(str(path))
    data = model.createData()
    fid = model.getFrameId(frame)

    def fk(q: np.ndarray) -> np.ndarray:
        full = np.zeros(model.nq)
        full[:7] = q
        pin.framesForwardKinematics(model, data, full)
        return np.asarray(data.oMf[fid].homogeneous)

    return fk


class Arm:
    """A Panda as optik reads it, with an FK that optik did not compute."""

    def __init__(self, kind: str, robot: Robot, fk: Callable[[np.ndarray], np.ndarray]):
        self.kind = kind
        self.robot = robot
        self.fk = fk


def _problems_panda() -> Robot:
    return load_problem(next(p for p in builtin_problems() if p.stem == "panda")).robot


@pytest.fixture(scope="module")
def problems_arm() -> Arm:
    robot = _problems_panda()
    return Arm("problems", robot, _table_fk(robot))


@pytest.fixture(scope="module")
def pybullet_arm() -> Arm:
    """pybullet's URDF up to its grasp target (the hand's -45 deg and 0.105 m as tool)."""
    robot = Robot.from_urdf(PYBULLET_URDF, "panda_link0", "panda_grasptarget")
    return Arm("pybullet", robot, _pinocchio_fk(PYBULLET_URDF, "panda_grasptarget"))


@pytest.fixture(scope="module", params=["problems", "pybullet"])
def arm(request: pytest.FixtureRequest, problems_arm: Arm, pybullet_arm: Arm) -> Arm:
    return problems_arm if request.param == "problems" else pybullet_arm


# ---------------------------------------------------------------------- checks
def _errors(arm: Arm, q: np.ndarray, T: np.ndarray) -> tuple[float, float]:
    """Position (m) and rotation angle (rad, scipy) between ``fk(q)`` and ``T``."""
    F = arm.fk(q)
    angle = Rotation.from_matrix(F[:3, :3].T @ T[:3, :3]).magnitude()
    return float(np.linalg.norm(F[:3, 3] - T[:3, 3])), float(angle)


def _check(arm: Arm, T: np.ndarray, branches: list[np.ndarray], value: float) -> None:
    """Every branch reaches ``T`` (1e-10), lies inside the limits and holds q7 exactly."""
    robot = arm.robot
    for b in branches:
        assert b.shape == (7,)
        assert b[6] == value
        assert np.all(b >= robot.lower - 1e-12) and np.all(b <= robot.upper + 1e-12), b
        position, angle = _errors(arm, b, T)
        assert position < FK_TOL and angle < FK_TOL, (b, position, angle)


def _source_distance(branches: list[np.ndarray], q: np.ndarray) -> float:
    """Max-abs distance from ``q`` to the nearest branch (every range is under 2 pi)."""
    return min((float(np.max(np.abs(b - q))) for b in branches), default=math.inf)


def _solve(arm: Arm, q: np.ndarray, q_ref: np.ndarray | None = None) -> list[np.ndarray]:
    """Every branch of ``q``'s pose (by the reference FK) with q7 held at ``q[6]``."""
    T = arm.fk(q)
    branches = analytic_ik(arm.robot, T, q_ref=q_ref, free_joint=Q7, free_value=q[6])
    _check(arm, T, branches, q[6])
    return branches


# ---------------------------------------------------------------------- the structure
def test_the_structure_is_found_from_the_axes(problems_arm: Arm, pybullet_arm: Arm) -> None:
    """The six joints left by q7 are a meeting pair, an elbow and a wrist read backwards."""
    for robot in (problems_arm.robot, pybullet_arm.robot):
        plan = free_joint_plan(robot, 6)
        assert plan.reason == "" and plan.reverse and plan.held == 6
        axes = joint_axes(robot)
        z, p = axes.directions, axes.points
        # Independent facts of the geometry: axes 1, 2, 3 through one point, 5 and 6
        # through another, axis 4 through neither, axes 6 and 7 0.088 m apart.
        for i, j in ((0, 1), (1, 2), (4, 5)):
            assert abs(np.cross(z[i], z[j]) @ (p[j] - p[i])) < 1e-11
        assert abs(np.cross(z[5], z[6]) @ (p[6] - p[5])) == pytest.approx(0.088, abs=1e-9)


@pytest.mark.parametrize("k", range(6))
def test_other_held_joints_say_why_there_is_no_closed_form(problems_arm: Arm, k: int) -> None:
    robot = problems_arm.robot
    value = 0.5 * float(robot.lower[k] + robot.upper[k])
    with pytest.raises(AnalyticIKError, match=r"has no closed form: .*(do not meet|parallel)"):
        analytic_ik(
            robot, robot.fk(robot.mid_limits), free_joint=robot.joint_names[k], free_value=value
        )


# ---------------------------------------------------------------------- every branch
def test_random_poses_return_every_branch_and_the_source(arm: Arm) -> None:
    """500 random in-limit configurations: every branch verified, the source among them."""
    robot = arm.robot
    rng = np.random.default_rng(7)
    counts = []
    for q in rng.uniform(robot.lower, robot.upper, (500, 7)):
        branches = _solve(arm, q)
        assert _source_distance(branches, q) < SOURCE_TOL, q
        counts.append(len(branches))
    # Two elbows x two of the pair (q5, q6) x two shoulders; the limits keep fewer.
    assert max(counts) == 8 and min(counts) >= 1


@needs_erd
def test_example_robot_data_panda() -> None:
    """example-robot-data's URDF up to its TCP frame (the hand's 0.1034 m as tool)."""
    assert ERD_URDF is not None
    robot = Robot.from_urdf(ERD_URDF, "panda_link0", "panda_hand_tcp")
    arm = Arm("erd", robot, _pinocchio_fk(ERD_URDF, "panda_hand_tcp"))
    rng = np.random.default_rng(8)
    for q in rng.uniform(robot.lower, robot.upper, (200, 7)):
        assert _source_distance(_solve(arm, q), q) < SOURCE_TOL, q


def test_base_and_tool_transforms_are_absorbed(problems_arm: Arm) -> None:
    """The same table under a tilted, shifted base and a longer, turned tool."""
    panda = problems_arm.robot
    base = np.eye(4)
    base[:3, :3] = Rotation.from_euler("xyz", [0.3, -0.2, 1.1]).as_matrix()
    base[:3, 3] = (0.4, -0.7, 0.25)
    tool = panda.T_flange_tool.copy()
    tool[:3, :3] = tool[:3, :3] @ Rotation.from_euler("zy", [0.7, 0.2]).as_matrix()
    tool[:3, 3] += (0.02, -0.01, 0.05)
    assert panda.dh is not None
    robot = Robot.from_mdh(panda.dh, name="panda moved", base=base, tool=tool)
    arm = Arm("problems", robot, _table_fk(robot))
    rng = np.random.default_rng(9)
    for q in rng.uniform(robot.lower, robot.upper, (200, 7)):
        assert _source_distance(_solve(arm, q), q) < SOURCE_TOL, q


def _eaik(robot: Robot, value: float) -> tuple[HPRobot, np.ndarray]:
    """EAIK's solver for ``robot``'s joint axes with joint 7 locked at ``value``.

    EAIK takes the axes as directions and offsets between consecutive joint points, and
    ends in a frame with the world's orientation: a target's rotation is turned by the
    tool's rotation at q = 0 (returned) before EAIK sees it.
    """
    axes = joint_axes(robot)
    points = np.vstack([np.zeros(3), axes.points, axes.tool[:3, 3]])
    return HPRobot(axes.directions, np.diff(points, axis=0), fixed_axes=[(6, value)]), axes.tool


def _newton_held(robot: Robot, q: np.ndarray, target: np.ndarray) -> np.ndarray:
    """Two Gauss-Newton steps of joints 1-6 towards ``target`` (``Robot.fk``, q7 kept)."""
    for _ in range(2):
        T, J = robot.fk_jacobian(q)
        R = target[:3, :3] @ T[:3, :3].T
        vee = 0.5 * np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])
        err = np.concatenate([target[:3, 3] - T[:3, 3], vee])
        q = q.copy()
        q[:6] += np.linalg.lstsq(J[:, :6], err, rcond=None)[0]
    return q


def test_same_branches_as_eaik(arm: Arm) -> None:
    """Without limits: as many branches as EAIK's exact solutions, each one of EAIK's.

    EAIK solves the ideal arm of the axes it is given and stops there: on the URDF, whose
    axes meet only to 1e-12 m, its branches are compared after two Gauss-Newton steps
    (one pose of 200 is otherwise 1.3e-9 rad off ours, which reach the pose to 1e-15)."""
    robot = arm.robot
    value = 0.7
    solver, tool = _eaik(robot, value)
    rng = np.random.default_rng(10)
    for q in rng.uniform(robot.lower, robot.upper, (200, 7)):
        q[6] = value
        T = arm.fk(q)
        target = T.copy()
        target[:3, :3] = T[:3, :3] @ tool[:3, :3].T
        sol = solver.IK(target)
        exact = [
            _newton_held(robot, np.asarray(x), T)
            for x, ls in zip(sol.Q, sol.is_LS, strict=True)
            if not ls
        ]
        branches = analytic_ik(robot, T, within_limits=False, free_joint=Q7, free_value=value)
        assert len(branches) == len(exact), q
        for b in branches:
            gaps = [
                np.max(np.abs(np.remainder(b - e + math.pi, 2 * math.pi) - math.pi)) for e in exact
            ]
            assert min(gaps) < 1e-9, q


# ---------------------------------------------------------------------- singular poses
def _clear(q: np.ndarray, keep: str) -> bool:
    """No other singular joint value within 0.1 rad (one singularity at a time)."""
    away = {
        "q2": abs(q[1]),
        "stretched": abs(q[3] - STRETCHED_Q4),
        "q4=0": abs(q[3]),
        "q5": abs(abs(q[4]) - 0.5 * math.pi),
    }
    return all(v > 0.1 for name, v in away.items() if name != keep)


def _singular_samples(
    robot: Robot,
    rng: np.random.Generator,
    n: int,
    set_value: Callable[[np.ndarray], None],
    keep: str,
) -> list[np.ndarray]:
    out: list[np.ndarray] = []
    for _ in range(100 * n):
        q = rng.uniform(robot.lower, robot.upper)
        set_value(q)
        if np.all(q >= robot.lower) and np.all(q <= robot.upper) and _clear(q, keep):
            out.append(q)
            if len(out) == n:
                return out
    raise AssertionError(f"only {len(out)} of {n} samples inside the limits")


def _setter(j: int, value: float) -> Callable[[np.ndarray], None]:
    def set_value(q: np.ndarray) -> None:
        q[j] = value

    return set_value


@pytest.mark.parametrize(
    ("label", "j", "value"),
    [
        ("q5 = 0", 4, 0.0),
        ("q6 = 0", 5, 0.0),
        ("q6 = pi/2", 5, 0.5 * math.pi),
        ("q6 = pi", 5, math.pi),
        ("q4 at its lower limit", 3, -math.inf),
        ("q6 at its upper limit", 5, math.inf),
    ],
)
def test_special_values_that_are_not_singular(arm: Arm, label: str, j: int, value: float) -> None:
    """q5 = 0, q6 at 0, pi/2, pi, joints at a limit: nothing coincides; the source is found."""
    rng = np.random.default_rng(20 + j)
    value = float(np.clip(value, arm.robot.lower[j], arm.robot.upper[j]))
    for q in _singular_samples(arm.robot, rng, 60, _setter(j, value), ""):
        assert _source_distance(_solve(arm, q), q) < SOURCE_TOL, (label, q)


def test_shoulder_singularity_q1_plus_q3(arm: Arm) -> None:
    """q2 = 0 puts axes 1 and 3 on one line: only q1 + q3 is defined, and q3 takes
    ``q_ref``'s value. With the source as reference the source comes back; with another,
    branches still come back (each verified by :func:`_check`)."""
    robot = arm.robot
    rng = np.random.default_rng(30)
    for q in _singular_samples(robot, rng, 80, _setter(1, 0.0), "q2"):
        assert _source_distance(_solve(arm, q, q_ref=q), q) < SOURCE_TOL, q
        assert _solve(arm, q, q_ref=rng.uniform(robot.lower, robot.upper))


@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_double_root_of_the_pair(arm: Arm, sign: float) -> None:
    """q5 = +-pi/2: the shoulder lies in the plane of axes 5 and 6, and the pair's two
    solutions meet (the case a branch was once lost on the URDF, whose axes meet only to
    1e-12 m: the subproblem's tangent test now allows the elbow's reach tolerance)."""
    rng = np.random.default_rng(40)
    for q in _singular_samples(arm.robot, rng, 80, _setter(4, sign * 0.5 * math.pi), "q5"):
        assert _source_distance(_solve(arm, q, q_ref=q), q) < DOUBLE_ROOT_TOL[arm.kind], q
        assert _source_distance(_solve(arm, q), q) < DOUBLE_ROOT_TOL[arm.kind], q


def test_stretched_elbow(arm: Arm) -> None:
    """q4 = -0.467 rad: the shoulder-wrist distance at its largest, one elbow (double root)."""
    rng = np.random.default_rng(50)
    for q in _singular_samples(arm.robot, rng, 80, _setter(3, STRETCHED_Q4), "stretched"):
        assert _source_distance(_solve(arm, q), q) < DOUBLE_ROOT_TOL[arm.kind], q


def _wrist_point_on_axis_1(robot: Robot, q: np.ndarray) -> np.ndarray:
    """The wrist point (where axes 5 and 6 meet) off axis 1, from ``Robot.frames``."""
    F = robot.frames(q)
    W = F[5][:3, 3]  # the frame of joint 5: its origin is on axes 5 and 6 (both readers)
    z1, o1 = F[0][:3, 2], F[0][:3, 3]
    d = W - o1
    return np.asarray(d - (d @ z1) * z1)


def test_wrist_point_on_axis_1(arm: Arm) -> None:
    """The wrist point on axis 1 (the shoulder singularity of the q7 solvers that take q1
    from the wrist point's azimuth) is not singular here: the source is found."""
    robot = arm.robot
    rng = np.random.default_rng(60)
    found = 0
    while found < 30:
        q = rng.uniform(robot.lower, robot.upper)

        def miss(x: np.ndarray, q: np.ndarray = q) -> np.ndarray:
            return _wrist_point_on_axis_1(robot, np.r_[q[0], x, q[3:]])

        q[1:3] = least_squares(miss, q[1:3], xtol=1e-15, ftol=1e-15, gtol=1e-15).x
        if not (np.linalg.norm(miss(q[1:3])) < 1e-12 and np.all(robot.within_limits(q))):
            continue
        if not _clear(q, ""):
            continue
        found += 1
        assert _source_distance(_solve(arm, q), q) < SOURCE_TOL, q


def test_shoulder_on_axis_5_is_a_self_motion(pybullet_arm: Arm) -> None:
    """q4 = 0 (inside pybullet's limits, not the Panda's datasheet ones): the shoulder
    lies on axis 5, so q5 and the shoulder turn together: q5 takes ``q_ref``'s value.
    With q2 = 0 as well the wrist point is on axis 1 too."""
    robot = pybullet_arm.robot
    assert robot.upper[3] == 0.0
    rng = np.random.default_rng(70)
    for q in _singular_samples(robot, rng, 40, _setter(3, 0.0), "q4=0"):
        assert _source_distance(_solve(pybullet_arm, q, q_ref=q), q) < SOURCE_TOL, q
        assert _solve(pybullet_arm, q, q_ref=rng.uniform(robot.lower, robot.upper))
    for q in rng.uniform(robot.lower, robot.upper, (40, 7)):
        q[1] = q[3] = 0.0
        assert np.linalg.norm(_wrist_point_on_axis_1(robot, q)) < 1e-11  # 11-digit angles
        assert _source_distance(_solve(pybullet_arm, q, q_ref=q), q) < SOURCE_TOL, q


def test_axis_6_never_meets_the_shoulder(problems_arm: Arm) -> None:
    """The one singularity not tested above, axis 6 through the shoulder point, cannot
    occur: axis 6 is perpendicular to axis 5 through the wrist point, and the shoulder's
    offset along axis 5 from the wrist point stays below -0.06 m for every q4 in
    [-pi, 0] (the widest limits, pybullet's)."""
    robot = problems_arm.robot
    along = []
    for q4 in np.linspace(-math.pi, 0.0, 721):
        q = np.zeros(7)
        q[3] = q4
        F = robot.frames(q)
        S, W, z5 = F[1][:3, 3], F[5][:3, 3], F[5][:3, 2]
        along.append(float((S - W) @ z5))
    assert max(along) < -0.06


# ---------------------------------------------------------------------- independent references
def test_numeric_solutions_with_q7_frozen_are_among_the_branches(arm: Arm) -> None:
    """``solve_ik(frozen={q7: v})`` from random starts finds nothing the closed form lacks."""
    assert arm.robot.joint_names[6] == Q7
    rng = np.random.default_rng(80)
    assert frozen_answers_among_branches(arm.robot, arm.fk, 6, rng, _source_distance) >= 10


def test_batch_equals_single_calls(arm: Arm) -> None:
    robot = arm.robot
    rng = np.random.default_rng(90)
    Q = rng.uniform(robot.lower, robot.upper, (60, 7))
    Q[::6, 1] = 0.0  # some singular rows: q2 = 0, q5 = pi/2, a stretched elbow
    Q[1::6, 4] = 0.5 * math.pi
    Q[2::6, 3] = STRETCHED_Q4
    T = np.array([arm.fk(q) for q in Q])
    T[5, :3, 3] = (2.0, 0.0, 0.5)  # out of reach
    refs = rng.uniform(robot.lower, robot.upper, (60, 7))
    for q_ref, values in ((None, Q[:, 6]), (refs, Q[:, 6]), (refs[0], float(Q[0, 6]))):
        for within in (True, False):
            batch = analytic_ik_batch(
                robot, T, q_ref=q_ref, within_limits=within, free_joint=Q7, free_value=values
            )
            assert batch.counts[5] == 0
            for i in range(60):
                value = values[i] if np.ndim(values) else values
                ref = None if q_ref is None else (q_ref[i] if np.ndim(q_ref) == 2 else q_ref)
                single = analytic_ik(
                    robot, T[i], q_ref=ref, within_limits=within, free_joint=Q7, free_value=value
                )
                assert batch.counts[i] == len(single)
                if single:
                    np.testing.assert_array_equal(batch.q[i, : len(single)], np.array(single))
                assert np.all(np.isnan(batch.q[i, len(single) :]))


# ---------------------------------------------------------------------- no branch, bad input
def test_no_branch_for_the_held_value(problems_arm: Arm) -> None:
    """Out of reach, and reachable but not with that q7: an empty set, and ``solve_ik``
    with q7 frozen there reports no success."""
    robot = problems_arm.robot
    far = np.eye(4)
    far[:3, 3] = (1.5, 0.2, 0.4)
    assert analytic_ik(robot, far, free_joint=Q7, free_value=0.3) == []
    assert not solve_ik(robot, far, frozen={Q7: 0.3}).success
    # Near full reach, turning q7 away from the pose's own value leaves no solution at all
    # (not even outside the limits: without them the closed form is complete).
    rng = np.random.default_rng(100)
    none = 0
    for q in rng.uniform(robot.lower, robot.upper, (200, 7)):
        q[3] = STRETCHED_Q4 + 0.05
        T = robot.fk(q)
        assert analytic_ik(robot, T, free_joint=Q7, free_value=q[6])  # the pose's own q7
        other = q[6] - 2.5 if q[6] > 0 else q[6] + 2.5
        if analytic_ik(robot, T, within_limits=False, free_joint=Q7, free_value=other):
            continue
        none += 1
        if none <= 3:
            res = solve_ik(robot, T, frozen={Q7: other})
            assert (res.status, res.solver) == ("unreachable", "analytic"), res.message
            # An independent search (no closed-form start) finds nothing either.
            searched = solve_ik(robot, T, frozen={Q7: other}, restarts=40, warm_start="q0")
            assert not searched.success, searched.q
    assert none >= 3


def test_no_candidate_is_not_searched_from_a_distant_reference(
    problems_arm: Arm, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A held value without a single raw candidate gives ``[]`` at once: the polish (for
    rounding at degenerate poses) runs only from candidates or a reference that is a
    near-solution, as when the reference is the answer itself."""
    import optik.analytic.held_joint as held

    robot = problems_arm.robot
    q = np.array([0.5, -0.3, 0.4, -2.2, -0.8, 2.4, 0.7])
    T = robot.fk(q)
    assert analytic_ik(robot, T, within_limits=False, free_joint=Q7, free_value=2.0) == []
    calls: list[int] = []
    real = held.polish

    def spy(*args: object, **kwargs: object) -> list[np.ndarray]:
        calls.append(1)
        return real(*args, **kwargs)  # type: ignore[arg-type]

    monkeypatch.setattr(held, "polish", spy)
    assert analytic_ik(robot, T, free_joint=Q7, free_value=2.0) == []
    assert analytic_ik_batch(robot, T[None], free_joint=Q7, free_value=2.0).counts[0] == 0
    assert not calls
    # A near-solution as reference is still polished when the closed form finds nothing
    # (here made to find nothing, as rounding could at a degenerate pose).
    near = q.copy()
    near[:6] += 1e-5
    monkeypatch.setattr(held.free_joint, "solve", lambda *args: 0)
    monkeypatch.setattr(held, "free_joint_raw", lambda *args: [])
    branches = analytic_ik(robot, T, q_ref=near, free_joint=Q7, free_value=0.7)
    assert calls and _source_distance(branches, q) < SOURCE_TOL


def test_bad_input(problems_arm: Arm) -> None:
    robot = problems_arm.robot
    target = robot.fk(robot.mid_limits)
    with pytest.raises(OptikError, match=r"free_joint must name a joint.*panda_joint1"):
        analytic_ik(robot, target, free_joint="panda_joint8", free_value=0.1)
    with pytest.raises(OptikError, match="outside the limits of joint 'panda_joint7'"):
        analytic_ik(robot, target, free_joint=Q7, free_value=3.0)
    with pytest.raises(OptikError, match="free_value: expected a number, not NaN"):
        analytic_ik(robot, target, free_joint=Q7, free_value=math.nan)
    with pytest.raises(OptikError, match="free_value"):
        analytic_ik(robot, target, free_joint=Q7, free_value=math.inf)
    with pytest.raises(NonFiniteError, match="free_value"):
        analytic_ik_batch(robot, np.stack([target] * 2), free_joint=Q7, free_value=[0.1, math.nan])
    with pytest.raises(OptikError, match="free_value is required"):
        analytic_ik(robot, target, free_joint=Q7)
    with pytest.raises(OptikError, match=r"free_value\[1\] = -3.0 is outside the limits"):
        analytic_ik_batch(robot, np.stack([target] * 2), free_joint=Q7, free_value=[0.1, -3.0])
