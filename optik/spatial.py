"""Rotations, homogeneous transforms and pose errors.

Naming rule used across optik: ``T_a_b`` is the pose of frame ``b`` expressed in frame
``a`` (so ``T_a_c = T_a_b @ T_b_c``). Rotations are 3x3, transforms 4x4, angles in
radians. Functions accept a leading batch axis where stated.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from optik import _math
from optik._checks import FloatArray, as_float_array, check_finite
from optik.errors import InvalidRotationError, ShapeError

_LAST_ROW = np.array([0.0, 0.0, 0.0, 1.0])
_ROW_TOLERANCE = 1e-9
"""Largest deviation of a pose's last row from (0, 0, 0, 1)."""

ROTATION_TOLERANCE = 1e-6
"""Largest accepted ``max |R^T R - I|`` for a user-supplied rotation."""


def rot_x(angle: float) -> FloatArray:
    """Rotation about x by ``angle`` (rad), 3x3."""
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def rot_y(angle: float) -> FloatArray:
    """Rotation about y by ``angle`` (rad), 3x3."""
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def rot_z(angle: float) -> FloatArray:
    """Rotation about z by ``angle`` (rad), 3x3."""
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def rpy_to_matrix(roll: float, pitch: float, yaw: float) -> FloatArray:
    """Rotation ``Rz(yaw) Ry(pitch) Rx(roll)`` (the URDF ``rpy`` convention), 3x3."""
    return rot_z(yaw) @ rot_y(pitch) @ rot_x(roll)


def transform(rotation: Any = None, translation: Any = None) -> FloatArray:
    """4x4 homogeneous transform from a 3x3 rotation and a 3-vector (defaults: I, 0)."""
    T = np.eye(4)
    if rotation is not None:
        T[:3, :3] = rotation
    if translation is not None:
        T[:3, 3] = translation
    return T


def invert_transform(T: FloatArray) -> FloatArray:
    """Inverse of a rigid transform (4x4 or (N, 4, 4)) using ``R^T``."""
    R = T[..., :3, :3]
    p = T[..., :3, 3]
    out = np.zeros_like(T)
    Rt = np.swapaxes(R, -1, -2)
    out[..., :3, :3] = Rt
    out[..., :3, 3] = -np.einsum("...ij,...j->...i", Rt, p)
    out[..., 3, 3] = 1.0
    return out


def skew(v: FloatArray) -> FloatArray:
    """Skew-symmetric matrix of a 3-vector (or batch ``(..., 3)``)."""
    out = np.zeros((*v.shape[:-1], 3, 3))
    out[..., 0, 1], out[..., 0, 2] = -v[..., 2], v[..., 1]
    out[..., 1, 0], out[..., 1, 2] = v[..., 2], -v[..., 0]
    out[..., 2, 0], out[..., 2, 1] = -v[..., 1], v[..., 0]
    return out


def vee(M: FloatArray) -> FloatArray:
    """The 3-vector ``(M21, M02, M10)``; inverse of :func:`skew` on skew matrices."""
    return np.stack([M[..., 2, 1], M[..., 0, 2], M[..., 1, 0]], axis=-1)


def rotation_angle(R: FloatArray) -> FloatArray | float:
    """Rotation angle in [0, pi] of ``R`` (3x3 or batch), accurate for tiny angles.

    Uses ``atan2(||vee(R - R^T)|| / 2, (trace R - 1) / 2)``; ``arccos`` of the trace
    loses all precision below about 2e-8 rad (:func:`optik._math.rotation_angle`).
    """
    R = np.asarray(R, dtype=np.float64)
    if R.ndim == 2:
        return _math.rotation_angle(np.ascontiguousarray(R))
    flat = np.ascontiguousarray(R.reshape(-1, 3, 3))
    out = np.empty(flat.shape[0])
    _math.rotation_angles(flat, out)
    return out.reshape(R.shape[:-2])


def exp_so3(omega: FloatArray) -> FloatArray:
    """Rotation matrix of the rotation vector ``omega`` (rad), Rodrigues' formula."""
    omega = np.asarray(omega, dtype=float)
    theta = float(np.linalg.norm(omega))
    K = skew(omega)
    if theta < 1e-8:
        return np.eye(3) + K + 0.5 * K @ K
    return np.eye(3) + (np.sin(theta) / theta) * K + ((1 - np.cos(theta)) / theta**2) * K @ K


