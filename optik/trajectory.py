"""Time-parameterised trajectories along a planned joint path (TOPP-RA; ``trajectory`` extra).

A :class:`~optik.planning.PathPlan` is a sequence of joint vectors without timing.
:func:`plan_trajectory` (``PathPlan.to_trajectory``) makes it executable:

1. **Segments.** The plan splits where a waypoint is unsolved (``unreachable``,
   ``outside_limits``, ``not_found``) or flagged ``discontinuity`` (a branch switch): the
   robot cannot move through such a place along the path, so it is never bridged. Each
   stretch of consecutive solved, continuous waypoints is one :class:`TrajectorySegment`
   that starts and ends at rest.
2. **Geometric path.** Within a segment the joint path is an interpolating spline through
   the waypoints, parameterised by the cumulative joint-space chord length ``s`` (the sum
   of ``||q_{k+1} - q_k||``, mixed rad and m): a natural cubic spline (C2, so the joint
   acceleration is continuous), or, where that spline would leave the joint limits between
   two waypoints, a monotone PCHIP spline (C1), which never overshoots its waypoints.
   Waypoints closer than :data:`MERGE_TOLERANCE` times the segment's chord length
   (at least 1e-9 rad or m) to the previous knot are merged into it: the path passes
   through that knot at their stated time, so the trajectory holds each waypoint's
   configuration to within that distance, and the tool's move from it is counted in
   the segment's measured departure (and ``path_tolerance``).
3. **Timing.** TOPP-RA (Pham and Pham, 2018, the ``toppra`` package) finds the fastest
   path speed ``ds/dt`` under the joint velocity and acceleration limits on a grid of ``s``,
   with constant path acceleration between grid points. The limits hold at the grid points;
   between them each joint's acceleration is a quadratic and its squared speed a quintic in
   ``s``, whose exact maxima are found (:meth:`_Timing.peaks`). If one exceeds its limit,
   the segment's time is stretched uniformly (speeds divided by ``r``, accelerations by
   ``r²``) until none does.

The samples lie exactly on the geometric path; between waypoints that path is an
interpolation, so its tool pose departs slightly from the Cartesian path: with a robot,
the largest departure of each segment is measured (position, m; orientation, rad) and,
with ``path_tolerance``, enforced. The sampled arrays hold at most
:data:`MAX_TRAJECTORY_SAMPLES` samples.
"""

from __future__ import annotations

import contextlib
import csv
import importlib.util
import json
import logging
import math
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, TYPE_CHECKING, Any

import numpy as np

from optik._checks import FloatArray, as_float_array, check_int, check_real
from optik._files import output_path, write_atomic_with
from optik.errors import OptikError, ShapeError
from optik.path_departure import merge_departure, segment_departure

if TYPE_CHECKING:
    from optik.model import Robot
    from optik.planning import PathPlan

__all__ = [
    "MAX_GRID",
    "MAX_RATE_LIMIT",
    "MAX_TRAJECTORY_SAMPLES",
    "MERGE_TOLERANCE",
    "MIN_RATE_LIMIT",
    "Trajectory",
    "TrajectorySegment",
    "plan_trajectory",
]

MAX_TRAJECTORY_SAMPLES = 10_000_000
"""Most samples a trajectory may hold (10 million samples of a 6-joint robot are 1.5 GB)."""

MAX_GRID = 20_000
"""Largest ``grid`` of :func:`plan_trajectory`: TOPP-RA's time grows with its intervals
(about 1 s per segment at this many, 60 s at a million), and the duration changes by
less than 0.1 % beyond the default 200."""

MIN_RATE_LIMIT = 1e-9
"""Smallest accepted velocity or acceleration limit (rad or m per s, or per s^2): the time
scale of a segment, about its length over the limit, is squared on the way to TOPP-RA,
which must stay finite."""
MAX_RATE_LIMIT = 1e9
"""Largest accepted velocity or acceleration limit (same units)."""

MERGE_TOLERANCE = 1e-6
"""Waypoints of a segment closer than this fraction of its joint-space chord length are one."""

_UNSOLVED = ("unreachable", "outside_limits", "not_found")
# rad or m: the least merge distance, whatever the segment's length (TOPP-RA finds no
# parameterisation of a motion of 1e-11 to 1e-10 in all: "not controllable").
_SAME_POINT = 1e-9
_LIMIT_SLACK = 1e-12  # rad or m: a spline within this of a limit stays inside it


