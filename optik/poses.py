"""Poses in the forms people have, built and converted in one place.

:func:`pose` builds a 4x4 homogeneous transform (or an ``(N, 4, 4)`` batch) from a
position and at most one rotation form, each named by its keyword so that nothing is
guessed:

- ``rotation``: a 3x3 rotation matrix (or ``(N, 3, 3)``) or a ``scipy.spatial.transform.
  Rotation``; ``pose(p, R)`` is the ``(p, R)`` pair;
- ``quat_wxyz`` / ``quat_xyzw``: a unit quaternion, scalar first or scalar last;
- ``rpy`` with ``rpy_convention="urdf"``: roll, pitch, yaw with
  ``R = Rz(yaw) Ry(pitch) Rx(roll)`` (fixed axes x, then y, then z), radians unless
  ``degrees=True``.

The converters :func:`to_position_rotation`, :func:`to_rotation`, :func:`to_quat_wxyz`,
:func:`to_quat_xyzw` and :func:`to_rpy` turn a pose back into those forms, and
:func:`as_target_pose` reads an IK target given in any of them. Quaternion and Euler
arithmetic is scipy's (``Rotation``); this module only names the conventions and checks
the input. Units: metres and radians (degrees only where ``degrees=True`` says so).
"""

from __future__ import annotations

import warnings
from collections.abc import Mapping
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation

from optik._checks import FloatArray, as_float_array, check_bool, check_finite
from optik.errors import OptikError, ShapeError
from optik.spatial import as_pose, check_rotation

__all__ = [
    "QUAT_NORM_TOLERANCE",
    "RPY_CONVENTIONS",
    "TARGET_KEYS",
    "InvalidQuaternionError",
    "PoseArgumentError",
    "PositionOnlyTargetError",
    "as_target_pose",
    "pose",
    "to_position_rotation",
    "to_quat_wxyz",
    "to_quat_xyzw",
    "to_rotation",
    "to_rpy",
]

QUAT_NORM_TOLERANCE = 1e-3
"""Largest accepted ``| ||q|| - 1 |`` of a quaternion; within it ``q`` is normalised.

A unit quaternion written to four decimals, e.g. ``(0.7071, 0, 0, 0.7071)`` (norm
0.99999), is accepted; a vector that is far from unit length (a rotation vector, Euler
angles, a zero) is rejected rather than silently rescaled.
"""

RPY_CONVENTIONS: dict[str, str] = {
    "urdf": (
        "R = Rz(yaw) Ry(pitch) Rx(roll): fixed axes x, then y, then z (equivalently moving "
        "axes z, y', x''), as URDF's <origin rpy> and optik.spatial.rpy_to_matrix"
    ),
}
"""Roll-pitch-yaw conventions by name, with their meaning."""

# scipy's sequence for each convention: lower case is extrinsic (fixed axes), so
# from_euler("xyz", (r, p, y)) = Rz(y) Ry(p) Rx(r).
_SCIPY_SEQUENCE = {"urdf": "xyz"}

TARGET_KEYS = ("position", "rotation", "quat_wxyz", "quat_xyzw", "rpy", "rpy_convention", "degrees")
"""Keys a mapping target may hold: the keywords of :func:`pose`."""

_ROTATION_FORMS = ("rotation", "quat_wxyz", "quat_xyzw", "rpy")
_MODES = ("pose", "position")


# ---------------------------------------------------------------------- errors
class PoseArgumentError(OptikError):
    """A pose argument is ambiguous, missing or of an unknown kind."""

    def __init__(self, name: str, message: str) -> None:
        self.name = name
        self.detail = message
        super().__init__(f"{name}: {message}")


