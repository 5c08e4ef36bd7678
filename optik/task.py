"""The IK task: which parts of the tool's pose a target constrains, and how tightly.

A task is a full pose, a point, an orientation, or a tool axis (5-D: the tool's axis
``axis`` must point along the target's same axis, the rotation about it is free), with
optional per-axis weights and two tolerances. Every solver reads the same packed task
(:attr:`Task.packed`) through the compiled functions of this module, so the residual a
solver drives to zero and the errors optik judges a result by are written once.

Weights ``w`` (6,) >= 0 are on ``[x, y, z, rx, ry, rz]`` **in the target frame**: the
residual is ``sqrt(w) * [R*^T (p* - p); R*^T r]`` where ``r`` is the rotation error (the
rotation vector ``log(R* R^T)`` for a full orientation; for a tool axis ``a`` and its
target ``a*`` the rotation vector of the smallest rotation taking ``a`` to ``a*``). A zero
position weight frees that target axis (e.g. the insertion depth along the target's z),
also in position mode, where a target given with a rotation lends its axes to the
weights (:attr:`Task.needs_target_frame`); a point target's axes are the world's.
The rotational weights are all positive (full orientation), exactly one zero (that tool
axis points along the target's: ``mode="axis"``), or all zero (no orientation:
``mode="position"``). The modes are shortcuts for weights.

Errors (what success is judged by, and what :class:`optik.IKResult` reports): the
position error is the norm of ``R*^T (p - p*)`` over the constrained axes (m); the
orientation error is ``angle(R*^T R)`` for a full orientation, the angle between the
tool axis and the target's for ``axis``, and 0 without orientation (rad). Success:
position error <= ``position_tol`` and orientation error <= ``orientation_tol`` (and the
limits, judged by :mod:`optik.verify`).

Positive weights do not change what success is, nor the answers of a reachable target
(a zero residual is a zero residual under any weights): they choose the compromise when
the target cannot be met. Graded weights slow a search, though: with rows 1e-6 of the
others, each step that keeps the heavy rows met may cut the light rows' error only by
about that ratio. The solvers therefore search with :attr:`Task.search` (the positive
weights set to 1) and take the graded task only for the compromise of a failed search.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from optik._checks import FloatArray, check_choice, check_real, finite_array
from optik._math import log_rotation
from optik._numba import inline, jit
from optik.errors import OptikError

MODES = ("pose", "position", "orientation", "axis")
AXES = ("x", "y", "z")

# Layout of Task.packed (float64).
_W = 0  # (6,) weights, target frame
_KIND = 6  # rotation kind: 0 none, 1 full, 2 axis
_AXIS = 7  # tool axis index (axis kind)
_PTOL = 8  # position tolerance (m)
_RTOL = 9  # orientation tolerance (rad)
_FAST = 10  # 1: full pose, unit weights (world-frame residual); 2: position, unit weights
_BIAS = 11  # factor on the LM damping's bias (a length-balanced search task's, else 1)
_LENGTH = 12  # a length-balanced search's arm size L (m), else 0: slides damped by 1/L^2
_PACKED = 13

NO_ROTATION = 0
FULL_ROTATION = 1
AXIS_ROTATION = 2


@dataclass(frozen=True, eq=False)
class Task:
    """A validated IK task (build it with :func:`make_task`).

    Attributes:
        mode: ``"pose"``, ``"position"``, ``"orientation"`` or ``"axis"``.
        axis: index of the tool axis of ``mode="axis"`` (0 x, 1 y, 2 z), else -1.
        weights: (6,) weights on ``[x, y, z, rx, ry, rz]`` in the target frame, divided
            by the largest (a uniform scale describes the same task).
        position_tol: position tolerance (m).
        orientation_tol: orientation tolerance (rad).
        packed: the task as the compiled kernels take it (read-only).
        features: (12,) weights of the seed-table features that rank starts for it
            (:func:`task_features`).
    """

    mode: str
    axis: int
    weights: FloatArray
    position_tol: float
    orientation_tol: float
    packed: FloatArray
    features: FloatArray

    @property
    def constrains_position(self) -> bool:
        """Whether every position axis is constrained (then the reach sphere is a proof)."""
        w = self.weights
        return bool(w[0] > 0.0 and w[1] > 0.0 and w[2] > 0.0)

    @property
    def needs_target_frame(self) -> bool:
        """Whether a position task's weights differ between its axes.

        Then a target's rotation (when it has one) is the frame they are on; a point's
        frame is the world's.
        """
        w = self.weights
        return self.mode == "position" and not (w[0] == w[1] == w[2])

    @property
    def is_pose_or_position(self) -> bool:
        """A plain full pose or a point with unit weights: what the closed forms solve."""
        return int(self.packed[_FAST]) != 0

    @property
    def is_graded(self) -> bool:
        """Whether the positive weights differ (then :attr:`search` is another task)."""
        positive = self.weights[self.weights > 0.0]
        return bool(np.any(positive != 1.0))

    @property
    def damping_bias(self) -> float:
        """The factor on a damped search's bias (:func:`balanced_search`; else 1)."""
        return float(self.packed[_BIAS])

    @property
    def balance_length(self) -> float:
        """The arm's size (m) a balanced search is measured in (:func:`balanced_search`), else 0."""
        return float(self.packed[_LENGTH])

    @property
    def search(self) -> Task:
        """The task with every positive weight set to 1 (``self`` if none is graded).

        The same success and the same answers of a reachable target, with a search
        unslowed by graded weights (see the module). Made once per task: every query
        asks for it (a plain property, not ``functools.cached_property``, whose lock
        costs half a microsecond a call on Python 3.11).
        """
        twin = self.__dict__.get("_search")
        if twin is None:
            twin = self
            if self.is_graded:
                axis = AXES[self.axis] if self.axis >= 0 else "z"
                binary = (self.weights > 0.0).astype(float)
                tol = (self.position_tol, self.orientation_tol)
                twin = _make_task(self.mode, axis, binary, tol)
            object.__setattr__(self, "_search", twin)  # a frozen dataclass: kept by hand
        return twin


