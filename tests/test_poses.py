"""Pose forms: every conversion against scipy's Rotation and written-out matrices."""

from __future__ import annotations

import math
import re
import warnings
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from conftest import assert_close, assert_rigid
from hypothesis import given
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

import optik
from optik.errors import (
    ArgumentError,
    InvalidRotationError,
    NonFiniteError,
    OptikError,
    ShapeError,
)
from optik.poses import (
    QUAT_NORM_TOLERANCE,
    RPY_CONVENTIONS,
    TARGET_KEYS,
    InvalidQuaternionError,
    PoseArgumentError,
    PositionOnlyTargetError,
    as_target_pose,
    pose,
    to_position_rotation,
    to_quat_wxyz,
    to_quat_xyzw,
    to_rotation,
    to_rpy,
)
from optik.spatial import as_target, rotation_angle, rpy_to_matrix

ROOT = Path(__file__).resolve().parent.parent
H = math.sqrt(0.5)  # cos 45° = sin 45°

# Rotations by +90° about x, y and z, written out (columns are the images of x, y, z).
RX90 = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])
RY90 = np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]])
RZ90 = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
QUARTER_TURNS = [  # (axis, matrix, quaternion (w, x, y, z))
    ("x", RX90, (H, H, 0.0, 0.0)),
    ("y", RY90, (H, 0.0, H, 0.0)),
    ("z", RZ90, (H, 0.0, 0.0, H)),
]


def hamilton_matrix(q_wxyz: Any) -> np.ndarray:
    """Rotation matrix of a unit quaternion (w, x, y, z), the textbook formula."""
    w, x, y, z = np.asarray(q_wxyz, dtype=float) / np.linalg.norm(q_wxyz)
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )


def rpy_product(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """Rz(yaw) Ry(pitch) Rx(roll), each factor written out here."""
    cr, sr, cp, sp, cy, sy = (f(a) for a in (roll, pitch, yaw) for f in (math.cos, math.sin))
    Rx = np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
    Ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    Rz = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]])
    return Rz @ Ry @ Rx


def same_quaternion(a: Any, b: Any, atol: float = 1e-12) -> None:
    """Assert ``a`` equals ``b`` or ``-b``: q and -q are the same rotation."""
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    sign = np.where(np.sum(a * b, axis=-1, keepdims=True) < 0.0, -1.0, 1.0)
    assert_close(a, sign * b, atol=atol)


# ---------------------------------------------------------------------- strategies
components = st.floats(-1.0, 1.0, allow_nan=False)
quaternions = (
    st.tuples(components, components, components, components)
    .map(np.array)
    .filter(lambda q: np.linalg.norm(q) > 0.1)
    .map(lambda q: q / np.linalg.norm(q))
)
angles = st.floats(-math.pi, math.pi, allow_nan=False)
# Offsets from pitch = ±90°, from exact gimbal lock out to clearly regular.
lock_offsets = st.sampled_from([0.0, 1e-15, 1e-12, 1e-9, 1e-8, 1e-7, 1e-6, 1e-4, 1e-2]).flatmap(
    lambda d: st.sampled_from([d, -d])
)
positions = st.tuples(*[st.floats(-2.0, 2.0, allow_nan=False)] * 3).map(np.array)


# ---------------------------------------------------------------------- the convention itself
def test_urdf_rpy_is_scipy_extrinsic_xyz_and_optik_rpy_to_matrix() -> None:
    # The meaning stated in RPY_CONVENTIONS["urdf"], checked on non-trivial angles.
    r, p, y = 0.3, -0.7, 1.9
    R = rpy_product(r, p, y)
    assert_close(rpy_to_matrix(r, p, y), R, atol=1e-15)
    assert_close(Rotation.from_euler("xyz", [r, p, y]).as_matrix(), R, atol=1e-15)
    assert_close(Rotation.from_euler("ZYX", [y, p, r]).as_matrix(), R, atol=1e-15)
    assert_close(pose(rpy=(r, p, y), rpy_convention="urdf")[:3, :3], R, atol=1e-15)
    assert "Rz(yaw) Ry(pitch) Rx(roll)" in RPY_CONVENTIONS["urdf"]