class InvalidQuaternionError(OptikError):
    """A quaternion is zero or farther from unit norm than :data:`QUAT_NORM_TOLERANCE`."""

    def __init__(self, name: str, norm: float, tolerance: float, index: int | None = None) -> None:
        self.name = name
        self.norm = norm
        self.tolerance = tolerance
        self.index = index
        where = f" at row {index}" if index is not None else ""
        if norm == 0.0:
            text = f"zero quaternion{where}, which is no rotation"
        else:
            text = (
                f"quaternion norm {norm:.6g}{where} differs from 1 by more than "
                f"{tolerance:g}; give a unit quaternion"
            )
        super().__init__(f"{name}: {text}")


class PositionOnlyTargetError(ShapeError):
    """A target without an orientation was given in pose mode.

    A :class:`~optik.errors.ShapeError`, as a 3-vector target in pose mode always was;
    the message says how to ask for position-only IK.
    """

    def __init__(self, name: str, got: tuple[int, ...], what: str = "") -> None:
        self.name = name
        self.expected = "(4, 4) in pose mode"
        self.got = tuple(got)
        given = what or f"shape {self.got}"
        OptikError.__init__(
            self,
            f"{name}: a position without an orientation ({given}); to solve for the "
            'position only, pass mode="position"; to set the orientation too, give it: a '
            '4x4 pose, a (p, R) pair, {"position": p, "quat_wxyz": q} or '
            "optik.pose(p, quat_wxyz=q)",
        )


# ---------------------------------------------------------------------- building
def pose(
    position: Any = None,
    rotation: Any = None,
    *,
    quat_wxyz: Any = None,
    quat_xyzw: Any = None,
    rpy: Any = None,
    rpy_convention: str | None = None,
    degrees: bool = False,
) -> FloatArray:
    """A 4x4 pose from a position and at most one named rotation form.

    Give at most one of ``rotation``, ``quat_wxyz``, ``quat_xyzw`` and ``rpy``; with none,
    the rotation is the identity. Every input may carry a leading batch axis ``N``; a
    single value is repeated along the other inputs' batch, and two batches must have
    the same ``N``.

    Examples:
        ``pose((0.4, 0, 0.3), quat_wxyz=(0, 1, 0, 0))`` (half a turn about x);
        ``pose(p, R)`` for a ``(p, R)`` pair (``R`` a matrix or a scipy ``Rotation``);
        ``pose(p, rpy=(0, 90, 0), rpy_convention="urdf", degrees=True)``.

    Args:
        position: translation (3,) or (N, 3), m; default zero.
        rotation: rotation matrix (3, 3) or (N, 3, 3) (proper: ``max |R^T R - I| <=
            1e-6`` and det +1, as :func:`optik.spatial.check_rotation`), or a
            ``scipy.spatial.transform.Rotation`` (single or of length N).
        quat_wxyz: quaternion ``(w, x, y, z)``, scalar first, (4,) or (N, 4).
        quat_xyzw: quaternion ``(x, y, z, w)``, scalar last (scipy's and ROS's order),
            (4,) or (N, 4). A quaternion whose norm is within
            :data:`QUAT_NORM_TOLERANCE` of 1 is normalised; ``q`` and ``-q`` give the same
            rotation.
        rpy: ``(roll, pitch, yaw)``, (3,) or (N, 3), rad (deg with ``degrees=True``).
        rpy_convention: required with ``rpy``: the name of its convention, a key of
            :data:`RPY_CONVENTIONS`. ``"urdf"`` means ``R = Rz(yaw) Ry(pitch) Rx(roll)``
            (rotate about the fixed x axis by roll, then fixed y by pitch, then fixed z by
            yaw), the convention of :func:`optik.spatial.rpy_to_matrix`.
        degrees: ``rpy`` is in degrees; only valid with ``rpy``.

    Returns:
        The pose ``T`` (4, 4), or (N, 4, 4) when any input is batched, float64.

    Raises:
        PoseArgumentError: two rotation forms, ``rpy`` without (or with an unknown)
            ``rpy_convention``, ``rpy_convention`` or ``degrees`` without ``rpy``, or a
            ``(p, R)`` pair passed as ``position``.
        ShapeError: an input of the wrong shape, or batches of different lengths.
        NonFiniteError: a NaN or infinite entry.
        InvalidQuaternionError: a zero quaternion or one too far from unit norm.
        InvalidRotationError: a rotation matrix that is not a proper rotation.
    """
    if _is_pair(position) and rotation is None:
        raise PoseArgumentError(
            "position", "got a (p, R) pair; pass it as pose(p, R), e.g. pose(*pair)"
        )
    return _build(
        {
            "position": position,
            "rotation": rotation,
            "quat_wxyz": quat_wxyz,
            "quat_xyzw": quat_xyzw,
            "rpy": rpy,
            "rpy_convention": rpy_convention,
            "degrees": degrees,
        },
        {key: key for key in TARGET_KEYS},
    )