WEIGHT_RANGE = (1e-100, 1e100)
"""Smallest and largest positive task weight accepted (no unit)."""


def _parse_tol(tol: Any) -> tuple[float, float]:
    if isinstance(tol, tuple | list):
        if len(tol) != 2:
            raise OptikError(
                f"tol must be a number or (position_tol_m, orientation_tol_rad), got {tol!r}"
            )
        return (
            check_real("tol[0] (position, m)", tol[0], positive=True),
            check_real("tol[1] (orientation, rad)", tol[1], positive=True),
        )
    value = check_real("tol", tol, positive=True)
    return value, value


def make_task(mode: Any = "pose", *, axis: Any = "z", weights: Any = None, tol: Any = 1e-6) -> Task:
    """Validate a task description (see the module docstring for the semantics).

    Args:
        mode: ``"pose"``, ``"position"``, ``"orientation"`` or ``"axis"``.
        axis: ``"x"``, ``"y"`` or ``"z"``: the tool axis of ``mode="axis"``.
        weights: (6,) >= 0 on ``[x, y, z, rx, ry, rz]`` in the target frame, or ``None``
            (ones, with the mode's zeros); the positive ones within :data:`WEIGHT_RANGE`.
            Only their ratios count: the task keeps them divided by the largest. With the
            default ``mode="pose"`` the pattern of rotational weights chooses the mode;
            with another mode it must agree with it.
        tol: one tolerance for both errors, or ``(position_tol_m, orientation_tol_rad)``.

    Raises:
        OptikError: an unknown mode or axis, weights with NaN, infinities, negative
            entries or an unsupported rotational pattern, a non-positive tolerance.
    """
    if type(mode) is str and type(axis) is str and type(tol) in (float, int):
        # Queries repeat their task: cache it by value. The types keep True apart from 1.
        w_key = _weights_key(weights)
        if w_key is None:
            return _make_task(mode, axis, weights, tol)
        key = (mode, axis, type(tol), tol, w_key)
        cached = _PLAIN_TASKS.get(key)
        if cached is None:
            cached = _make_task(mode, axis, weights, tol)
            if len(_PLAIN_TASKS) < 1024:
                _PLAIN_TASKS[key] = cached
        return cached
    return _make_task(mode, axis, weights, tol)


