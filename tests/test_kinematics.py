"""Forward kinematics, frames and Jacobians against independent references.

References: products of DH / modified-DH A-matrices written out in conftest from each
robot's DH rows, central finite differences of ``fk``, and the DOBOT's closed-form
position (seed 001's common model).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import (
    PROBLEM_NAMES,
    assert_close,
    assert_rigid,
    coupling_from_rows,
    dh_matrix,
    fd_jacobian,
    mdh_matrix,
    random_q,
    reference_fk,
    reference_frames,
    robot_of,
)
from hypothesis import given
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from optik.model import DHJoint, Mimic, Robot

N_CONFIGS = 24


def _reach(robot: Robot) -> float:
    """A length scale of the robot (m), for absolute tolerances."""
    assert robot.dh is not None
    upper = np.where(np.isfinite(robot.upper), np.abs(robot.upper), 0.0)
    prismatic = sum(u for u, j in zip(upper, robot.joints, strict=True) if j.kind == "prismatic")
    links = sum(abs(r.a) + abs(r.d) for r in robot.dh)
    return 1.0 + links + prismatic


def _random_pose(rng: np.random.Generator) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = Rotation.random(random_state=rng).as_matrix()
    T[:3, 3] = rng.uniform(-1.0, 1.0, 3)
    return T


def _rz(angle: float) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


# ---------------------------------------------------------------------- FK vs DH product
def test_fk_matches_dh_product(problem_robot: Robot, rng: np.random.Generator) -> None:
    Q = random_q(problem_robot, rng, N_CONFIGS)
    for q in Q:
        assert_close(
            problem_robot.fk(q),
            reference_fk(problem_robot, q),
            atol=1e-12 * _reach(problem_robot),
            what=f"{problem_robot.name} q={q}",
        )


def test_fk_at_limits_matches_dh_product(problem_robot: Robot) -> None:
    lo = np.where(np.isfinite(problem_robot.lower), problem_robot.lower, -math.pi)
    hi = np.where(np.isfinite(problem_robot.upper), problem_robot.upper, math.pi)
    for q in (lo, hi, np.where(np.arange(problem_robot.dof) % 2 == 0, lo, hi)):
        assert_close(
            problem_robot.fk(q), reference_fk(problem_robot, q), atol=1e-12 * _reach(problem_robot)
        )


def test_coupling_matches_mimic_rows(problem_robot: Robot) -> None:
    assert_close(problem_robot.coupling, coupling_from_rows(problem_robot), atol=0.0)


def test_fk_not_trivially_constant(problem_robot: Robot, rng: np.random.Generator) -> None:
    # Guards the reference comparison: every joint moves the tool (pose changes).
    q = random_q(problem_robot, rng)
    T0 = problem_robot.fk(q)
    for k in range(problem_robot.dof):
        dq = np.zeros(problem_robot.dof)
        dq[k] = 0.1
        assert np.max(np.abs(problem_robot.fk(q + dq) - T0)) > 1e-4, k


def test_base_and_tool_order(rng: np.random.Generator) -> None:
    """fk = T_world_base @ A_1 ... A_n @ T_flange_tool, with non-commuting base and tool."""
    rows = [
        DHJoint(a=0.3, alpha=0.4, d=0.2, theta=0.1, role="arm"),
        DHJoint(a=-0.2, alpha=-1.1, d=0.05, theta=-0.7, kind="prismatic", lower=-0.5, upper=0.5),
        DHJoint(a=0.1, alpha=1.3, d=-0.3, theta=2.0, role="wrist"),
    ]
    base, tool = _random_pose(rng), _random_pose(rng)
    robot = Robot.from_dh(rows, base=base, tool=tool)
    for q in random_q(robot, rng, N_CONFIGS):
        chain = (
            dh_matrix(0.3, 0.4, 0.2, 0.1 + q[0])
            @ dh_matrix(-0.2, -1.1, 0.05 + q[1], -0.7)
            @ dh_matrix(0.1, 1.3, -0.3, 2.0 + q[2])
        )
        assert_close(robot.fk(q), base @ chain @ tool, atol=1e-12)


def test_mdh_prismatic_with_offsets(rng: np.random.Generator) -> None:
    """Modified DH with a prismatic joint whose theta and d offsets are non-zero."""
    rows = [
        DHJoint(a=0.0, alpha=0.0, d=0.1, theta=0.2, role="arm"),
        DHJoint(a=0.25, alpha=-0.9, d=0.15, theta=0.6, kind="prismatic", lower=0.0, upper=0.4),
        DHJoint(a=-0.1, alpha=1.2, d=0.07, theta=-0.3, role="wrist"),
    ]
    tool = _random_pose(rng)
    robot = Robot.from_mdh(rows, tool=tool)
    for q in random_q(robot, rng, N_CONFIGS):
        chain = (
            mdh_matrix(0.0, 0.0, 0.2 + q[0], 0.1)
            @ mdh_matrix(-0.9, 0.25, 0.6, 0.15 + q[1])
            @ mdh_matrix(1.2, -0.1, -0.3 + q[2], 0.07)
        )
        assert_close(robot.fk(q), chain @ tool, atol=1e-12)


def test_offsets_are_values_at_zero() -> None:
    """The stated theta (revolute) / d (prismatic) is the joint's value at q = 0."""
    robot = Robot.from_dh(
        [
            DHJoint(a=1.0, theta=math.pi / 2, role="arm"),
            DHJoint(d=0.5, kind="prismatic", lower=0.0, upper=1.0),
        ]
    )
    T = robot.fk([0.0, 0.0])
    assert_close(T[:3, 3], [0.0, 1.0, 0.5], atol=1e-15)
    T = robot.fk([-math.pi / 2, 0.25])
    assert_close(T[:3, 3], [1.0, 0.0, 0.75], atol=1e-15)