def log_so3(R: FloatArray) -> FloatArray:
    """Rotation vector (axis times angle, rad) of the 3x3 rotation ``R``.

    Stable at both ends: a series for small angles and the symmetric part of ``R``
    near pi, where ``sin(angle)`` vanishes (:func:`optik._math.log_rotation`).
    """
    out = np.empty(3)
    _math.log_rotation(np.ascontiguousarray(R, dtype=np.float64), out)
    return out


def rotation_error_vector(R_current: FloatArray, R_target: FloatArray) -> FloatArray:
    """Base-frame rotation vector taking ``R_current`` to ``R_target``: ``log(R* R^T)``."""
    return log_so3(R_target @ R_current.T)


def _rotation_defects(R: FloatArray) -> tuple[float, float]:
    """``max |R^T R - I|`` and the determinant farthest from 1, over a 3x3 or a batch."""
    R = np.ascontiguousarray(R, dtype=np.float64)
    if R.ndim == 2:
        err, det = _math.rotation_defects(R)
    else:
        err, det = _math.worst_rotation_defects(R.reshape(-1, 3, 3))
    return float(err), float(det)


def check_rotation(name: str, R: FloatArray, tol: float = ROTATION_TOLERANCE) -> None:
    """Raise :class:`InvalidRotationError` unless ``R`` (3x3 or batch) is a proper rotation."""
    if R.size == 0:
        return
    err, det = _rotation_defects(R)
    if err > tol or abs(det - 1.0) > 10 * tol:
        raise InvalidRotationError(name, err, det)


def as_pose(name: str, value: Any, batch: bool = False) -> FloatArray:
    """Validate a 4x4 homogeneous transform (or ``(N, 4, 4)`` when ``batch``)."""
    if (
        type(value) is np.ndarray
        and value.dtype == np.float64
        and value.flags.c_contiguous
        and (value.shape == (4, 4) or (batch and value.ndim == 3 and value.shape[1:] == (4, 4)))
    ):
        # The common case in one compiled pass; any defect takes the path below, which
        # names it.
        poses = value.reshape(-1, 4, 4)
        if _math.first_bad_pose(poses, ROTATION_TOLERANCE, _ROW_TOLERANCE) < 0:
            return value
    T = as_float_array(name, value)
    if not (T.shape == (4, 4) or (batch and T.ndim == 3 and T.shape[1:] == (4, 4))):
        raise ShapeError(name, "(4, 4)" + (" or (N, 4, 4)" if batch else ""), T.shape)
    check_finite(name, T)
    if T.size == 0:
        return T  # an empty batch: nothing to check
    bottom = T[3] if T.ndim == 2 else T[:, 3]
    if float(np.abs(bottom - _LAST_ROW).max()) > _ROW_TOLERANCE:
        rows = bottom.reshape(-1, 4)
        k = int(np.argmax(np.abs(rows - _LAST_ROW).max(axis=1)))
        where = f" (pose {k})" if T.ndim == 3 else ""
        found = ", ".join(f"{v:g}" for v in rows[k])
        raise ShapeError(
            name, "a homogeneous transform with last row (0, 0, 0, 1)", T.shape,
            f"not a homogeneous transform{where}: last row ({found}), expected (0, 0, 0, 1)",
        )  # fmt: skip
    check_rotation(name, T[..., :3, :3])
    return T


def as_target(value: Any, mode: str) -> FloatArray:
    """Validate an IK target as a 4x4 pose.

    ``mode="pose"`` needs a proper 4x4 transform; ``mode="position"`` takes a 3-vector, or
    a 4x4 whose translation is used (its rotation is then replaced by the identity).
    """
    if mode == "pose":
        return as_pose("target", value)
    array = as_float_array("target", value)
    if array.shape == (4, 4):
        return transform(None, as_pose("target", array)[:3, 3])
    if array.shape != (3,):
        raise ShapeError("target", "(3,) or (4, 4) in position mode", array.shape)
    return transform(None, check_finite("target", array))


def pose_error(T: FloatArray, T_target: FloatArray) -> tuple[float, float]:
    """Position error ``||p - p*||`` (m) and orientation error ``angle(R*^T R)`` (rad)."""
    position, orientation = _math.pose_error(
        np.ascontiguousarray(T, dtype=np.float64), np.ascontiguousarray(T_target, dtype=np.float64)
    )
    return float(position), float(orientation)
