"""How far a trajectory's tool departs from its plan's Cartesian path, by the plan's task.

:func:`optik.trajectory.plan_trajectory` samples each segment's joint path between
waypoints and measures, for its ``position_deviation`` and ``orientation_deviation``,
what the plan's task constrains: the position along the axes with a positive weight, in
the path's frame (none for an orientation plan); the rotation's angle from the geodesic
between the waypoints' rotations (pose and orientation plans), or the tool axis's angle
from the path's (axis plans). Each sample's nearest point on the geodesic is found by a
golden-section search around the best of a grid.

Each interval is sampled at :data:`_DEVIATION_SAMPLES` points, then each measure's
peak is sought by a golden-section search between the best sample's neighbours
(:data:`_PEAK_STEPS` steps), in the intervals whose samples reach at least half the
largest sampled value (a smooth departure sampled at 8 points reads within a few percent
of its peak): the samples alone read up to 2 % below the peak, so ``path_tolerance``
could pass a trajectory that exceeds it.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import numpy as np

from optik._checks import FloatArray
from optik.spatial import rotation_angle

if TYPE_CHECKING:
    from optik.model import Robot
    from optik.planning import PathPlan

_DEVIATION_SAMPLES = 8  # tool samples per interval between waypoints
_PEAK_STEPS = 12  # golden steps on an interval's peak: the bracket (2/9 of it) to 7e-4 of it
_PEAK_SHARE = 0.5  # intervals searched: their samples' best at least this share of the largest
_SLERP_SAMPLES = 33  # the grid of fractions along the geodesic
_GOLDEN_STEPS = 30  # shrinks each sample's bracket (1/16 of the interval) by 5e-7
_INTERVALS_AT_ONCE = 2048  # intervals measured in one pass (16,384 tool samples)


def _slerp(R0: FloatArray, R1: FloatArray, u: FloatArray) -> FloatArray:
    """(K, 3, 3) rotations on the geodesics from ``R0`` to ``R1`` at fractions ``u`` (K,).

    ``R0`` and ``R1`` are (K, 3, 3), one pair per fraction, or (3, 3).
    """
    from scipy.spatial.transform import Rotation

    rv = Rotation.from_matrix(np.swapaxes(R0, -1, -2) @ R1).as_rotvec().reshape(-1, 3)
    turned: FloatArray = R0 @ Rotation.from_rotvec(u[:, None] * rv).as_matrix()
    return turned


def least_over_geodesic(angle: Any, count: int) -> FloatArray:
    """Per tool sample, the least of ``angle(u)`` (count,) over the fraction ``u`` in [0, 1].

    ``angle`` maps fractions (count,) (one per sample) to angles (count,). A grid of
    :data:`_SLERP_SAMPLES` fractions, then a golden-section search around each sample's
    best (a grid alone overstates the angle by up to half its spacing: 5 mrad on a path
    turning 0.35 rad between waypoints).
    """
    grid = np.linspace(0.0, 1.0, _SLERP_SAMPLES)
    values = np.stack([angle(np.full(count, u)) for u in grid], axis=1)  # (count, M)
    best = np.argmin(values, axis=1)
    lo, hi = grid[np.maximum(best - 1, 0)], grid[np.minimum(best + 1, len(grid) - 1)]
    least: FloatArray = np.minimum(
        np.min(values, axis=1), golden_least(angle, lo, hi, _GOLDEN_STEPS)
    )
    return least


def golden_least(f: Any, lo: FloatArray, hi: FloatArray, steps: int) -> FloatArray:
    """Per entry, the least value of ``f`` found by a golden-section search in [lo, hi].

    ``f`` maps points (n,) to values (n,); ``lo``, ``hi`` (n,) bracket each entry's
    minimum, which ``steps`` steps narrow by 0.618 each.
    """
    ratio = 0.5 * (math.sqrt(5.0) - 1.0)
    a, b = hi - ratio * (hi - lo), lo + ratio * (hi - lo)
    fa, fb = f(a), f(b)
    for _ in range(steps):
        left = fa <= fb  # the minimum lies in [lo, b]
        hi, lo = np.where(left, b, hi), np.where(left, lo, a)
        b, a = np.where(left, a, lo + ratio * (hi - lo)), np.where(left, hi - ratio * (hi - lo), b)
        fresh = f(np.where(left, a, b))
        fb, fa = np.where(left, fa, fresh), np.where(left, fresh, fb)
    least: FloatArray = np.minimum(fa, fb)
    return least


def _departure(
    plan: PathPlan,
    T: FloatArray,
    nearest: FloatArray,
    frame: FloatArray,
    start: FloatArray,
    end: FloatArray,
) -> tuple[float, float]:
    """Largest departure (m, rad) of tool poses ``T`` (K, 4, 4) from the path, by the task.

    The largest of :func:`_departures` over the poses.
    """
    position, orientation = _departures(plan, T, nearest, frame, start, end)
    return float(np.max(position, initial=0.0)), float(np.max(orientation, initial=0.0))


def _departures(
    plan: PathPlan,
    T: FloatArray,
    nearest: FloatArray,
    frame: FloatArray,
    start: FloatArray,
    end: FloatArray,
    orientation: bool = True,
) -> tuple[FloatArray, FloatArray]:
    """Departures (K,) each, m and rad, of tool poses ``T`` (K, 4, 4) from the path.

    ``nearest`` (K, 3): each pose's nearest path point; ``frame`` (K, 3, 3): the path's
    rotation there (the frame of the task's weights); ``start``, ``end`` (K, 3, 3): the
    rotations at the ends of each pose's interval, whose geodesic the tool's rotation (or
    tool axis) is compared with, the nearest of its rotations counting. Zeros where the
    task constrains no position (no rotation), and for the rotation unless
    ``orientation``.
    """
    from scipy.spatial.transform import Rotation

    held = plan.weights[:3] > 0.0
    position = np.zeros(len(T))
    if np.any(held):
        offset = np.einsum("kji,kj->ki", frame, T[:, :3, 3] - nearest)  # in the path's frame
        position = np.linalg.norm(offset[:, held], axis=1)
    if not orientation or plan.mode not in ("pose", "orientation", "axis"):
        return position, np.zeros(len(T))
    rv = Rotation.from_matrix(np.swapaxes(start, -1, -2) @ end).as_rotvec()  # (K, 3)

    def angle(u: FloatArray) -> FloatArray:
        R = start @ Rotation.from_rotvec(u[:, None] * rv).as_matrix()  # (K, 3, 3)
        if plan.mode != "axis":
            return np.asarray(rotation_angle(np.einsum("kji,kjl->kil", R, T[:, :3, :3])))
        tool, path = T[:, :3, plan.axis], R[:, :, plan.axis]
        return np.arctan2(np.linalg.norm(np.cross(tool, path), axis=1), np.sum(tool * path, 1))

    return position, least_over_geodesic(angle, len(T))


def segment_departure(
    robot: Robot, plan: PathPlan, first: int, path: Any, s_way: FloatArray
) -> tuple[float, float]:
    """Largest tool departure (m, rad) from the Cartesian path between waypoints.

    The intervals' samples are measured :data:`_INTERVALS_AT_ONCE` intervals at a time
    (one FK call, one search over their geodesics): an interval at a time took 47 s on a
    path of 20,000 waypoints, all at once would take memory in proportion.
    """
    steps = np.diff(s_way)
    intervals = np.flatnonzero(steps > 0.0)  # not those of a waypoint merged into the last
    position = orientation = 0.0
    for lo in range(0, len(intervals), _INTERVALS_AT_ONCE):
        block = intervals[lo : lo + _INTERVALS_AT_ONCE]
        between = _intervals_departure(robot, plan, first, path, s_way[block], steps[block], block)
        position, orientation = max(position, between[0]), max(orientation, between[1])
    return position, orientation


def _intervals_departure(
    robot: Robot,
    plan: PathPlan,
    first: int,
    path: Any,
    starts: FloatArray,
    steps: FloatArray,
    intervals: np.ndarray,
) -> tuple[float, float]:
    """:func:`segment_departure` of the intervals starting at path parameters ``starts``.

    Each interval's samples, then per measure a golden-section search for its peak
    between the best sample's neighbours (:func:`_peak`).
    """

    def measured(
        rows: Any, w: FloatArray, orientation: bool = True
    ) -> tuple[FloatArray, FloatArray]:
        return _departures_at(
            robot, plan, first, path, starts[rows], steps[rows], intervals[rows], w, orientation
        )

    w = np.linspace(0.0, 1.0, _DEVIATION_SAMPLES + 2)  # the waypoints, then the samples
    inner = np.broadcast_to(w[1:-1], (len(intervals), _DEVIATION_SAMPLES))
    position, orientation = measured(slice(None), inner)
    return (
        _peak(position, w, lambda rows, u: measured(rows, u[:, None], False)[0][:, 0]),
        _peak(orientation, w, lambda rows, u: measured(rows, u[:, None])[1][:, 0]),
    )


def _peak(values: FloatArray, w: FloatArray, at: Any) -> float:
    """Largest departure over intervals whose samples (n, m) are ``values``.

    The samples lie at fractions ``w[1:-1]`` of each interval (``w[0] = 0`` and
    ``w[-1] = 1`` are its waypoints). In each interval whose best sample is at least
    :data:`_PEAK_SHARE` of the largest, a golden-section search for the peak between that
    sample's neighbours (:func:`golden_least` of the negated measure); ``at(rows, u)``
    maps those intervals' indices (k,) and fractions (k,) to the measure there (k,).
    """
    peak = float(np.max(values, initial=0.0))
    if peak == 0.0:  # the task measures nothing here (or the path is met exactly)
        return peak
    rows = np.flatnonzero(np.max(values, axis=1) >= _PEAK_SHARE * peak)
    best = np.argmax(values[rows], axis=1)
    lo, hi = w[best], w[best + 2]  # the best sample is w[best + 1]
    found = -golden_least(lambda u: -at(rows, u), lo, hi, _PEAK_STEPS)
    return max(peak, float(np.max(found)))


def _departures_at(
    robot: Robot,
    plan: PathPlan,
    first: int,
    path: Any,
    starts: FloatArray,
    steps: FloatArray,
    intervals: np.ndarray,
    w: FloatArray,
    orientation: bool = True,
) -> tuple[FloatArray, FloatArray]:
    """Departures (n, m) of the tool at fractions ``w`` (n, m) of each interval (n of them).

    As :func:`_departures` (``orientation`` as there), for the tool poses on the joint
    path at parameters ``starts + steps * w``.
    """
    n, m = w.shape
    T = robot.fk(path((starts[:, None] + steps[:, None] * w).ravel()))
    which = first + np.repeat(intervals, m)  # each sample's interval's first waypoint
    A, B = plan.poses[which], plan.poses[which + 1]  # (K, 4, 4)
    ab = B[:, :3, 3] - A[:, :3, 3]
    length2 = np.sum(ab * ab, axis=1)
    along_path = np.sum((T[:, :3, 3] - A[:, :3, 3]) * ab, axis=1)
    lam = np.where(
        length2 > 0.0, np.clip(along_path / np.where(length2 > 0.0, length2, 1.0), 0.0, 1.0), 0.0
    )
    frame = _slerp(A[:, :3, :3], B[:, :3, :3], lam)
    held = plan.weights[:3] > 0.0
    if np.any(held) and not np.all(held):
        # Nearest along the constrained axes only (a free axis's offset does not count):
        # lam and the path's frame there, twice, the frame turning slowly.
        for _ in range(2):
            offset = np.einsum("kji,kj->ki", frame, T[:, :3, 3] - A[:, :3, 3])[:, held]
            along = np.einsum("kji,kj->ki", frame, ab)[:, held]
            norm2 = np.sum(along * along, axis=1)
            ratio = np.sum(offset * along, axis=1) / np.where(norm2 > 0.0, norm2, 1.0)
            lam = np.where(norm2 > 0.0, np.clip(ratio, 0.0, 1.0), lam)
            frame = _slerp(A[:, :3, :3], B[:, :3, :3], lam)
    nearest = A[:, :3, 3] + lam[:, None] * ab
    position, turned = _departures(plan, T, nearest, frame, A[:, :3, :3], B[:, :3, :3], orientation)
    return position.reshape(n, m), turned.reshape(n, m)


def merge_departure(
    robot: Robot, plan: PathPlan, Q: FloatArray, kept: Any, knot_of: Any
) -> tuple[float, float]:
    """Largest tool move (m, rad) from a merged waypoint's configuration to its knot's."""
    knot_rows = kept[knot_of]
    merged = np.flatnonzero(knot_rows != np.arange(len(Q)))
    position = orientation = 0.0
    for k, knot in zip(merged, knot_rows[merged], strict=True):
        T_way, T_knot = robot.fk(Q[k])[None], robot.fk(Q[knot])
        frame, ends = plan.poses[k, :3, :3][None], T_knot[None, :3, :3]
        moved = _departure(plan, T_way, T_knot[None, :3, 3], frame, ends, ends)
        position, orientation = max(position, moved[0]), max(orientation, moved[1])
    return position, orientation


__all__ = ["golden_least", "least_over_geodesic", "merge_departure", "segment_departure"]