_PLAIN_TASKS: dict[tuple[Any, ...], Task] = {}


def _weights_key(weights: Any) -> tuple[Any, ...] | None:
    """A hashable copy of ``weights`` for the task cache, or ``None`` when not cacheable.

    ``None`` (no weights) is ``()``; a list or tuple of six plain floats or ints, or a
    float64 array of shape (6,), is the tuple of its values. Anything else (bools, other
    types, other shapes) is validated afresh each time.
    """
    if weights is None:
        return ()
    if type(weights) in (list, tuple):
        if len(weights) == 6 and all(type(x) in (float, int) for x in weights):
            try:
                return tuple(float(x) for x in weights)
            except OverflowError:  # an int beyond float range: let validation name it
                return None
        return None
    if isinstance(weights, np.ndarray) and weights.dtype == np.float64 and weights.shape == (6,):
        return tuple(weights.tolist())
    return None


def _make_task(
    mode: Any, axis: Any, weights: Any, tol: Any, bias: float = 1.0, length: float = 0.0
) -> Task:
    """:func:`make_task` without the cache of tasks without weights.

    ``bias`` and ``length``: the ``_BIAS`` and ``_LENGTH`` of a balanced search.
    """
    check_choice("mode", mode, MODES)
    given_mode = mode
    axis_name = check_choice("axis", axis, AXES)
    position_tol, orientation_tol = _parse_tol(tol)
    if weights is None:
        w = np.ones(6)
        if mode == "position":
            w[3:] = 0.0
        elif mode == "orientation":
            w[:3] = 0.0
        elif mode == "axis":
            w[3 + AXES.index(axis_name)] = 0.0
    else:
        w = finite_array("weights", weights, (6,)).copy()
        if np.any(w < 0.0):
            raise OptikError(f"weights must be >= 0, got {w.tolist()}")
        positive = w[w > 0.0]
        if np.any(positive < WEIGHT_RANGE[0]) or np.any(positive > WEIGHT_RANGE[1]):
            low, high = WEIGHT_RANGE
            raise OptikError(
                f"weights must be 0 or lie within [{low:g}, {high:g}] (the residual's squares "
                f"must stay finite and normal in float64), got {w.tolist()}"
            )
        zeros = [i for i in range(3) if w[3 + i] == 0.0]
        if len(zeros) == 2:
            raise OptikError(
                "weights: the rotational weights must be all positive (full orientation), "
                "exactly one zero (that tool axis is aligned, the rotation about it free) or "
                f"all zero (no orientation); got {w[3:].tolist()}"
            )
        pattern = {0: "pose", 1: "axis", 3: "position"}[len(zeros)]
        if pattern == "pose" and not np.any(w[:3] > 0.0):
            pattern = "orientation"
        if mode == "pose" and pattern != "pose":
            mode = pattern
        if pattern != mode:
            raise OptikError(f"weights {w.tolist()} do not describe mode {mode!r} ({pattern})")
        if mode == "axis" and given_mode == "axis" and AXES[zeros[0]] != axis_name:
            # Never guessed: the weights' free rotation and the axis named must agree.
            raise OptikError(
                f"axis={axis_name!r} (the default is 'z') but the weights {w.tolist()} free "
                f"the rotation about {AXES[zeros[0]]}: give axis={AXES[zeros[0]]!r}, or "
                f"weights whose zero rotational weight is on {axis_name}"
            )
        if mode == "axis":
            axis_name = AXES[zeros[0]]
    if not np.any(w > 0.0):
        raise OptikError("weights: at least one weight must be positive")
    # Weights all multiplied by one number describe the same task: the largest is 1, so
    # that every solver (its damping, its stall floor, a QP backend's tolerances) sees the
    # same numbers for it (weights of 1e-10 left the damping's bias to dominate).
    w = w / np.max(w)
    axis_index = AXES.index(axis_name) if mode == "axis" else -1
    kind = {"pose": FULL_ROTATION, "orientation": FULL_ROTATION, "axis": AXIS_ROTATION}.get(
        mode, NO_ROTATION
    )
    fast = 0
    if mode == "pose" and np.all(w == 1.0):
        fast = 1
    elif mode == "position" and np.all(w[:3] == 1.0):
        fast = 2
    packed = np.zeros(_PACKED)
    packed[_W : _W + 6] = w
    packed[_KIND] = kind
    packed[_AXIS] = max(axis_index, 0)
    packed[_PTOL] = position_tol
    packed[_RTOL] = orientation_tol
    packed[_FAST] = fast
    packed[_BIAS] = bias
    packed[_LENGTH] = length
    packed.flags.writeable = False
    features = task_features(packed)
    features.flags.writeable = False
    w.flags.writeable = False
    return Task(str(mode), axis_index, w, position_tol, orientation_tol, packed, features)