# ---------------------------------------------------------------------- known values
@pytest.mark.parametrize(("axis", "R", "q"), QUARTER_TURNS)
def test_quarter_turns_in_every_form(axis: str, R: np.ndarray, q: tuple[float, ...]) -> None:
    w, x, y, z = q
    expected = np.eye(4)
    expected[:3, :3] = R
    rpy_deg = {"x": (90.0, 0.0, 0.0), "y": (0.0, 90.0, 0.0), "z": (0.0, 0.0, 90.0)}[axis]
    built = [
        pose(quat_wxyz=q),
        pose(quat_xyzw=(x, y, z, w)),
        pose(rotation=R),
        pose(None, Rotation.from_euler(axis, 90, degrees=True)),
        pose(rpy=rpy_deg, rpy_convention="urdf", degrees=True),
        pose(rpy=np.radians(rpy_deg), rpy_convention="urdf"),
    ]
    for T in built:
        assert_close(T, expected, atol=1e-15)
    assert_close(to_quat_wxyz(expected), q, atol=1e-15)
    assert_close(to_quat_xyzw(expected), (x, y, z, w), atol=1e-15)
    assert_close(to_rpy(expected, rpy_convention="urdf", degrees=True), rpy_deg, atol=1e-12)
    assert_close(to_rotation(expected).as_matrix(), R, atol=1e-15)


def test_quaternion_order_is_never_guessed() -> None:
    # The same four numbers read scalar-first and scalar-last are different rotations.
    numbers = (H, H, 0.0, 0.0)
    assert_close(pose(quat_wxyz=numbers)[:3, :3], RX90, atol=1e-15)
    xyzw = pose(quat_xyzw=numbers)[:3, :3]  # x = y = sqrt(1/2): half a turn about x + y
    assert_close(xyzw, hamilton_matrix((0.0, H, H, 0.0)), atol=1e-15)
    assert rotation_angle(xyzw) == pytest.approx(math.pi)


def test_half_turns_have_a_canonical_quaternion() -> None:
    # w = 0: the first nonzero entry is made positive, whatever sign scipy returns.
    for R, q in (
        (np.diag([1.0, -1.0, -1.0]), (0.0, 1.0, 0.0, 0.0)),
        (np.diag([-1.0, 1.0, -1.0]), (0.0, 0.0, 1.0, 0.0)),
        (np.diag([-1.0, -1.0, 1.0]), (0.0, 0.0, 0.0, 1.0)),
    ):
        assert_close(to_quat_wxyz(pose(rotation=R)), q, atol=1e-15)
        assert_close(to_quat_wxyz(pose(quat_wxyz=-np.array(q))), q, atol=1e-15)


def test_position_and_identity() -> None:
    assert_close(pose(), np.eye(4), atol=0.0)
    T = pose((0.1, -0.2, 0.3))
    assert_close(T[:3, 3], (0.1, -0.2, 0.3), atol=0.0)
    assert_close(T[:3, :3], np.eye(3), atol=0.0)
    assert T.dtype == np.float64
    p, R = to_position_rotation(T)
    assert_close(p, (0.1, -0.2, 0.3), atol=0.0)
    assert_close(R, np.eye(3), atol=0.0)


# ---------------------------------------------------------------------- properties over rotations
@given(quaternions, positions)
def test_quaternion_forms_match_hamilton_and_scipy(q: np.ndarray, p: np.ndarray) -> None:
    T = pose(p, quat_wxyz=q)
    assert_rigid(T, atol=1e-14)
    assert_close(T[:3, :3], hamilton_matrix(q), atol=1e-14)
    assert_close(T[:3, :3], Rotation.from_quat(np.roll(q, -1)).as_matrix(), atol=1e-14)
    assert_close(T[:3, 3], p, atol=0.0)
    assert_close(pose(p, quat_xyzw=np.roll(q, -1)), T, atol=1e-15)
    assert_close(pose(p, quat_wxyz=-q), T, atol=1e-15)  # q and -q: one rotation
    same_quaternion(to_quat_wxyz(T), q, atol=1e-14)
    same_quaternion(to_quat_xyzw(T), np.roll(q, -1), atol=1e-14)
    assert to_quat_wxyz(T)[0] >= 0.0
    assert_close(np.linalg.norm(to_quat_wxyz(T)), 1.0, atol=1e-15)


@given(quaternions, positions)
def test_matrix_scipy_and_pair_round_trips(q: np.ndarray, p: np.ndarray) -> None:
    rotation = Rotation.from_quat(np.roll(q, -1))
    T = pose(p, rotation)
    assert_close(T[:3, :3], rotation.as_matrix(), atol=0.0)
    assert_close(pose(p, rotation=rotation.as_matrix()), T, atol=0.0)
    assert_close(pose(*to_position_rotation(T)), T, atol=0.0)
    back = to_rotation(T)
    assert isinstance(back, Rotation)
    assert back.single
    assert rotation_angle(back.as_matrix().T @ rotation.as_matrix()) < 1e-14
    assert_close(as_target_pose((p, rotation), "pose"), T, atol=0.0)
    assert_close(as_target_pose((p, rotation.as_matrix()), "pose"), T, atol=0.0)


