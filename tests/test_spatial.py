"""Rotations, transforms and pose errors against scipy and explicit matrices."""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import assert_close, assert_rigid
from hypothesis import given
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from optik.errors import InvalidRotationError, NonFiniteError, ShapeError
from optik.spatial import (
    as_pose,
    check_rotation,
    exp_so3,
    invert_transform,
    log_so3,
    pose_error,
    rot_x,
    rot_y,
    rot_z,
    rotation_angle,
    rotation_error_vector,
    rpy_to_matrix,
    skew,
    transform,
    vee,
)

angles = st.floats(-4.0, 4.0, allow_nan=False)
vectors = st.lists(st.floats(-3.0, 3.0), min_size=3, max_size=3).map(np.array)


# ---------------------------------------------------------------------- the test helper itself
def test_assert_close_rejects_nan_and_mismatch() -> None:
    assert_close([1.0, 2.0], [1.0, 2.0 + 1e-13], atol=1e-12)
    with pytest.raises(AssertionError, match="NaN"):
        assert_close([math.nan], [math.nan], atol=1.0)
    with pytest.raises(AssertionError, match="NaN"):
        assert_close([0.0], [math.nan], atol=1.0)
    with pytest.raises(AssertionError, match="shape"):
        assert_close(np.zeros(3), np.zeros((3, 1)))
    with pytest.raises(AssertionError, match=r"index \(1,\)"):
        assert_close([1.0, 2.0], [1.0, 2.1], atol=0.05)
    with pytest.raises(AssertionError):
        assert_close([math.inf], [1.0], atol=1.0)
    assert_close([math.inf, -math.inf], [math.inf, -math.inf], atol=0.0)
    assert_close([100.0], [101.0], rtol=0.02)


# ---------------------------------------------------------------------- elementary rotations
@given(angles)
def test_elementary_rotations_match_scipy(angle: float) -> None:
    for fn, axis in ((rot_x, "x"), (rot_y, "y"), (rot_z, "z")):
        assert_close(fn(angle), Rotation.from_euler(axis, angle).as_matrix(), atol=1e-15)


def test_elementary_rotations_direction() -> None:
    # Right-handed, active: a quarter turn about z takes x to y, about x takes y to z.
    assert_close(rot_z(math.pi / 2) @ [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], atol=1e-16)
    assert_close(rot_x(math.pi / 2) @ [0.0, 1.0, 0.0], [0.0, 0.0, 1.0], atol=1e-16)
    assert_close(rot_y(math.pi / 2) @ [0.0, 0.0, 1.0], [1.0, 0.0, 0.0], atol=1e-16)


@given(angles, angles, angles)
def test_rpy_is_fixed_axis_xyz(roll: float, pitch: float, yaw: float) -> None:
    expected = Rotation.from_euler("xyz", [roll, pitch, yaw]).as_matrix()  # extrinsic
    assert_close(rpy_to_matrix(roll, pitch, yaw), expected, atol=1e-15)


# ---------------------------------------------------------------------- transforms
def test_transform_defaults_and_layout() -> None:
    assert_close(transform(), np.eye(4), atol=0.0)
    T = transform(rot_z(0.3), [1.0, 2.0, 3.0])
    assert_close(T[:3, 3], [1.0, 2.0, 3.0], atol=0.0)
    assert_close(T[3], [0.0, 0.0, 0.0, 1.0], atol=0.0)
    assert_close(T @ [1.0, 0.0, 0.0, 1.0], [1 + math.cos(0.3), 2 + math.sin(0.3), 3.0, 1.0])


def test_invert_transform_single_and_batch(rng: np.random.Generator) -> None:
    R = Rotation.random(5, random_state=rng).as_matrix()
    T = np.tile(np.eye(4), (5, 1, 1))
    T[:, :3, :3] = R
    T[:, :3, 3] = rng.normal(size=(5, 3))
    inv = invert_transform(T)
    assert_close(inv, np.linalg.inv(T), atol=1e-14)
    assert_close(invert_transform(T[2]), np.linalg.inv(T[2]), atol=1e-14)
    assert_rigid(inv)


@given(vectors, vectors)
def test_skew_is_cross_product(v: np.ndarray, w: np.ndarray) -> None:
    assert_close(skew(v) @ w, np.cross(v, w), atol=1e-13)
    assert_close(vee(skew(v)), v, atol=0.0)
    assert_close(skew(v).T, -skew(v), atol=0.0)


def test_skew_vee_batch() -> None:
    v = np.arange(12.0).reshape(4, 3)
    assert skew(v).shape == (4, 3, 3)
    assert_close(vee(skew(v)), v, atol=0.0)