BALANCE_BAND = (0.5, 2.0)
"""Arm sizes (m) whose search keeps the plain task (:func:`balanced_search`)."""


@functools.lru_cache(maxsize=256)
def balanced_search(task: Task, length: float) -> Task:
    """:attr:`Task.search` for an arm of size ``length`` (m), its units balanced.

    On an arm smaller than a metre the position rows (m) are small beside the rotation
    rows (rad) and beside the damping's bias (``e^T e`` units), just as graded weights
    make them: a 2 mm Puma's damped least squares failed 37 of 40 targets; on a
    kilometre arm the rotation rows are the small ones (the jumbo drill at 1e3 solved 8
    of 200 batch targets). Measured in the arm's size, the residual ``[dp / L; dtheta]``
    and a slide's travel ``dq / L``, every row and column is of order one: the weights
    ``[w_p / L^2, w_r]``, divided by their largest (times ``_BIAS``, which multiplies the
    damping's bias the same), and a slide's damping over ``L^2`` (``_LENGTH``). Arms
    within :data:`BALANCE_BAND` keep :attr:`Task.search`. Success is judged as before.

    Args:
        task: the query's task.
        length: the arm's size (m), e.g. its reach radius.
    """
    search = task.search
    length = float(length)
    if not 0.0 < length < math.inf or BALANCE_BAND[0] <= length <= BALANCE_BAND[1]:
        return search  # a pure wrist (radius 0) has no size to measure in
    if not np.any(search.weights[:3] > 0.0):
        return search
    weights = search.weights.copy()
    weights[:3] /= length * length  # the residual [dp / L; dtheta]
    bias = 1.0 / float(np.max(weights))  # the normal equations times it: weights <= 1
    axis = AXES[search.axis] if search.axis >= 0 else "z"
    tol = (search.position_tol, search.orientation_tol)
    return _make_task(search.mode, axis, weights * bias, tol, bias=bias, length=length)


def as_task(mode: Any = "pose", tol: Any = 1e-6) -> Task:
    """A :class:`Task` unchanged, or :func:`make_task` of a mode and a tolerance."""
    if isinstance(mode, Task):
        return mode
    return make_task(mode, tol=tol)