@dataclass(frozen=True, eq=False)
class TrajectorySegment:
    """One stretch of the plan, executed from rest to rest without a stop.

    Attributes:
        first: index of its first plan waypoint.
        last: index of its last plan waypoint (inclusive).
        start: index of its first sample in :class:`Trajectory` arrays.
        stop: one past its last sample.
        t_start: time (s) of its first sample on the trajectory's clock.
        duration: its duration (s).
        interpolation: ``"cubic"`` (natural cubic spline) or ``"pchip"`` (monotone).
        s_waypoints: (k,) path parameter of each waypoint ``first..last`` (cumulative
            joint-space chord length, rad or m).
        waypoint_times: (k,) time (s, from ``t_start``) at which each waypoint is passed.
        position_deviation: largest distance (m) of the tool from the Cartesian path
            between waypoints (8 samples per interval, then the peak sought between
            them: :mod:`optik.path_departure`), along the axes the plan's task
            constrains (in the path's frame; 0 for orientation plans; NaN without a
            robot).
        orientation_deviation: largest angle (rad) of the tool's rotation from the path's
            (pose and orientation plans), of its tool axis from the path's (axis plans);
            0 for position plans, NaN without a robot.
    """

    first: int
    last: int
    start: int
    stop: int
    t_start: float
    duration: float
    interpolation: str
    s_waypoints: FloatArray
    waypoint_times: FloatArray
    position_deviation: float = math.nan
    orientation_deviation: float = math.nan