def _build(values: Mapping[str, Any], names: Mapping[str, str]) -> FloatArray:
    """The pose of :func:`pose`'s keywords ``values``; ``names`` label each in errors."""
    forms = [key for key in _ROTATION_FORMS if values.get(key) is not None]
    if len(forms) > 1:
        listed = " and ".join(names[key] for key in forms)
        raise PoseArgumentError(
            listed,
            "give at most one rotation form (rotation, quat_wxyz, quat_xyzw or rpy), "
            f"got {len(forms)}",
        )
    convention = values.get("rpy_convention")
    degrees = values.get("degrees", False)
    if not isinstance(degrees, (bool, np.bool_)):
        raise PoseArgumentError(names["degrees"], f"expected True or False, got {degrees!r}")
    if values.get("rpy") is None:
        if convention is not None:
            raise PoseArgumentError(names["rpy_convention"], "given without rpy")
        if degrees:
            raise PoseArgumentError(names["degrees"], "applies to rpy only, and no rpy is given")

    R: FloatArray | None = None
    form = forms[0] if forms else ""
    if form == "rotation":
        R = _rotation_matrix(names[form], values[form])
    elif form in ("quat_wxyz", "quat_xyzw"):
        R = _quaternion_matrix(names[form], values[form], scalar_first=form == "quat_wxyz")
    elif form == "rpy":
        R = _rpy_matrix(names[form], values[form], convention, bool(degrees), names)

    p: FloatArray | None = None
    if values.get("position") is not None:
        p = _batch_of("position", names["position"], values["position"], (3,), "(3,) or (N, 3)")
    return _assemble(p, R, names["position"], names[form] if form else "")


def _assemble(p: FloatArray | None, R: FloatArray | None, p_name: str, r_name: str) -> FloatArray:
    """Stack a translation and a rotation (either may be absent or batched) into poses."""
    n_p = p.shape[0] if p is not None and p.ndim == 2 else None
    n_r = R.shape[0] if R is not None and R.ndim == 3 else None
    if R is not None and n_p is not None and n_r is not None and n_p != n_r:
        raise ShapeError(r_name, f"a single rotation or {n_p} of them, to match {p_name}", R.shape)
    n = n_p if n_p is not None else n_r
    T = np.zeros((4, 4) if n is None else (n, 4, 4))
    T[..., :3, :3] = np.eye(3) if R is None else R
    if p is not None:
        T[..., :3, 3] = p
    T[..., 3, 3] = 1.0
    return T


def _batch_of(
    kind: str, name: str, value: Any, trailing: tuple[int, ...], expected: str
) -> FloatArray:
    """``value`` as a finite float64 array of shape ``trailing`` or ``(N, *trailing)``."""
    array = as_float_array(name, value)
    if array.shape[1:] != trailing and array.shape != trailing:
        raise ShapeError(name, f"{expected} for {kind}", array.shape)
    return check_finite(name, array)