# ---------------------------------------------------------------------- compiled core
@jit
def _axis_rotation(T: np.ndarray, G: np.ndarray, k: int, out: np.ndarray) -> float:
    """Rotation vector (world) of the smallest rotation taking tool axis k to the target's.

    Returns the angle between the two axes (rad, in [0, pi]).
    """
    ax, ay, az = T[0, k], T[1, k], T[2, k]
    bx, by, bz = G[0, k], G[1, k], G[2, k]
    vx = ay * bz - az * by
    vy = az * bx - ax * bz
    vz = ax * by - ay * bx
    s = math.sqrt(vx * vx + vy * vy + vz * vz)
    c = ax * bx + ay * by + az * bz
    theta = math.atan2(s, c)
    if s > 1e-9:
        f = theta / s
        out[0], out[1], out[2] = vx * f, vy * f, vz * f
    elif c > 0.0:
        out[0], out[1], out[2] = vx, vy, vz  # aligned: sin(theta) = theta to 1e-18
    else:
        # Opposite axes: turn by pi about the tool's next axis (perpendicular to both).
        j = (k + 1) % 3
        out[0], out[1], out[2] = math.pi * T[0, j], math.pi * T[1, j], math.pi * T[2, j]
    return theta


@inline
def _norm3(a: float, b: float, c: float) -> float:
    """``sqrt(a^2 + b^2 + c^2)``, scaled when the squares would overflow (1e200 m away)."""
    s = a * a + b * b + c * c
    if s < 1e300:
        return math.sqrt(s)
    m = max(abs(a), abs(b), abs(c))
    return m * math.sqrt((a / m) ** 2 + (b / m) ** 2 + (c / m) ** 2)


@jit
def task_error(
    T: np.ndarray, target: np.ndarray, task: np.ndarray, e: np.ndarray, M: np.ndarray
) -> tuple[float, float]:
    """Fill ``e`` (6,) with the task residual; return (position, orientation) errors.

    Fast tasks (:data:`_FAST`) keep the world frame, which the LM normal equations do not
    see (``J^T J`` and ``J^T e`` are invariant under a rotation of the rows): full pose
    ``[p* - p; log(R* R^T)]``, or the position part in ``e[:3]``. Otherwise
    ``sqrt(w) [R*^T (p* - p); R*^T r]`` in the target frame (see the module). ``M`` is
    3x4 scratch. The errors are the judged ones of the module docstring.
    """
    fast = task[_FAST]
    kind = int(task[_KIND])
    dx = target[0, 3] - T[0, 3]
    dy = target[1, 3] - T[1, 3]
    dz = target[2, 3] - T[2, 3]
    if fast == 2.0:
        e[0], e[1], e[2] = dx, dy, dz
        return _norm3(dx, dy, dz), 0.0
    w = M[:, 3]
    rot = 0.0
    if kind == FULL_ROTATION:
        for r in range(3):
            for c in range(3):
                M[r, c] = target[r, 0] * T[c, 0] + target[r, 1] * T[c, 1] + target[r, 2] * T[c, 2]
        log_rotation(M[:, :3], w)
        rot = math.sqrt(w[0] ** 2 + w[1] ** 2 + w[2] ** 2)
    elif kind == AXIS_ROTATION:
        rot = _axis_rotation(T, target, int(task[_AXIS]), w)
    else:
        w[0] = w[1] = w[2] = 0.0
    if fast == 1.0:
        e[0], e[1], e[2] = dx, dy, dz
        e[3], e[4], e[5] = w[0], w[1], w[2]
        return _norm3(dx, dy, dz), rot
    # Target frame: R*^T d and R*^T r, each weighted; the position error over the
    # constrained axes only.
    pos2 = 0.0
    big = 0.0
    for i in range(3):
        d = target[0, i] * dx + target[1, i] * dy + target[2, i] * dz
        v = target[0, i] * w[0] + target[1, i] * w[1] + target[2, i] * w[2]
        wp = task[_W + i]
        e[i] = math.sqrt(wp) * d
        e[3 + i] = math.sqrt(task[_W + 3 + i]) * v
        if wp > 0.0:
            pos2 += d * d
            big = max(big, abs(d))
    if pos2 < 1e300:
        return math.sqrt(pos2), rot
    # Squares beyond the float range (a target 1e200 m away): scaled by the largest.
    scaled = 0.0
    for i in range(3):
        if task[_W + i] > 0.0:
            d = (target[0, i] * dx + target[1, i] * dy + target[2, i] * dz) / big
            scaled += d * d
    return big * math.sqrt(scaled), rot