def test_mimic_multiplier_scales_chain_variable(rng: np.random.Generator) -> None:
    rows = [
        DHJoint(a=0.4, name="drive", role="arm"),
        DHJoint(a=0.3, name="follower", theta=0.2, mimic=Mimic("drive", -2.5)),
        DHJoint(a=0.2, name="last", role="wrist"),
    ]
    robot = Robot.from_dh(rows)
    assert robot.dof == 2
    assert robot.joint_names == ("drive", "last")
    for q in random_q(robot, rng, N_CONFIGS):
        chain = (
            dh_matrix(0.4, 0.0, 0.0, q[0])
            @ dh_matrix(0.3, 0.0, 0.0, 0.2 - 2.5 * q[0])
            @ dh_matrix(0.2, 0.0, 0.0, q[1])
        )
        assert_close(robot.fk(q), chain, atol=1e-12)
        # Planar chain: the Jacobian's angular z row is the summed coupling.
        assert_close(robot.jacobian(q)[5], [1.0 - 2.5, 1.0], atol=1e-14)


# ---------------------------------------------------------------------- Jacobian
def test_jacobian_matches_finite_differences(
    problem_robot: Robot, rng: np.random.Generator
) -> None:
    scale = _reach(problem_robot)
    for q in random_q(problem_robot, rng, N_CONFIGS):
        J = problem_robot.jacobian(q)
        assert J.shape == (6, problem_robot.dof)
        assert_close(J, fd_jacobian(problem_robot, q), atol=2e-8 * scale, what=problem_robot.name)


@pytest.mark.parametrize("name", ["stanford_arm", "jumbo_drill_6dof", "jumbo_spherical_arm"])
def test_prismatic_column_is_axis_without_rotation(name: str, rng: np.random.Generator) -> None:
    robot = robot_of(name)
    k = next(i for i, j in enumerate(robot.joints) if j.kind == "prismatic")
    for q in random_q(robot, rng, 5):
        frames = reference_frames(robot, q)
        z_axis = frames[k][:3, 2]  # standard DH: joint k+1 moves along z_k
        J = robot.jacobian(q)
        assert_close(J[:3, k], z_axis, atol=1e-13)
        assert_close(J[3:, k], np.zeros(3), atol=0.0)


def test_fk_jacobian_pose_and_jacobian(problem_robot: Robot, rng: np.random.Generator) -> None:
    """The one-pass kernel: its pose against the DH product, its Jacobian against FD."""
    for q in random_q(problem_robot, rng, 5):
        T, J = problem_robot.fk_jacobian(q)
        assert_close(T, reference_fk(problem_robot, q), atol=1e-12 * _reach(problem_robot))
        assert_close(J, fd_jacobian(problem_robot, q), atol=2e-8 * _reach(problem_robot))


# ---------------------------------------------------------------------- batches
def test_batched_equals_per_configuration(problem_robot: Robot, rng: np.random.Generator) -> None:
    Q = random_q(problem_robot, rng, N_CONFIGS)
    T = problem_robot.fk(Q)
    J = problem_robot.jacobian(Q)
    T2, _ = problem_robot.fk_jacobian(Q)  # its Jacobian is what jacobian(Q) returns
    assert T.shape == (N_CONFIGS, 4, 4)
    assert J.shape == (N_CONFIGS, 6, problem_robot.dof)
    for k, q in enumerate(Q):
        assert_close(T[k], problem_robot.fk(q), atol=1e-14)
        assert_close(J[k], problem_robot.jacobian(q), atol=1e-14)
        assert_close(T2[k], T[k], atol=1e-14)  # two different kernels
        assert_close(T[k], reference_fk(problem_robot, q), atol=1e-12 * _reach(problem_robot))