def _rotation_matrix(name: str, value: Any) -> FloatArray:
    """A proper rotation matrix (3, 3) or (N, 3, 3) from a matrix or a scipy Rotation."""
    if isinstance(value, Rotation):
        R = np.asarray(value.as_matrix(), dtype=np.float64)
        check_finite(name, R)
    else:
        R = _batch_of(
            "rotation",
            name,
            value,
            (3, 3),
            "(3, 3) or (N, 3, 3) matrix or a scipy Rotation (a quaternion goes to "
            "quat_wxyz= or quat_xyzw=, roll-pitch-yaw to rpy=)",
        )
    check_rotation(name, R)
    return R


def _quaternion_matrix(name: str, value: Any, scalar_first: bool) -> FloatArray:
    """Rotation matrix of a near-unit quaternion (4,) or (N, 4), in the named order."""
    q = _batch_of("a quaternion", name, value, (4,), "(4,) or (N, 4)")
    with np.errstate(over="ignore"):  # an entry of 1e200 gives norm inf: rejected below
        norm = np.linalg.norm(q, axis=-1)
    bad = np.abs(norm - 1.0) > QUAT_NORM_TOLERANCE
    if np.any(bad):
        k = int(np.argmax(bad)) if q.ndim == 2 else None
        row = q if k is None else q[k]
        # The norm of the entries scaled by the largest: 1e200 is no inf, 1e-300 no zero.
        peak = float(np.max(np.abs(row)))
        true_norm = peak * float(np.linalg.norm(row / peak)) if peak > 0.0 else 0.0
        raise InvalidQuaternionError(name, true_norm, QUAT_NORM_TOLERANCE, k)
    q = q / norm[..., None]
    xyzw = np.roll(q, -1, axis=-1) if scalar_first else q
    return np.asarray(Rotation.from_quat(xyzw).as_matrix(), dtype=np.float64)


def _convention(name: str, convention: Any) -> str:
    """The scipy Euler sequence of a named roll-pitch-yaw convention."""
    if convention is None:
        raise PoseArgumentError(
            name,
            'required: name the roll-pitch-yaw convention, e.g. rpy_convention="urdf" '
            "(R = Rz(yaw) Ry(pitch) Rx(roll))",
        )
    if not isinstance(convention, str) or convention not in _SCIPY_SEQUENCE:
        known = "; ".join(f"{key!r}: {meaning}" for key, meaning in RPY_CONVENTIONS.items())
        raise PoseArgumentError(name, f"unknown convention {convention!r}; known: {known}")
    return _SCIPY_SEQUENCE[str(convention)]


def _rpy_matrix(
    name: str, value: Any, convention: Any, degrees: bool, names: Mapping[str, str]
) -> FloatArray:
    """Rotation matrix of roll-pitch-yaw angles (3,) or (N, 3) in a named convention."""
    sequence = _convention(names["rpy_convention"], convention)
    angles = _batch_of("(roll, pitch, yaw)", name, value, (3,), "(3,) or (N, 3)")
    if angles.size == 0:
        return np.zeros((0, 3, 3))
    rotation = Rotation.from_euler(sequence, angles, degrees=degrees)
    return np.asarray(rotation.as_matrix(), dtype=np.float64)


# ---------------------------------------------------------------------- converting back
def to_position_rotation(T: Any) -> tuple[FloatArray, FloatArray]:
    """The ``(p, R)`` pair of a pose: ``pose(*to_position_rotation(T))`` equals ``T``.

    Args:
        T: pose (4, 4) or (N, 4, 4), validated as :func:`optik.spatial.as_pose`.

    Returns:
        ``(p, R)``: translation (3,) or (N, 3), m, and rotation (3, 3) or (N, 3, 3);
        copies, not views of ``T``.

    Raises:
        ShapeError: wrong shape or last row.
        NonFiniteError: a NaN or infinite entry.
        InvalidRotationError: the rotation block is not a proper rotation.
    """
    T = _as_pose("T", T, batch=True)
    return T[..., :3, 3].copy(), T[..., :3, :3].copy()