@given(angles, st.floats(-math.pi / 2, math.pi / 2), angles)
def test_rpy_round_trip_against_scipy(roll: float, pitch: float, yaw: float) -> None:
    T = pose(rpy=(roll, pitch, yaw), rpy_convention="urdf")
    assert_close(T[:3, :3], rpy_product(roll, pitch, yaw), atol=1e-15)
    assert_close(T[:3, :3], Rotation.from_euler("xyz", [roll, pitch, yaw]).as_matrix(), atol=1e-15)
    rpy = to_rpy(T, rpy_convention="urdf")
    assert np.all(np.abs(rpy[[0, 2]]) <= math.pi + 1e-15)
    assert abs(rpy[1]) <= math.pi / 2 + 1e-15
    back = rpy_product(*rpy)
    # Away from pitch = ±90° the angles come back; near it only the rotation does.
    bound = 1e-13 if math.cos(pitch) > 1e-3 else 2.5e-7
    assert rotation_angle(back.T @ T[:3, :3]) <= bound
    if math.cos(pitch) > 1e-3 and abs(roll) < math.pi - 1e-9 and abs(yaw) < math.pi - 1e-9:
        assert_close(rpy, (roll, pitch, yaw), atol=1e-10)
    degrees = to_rpy(T, rpy_convention="urdf", degrees=True)
    assert_close(degrees, np.degrees(rpy), atol=1e-12)
    assert_close(pose(rpy=degrees, rpy_convention="urdf", degrees=True), T, atol=1e-14)


@given(angles, lock_offsets, st.sampled_from([1.0, -1.0]), angles)
def test_rpy_near_gimbal_lock(roll: float, offset: float, side: float, yaw: float) -> None:
    pitch = side * (math.pi / 2 - offset)
    R = rpy_product(roll, pitch, yaw)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # scipy's gimbal-lock warning does not reach the user
        rpy = to_rpy(pose(rotation=R), rpy_convention="urdf")
    assert np.all(np.isfinite(rpy))
    assert abs(rpy[1]) <= math.pi / 2 + 1e-15
    # The documented bound: within 2.5e-7 rad near the lock (2.0e-7 measured).
    assert rotation_angle(rpy_product(*rpy).T @ R) <= 2.5e-7
    if offset == 0.0:
        assert rpy[2] == 0.0  # at the lock, the documented choice: yaw 0
    assert_close(pose(rpy=rpy, rpy_convention="urdf")[:3, :3], rpy_product(*rpy), atol=1e-15)