def test_batch_of_one_and_list_input() -> None:
    robot = robot_of("puma560")
    q = robot.mid_limits
    assert robot.fk(q[None, :]).shape == (1, 4, 4)
    assert_close(robot.fk(q[None, :])[0], robot.fk(q), atol=0.0)
    assert_close(robot.fk(list(q)), robot.fk(q), atol=0.0)
    assert robot.fk(np.zeros((0, robot.dof))).shape == (0, 4, 4)


# ---------------------------------------------------------------------- frames
def test_frames_match_dh_partial_products(problem_robot: Robot, rng: np.random.Generator) -> None:
    n_chain = len(problem_robot.chain_names)
    for q in random_q(problem_robot, rng, 5):
        frames = problem_robot.frames(q)
        assert frames.shape == (n_chain + 2, 4, 4)
        assert_close(frames[0], problem_robot.T_world_base, atol=0.0)
        assert_close(frames[-1], problem_robot.fk(q), atol=1e-14)
        expected = reference_frames(problem_robot, q)
        for i, (got, want) in enumerate(zip(frames, expected, strict=True)):
            assert_close(got, want, atol=1e-12 * _reach(problem_robot), what=f"frame {i}")


def test_frames_with_base_and_tool(rng: np.random.Generator) -> None:
    base, tool = _random_pose(rng), _random_pose(rng)
    rows = [DHJoint(a=0.5, alpha=0.3, role="arm"), DHJoint(a=0.4, d=0.1, role="arm")]
    robot = Robot.from_dh(rows, base=base, tool=tool)
    q = np.array([0.4, -0.8])
    frames = robot.frames(q)
    A1, A2 = dh_matrix(0.5, 0.3, 0.0, 0.4), dh_matrix(0.4, 0.0, 0.1, -0.8)
    assert_close(frames[0], base, atol=0.0)
    assert_close(frames[1], base @ A1, atol=1e-14)
    assert_close(frames[2], base @ A1 @ A2, atol=1e-14)
    assert_close(frames[3], base @ A1 @ A2 @ tool, atol=1e-14)


# ---------------------------------------------------------------------- DOBOT closed form
def test_dobot_closed_form_position_and_yaw(rng: np.random.Generator) -> None:
    """Seed 001's common model, independent of the DH rows and of the coupling matrix."""
    robot = robot_of("dobot_magician")
    for q in random_q(robot, rng, N_CONFIGS):
        j1, j2, j3, j4 = q
        r = 0.135 * math.sin(j2) + 0.147 * math.cos(j3)
        z = 0.138 + 0.135 * math.cos(j2) - 0.147 * math.sin(j3)
        T = robot.fk(q)
        assert_close(T[:3, 3], [r * math.cos(j1), r * math.sin(j1), z], atol=1e-14)
        assert_close(T[:3, :3], _rz(j1 + j4), atol=1e-14)


def test_dobot_known_configuration_in_millimetres() -> None:
    # J = (0, 0, 0, 0): rear arm vertical, forearm horizontal -> (147, 0, 138 + 135) mm.
    robot = robot_of("dobot_magician")
    assert_close(robot.fk(np.zeros(4))[:3, 3] * 1000.0, [147.0, 0.0, 273.0], atol=1e-10)
    # J2 = 90 deg is outside the limits but the model holds there: rear arm horizontal.
    q = np.radians([90.0, 90.0, 90.0, 0.0])
    assert_close(robot.fk(q)[:3, 3] * 1000.0, [0.0, 135.0, 138.0 - 147.0], atol=1e-10)


# ---------------------------------------------------------------------- properties
@pytest.mark.parametrize("name", PROBLEM_NAMES)
@given(data=st.data())
def test_fk_is_rigid_transform(name: str, data: st.DataObject) -> None:
    robot = robot_of(name)
    lo = np.where(np.isfinite(robot.lower), robot.lower, -math.pi)
    hi = np.where(np.isfinite(robot.upper), robot.upper, math.pi)
    u = np.array(data.draw(st.lists(st.floats(0.0, 1.0), min_size=robot.dof, max_size=robot.dof)))
    q = lo + u * (hi - lo)
    assert robot.within_limits(q)
    T = robot.fk(q)
    assert_rigid(T, atol=1e-12)
    # Jacobian columns: unit axes (revolute angular part, prismatic linear part).
    J = robot.jacobian(q)
    C = robot.coupling
    for k, joint in enumerate(robot.joints):
        if C[:, k].sum() != 1.0 or np.count_nonzero(C[:, k]) != 1:
            continue  # a coupled coordinate drives several axes
        axis = J[:3, k] if joint.kind == "prismatic" else J[3:, k]
        assert_close(np.linalg.norm(axis), 1.0, atol=1e-12)