def to_rotation(T: Any) -> Rotation:
    """The rotation of a pose as a ``scipy.spatial.transform.Rotation``.

    Args:
        T: pose (4, 4) or (N, 4, 4), validated as :func:`optik.spatial.as_pose`.

    Returns:
        A single ``Rotation`` for (4, 4), a ``Rotation`` of length N for (N, 4, 4).

    Raises:
        ShapeError: wrong shape or last row.
        NonFiniteError: a NaN or infinite entry.
        InvalidRotationError: the rotation block is not a proper rotation.
    """
    return Rotation.from_matrix(_as_pose("T", T, batch=True)[..., :3, :3])


def to_quat_xyzw(T: Any) -> FloatArray:
    """The unit quaternion ``(x, y, z, w)`` (scalar last) of a pose's rotation.

    ``q`` and ``-q`` are the same rotation; the one returned has ``w >= 0`` (and, when
    ``w == 0``, its first nonzero entry positive), so equal rotations give equal output.

    Args:
        T: pose (4, 4) or (N, 4, 4), validated as :func:`optik.spatial.as_pose`.

    Returns:
        Quaternion (4,) or (N, 4).

    Raises:
        ShapeError: wrong shape or last row.
        NonFiniteError: a NaN or infinite entry.
        InvalidRotationError: the rotation block is not a proper rotation.
    """
    q = np.asarray(to_rotation(T).as_quat(), dtype=np.float64)
    return _canonical_xyzw(q)


def to_quat_wxyz(T: Any) -> FloatArray:
    """The unit quaternion ``(w, x, y, z)`` (scalar first) of a pose's rotation.

    :func:`to_quat_xyzw` with the scalar moved first: the same argument (a pose (4, 4) or
    (N, 4, 4)), sign rule (``w >= 0``) and errors; returns (4,) or (N, 4).
    """
    return np.roll(to_quat_xyzw(T), 1, axis=-1)


def _canonical_xyzw(q: FloatArray) -> FloatArray:
    """Flip ``q`` (..., 4), scalar last, to ``w > 0``, or first nonzero entry > 0 at w = 0."""
    if q.size == 0:
        return q
    # The first nonzero of (w, x, y, z) decides the sign.
    ordered = np.roll(q, 1, axis=-1)
    first = np.argmax(ordered != 0.0, axis=-1)
    lead = np.take_along_axis(ordered, np.expand_dims(first, -1), axis=-1)
    return np.where(lead < 0.0, -q, q)


def to_rpy(T: Any, *, rpy_convention: str | None = None, degrees: bool = False) -> FloatArray:
    """Roll, pitch and yaw of a pose's rotation in a named convention.

    With ``rpy_convention="urdf"``, ``R = Rz(yaw) Ry(pitch) Rx(roll)``; roll and yaw lie in
    [-pi, pi], pitch in [-pi/2, pi/2], and ``pose(rpy=to_rpy(T, ...), ...)`` reproduces
    the rotation. At pitch = ±pi/2 (gimbal lock) only roll - yaw (pitch +pi/2) or roll +
    yaw (pitch -pi/2) is determined; scipy then sets yaw to 0, and within about 1e-7 rad
    of the lock the triple reproduces the rotation to within 2.5e-7 rad rather than to
    rounding error.

    Args:
        T: pose (4, 4) or (N, 4, 4), validated as :func:`optik.spatial.as_pose`.
        rpy_convention: required: a key of :data:`RPY_CONVENTIONS` (``"urdf"``).
        degrees: return degrees instead of radians.

    Returns:
        ``(roll, pitch, yaw)`` (3,) or (N, 3), rad (deg with ``degrees=True``).

    Raises:
        PoseArgumentError: a missing or unknown ``rpy_convention``, or ``degrees`` not a
            bool.
        ShapeError: wrong shape or last row.
        NonFiniteError: a NaN or infinite entry.
        InvalidRotationError: the rotation block is not a proper rotation.
    """
    sequence = _convention("rpy_convention", rpy_convention)
    if not isinstance(degrees, (bool, np.bool_)):
        raise PoseArgumentError("degrees", f"expected True or False, got {degrees!r}")
    rotation = to_rotation(T)
    with warnings.catch_warnings():
        # The gimbal-lock case is documented above; scipy's warning adds nothing.
        warnings.filterwarnings("ignore", message="Gimbal lock detected", category=UserWarning)
        angles = rotation.as_euler(sequence, degrees=bool(degrees))
    return np.asarray(angles, dtype=np.float64)