# ---------------------------------------------------------------------- batches
def test_batches_equal_stacked_singles(rng: np.random.Generator) -> None:
    n = 7
    q = rng.normal(size=(n, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    p = rng.uniform(-1.0, 1.0, size=(n, 3))
    rpy = rng.uniform(-3.0, 3.0, size=(n, 3))
    rpy[:, 1] = rng.uniform(-1.5, 1.5, size=n)
    rotation = Rotation.from_quat(np.roll(q, -1, axis=1))
    cases = [
        (pose(p, quat_wxyz=q), [pose(p[i], quat_wxyz=q[i]) for i in range(n)]),
        (pose(p, quat_xyzw=q), [pose(p[i], quat_xyzw=q[i]) for i in range(n)]),
        (pose(p, rotation), [pose(p[i], rotation[i]) for i in range(n)]),
        (pose(p, rotation.as_matrix()), [pose(p[i], rotation[i].as_matrix()) for i in range(n)]),
        (
            pose(p, rpy=rpy, rpy_convention="urdf"),
            [pose(p[i], rpy=rpy[i], rpy_convention="urdf") for i in range(n)],
        ),
        (pose(p), [pose(p[i]) for i in range(n)]),
    ]
    for batch, singles in cases:
        assert batch.shape == (n, 4, 4)
        assert_close(batch, np.stack(singles), atol=1e-15)
        assert_rigid(batch, atol=1e-14)
    T = pose(p, quat_wxyz=q)
    assert_close(to_quat_wxyz(T), np.stack([to_quat_wxyz(t) for t in T]), atol=1e-15)
    assert_close(to_quat_xyzw(T), np.stack([to_quat_xyzw(t) for t in T]), atol=1e-15)
    same_quaternion(to_quat_wxyz(T), q, atol=1e-14)
    assert np.all(to_quat_wxyz(T)[:, 0] >= 0.0)
    assert_close(
        to_rpy(T, rpy_convention="urdf"),
        np.stack([to_rpy(t, rpy_convention="urdf") for t in T]),
        atol=1e-15,
    )
    positions_back, rotations_back = to_position_rotation(T)
    assert positions_back.shape == (n, 3)
    assert rotations_back.shape == (n, 3, 3)
    assert_close(positions_back, p, atol=0.0)
    assert len(to_rotation(T)) == n
    assert_close(to_rotation(T).as_matrix(), T[:, :3, :3], atol=1e-15)


def test_a_single_value_is_repeated_along_a_batch(rng: np.random.Generator) -> None:
    p = rng.uniform(-1.0, 1.0, size=(4, 3))
    T = pose(p, quat_wxyz=(H, H, 0.0, 0.0))
    assert T.shape == (4, 4, 4)
    assert_close(T[:, :3, :3], np.broadcast_to(RX90, (4, 3, 3)), atol=1e-15)
    assert_close(T[:, :3, 3], p, atol=0.0)
    U = pose((1.0, 2.0, 3.0), rpy=np.zeros((3, 3)), rpy_convention="urdf")
    assert U.shape == (3, 4, 4)
    assert_close(U[:, :3, 3], np.tile([1.0, 2.0, 3.0], (3, 1)), atol=0.0)


def test_empty_batches() -> None:
    T = pose(np.zeros((0, 3)), quat_wxyz=np.zeros((0, 4)))
    assert T.shape == (0, 4, 4)
    assert to_quat_wxyz(T).shape == (0, 4)
    assert to_rpy(T, rpy_convention="urdf").shape == (0, 3)
    assert pose(rpy=np.zeros((0, 3)), rpy_convention="urdf").shape == (0, 4, 4)
    assert as_target_pose(np.zeros((0, 4, 4)), "pose", batch=True).shape == (0, 4, 4)


def test_converters_return_copies() -> None:
    T = pose((1.0, 2.0, 3.0), RZ90)
    p, R = to_position_rotation(T)
    p[:] = 0.0
    R[:] = 0.0
    assert_close(T[:3, 3], (1.0, 2.0, 3.0), atol=0.0)
    assert_close(T[:3, :3], RZ90, atol=0.0)


# ---------------------------------------------------------------------- quaternion norms
def test_near_unit_quaternions_are_normalised() -> None:
    four_decimals = (0.7071, 0.0, 0.0, 0.7071)  # norm 0.99999: as people write it
    assert_close(pose(quat_wxyz=four_decimals)[:3, :3], RZ90, atol=1e-15)
    scale = 1.0 + 0.9 * QUAT_NORM_TOLERANCE
    q = np.array([0.5, -0.5, 0.5, 0.5])
    assert_close(pose(quat_wxyz=scale * q), pose(quat_wxyz=q), atol=1e-15)
    assert_rigid(pose(quat_xyzw=scale * q), atol=1e-15)


@pytest.mark.parametrize("key", ["quat_wxyz", "quat_xyzw"])
def test_bad_quaternions_are_rejected(key: str) -> None:
    with pytest.raises(InvalidQuaternionError, match=rf"^{key}: zero quaternion") as zero:
        pose(**{key: (0.0, 0.0, 0.0, 0.0)})
    assert zero.value.norm == 0.0
    too_long = 1.0 + 1.1 * QUAT_NORM_TOLERANCE
    with pytest.raises(InvalidQuaternionError, match=rf"^{key}: quaternion norm") as far:
        pose(**{key: (too_long, 0.0, 0.0, 0.0)})
    assert far.value.norm == pytest.approx(too_long)
    assert far.value.tolerance == QUAT_NORM_TOLERANCE
    assert isinstance(far.value, OptikError)
    with pytest.raises(InvalidQuaternionError, match=r"row 2") as row:
        pose(**{key: [(1.0, 0, 0, 0), (1.0, 0, 0, 0), (0.0, 0, 0, 0)]})
    assert row.value.index == 2
    with pytest.raises(InvalidQuaternionError, match=r"quaternion norm 2"):
        pose(**{key: (1.0, 1.0, 1.0, 1.0)})  # four numbers that are not a unit quaternion
    with pytest.raises(ShapeError, match=rf"^{key}: expected shape \(4,\) or \(N, 4\)"):
        pose(**{key: (1.0, 0.0, 0.0)})
    with pytest.raises(NonFiniteError, match=rf"^{key}:"):
        pose(**{key: (math.nan, 0.0, 0.0, 1.0)})


# ---------------------------------------------------------------------- pose() argument errors
def test_one_rotation_form_at_most() -> None:
    with pytest.raises(PoseArgumentError, match=r"quat_wxyz and rpy: give at most one") as err:
        pose(quat_wxyz=(1, 0, 0, 0), rpy=(0, 0, 0), rpy_convention="urdf")
    assert err.value.name == "quat_wxyz and rpy"
    with pytest.raises(PoseArgumentError, match=r"rotation and quat_xyzw"):
        pose(None, np.eye(3), quat_xyzw=(0, 0, 0, 1))
    with pytest.raises(PoseArgumentError, match=r"quat_wxyz and quat_xyzw"):
        pose(quat_wxyz=(1, 0, 0, 0), quat_xyzw=(0, 0, 0, 1))


def test_rpy_needs_its_convention_named() -> None:
    with pytest.raises(PoseArgumentError, match=r'^rpy_convention: required.*"urdf"'):
        pose(rpy=(0.1, 0.2, 0.3))
    with pytest.raises(PoseArgumentError, match=r"unknown convention 'zyx'.*'urdf'"):
        pose(rpy=(0.1, 0.2, 0.3), rpy_convention="zyx")
    with pytest.raises(PoseArgumentError, match=r"^rpy_convention: given without rpy"):
        pose(quat_wxyz=(1, 0, 0, 0), rpy_convention="urdf")
    with pytest.raises(PoseArgumentError, match=r"^degrees: applies to rpy only"):
        pose((0, 0, 0), degrees=True)
    with pytest.raises(PoseArgumentError, match=r"^degrees: expected True or False"):
        pose(rpy=(0, 0, 0), rpy_convention="urdf", degrees="yes")  # type: ignore[arg-type]
    with pytest.raises(ShapeError, match=r"^rpy: expected shape \(3,\) or \(N, 3\)"):
        pose(rpy=(0.1, 0.2), rpy_convention="urdf")
    with pytest.raises(NonFiniteError, match=r"^rpy:"):
        pose(rpy=(0.1, math.inf, 0.3), rpy_convention="urdf")
    with pytest.raises(PoseArgumentError, match=r"^rpy_convention: required"):
        to_rpy(np.eye(4))
    with pytest.raises(PoseArgumentError, match=r"unknown convention"):
        to_rpy(np.eye(4), rpy_convention="ZYX")
    with pytest.raises(PoseArgumentError, match=r"^degrees:"):
        to_rpy(np.eye(4), rpy_convention="urdf", degrees=1)  # type: ignore[arg-type]


def test_rotation_matrices_use_optiks_check() -> None:
    off = np.eye(3)
    off[0, 1] = 1e-5  # max |R^T R - I| = 1e-5 > 1e-6
    with pytest.raises(InvalidRotationError, match=r"^rotation: not a rotation matrix"):
        pose(rotation=off)
    within = np.eye(3)
    within[0, 1] = 1e-7  # inside the tolerance of optik.spatial.check_rotation
    assert_close(pose(rotation=within)[:3, :3], within, atol=0.0)
    with pytest.raises(InvalidRotationError, match=r"det = -1") as reflection:
        pose(rotation=np.diag([1.0, 1.0, -1.0]))
    assert reflection.value.determinant == pytest.approx(-1.0)
    batch = np.stack([np.eye(3), np.diag([-1.0, 1.0, 1.0])])
    with pytest.raises(InvalidRotationError):
        pose(rotation=batch)
    with pytest.raises(NonFiniteError, match=r"^rotation:"):
        pose(rotation=np.full((3, 3), math.nan))
    with pytest.raises(ShapeError, match=r"a quaternion goes to quat_wxyz= or quat_xyzw="):
        pose((0, 0, 0), (1.0, 0.0, 0.0, 0.0))
    with pytest.raises(ShapeError, match=r"^rotation:"):
        pose(rotation=np.eye(4))


def test_position_errors() -> None:
    with pytest.raises(ShapeError, match=r"^position: expected shape \(3,\) or \(N, 3\)"):
        pose((1.0, 2.0))
    with pytest.raises(ShapeError, match=r"^position:"):
        pose(np.eye(4))
    with pytest.raises(NonFiniteError, match=r"^position: .* index \(1,\)"):
        pose((1.0, math.nan, 2.0))
    with pytest.raises(ArgumentError, match=r"^position: expected a numeric array"):
        pose(("a", "b", "c"))
    with pytest.raises(PoseArgumentError, match=r"^position: got a \(p, R\) pair; .*pose\(p, R\)"):
        pose(((1.0, 2.0, 3.0), np.eye(3)))


def test_batch_lengths_must_agree() -> None:
    with pytest.raises(ShapeError, match=r"^quat_wxyz: expected shape a single rotation or 2"):
        pose(np.zeros((2, 3)), quat_wxyz=np.tile([1.0, 0, 0, 0], (3, 1)))
    with pytest.raises(ShapeError, match=r"^rotation:"):
        pose(np.zeros((2, 3)), Rotation.identity(3))


# ---------------------------------------------------------------------- IK targets
def test_array_targets_follow_todays_rules(rng: np.random.Generator) -> None:
    T = pose(rng.uniform(-1, 1, 3), Rotation.from_rotvec(rng.normal(size=3)))
    assert as_target_pose(T, "pose") is T  # validated, not copied (the hot path)
    assert_close(as_target_pose(T.tolist(), "pose"), as_target(T.tolist(), "pose"), atol=0.0)
    assert_close(as_target_pose(T, "position"), as_target(T, "position"), atol=0.0)
    assert_close(as_target_pose(T[:3, 3], "position"), as_target(T[:3, 3], "position"), atol=0.0)
    # Position mode drops the rotation without touching the caller's array.
    assert_close(as_target_pose(T, "position")[:3, :3], np.eye(3), atol=0.0)
    assert rotation_angle(T[:3, :3]) > 0.0
    for bad in (
        np.diag([1.0, 1.0, -1.0, 1.0]),  # det -1
        pose(rotation=np.eye(3)) + np.eye(4) * 1e-5 * np.r_[1, 0, 0, 0],  # not orthonormal
        np.vstack([np.eye(4)[:3], [0.0, 0.0, 1e-6, 1.0]]),  # last row
        np.full((4, 4), math.nan),
        np.eye(3),
    ):
        for mode in ("pose", "position"):
            with pytest.raises(OptikError) as mine:
                as_target_pose(bad, mode)
            with pytest.raises(OptikError) as todays:
                as_target(bad, mode)
            assert type(mine.value) is type(todays.value)
            assert str(mine.value) == str(todays.value)


@pytest.mark.parametrize("batch", [False, True])
def test_a_bare_position_says_how_to_ask_for_position_only(batch: bool) -> None:
    p = np.zeros((5, 3)) if batch else np.zeros(3)
    with pytest.raises(PositionOnlyTargetError, match=r'pass mode="position"') as err:
        as_target_pose(p, "pose", name="targets" if batch else "target", batch=batch)
    assert isinstance(err.value, ShapeError)  # as a 3-vector in pose mode always was
    assert err.value.got == p.shape
    assert str(err.value).startswith("targets:" if batch else "target:")
    assert "optik.pose(p, quat_wxyz=q)" in str(err.value)
    with pytest.raises(PositionOnlyTargetError, match=r'"position" only.*mode="position"'):
        as_target_pose({"position": (1.0, 2.0, 3.0)}, "pose")
    T = as_target_pose(p, "position", batch=batch)
    assert T.shape == ((5, 4, 4) if batch else (4, 4))
    assert_close(T, np.broadcast_to(np.eye(4), T.shape), atol=0.0)


def test_pair_and_mapping_targets(rng: np.random.Generator) -> None:
    q = rng.normal(size=4)
    q /= np.linalg.norm(q)
    p = rng.uniform(-1, 1, 3)
    T = pose(p, quat_wxyz=q)
    R = T[:3, :3]
    rpy = to_rpy(T, rpy_convention="urdf")
    forms: list[Any] = [
        (p, R),
        [p, R],
        (tuple(p), R.tolist()),
        (p, Rotation.from_matrix(R)),
        {"position": p, "quat_wxyz": q},
        {"position": p, "quat_xyzw": np.roll(q, -1)},
        {"position": p, "quat_wxyz": -q},
        {"position": p, "rotation": R},
        {"position": p, "rotation": Rotation.from_matrix(R)},
        {"position": p, "rpy": rpy, "rpy_convention": "urdf"},
        {"position": p, "rpy": np.degrees(rpy), "rpy_convention": "urdf", "degrees": True},
    ]
    for form in forms:
        assert_close(as_target_pose(form, "pose"), T, atol=1e-14)
        only = as_target_pose(form, "position")
        assert_close(only[:3, 3], p, atol=0.0)
        assert_close(only[:3, :3], np.eye(3), atol=0.0)
    assert_close(as_target_pose({"position": p}, "position"), pose(p), atol=0.0)
    assert set(TARGET_KEYS) == {
        "position",
        "rotation",
        "quat_wxyz",
        "quat_xyzw",
        "rpy",
        "rpy_convention",
        "degrees",
    }


def test_batched_targets(rng: np.random.Generator) -> None:
    n = 4
    p = rng.uniform(-1, 1, (n, 3))
    rotation = Rotation.from_rotvec(rng.normal(size=(n, 3)))
    T = pose(p, rotation)
    for form in (
        T,
        (p, rotation),
        (p, rotation.as_matrix()),
        {"position": p, "rotation": rotation},
    ):
        assert_close(as_target_pose(form, "pose", batch=True), T, atol=0.0)
    assert_close(as_target_pose(p, "position", batch=True), pose(p), atol=0.0)
    assert_close(as_target_pose(T, "position", batch=True), pose(p), atol=0.0)
    with pytest.raises(ShapeError, match=r"^targets: expected shape \(N, 4, 4\) \(a batch\)"):
        as_target_pose(T[0], "pose", name="targets", batch=True)
    with pytest.raises(ShapeError, match=r"^target: expected shape \(4, 4\), got \(4, 4, 4\)"):
        as_target_pose(T, "pose")
    with pytest.raises(ShapeError, match=r"^target: expected shape a single pose"):
        as_target_pose((p, rotation), "pose")
    with pytest.raises(ShapeError, match=r"^targets: expected shape \(N, 3\) or \(N, 4, 4\)"):
        as_target_pose(np.zeros((n, 2)), "position", name="targets", batch=True)
    bad = T.copy()
    bad[2, :3, :3] = np.diag([1.0, 1.0, -1.0])
    with pytest.raises(InvalidRotationError, match=r"^targets:"):
        as_target_pose(bad, "pose", name="targets", batch=True)


def test_target_errors_name_the_part() -> None:
    p = (0.1, 0.2, 0.3)
    with pytest.raises(InvalidQuaternionError, match=r'^target\["quat_wxyz"\]: zero'):
        as_target_pose({"position": p, "quat_wxyz": (0, 0, 0, 0)}, "pose")
    with pytest.raises(InvalidQuaternionError, match=r'^goal\["quat_xyzw"\]:'):
        as_target_pose({"position": p, "quat_xyzw": (0, 0, 0, 2)}, "position", name="goal")
    with pytest.raises(InvalidRotationError, match=r"^target\[1\]:"):
        as_target_pose((p, np.diag([1.0, -1.0, 1.0])), "pose")
    with pytest.raises(ShapeError, match=r"^target\[0\]:"):
        as_target_pose(((0.1, 0.2), np.eye(3)), "pose")
    with pytest.raises(PoseArgumentError, match=r'^target\["quat_wxyz"\] and target\["rpy"\]'):
        as_target_pose({"position": p, "quat_wxyz": (1, 0, 0, 0), "rpy": (0, 0, 0)}, "pose")
    with pytest.raises(PoseArgumentError, match=r'^target\["rpy_convention"\]: required'):
        as_target_pose({"position": p, "rpy": (0, 0, 0)}, "pose")
    with pytest.raises(PoseArgumentError, match=r"^target: unknown key 'quaternion'"):
        as_target_pose({"position": p, "quaternion": (1, 0, 0, 0)}, "pose")
    with pytest.raises(PoseArgumentError, match=r'^target: a mapping target needs "position"'):
        as_target_pose({"quat_wxyz": (1, 0, 0, 0)}, "pose")
    with pytest.raises(PoseArgumentError, match=r"^target: a rotation without a position"):
        as_target_pose(Rotation.identity(), "pose")
    with pytest.raises(PoseArgumentError, match=r"read as \(p, R\) only when.*quat_wxyz"):
        as_target_pose((p, (1.0, 0.0, 0.0, 0.0)), "pose")  # a quaternion must be named
    with pytest.raises(PoseArgumentError, match=r'^mode: expected "pose" or "position"'):
        as_target_pose(np.eye(4), "orientation")
    with pytest.raises(ArgumentError, match=r"^target: expected a numeric array"):
        as_target_pose("not a pose", "pose")
    with pytest.raises(NonFiniteError, match=r'^target\["position"\]:'):
        as_target_pose({"position": (0, math.nan, 0), "rotation": np.eye(3)}, "pose")


def test_converters_validate_their_input() -> None:
    for fn in (to_position_rotation, to_rotation, to_quat_wxyz, to_quat_xyzw):
        with pytest.raises(ShapeError, match=r"^T:"):
            fn(np.eye(3))
        with pytest.raises(InvalidRotationError, match=r"^T:"):
            fn(np.diag([1.0, 1.0, -1.0, 1.0]))
        with pytest.raises(NonFiniteError, match=r"^T:"):
            fn(np.full((4, 4), math.nan))
    with pytest.raises(InvalidRotationError, match=r"^T:"):
        to_rpy(np.diag([1.0, 1.0, -1.0, 1.0]), rpy_convention="urdf")


# ---------------------------------------------------------------------- the docs
def test_conventions_pose_forms_block_runs() -> None:
    text = (ROOT / "docs" / "conventions.md").read_text(encoding="utf-8")
    section = text.split("## Pose forms", 1)[1].split("\n## ", 1)[0]
    blocks = re.findall(r"```python\n(.*?)```", section, flags=re.S)
    assert blocks, "docs/conventions.md: the Pose forms section has no python block"
    namespace: dict[str, object] = {"__name__": "__doc__"}
    for code in blocks:
        exec(compile(code, "docs/conventions.md", "exec"), namespace)


@pytest.mark.parametrize("dtype", [np.float64, np.float32, np.int64])
def test_an_empty_batch_of_poses_is_valid_and_plans_to_nothing(dtype: Any) -> None:
    from optik.spatial import as_pose

    empty = np.zeros((0, 4, 4), dtype=dtype)
    assert as_pose("poses", empty, batch=True).shape == (0, 4, 4)
    panda = optik.load_problem("panda").robot
    plan = optik.plan_path(panda, empty)
    assert plan.q.shape == (0, panda.dof) and plan.status == []


def test_a_wrong_last_row_is_named_with_its_values() -> None:
    # It read "expected shape a homogeneous transform ..., got (4, 4)": the shape was right.
    puma = optik.load_problem("puma560").robot
    with pytest.raises(
        ShapeError, match=r"target: not a homogeneous transform: last row \(0, 0, 0, 2\)"
    ):
        optik.solve_ik(puma, np.eye(4) * 2.0)
    batch = np.stack([np.eye(4)] * 3)
    batch[2, 3, 0] = 0.5
    with pytest.raises(ShapeError, match=r"\(pose 2\): last row \(0.5, 0, 0, 1\)"):
        optik.solve_ik_batch(puma, batch)


def test_a_missing_problem_file_says_so_without_a_location() -> None:
    with pytest.raises(optik.errors.ProblemFileError) as info:
        optik.load_problem("nowhere-at-all.toml")
    assert str(info.value).startswith("nowhere-at-all.toml: file not found")


def test_a_problem_files_target_or_a_pair_that_is_no_p_r_is_told_how_to_pass() -> None:
    from optik.problems import Target

    robot = optik.load_problem("puma560").robot
    target = Target("t", "pose", robot.fk(robot.mid_limits))
    with pytest.raises(PoseArgumentError, match=r"target\.pose with mode=target\.mode"):
        optik.solve_ik(robot, target)
    # (p, rpy) and (p, quat): a bare shape error before for the first, a hint for the second.
    for pair in (((0.1, 0.2, 0.3), (0.1, 0.2, 0.3)), ((0.1, 0.2, 0.3), (1.0, 0, 0, 0))):
        with pytest.raises(PoseArgumentError, match="name other forms"):
            as_target_pose(pair, "pose")
    # Two positions stay a batch of positions, and a shape error where one is expected.
    two = [(0.1, 0.2, 0.3), (0.4, 0.5, 0.6)]
    assert as_target_pose(two, "position", batch=True).shape == (2, 4, 4)
    for value, mode in ((two, "position"), ([0.1, 0.2], "position"), ([np.eye(4)] * 2, "pose")):
        with pytest.raises(ShapeError):
            as_target_pose(value, mode)
    with pytest.raises(PositionOnlyTargetError):  # its hint: mode="position"
        as_target_pose(two, "pose", batch=True)


def test_a_refused_quaternions_norm_is_reported_without_overflow() -> None:
    # Its norm was printed as inf (1e200) or the quaternion called zero (1e-300).
    with pytest.raises(InvalidQuaternionError, match=r"norm 1e\+200 differs"):
        pose(quat_wxyz=(1e200, 0.0, 0.0, 0.0))
    with pytest.raises(InvalidQuaternionError, match=r"norm 9\.89949e-301 differs"):
        pose(quat_wxyz=(7e-301, 0.0, 0.0, 7e-301))
    with pytest.raises(InvalidQuaternionError, match="zero quaternion at row 1"):
        pose(quat_wxyz=[(1.0, 0.0, 0.0, 0.0), (0.0, 0.0, 0.0, 0.0)])
