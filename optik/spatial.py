"""Rotations, homogeneous transforms and pose errors.

Naming rule used across optik: ``T_a_b`` is the pose of frame ``b`` expressed in frame
``a`` (so ``T_a_c = T_a_b @ T_b_c``). Rotations are 3x3, transforms 4x4, angles in
radians. Functions accept a leading batch axis where stated.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from optik._checks import FloatArray, as_float_array, check_finite
from optik.errors import InvalidRotationError, ShapeError

_LAST_ROW = np.array([0.0, 0.0, 0.0, 1.0])

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
    loses all precision below about 2e-8 rad.
    """
    s = 0.5 * np.linalg.norm(vee(R - np.swapaxes(R, -1, -2)), axis=-1)
    c = 0.5 * (np.trace(R, axis1=-2, axis2=-1) - 1.0)
    angle = np.arctan2(s, c)
    return float(angle) if np.ndim(angle) == 0 else angle


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
    near pi, where ``sin(angle)`` vanishes.
    """
    v = 0.5 * vee(R - R.T)
    s = float(np.linalg.norm(v))
    c = 0.5 * (float(np.trace(R)) - 1.0)
    theta = float(np.arctan2(s, c))
    if theta < 1e-6:
        return v * (1.0 + theta * theta / 6.0)
    if theta < np.pi - 1e-3:
        return v * (theta / s)
    # Near pi: R + R^T = 2 cos(t) I + 2 (1 - cos t) a a^T determines the axis up to sign.
    B = 0.5 * (R + R.T) - c * np.eye(3)
    k = int(np.argmax(np.diag(B)))
    axis = B[:, k] / np.sqrt(max(B[k, k], 1e-300))
    axis /= np.linalg.norm(axis)
    if float(axis @ v) < 0.0:
        axis = -axis
    return axis * theta


def rotation_error_vector(R_current: FloatArray, R_target: FloatArray) -> FloatArray:
    """Base-frame rotation vector taking ``R_current`` to ``R_target``: ``log(R* R^T)``."""
    return log_so3(R_target @ R_current.T)


def _rotation_defects(R: FloatArray) -> tuple[float, float]:
    """``max |R^T R - I|`` and the determinant farthest from 1, over a 3x3 or a batch."""
    if R.ndim == 2:
        # Plain floats: for one 3x3, numpy's per-call overhead dominates the arithmetic.
        (a, b, c), (d, e, f), (g, h, i) = R.tolist()
        err = max(
            abs(a * a + d * d + g * g - 1.0),
            abs(b * b + e * e + h * h - 1.0),
            abs(c * c + f * f + i * i - 1.0),
            abs(a * b + d * e + g * h),
            abs(a * c + d * f + g * i),
            abs(b * c + e * f + h * i),
        )
        return err, a * (e * i - f * h) - b * (d * i - f * g) + c * (d * h - e * g)
    gram = np.swapaxes(R, -1, -2) @ R - np.eye(3)
    det = np.linalg.det(R).reshape(-1)
    return float(np.abs(gram).max()), float(det[np.argmax(np.abs(det - 1.0))])


def check_rotation(name: str, R: FloatArray, tol: float = ROTATION_TOLERANCE) -> None:
    """Raise :class:`InvalidRotationError` unless ``R`` (3x3 or batch) is a proper rotation."""
    if R.size == 0:
        return
    err, det = _rotation_defects(R)
    if err > tol or abs(det - 1.0) > 10 * tol:
        raise InvalidRotationError(name, err, det)


def as_pose(name: str, value: Any, batch: bool = False) -> FloatArray:
    """Validate a 4x4 homogeneous transform (or ``(N, 4, 4)`` when ``batch``)."""
    T = as_float_array(name, value)
    if not (T.shape == (4, 4) or (batch and T.ndim == 3 and T.shape[1:] == (4, 4))):
        raise ShapeError(name, "(4, 4)" + (" or (N, 4, 4)" if batch else ""), T.shape)
    check_finite(name, T)
    bottom = T[3] if T.ndim == 2 else T[:, 3]
    if float(np.abs(bottom - _LAST_ROW).max()) > 1e-9:
        raise ShapeError(name, "a homogeneous transform with last row (0, 0, 0, 1)", T.shape)
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
    d = T[:3, 3] - T_target[:3, 3]
    position = math.sqrt(float(d @ d))
    R = T_target[:3, :3].T @ T[:3, :3]
    sx, sy, sz = R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]
    s = 0.5 * math.sqrt(sx * sx + sy * sy + sz * sz)
    c = 0.5 * (R[0, 0] + R[1, 1] + R[2, 2] - 1.0)
    return position, math.atan2(s, c)