# ---------------------------------------------------------------------- IK targets
def as_target_pose(
    value: Any, mode: str, *, name: str = "target", batch: bool = False
) -> FloatArray:
    """Read an IK target given in any pose form as a validated 4x4 pose.

    Accepted forms:

    - a 4x4 homogeneous transform (``(N, 4, 4)`` with ``batch``), checked as
      :func:`optik.spatial.as_pose` (last row ``(0, 0, 0, 1)`` to 1e-9, rotation
      ``max |R^T R - I| <= 1e-6`` with det +1); in pose mode the validated array itself
      is returned, not a copy;
    - a ``(p, R)`` pair (tuple or list): ``p`` (3,) or (N, 3), ``R`` a rotation matrix
      (3, 3) or (N, 3, 3) or a scipy ``Rotation``;
    - a mapping with the keywords of :func:`pose` (:data:`TARGET_KEYS`), e.g.
      ``{"position": p, "quat_wxyz": q}``; ``"position"`` is required;
    - in position mode, also a 3-vector (``(N, 3)`` with ``batch``).

    In position mode the rotation of any form is still validated and then replaced by
    the identity (only the translation counts). In pose mode a target without an
    orientation (a 3-vector, or a mapping with only ``"position"``) raises
    :class:`PositionOnlyTargetError`, whose message says to pass ``mode="position"``.

    Args:
        value: the target, in one of the forms above.
        mode: ``"pose"`` or ``"position"``.
        name: argument name used in error messages (e.g. ``"targets"``).
        batch: expect a batch: the result is (N, 4, 4); without it, (4, 4).

    Returns:
        The target pose (4, 4), or (N, 4, 4) with ``batch``, float64.

    Raises:
        PositionOnlyTargetError: a target without an orientation in pose mode.
        PoseArgumentError: an unknown ``mode``, an unknown mapping key, a mapping without
            ``"position"``, a bare ``Rotation``, or an argument error of :func:`pose`.
        ArgumentError: ``batch`` not a bool.
        ShapeError: wrong shape (single where a batch is expected, or the reverse).
        NonFiniteError: a NaN or infinite entry.
        InvalidQuaternionError: a zero quaternion or one too far from unit norm.
        InvalidRotationError: a rotation that is not a proper rotation.
    """
    if not isinstance(mode, str) or mode not in _MODES:
        raise PoseArgumentError("mode", f'expected "pose" or "position", got {mode!r}')
    if type(batch) is not bool:
        batch = check_bool("batch", batch)
    if type(value) is np.ndarray and value.dtype.kind == "f":  # the common case first
        T = _from_array(name, value, mode, batch)
    elif isinstance(value, Mapping):
        T = _from_mapping(name, value, mode)
    elif isinstance(value, Rotation):
        raise PoseArgumentError(
            name,
            "a rotation without a position; give a (p, R) pair, "
            '{"position": p, "rotation": R} or optik.pose(p, R)',
        )
    elif _is_pair(value):
        names = {key: name for key in TARGET_KEYS}
        names.update(position=f"{name}[0]", rotation=f"{name}[1]")
        T = _build({"position": value[0], "rotation": value[1]}, names)
        T = _position_only(T) if mode == "position" else T
    elif _is_problem_target(value):
        raise PoseArgumentError(
            name,
            "an optik.Target (a problem file's named target) is not a pose; pass "
            "target.pose with mode=target.mode and tol=(target.tolerance, "
            "target.angle_tolerance)",
        )
    else:
        pair = isinstance(value, (tuple, list)) and len(value) == 2
        try:
            array = as_float_array(name, value)
        except ShapeError:
            if pair:  # (p, quat): a ragged pair
                raise _not_a_p_r_pair(name) from None
            raise
        try:
            T = _from_array(name, array, mode, batch)
        except ShapeError:
            if pair and mode == "pose" and not batch and array.shape == (2, 3):  # (p, rpy)
                raise _not_a_p_r_pair(name) from None
            raise
    if batch != (T.ndim == 3):
        expected = "(N, 4, 4) (a batch)" if batch else "a single pose (4, 4)"
        raise ShapeError(name, expected, T.shape)
    return T