@jit
def task_rows(J: np.ndarray, target: np.ndarray, task: np.ndarray) -> int:
    """Turn the world-frame Jacobian ``J`` (6, dof) into the task's rows, in place.

    Returns the number of rows the residual of :func:`task_error` uses (3 or 6): fast
    tasks keep ``J`` as it is; others get ``sqrt(w) [R*^T J_v; R*^T J_w]``.
    """
    fast = task[_FAST]
    if fast == 1.0:
        return 6
    if fast == 2.0:
        return 3
    s0, s1, s2 = math.sqrt(task[_W]), math.sqrt(task[_W + 1]), math.sqrt(task[_W + 2])
    s3, s4, s5 = math.sqrt(task[_W + 3]), math.sqrt(task[_W + 4]), math.sqrt(task[_W + 5])
    for a in range(J.shape[1]):
        v0, v1, v2, w0, w1, w2 = J[0, a], J[1, a], J[2, a], J[3, a], J[4, a], J[5, a]
        J[0, a] = s0 * (target[0, 0] * v0 + target[1, 0] * v1 + target[2, 0] * v2)
        J[1, a] = s1 * (target[0, 1] * v0 + target[1, 1] * v1 + target[2, 1] * v2)
        J[2, a] = s2 * (target[0, 2] * v0 + target[1, 2] * v1 + target[2, 2] * v2)
        J[3, a] = s3 * (target[0, 0] * w0 + target[1, 0] * w1 + target[2, 0] * w2)
        J[4, a] = s4 * (target[0, 1] * w0 + target[1, 1] * w1 + target[2, 1] * w2)
        J[5, a] = s5 * (target[0, 2] * w0 + target[1, 2] * w1 + target[2, 2] * w2)
    return 6


@jit
def task_features(task: np.ndarray) -> np.ndarray:
    """(12,) weights of the seed-table pose features that rank starts for ``task``.

    Position (3) then ``sqrt(w) R`` row by row (9): all for a full pose; the position
    when any position weight is positive; the rotation when the orientation is full;
    the column of the tool axis for ``axis``. Each weight is 1 (0: not used), but a
    length-balanced search's position weight ``1 / L^2`` (:func:`balanced_search`):
    distances in the arm's size, as near a metre arm's, not ranked by rotation alone on
    a millimetre arm nor by position alone on a kilometre one.
    """
    mask = np.zeros(12)
    if task[_W] > 0.0 or task[_W + 1] > 0.0 or task[_W + 2] > 0.0:
        length = task[_LENGTH]
        # Capped: the square of a size below 1e-154 m underflows.
        w = min(1.0 / (length * length), 1e300) if length > 0.0 else 1.0
        mask[0] = mask[1] = mask[2] = w
    kind = int(task[_KIND])
    if kind == FULL_ROTATION:
        for j in range(3, 12):
            mask[j] = 1.0
    elif kind == AXIS_ROTATION:
        k = int(task[_AXIS])
        mask[3 + k] = mask[6 + k] = mask[9 + k] = 1.0
    return mask


@inline  # two comparisons; and its callers pass the task read-only and writable
def task_converged(position: float, orientation: float, task: np.ndarray) -> bool:
    """Both judged errors within the task's tolerances."""
    return position <= task[_PTOL] and orientation <= task[_RTOL]


@jit
def task_errors_of(T: np.ndarray, target: np.ndarray, task: np.ndarray) -> tuple[float, float]:
    """The judged (position, orientation) errors of pose ``T`` against ``target``."""
    e = np.empty(6)
    M = np.empty((3, 4))
    return task_error(T, target, task, e, M)


__all__ = [
    "AXES",
    "MODES",
    "WEIGHT_RANGE",
    "Task",
    "as_task",
    "make_task",
    "task_error",
    "task_rows",
]