@dataclass(frozen=True)
class _Timing:
    """A segment's geometric path and its path-speed profile (constant ``s̈`` per interval)."""

    path: Any  # scipy PPoly-like: path(s, nu) -> (..., dof)
    ss: FloatArray  # (M + 1,) grid of s
    sd: FloatArray  # (M + 1,) path speed ds/dt at the grid
    ts: FloatArray  # (M + 1,) time at the grid, s
    us: FloatArray  # (M,) path acceleration in each interval

    @classmethod
    def build(cls, path: Any, ss: FloatArray, sd: FloatArray) -> _Timing:
        ds = np.diff(ss)
        us = (sd[1:] ** 2 - sd[:-1] ** 2) / (2.0 * ds)
        # Two zero speeds in a row give an infinite time: plan_trajectory rejects it.
        with np.errstate(divide="ignore"):
            ts = np.concatenate([[0.0], np.cumsum(2.0 * ds / (sd[1:] + sd[:-1]))])
        return cls(path, ss, sd, ts, us)

    def scaled(self, r: float) -> _Timing:
        """The same path traversed ``r`` times slower."""
        return _Timing.build(self.path, self.ss, self.sd / r)

    @property
    def duration(self) -> float:
        return float(self.ts[-1])

    def at(self, t: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
        t = np.clip(t, 0.0, self.duration)
        i = np.clip(np.searchsorted(self.ts, t, side="right") - 1, 0, len(self.us) - 1)
        dt = t - self.ts[i]
        u = self.us[i]
        v = np.maximum(self.sd[i] + dt * u, 0.0)
        s = np.clip(self.ss[i] + dt * self.sd[i] + 0.5 * dt**2 * u, self.ss[i], self.ss[i + 1])
        d1 = self.path(s, 1)
        qd = d1 * v[:, None] + 0.0  # + 0.0: no negative zeros at rest
        return self.path(s), qd, self.path(s, 2) * v[:, None] ** 2 + d1 * u[:, None]

    def peaks(self) -> tuple[FloatArray, FloatArray]:
        """Largest ``|qd|`` and ``|qdd|`` (dof,) over the whole segment, not only the grid.

        Every knot of the path is a grid point, so each grid interval lies in one cubic
        piece: there ``x = ṡ²`` is linear in ``s``, ``q'`` quadratic and ``q''`` linear, so
        ``qdd = q'' x + q' s̈`` is a quadratic and ``qd² = q'² x`` a quintic in ``s``. Each
        is fitted exactly from its values at degree + 1 points, and its maximum on the
        interval taken over the ends and the real roots of its derivative there.
        """
        # Interior (Chebyshev) nodes: at a knot a PCHIP path's q'' jumps, and the spline
        # evaluates there with the next piece.
        w6, w3 = _chebyshev(6), _chebyshev(3)
        speed2 = self._rates(w6)[0] ** 2
        accel = self._rates(w3)[1]
        return np.sqrt(_poly_max(w6, speed2).max(axis=0)), _poly_max(w3, accel).max(axis=0)

    def _rates(self, w: FloatArray) -> tuple[FloatArray, FloatArray]:
        """``qd`` and ``qdd`` (M, len(w), dof) at fractions ``w`` of every grid interval."""
        s = self.ss[:-1, None] + np.diff(self.ss)[:, None] * w
        x = self.sd[:-1, None] ** 2 + 2.0 * self.us[:, None] * (s - self.ss[:-1, None])
        d1 = self.path(s.ravel(), 1).reshape(*s.shape, -1)
        d2 = self.path(s.ravel(), 2).reshape(*s.shape, -1)
        # qd = q' sqrt(x) is not a polynomial, but qd² = q'² x is; keep the sign apart.
        speed = d1 * np.sqrt(np.maximum(x, 0.0))[..., None]
        return speed, d2 * x[..., None] + d1 * self.us[:, None, None]


def _chebyshev(n: int) -> FloatArray:
    """The ``n`` Chebyshev nodes of the first kind on [0, 1] (interior points)."""
    return (1.0 - np.cos((2 * np.arange(n) + 1) * np.pi / (2 * n))) / 2.0


def _poly_max(w: FloatArray, values: FloatArray) -> FloatArray:
    """Largest ``|p|`` on [0, 1] of the polynomials through ``values`` (M, len(w), dof).

    Returns (M, dof). The roots of ``p'`` come from batched companion matrices; a root
    found slightly off changes the value there only to second order.
    """
    n = len(w)
    M, _, dof = values.shape
    coef = np.linalg.solve(
        np.vander(w, n, increasing=True), values.transpose(1, 0, 2).reshape(n, -1)
    )
    best = np.maximum(np.abs(coef[0]), np.abs(coef.sum(axis=0)))  # |p(0)|, |p(1)|
    deriv = coef[1:] * np.arange(1, n)[:, None]  # p' coefficients, increasing order
    lead = deriv[-1]
    scale = np.max(np.abs(deriv), axis=0)
    usable = np.abs(lead) > 1e-12 * np.maximum(scale, 1e-300)
    m = n - 2  # degree of p'
    if m == 1:
        roots = np.where(usable, -deriv[0] / np.where(usable, lead, 1.0), -1.0)[:, None]
    else:
        companion = np.zeros((deriv.shape[1], m, m))
        companion[:, 1:, :-1] = np.eye(m - 1)
        companion[:, :, -1] = -(deriv[:-1] / np.where(usable, lead, 1.0)).T
        companion[~usable] = 0.0
        eig = np.linalg.eigvals(companion)
        roots = np.where(np.abs(eig.imag) < 1e-9, eig.real, -1.0)
    inside = (roots > 0.0) & (roots < 1.0) & usable[:, None]
    powers = np.where(inside, roots, 0.0)[:, :, None] ** np.arange(n)
    at_roots = np.einsum("krn,nk->kr", powers, coef)
    best = np.maximum(best, np.max(np.where(inside, np.abs(at_roots), 0.0), axis=1))
    # Where p' was too close to a lower degree for its roots, sample p densely instead.
    if not usable.all():
        dense = np.linspace(0.0, 1.0, 65)[:, None] ** np.arange(n)
        sampled = np.max(np.abs(dense @ coef[:, ~usable]), axis=0)
        best[~usable] = np.maximum(best[~usable], sampled)
    return best.reshape(M, dof)


@dataclass(frozen=True, eq=False)
class Trajectory:
    """A time-parameterised joint trajectory, in one or more segments.

    The segments lie end to end on one clock: segment ``k + 1`` starts at the instant
    segment ``k`` ends (both at rest), and the joint values jump there (a branch switch or
    an unsolved stretch of the plan). Execute each segment on its own.

    Attributes:
        t: (N,) sample times, s, non-decreasing (a boundary time appears twice).
        q: (N, dof) joint positions (rad or m).
        qd: (N, dof) joint velocities (rad/s or m/s).
        qdd: (N, dof) joint accelerations (rad/s² or m/s²).
        segments: the segments, in order; each names its plan waypoints and samples.
        joint_names: names of the joints, in ``q`` order.
        velocity_limits: (dof,) limits used (rad/s or m/s).
        acceleration_limits: (dof,) limits used (rad/s² or m/s²).
    """

    t: FloatArray
    q: FloatArray
    qd: FloatArray
    qdd: FloatArray
    segments: tuple[TrajectorySegment, ...]
    joint_names: tuple[str, ...]
    velocity_limits: FloatArray
    acceleration_limits: FloatArray
    _timings: tuple[_Timing, ...] = field(default=(), repr=False)

    @property
    def duration(self) -> float:
        """Total time (s): the sum of the segments' durations."""
        return float(sum(seg.duration for seg in self.segments))

    def at(self, segment: int, t: Any) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Exact positions, velocities and accelerations of one segment at any times.

        Args:
            segment: index into :attr:`segments`.
            t: times (s) from the segment's start, a scalar or (K,); clipped to
                ``[0, duration]``.

        Returns:
            ``(q, qd, qdd)``, each (K, dof).
        """
        k = check_int("segment", segment, minimum=0, maximum=len(self.segments) - 1)
        times = np.atleast_1d(as_float_array("t", t)).ravel()
        if not np.all(np.isfinite(times)):
            raise OptikError("t: times must be finite")
        return self._timings[k].at(times)

    def save(self, path: str | Path) -> Path:
        """Write ``.csv`` (one row per sample) or ``.json`` (ROS ``JointTrajectory`` shape).

        The JSON file holds ``{"joint_names", "duration", "segments": [...]}``; each segment
        is shaped like a ROS ``trajectory_msgs/JointTrajectory`` message (``joint_names``,
        ``points`` with ``positions``, ``velocities``, ``accelerations`` and
        ``time_from_start {sec, nanosec}`` from the segment's start) plus the plan
        waypoints it covers. Written whole or not at all.

        Args:
            path: the file to write; its suffix (``.csv`` or ``.json``) picks the format.

        Raises:
            OptikError: an unknown suffix.
            OutputFileError: the file cannot be written.
        """
        target = output_path(path)
        suffix = target.suffix.lower()
        if suffix == ".csv":
            return write_atomic_with(target, self._write_csv)
        if suffix == ".json":
            return write_atomic_with(target, self._write_json)
        raise OptikError(f"{target}: unknown trajectory format {suffix!r} (expected .csv, .json)")

    def to_ros(self) -> list[dict[str, Any]]:
        """Each segment as a dict shaped like a ROS ``trajectory_msgs/JointTrajectory``."""
        out = []
        for seg in self.segments:
            points = []
            for k in range(seg.start, seg.stop):
                sec, nanosec = _ros_time(float(self.t[k] - seg.t_start))
                points.append(
                    {
                        "positions": self.q[k].tolist(),
                        "velocities": self.qd[k].tolist(),
                        "accelerations": self.qdd[k].tolist(),
                        "effort": [],
                        "time_from_start": {"sec": sec, "nanosec": nanosec},
                    }
                )
            out.append(
                {
                    "header": {"stamp": {"sec": 0, "nanosec": 0}, "frame_id": ""},
                    "joint_names": list(self.joint_names),
                    "points": points,
                    "waypoints": [seg.first, seg.last],
                }
            )
        return out

    def _write_csv(self, handle: IO[str]) -> None:
        names = self.joint_names
        header = ["segment", "t", *names]
        header += [f"{n}.velocity" for n in names] + [f"{n}.acceleration" for n in names]
        # Quoted where needed: a URDF joint name may hold a comma.
        csv.writer(handle, lineterminator="\n").writerow(header)
        for k_seg, seg in enumerate(self.segments):
            for k in range(seg.start, seg.stop):
                cells = [str(k_seg), f"{self.t[k]:.9f}"]
                cells += [f"{v:.12g}" for v in (*self.q[k], *self.qd[k], *self.qdd[k])]
                handle.write(",".join(cells) + "\n")

    def _write_json(self, handle: IO[str]) -> None:
        json.dump(
            {
                "joint_names": list(self.joint_names),
                "duration": self.duration,
                "velocity_limits": self.velocity_limits.tolist(),
                "acceleration_limits": self.acceleration_limits.tolist(),
                "segments": self.to_ros(),
            },
            handle,
        )


def _ros_time(t: float) -> tuple[int, int]:
    """``(sec, nanosec)`` of a non-negative time ``t`` (s), as a ROS Duration."""
    nanoseconds = round(t * 1e9)
    return nanoseconds // 1_000_000_000, nanoseconds % 1_000_000_000


# ------------------------------------------------------------------------ limits
def rate_limits(
    name: str, given: Any, known: FloatArray | None, names: Sequence[str]
) -> FloatArray:
    """Per-joint limits (dof,): ``given`` (a scalar or one per joint), else ``known``.

    Raises:
        OptikError: ``given`` of the wrong length, NaN, or outside [:data:`MIN_RATE_LIMIT`,
            :data:`MAX_RATE_LIMIT`]; or
            ``given`` is ``None`` and some joint has no known limit (the message names the
            joints and how to give them).
    """
    dof = len(names)
    if given is None:
        unknown = (
            []
            if known is None
            else [n for n, v in zip(names, known, strict=True) if not np.isfinite(v)]
        )
        if known is None or unknown:
            where = (
                "no robot was given to read them from"
                if known is None
                else f"none known for joint(s) {unknown} (neither the URDF nor the problem "
                "file states them)"
            )
            raise OptikError(f"{name}: {where}; give {name}= one value or one per joint")
        return np.array(known, dtype=float)
    values = as_float_array(name, given)
    if values.ndim == 0:
        values = np.full(dof, float(values))
    if values.shape != (dof,):
        raise ShapeError(name, f"a scalar or ({dof},), one per joint {tuple(names)}", values.shape)
    bad = ~((values >= MIN_RATE_LIMIT) & (values <= MAX_RATE_LIMIT))
    if bad.any():
        joints = [f"{n}={v!r}" for n, v, b in zip(names, values.tolist(), bad, strict=True) if b]
        raise OptikError(
            f"{name}: limits must lie in [{MIN_RATE_LIMIT:g}, {MAX_RATE_LIMIT:g}] "
            f"(rad or m per s, or per s^2), got {', '.join(joints)}"
        )
    return values


# ------------------------------------------------------------------------ segments
def plan_stretches(plan: PathPlan) -> list[tuple[int, int]]:
    """``(first, last)`` waypoint indices of each stretch that one segment can cover."""
    stretches: list[tuple[int, int]] = []
    first: int | None = None
    for k, status in enumerate(plan.status):
        solved = status not in _UNSOLVED and not np.isnan(plan.q[k]).any()
        if first is not None and (not solved or status == "discontinuity"):
            stretches.append((first, k - 1))
            first = None
        if solved and first is None:
            first = k
    if first is not None:
        stretches.append((first, len(plan.status) - 1))
    return stretches


def _chord(Q: FloatArray) -> FloatArray:
    """Cumulative joint-space chord length at each row of ``Q`` (k, dof)."""
    return np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(Q, axis=0), axis=1))])


def _merge_close(Q: FloatArray) -> tuple[Any, Any]:
    """The waypoints of ``Q`` (k, dof) kept as knots, and for each waypoint its knot.

    Returns ``(kept, knot_of)``: indices into ``Q`` of the knots (the first waypoint always
    one), and per waypoint the index into ``kept`` of the knot it is merged into. A
    waypoint within ``max(MERGE_TOLERANCE * chord length, 1e-9)`` (rad or m, Euclidean) of
    the last knot is merged into it: a spline through both would bend sharply between
    them, and TOPP-RA's rounding over so short an interval would read as a large
    acceleration. Each waypoint is thus within that distance of its knot.
    """
    steps = np.linalg.norm(np.diff(Q, axis=0), axis=1)
    tol = max(_SAME_POINT, MERGE_TOLERANCE * float(steps.sum()))
    if np.all(steps > tol):  # the common case: every waypoint is a knot
        return np.arange(len(Q)), np.arange(len(Q))
    kept = [0]
    knot_of = np.zeros(len(Q), dtype=int)
    for k in range(1, len(Q)):
        if np.linalg.norm(Q[k] - Q[kept[-1]]) > tol:
            kept.append(k)
        knot_of[k] = len(kept) - 1
    return np.array(kept), knot_of


def joint_path(Q: FloatArray, lower: FloatArray, upper: FloatArray) -> tuple[Any, FloatArray, str]:
    """The interpolating spline through ``Q`` (k >= 2 distinct rows), its knots, its kind."""
    from scipy.interpolate import CubicSpline, PchipInterpolator

    s = _chord(Q)
    spline = CubicSpline(s, Q, bc_type="natural", axis=0)
    # The natural cubic can overshoot between waypoints: compare its exact range.
    low, high = _cubic_range(spline.c, np.diff(s))
    if np.all(low >= lower - _LIMIT_SLACK) and np.all(high <= upper + _LIMIT_SLACK):
        return spline, s, "cubic"
    return PchipInterpolator(s, Q, axis=0), s, "pchip"


def _cubic_range(c: FloatArray, h: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Least and greatest values (dof,) of a piecewise cubic with coefficients ``c``.

    ``c`` is scipy's (4, m, dof) layout: on piece ``i`` the value is
    ``c0 t³ + c1 t² + c2 t + c3`` for ``t`` in [0, ``h[i]``]. The extremes are at the ends
    of the pieces or where ``3 c0 t² + 2 c1 t + c2 = 0`` inside them.
    """
    a, b, d = 3.0 * c[0], 2.0 * c[1], c[2]
    disc = np.sqrt(np.maximum(b * b - 4.0 * a * d, 0.0))
    with np.errstate(divide="ignore", invalid="ignore"):
        quadratic = np.stack([(-b + disc) / (2.0 * a), (-b - disc) / (2.0 * a)])
        linear = -d / b
    roots = np.where(np.abs(a) > 0, quadratic, np.where(np.abs(b) > 0, linear, 0.0))
    H = h[None, :, None]
    t = np.concatenate([np.zeros((1, *c.shape[1:])), np.broadcast_to(H, (1, *c.shape[1:]))])
    inside = np.isfinite(roots) & (roots > 0) & (roots < H)
    t = np.concatenate([t, np.where(inside, roots, 0.0)])
    values = ((c[0] * t + c[1]) * t + c[2]) * t + c[3]
    return values.min(axis=(0, 1)), values.max(axis=(0, 1))


def _grid(knots: FloatArray, intervals: int) -> FloatArray:
    """At least ``intervals`` grid intervals, every knot a grid point.

    Each knot interval gets a share in proportion to its length (at least one): splitting
    a short interval as finely as a long one would only magnify TOPP-RA's rounding.
    """
    lengths = np.diff(knots)
    # The - 1e-9 keeps equal intervals from getting one piece more through rounding.
    per = np.maximum(1, np.ceil(lengths * (intervals / knots[-1]) - 1e-9)).astype(int)
    piece = np.repeat(np.arange(len(per)), per)
    step = np.arange(len(piece)) - np.repeat(np.cumsum(per) - per, per)
    inner = knots[piece] + lengths[piece] * step / per[piece]
    return np.concatenate([inner, knots[-1:]])


TOPPRA_MISSING = "trajectories need toppra: pip install 'optik[trajectory]'"
"""The error of a trajectory asked for without the ``trajectory`` extra."""


def require_toppra() -> None:
    """Raise :class:`~optik.errors.OptikError` naming the extra unless toppra is installed.

    For a caller that would otherwise do its other work first (``optik plan
    --trajectory`` solves the whole path before it times it).
    """
    if importlib.util.find_spec("toppra") is None:
        raise OptikError(TOPPRA_MISSING)


@contextlib.contextmanager
def _quiet_toppra() -> Iterator[None]:
    """Hold back the log of toppra below ERROR for the duration, then restore its level.

    Its warnings are its own retries ("A numerical error occurs ... slightly reduced"),
    hundreds of lines on a short segment, while the outcome is checked here from its
    return code. (``toppra.setup_logging``, called before, also added one more console
    handler to its logger at every call, so that each line came out once per earlier
    trajectory.)
    """
    logger = logging.getLogger("toppra")
    level = logger.level
    logger.setLevel(logging.ERROR)
    try:
        yield
    finally:
        logger.setLevel(level)


def _toppra_speed(path: Any, grid: FloatArray, vlim: FloatArray, alim: FloatArray) -> FloatArray:
    """TOPP-RA's fastest path speed ``ds/dt`` at the grid points, at rest at both ends.

    ``grid`` starts at 0. TOPP-RA's tolerances are absolute, so it solves in units where the
    path is 1 long and lasts about 1 (``s = length * x``, ``t = scale * tau``); otherwise
    its rounding, large beside small speeds or short grid intervals, reads as accelerations.
    """
    try:
        import toppra
        import toppra.algorithm
        import toppra.constraint
    except ImportError as exc:  # pragma: no cover - toppra is in the test extra
        raise OptikError(TOPPRA_MISSING) from exc

    length = float(grid[-1])
    # A time scale (s) of the segment: the longer of cruising and accelerating through it.
    scale = max(length / float(np.min(vlim)), math.sqrt(length / float(np.min(alim))))

    class _Path(toppra.interpolator.AbstractGeometricPath):
        def __call__(self, s: Any, order: int = 0) -> Any:
            return path(np.asarray(s) * length, order) * length**order

        @property
        def dof(self) -> int:
            return len(vlim)

        @property
        def path_interval(self) -> FloatArray:
            return np.array([0.0, 1.0])

    constraints = [
        toppra.constraint.JointVelocityConstraint(np.column_stack([-vlim, vlim]) * scale),
        toppra.constraint.JointAccelerationConstraint(np.column_stack([-alim, alim]) * scale**2),
    ]
    instance = toppra.algorithm.TOPPRA(constraints, _Path(), gridpoints=grid / length)
    with _quiet_toppra():
        instance.compute_parameterization(0.0, 0.0)
    code = instance.problem_data.return_code
    sd = instance.problem_data.sd_vec
    if sd is None or code != toppra.algorithm.ParameterizationReturnCode.Ok:
        raise OptikError(f"TOPP-RA found no parameterisation ({code}); check the limits")
    return np.maximum(np.asarray(sd, dtype=float), 0.0) * (length / scale)


def _fit_limits(timing: _Timing, vlim: FloatArray, alim: FloatArray) -> _Timing:
    """Stretch time so that the largest velocities and accelerations are within limits."""
    vmax, amax = timing.peaks()
    r = max(float(np.max(vmax / vlim)), math.sqrt(float(np.max(amax / alim))))
    # A hair of slack for rounding: stretching by r divides qd by r and qdd by r².
    return timing.scaled(r * (1.0 + 1e-9)) if r > 1.0 else timing


# ------------------------------------------------------------------------ main
def plan_trajectory(
    plan: PathPlan,
    velocity_limits: Any = None,
    acceleration_limits: Any = None,
    *,
    robot: Robot | None = None,
    dt: float = 0.01,
    grid: int = 200,
    path_tolerance: float | None = None,
) -> Trajectory:
    """The time-optimal trajectory along a plan's joint path, in segments (see the module).

    Args:
        plan: the plan.
        velocity_limits: joint speed limits, one value for all or one per joint (rad/s or
            m/s); default: the robot's (from the URDF's ``<limit velocity>`` or the problem
            file's ``velocity`` fields).
        acceleration_limits: joint acceleration limits, one value or one per joint (rad/s²
            or m/s²); default: the robot's (the problem file's ``acceleration`` fields;
            URDF does not state them).
        robot: the robot the plan was made for: the source of default limits, and of the
            measured departure from the Cartesian path.
        dt: sampling step (s) of the returned arrays; each segment also has a sample at its
            end; at most :data:`MAX_TRAJECTORY_SAMPLES` samples in all.
            :meth:`Trajectory.at` evaluates at any time.
        grid: least number of TOPP-RA grid intervals per segment (every waypoint is a grid
            point), 1 to :data:`MAX_GRID`.
        path_tolerance: largest accepted departure (m for position, rad for orientation)
            of the tool from the Cartesian path between waypoints; needs ``robot``.

    Returns:
        A :class:`Trajectory`; a plan without a solved waypoint gives one without segments.

    Raises:
        OptikError: an infinite joint value in ``plan.q``; no limits given or known,
            limits of the wrong length or not finite and positive, ``dt``, ``grid`` or
            ``path_tolerance`` out of range, a robot whose joints do not match the plan,
            a departure beyond ``path_tolerance`` (plan with a finer path step, or loosen
            it), or more than :data:`MAX_TRAJECTORY_SAMPLES` samples (raise ``dt`` or the
            limits).
    """
    # What is read of a plan (optik.planning imports this module: no isinstance here).
    if not all(hasattr(plan, name) for name in ("q", "status", "joint_names", "poses", "mode")):
        raise OptikError(
            f"plan: expected an optik.PathPlan (from optik.plan_path), got {type(plan).__name__}"
        )
    dt = check_real("dt", dt, positive=True)
    grid = check_int("grid", grid, minimum=1, maximum=MAX_GRID)
    dof = plan.q.shape[1]
    infinite = np.argwhere(np.isinf(plan.q))
    if len(infinite):  # NaN rows are unsolved waypoints; an infinity is no joint value
        k, j = infinite[0]
        raise OptikError(f"plan: q[{k}, {j}] is {plan.q[k, j]} (a solved waypoint's joint value)")
    names = plan.joint_names or tuple(f"q{i + 1}" for i in range(dof))
    if robot is not None:
        from optik.model import Robot

        if not isinstance(robot, Robot):
            raise OptikError(f"robot: expected an optik.Robot, got {type(robot).__name__}")
        if robot.dof != dof or (plan.joint_names and robot.joint_names != plan.joint_names):
            raise OptikError(
                f"robot: {robot.name!r} has joints {robot.joint_names}, the plan "
                f"{names} ({dof} joints)"
            )
    if path_tolerance is not None:
        path_tolerance = check_real("path_tolerance", path_tolerance, positive=True)
        if robot is None:
            raise OptikError("path_tolerance: needs robot= to measure the tool's departure")
    vlim = rate_limits(
        "velocity_limits", velocity_limits, None if robot is None else robot.velocity_limits, names
    )
    alim = rate_limits(
        "acceleration_limits",
        acceleration_limits,
        None if robot is None else robot.acceleration_limits,
        names,
    )
    lower = np.full(dof, -np.inf) if robot is None else robot.lower
    upper = np.full(dof, np.inf) if robot is None else robot.upper

    segments: list[TrajectorySegment] = []
    timings: list[_Timing] = []
    parts: list[tuple[FloatArray, ...]] = []
    clock = 0.0
    count = 0
    for first, last in plan_stretches(plan):
        Q = plan.q[first : last + 1]
        kept, knot_of = _merge_close(Q)
        if len(kept) < 2:  # one point: the segment holds still
            timing = _Timing(_Hold(Q[0]), np.zeros(2), np.zeros(2), np.zeros(2), np.zeros(1))
            kind, s_way, t_way = "hold", np.zeros(len(Q)), np.zeros(len(Q))
        else:
            path, knots, kind = joint_path(Q[kept], lower, upper)
            s_way = knots[knot_of]  # a merged waypoint is passed when its knot is
            ss = _grid(knots, grid)
            timing = _fit_limits(
                _Timing.build(path, ss, _toppra_speed(path, ss, vlim, alim)), vlim, alim
            )
            if not np.all(np.isfinite(timing.ts)):  # a zero speed inside the path
                raise OptikError(
                    f"waypoints {first} to {last}: TOPP-RA stopped inside the path, so its "
                    "time is not finite"
                )
            t_way = np.interp(s_way, timing.ss, timing.ts)
        deviation = (math.nan, math.nan)
        if robot is not None:
            merged = merge_departure(robot, plan, Q, kept, knot_of)
            between = (0.0, 0.0)
            if kind != "hold":
                between = segment_departure(robot, plan, first, timing.path, s_way)
            deviation = (max(between[0], merged[0]), max(between[1], merged[1]))
            if path_tolerance is not None and max(deviation) > path_tolerance:
                raise OptikError(
                    f"the joint path between waypoints {first} and {last} departs "
                    f"{deviation[0]:.3g} m / {deviation[1]:.3g} rad from the Cartesian path, "
                    f"beyond path_tolerance {path_tolerance:g}: plan with a finer path step"
                )
        duration = timing.duration
        # Count before allocating: tiny limits or a tiny dt ask for billions of samples.
        if not count + duration / dt <= MAX_TRAJECTORY_SAMPLES - 2:
            raise OptikError(
                f"dt: sampling {clock + duration:.6g} s of trajectory every {dt:g} s gives more "
                f"than MAX_TRAJECTORY_SAMPLES = {MAX_TRAJECTORY_SAMPLES:,} samples; raise dt "
                "(optik plan --dt) or the limits (Trajectory.at evaluates at any time)"
            )
        local = np.append(np.arange(0.0, duration, dt), duration) if duration > 0 else np.zeros(1)
        q, qd, qdd = timing.at(local)
        segments.append(
            TrajectorySegment(
                first=first,
                last=last,
                start=count,
                stop=count + len(local),
                t_start=clock,
                duration=duration,
                interpolation=kind,
                s_waypoints=s_way,
                waypoint_times=t_way,
                position_deviation=deviation[0],
                orientation_deviation=deviation[1],
            )
        )
        timings.append(timing)
        parts.append((clock + local, q, qd, qdd))
        clock += duration
        count += len(local)
    if parts:
        t, q, qd, qdd = (np.concatenate([p[i] for p in parts]) for i in range(4))
    else:
        t, q, qd, qdd = np.zeros(0), np.zeros((0, dof)), np.zeros((0, dof)), np.zeros((0, dof))
    return Trajectory(
        t=t,
        q=q,
        qd=qd,
        qdd=qdd,
        segments=tuple(segments),
        joint_names=tuple(names),
        velocity_limits=vlim,
        acceleration_limits=alim,
        _timings=tuple(timings),
    )


class _Hold:
    """A path that stays at one configuration (a segment of one waypoint)."""

    def __init__(self, q: FloatArray) -> None:
        self.q = q

    def __call__(self, s: Any, nu: int = 0) -> FloatArray:
        n = np.size(s)
        return np.broadcast_to(self.q if nu == 0 else 0.0 * self.q, (n, len(self.q))).copy()