def _not_a_p_r_pair(name: str) -> PoseArgumentError:
    """The error of a pair given as a target whose second item is no rotation matrix."""
    return PoseArgumentError(
        name,
        "a pair is read as (p, R) only when its second item is a 3x3 rotation matrix or "
        'a scipy Rotation; name other forms, e.g. {"position": p, "quat_wxyz": q}',
    )


def _is_problem_target(value: Any) -> bool:
    """Whether ``value`` is an :class:`optik.problems.Target` (a named target, no pose)."""
    from optik.problems import Target

    return isinstance(value, Target)


def _from_array(name: str, array: FloatArray, mode: str, batch: bool) -> FloatArray:
    """A target given as an array: a pose, or in position mode a translation."""
    array = np.asarray(array, dtype=np.float64)
    if array.shape[-2:] == (4, 4) and array.ndim in ((2, 3) if batch else (2,)):
        T = _as_pose(name, array, batch=batch)
        return _position_only(T) if mode == "position" else T
    if array.shape[-1:] == (3,) and array.ndim in ((1, 2) if batch else (1,)):
        if mode == "pose":
            raise PositionOnlyTargetError(name, array.shape)
        return _assemble(check_finite(name, array), None, name, "")
    if mode == "pose":
        expected = "(N, 4, 4)" if batch else "(4, 4)"
    else:
        expected = "(N, 3) or (N, 4, 4)" if batch else "(3,) or (4, 4)"
        expected += " in position mode"
    raise ShapeError(name, expected, array.shape)


def _as_pose(name: str, value: Any, batch: bool) -> FloatArray:
    """:func:`optik.spatial.as_pose`, also for an empty batch ``(0, 4, 4)``."""
    array = as_float_array(name, value)
    if batch and array.shape == (0, 4, 4):
        return array  # nothing to check, and as_pose's max() needs one entry
    return as_pose(name, array, batch=batch)


def _from_mapping(name: str, value: Mapping[Any, Any], mode: str) -> FloatArray:
    """A target given as a mapping of :func:`pose`'s keywords."""
    unknown = [key for key in value if key not in TARGET_KEYS]
    if unknown:
        raise PoseArgumentError(
            name, f"unknown key {unknown[0]!r}; expected some of {', '.join(TARGET_KEYS)}"
        )
    if value.get("position") is None:
        raise PoseArgumentError(name, 'a mapping target needs "position"')
    if mode == "pose" and all(value.get(key) is None for key in _ROTATION_FORMS):
        p = as_float_array(f'{name}["position"]', value["position"])
        raise PositionOnlyTargetError(name, p.shape, 'a mapping with "position" only')
    T = _build(value, {key: f'{name}["{key}"]' for key in TARGET_KEYS})
    return _position_only(T) if mode == "position" else T


def _position_only(T: FloatArray) -> FloatArray:
    """A new pose with the translation of ``T`` and the identity rotation."""
    return _assemble(T[..., :3, 3], None, "", "")


def _is_pair(value: Any) -> bool:
    """Whether ``value`` is a ``(p, R)`` pair: two items, the second a rotation."""
    if not isinstance(value, (tuple, list)) or len(value) != 2:
        return False
    second = value[1]
    if isinstance(second, Rotation):
        return True
    try:
        shape = np.shape(second)
    except ValueError:  # ragged
        return False
    return len(shape) in (2, 3) and shape[-2:] == (3, 3)