# ---------------------------------------------------------------------- exp / log / angle
@given(vectors)
def test_exp_so3_matches_scipy(omega: np.ndarray) -> None:
    assert_close(exp_so3(omega), Rotation.from_rotvec(omega).as_matrix(), atol=1e-13)


@given(vectors)
def test_log_so3_matches_scipy(omega: np.ndarray) -> None:
    R = Rotation.from_rotvec(omega).as_matrix()
    expected = Rotation.from_matrix(R).as_rotvec()  # angle in [0, pi]
    got = log_so3(R)
    if np.linalg.norm(expected) > math.pi - 1e-6:
        # At pi the axis sign is free: compare the rotations instead.
        assert_close(Rotation.from_rotvec(got).as_matrix(), R, atol=1e-9)
    else:
        assert_close(got, expected, atol=1e-9)


@pytest.mark.parametrize("angle", [0.0, 1e-12, 1e-9, 1e-7, 1e-3, 1.0, 3.0, math.pi - 1e-4])
def test_log_so3_and_angle_near_zero_and_pi(angle: float) -> None:
    axis = np.array([2.0, -1.0, 0.5]) / math.sqrt(5.25)
    R = Rotation.from_rotvec(axis * angle).as_matrix()
    assert rotation_angle(R) == pytest.approx(angle, rel=1e-6, abs=1e-15)
    assert_close(log_so3(R), axis * angle, atol=1e-9, rtol=1e-6)


def test_rotation_angle_resolves_tiny_angles() -> None:
    # arccos((trace - 1) / 2) returns 0 below ~2e-8 rad; the atan2 form does not.
    R = rot_z(1e-10)
    assert math.acos(min(1.0, (np.trace(R) - 1.0) / 2.0)) == 0.0
    assert rotation_angle(R) == pytest.approx(1e-10, rel=1e-6)


def test_rotation_angle_batch() -> None:
    R = np.stack([rot_x(0.1), rot_y(-0.2), rot_z(3.0)])
    assert_close(rotation_angle(R), [0.1, 0.2, 3.0], atol=1e-14)


def test_rotation_error_vector(rng: np.random.Generator) -> None:
    R = Rotation.random(random_state=rng).as_matrix()
    omega = np.array([0.1, -0.3, 0.2])
    R_target = Rotation.from_rotvec(omega).as_matrix() @ R  # world-frame perturbation
    assert_close(rotation_error_vector(R, R_target), omega, atol=1e-12)


def test_pose_error() -> None:
    T = transform(rot_z(0.2), [1.0, 2.0, 3.0])
    T_target = transform(rot_z(0.2) @ rot_x(0.05), [1.0, 2.0 + 3e-3, 3.0 - 4e-3])
    position, orientation = pose_error(T, T_target)
    assert position == pytest.approx(5e-3, rel=1e-12)
    assert orientation == pytest.approx(0.05, rel=1e-12)


# ---------------------------------------------------------------------- validation
def test_check_rotation_accepts_rotation_and_rejects_others(rng: np.random.Generator) -> None:
    check_rotation("R", Rotation.random(4, random_state=rng).as_matrix())
    with pytest.raises(InvalidRotationError, match=r"R: not a rotation.*det = -1"):
        check_rotation("R", np.diag([1.0, -1.0, 1.0]))
    scaled = 1.001 * np.eye(3)
    with pytest.raises(InvalidRotationError, match=r"max \|R\^T R - I\| = 0\.002"):
        check_rotation("R", scaled)
    check_rotation("R", (1 + 1e-8) * np.eye(3))  # within the 1e-6 tolerance


def test_as_pose_validation() -> None:
    assert_close(as_pose("T", np.eye(4)), np.eye(4), atol=0.0)
    with pytest.raises(ShapeError, match=r"T: expected shape \(4, 4\), got \(4, 3\)"):
        as_pose("T", np.zeros((4, 3)))
    bad = np.eye(4)
    bad[1, 3] = math.nan
    with pytest.raises(NonFiniteError, match=r"T: .*index \(1, 3\)"):
        as_pose("T", bad)
    with pytest.raises(InvalidRotationError, match="pose"):
        as_pose("pose", np.diag([2.0, 0.5, 1.0, 1.0]))
    batch = np.stack([np.eye(4), np.eye(4)])
    assert as_pose("T", batch, batch=True).shape == (2, 4, 4)
    with pytest.raises(ShapeError):
        as_pose("T", batch)
