"""Six revolute joints with three axes through one point, found from the joint axes.

The family ``spherical_axes`` takes any chain of six revolute joints whose axes at
``q = 0`` (:func:`optik.analytic.geometry.joint_axes`, world frame, whatever the robot
was read from) have a spherical wrist (axes 4, 5 and 6 through one point) and an arm the
Paden–Kahan subproblems solve:

- axes 1 and 2 meet, and axis 3 passes through neither that point nor the wrist centre
  (:mod:`optik.analytic.pair_wrist`; EAIK's "spherical, first two intersecting");
- axes 1 and 2 are parallel (:data:`optik.analytic.parallel_arm.PARALLEL_12`; "first two
  parallel");
- axes 2 and 3 are parallel (:data:`optik.analytic.parallel_arm.PARALLEL_23`; "second
  two parallel": the Puma and the UR-less industrial arms with any twists and offsets);
- axes 2 and 3 meet (:data:`SECOND_PAIR`,
  :func:`optik.analytic.pair_wrist.second_pair_candidates`; "second two intersecting");
- none of these, with axis 3 missing the wrist centre (:data:`GENERAL`,
  :mod:`optik.analytic.general_arm`; "no parallel, no intersecting"): one quartic.

Or the same read backwards (:func:`optik.analytic.geometry.reversed_axes`): a spherical
shoulder (axes 1, 2 and 3 through one point) and an arm among axes 4 to 6. A robot that
both readings fit takes the one in order, unless only the other avoids the quartic.
Tolerances are those of the geometry (:data:`optik.analytic.geometry.ANGLE_TOL`,
``LENGTH_TOL`` times the arm's size). It is registered after the DH families: a robot
that ``spherical_wrist`` or ``ur`` fits keeps that family; this one covers the twists,
offsets and joint orders they do not.

Compiled end to end as the DH families are, a pipeline per arm kind
(:func:`kind_pipeline`: one target, or a batch) runs the closed form, then the steps of
:func:`optik.analytic._pipeline.postprocess_rows` (wrapping into the limits, the limit
filter, the FK check on the robot's own chain, de-duplication, the sort), on the robot's
parameter vector (:func:`pack_axes_params`; :meth:`SphericalAxes.compiled`).

The same pipeline carries the family ``three_parallel`` (:class:`ThreeParallelAxes`,
:func:`parallel_plan`): three parallel axes and no spherical wrist, two more arm kinds
(:data:`THREE_INNER`, :data:`THREE_OUTER`, :mod:`optik.analytic.three_parallel`).
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from typing import Any, NamedTuple

import numpy as np

from optik._checks import FloatArray
from optik._nrt import borrowed
from optik._numba import inline as _inline
from optik._numba import jit as _jit
from optik.analytic._base import CompiledPipeline, PlannedFamily, register
from optik.analytic._compiled import (
    MAX_BRANCHES,
    axes_block,
    axes_offsets,
    axes_wrist_centre,
    pack_axes_vector,
    tolerance_block,
)
from optik.analytic._pipeline import Layout, postprocess_rows
from optik.analytic._pipeline_args import batch_work, flag_bits, input_code, pad_rows, work_rows
from optik.analytic.free_joint import inverse_into
from optik.analytic.general_arm import general_arm_candidates
from optik.analytic.geometry import (
    ANGLE_TOL,
    LENGTH_TOL,
    Axes,
    joint_axes,
    line_distance,
    point_line_distance,
    reversed_axes,
    revolute_chain_reason,
)
from optik.analytic.pair_wrist import (
    AxesQuery,
    axis_label,
    meet_reason,
    meeting,
    pair_wrist_candidates,
    second_pair_candidates,
    structure_reason,
    wrist_reason,
)
from optik.analytic.parallel_arm import PARALLEL_12, PARALLEL_23, parallel_arm_candidates
from optik.analytic.three_parallel import three_inner_candidates, three_outer_candidates
from optik.errors import OptikError
from optik.model import Robot

INTERSECTING = 3
"""Arm kind: axes 1 and 2 meet (:func:`optik.analytic.pair_wrist.pair_wrist_candidates`)."""
GENERAL = 4
"""Arm kind: none of the others (:func:`optik.analytic.general_arm.general_arm_candidates`)."""
SECOND_PAIR = 5
"""Arm kind: axes 2 and 3 meet (:func:`optik.analytic.pair_wrist.second_pair_candidates`)."""
THREE_INNER = 6
"""Not a wrist's arm: axes 2, 3, 4 parallel (family ``three_parallel``,
:func:`optik.analytic.three_parallel.three_inner_candidates`)."""
THREE_OUTER = 7
"""Not a wrist's arm: axes 1, 2, 3 parallel, axes 5 and 6 meeting (family
``three_parallel``, :func:`optik.analytic.three_parallel.three_outer_candidates`)."""
KIND_NAMES = {
    INTERSECTING: "axes 1 and 2 meet",
    PARALLEL_12: "axes 1 and 2 parallel",
    PARALLEL_23: "axes 2 and 3 parallel",
    SECOND_PAIR: "axes 2 and 3 meet",
    GENERAL: "general arm (a quartic)",
    THREE_INNER: "axes 2, 3 and 4 parallel (three_parallel)",
    THREE_OUTER: "axes 1, 2 and 3 parallel, axes 5 and 6 meeting (three_parallel)",
}
"""What each arm kind means, for messages and docs."""


class AxesPlan(NamedTuple):
    """How a six-joint robot is solved by ``spherical_axes`` (:func:`axes_plan`).

    Attributes:
        kind: the arm's kind (:data:`INTERSECTING`, ``PARALLEL_12``, ``PARALLEL_23``,
            :data:`SECOND_PAIR`, :data:`GENERAL`), 0 when the robot does not fit.
        reverse: whether the closed form solves the chain read backwards.
        directions: (6, 3) unit joint directions at ``q = 0`` of the chain as solved.
        points: (6, 3) a point on each of its axes (m).
        tool: (4, 4) its tool at ``q = 0``.
        tols: the tolerance block of :mod:`optik.analytic._compiled`.
        reason: ``""`` when the robot fits, else why not.
    """

    kind: int
    reverse: bool
    directions: FloatArray
    points: FloatArray
    tool: FloatArray
    tols: FloatArray
    reason: str


def _parallel(axes: Axes, i: int, j: int) -> bool:
    z = axes.directions
    return float(np.linalg.norm(np.cross(z[i], z[j]))) <= ANGLE_TOL


def arm_kind(axes: Axes, names: tuple[str, ...]) -> tuple[int, str]:
    """The arm kind of six axes with a spherical wrist, or ``(0, why not)``.

    Args:
        axes: the six joint axes at ``q = 0``.
        names: the six joints' names, for the messages.
    """
    why = wrist_reason(axes, names)
    if why is not None:
        return 0, why
    tol = LENGTH_TOL * axes.size
    z, p = axes.directions, axes.points
    W = meeting(axes, 3, 4)
    a1, a2, a3 = (axis_label(names, i) for i in range(3))
    if not _parallel(axes, 0, 1) and structure_reason(axes, names) is None:
        return INTERSECTING, ""
    for i, kind in ((0, PARALLEL_12), (1, PARALLEL_23)):
        if not _parallel(axes, i, i + 1):
            continue
        other = 2 if kind == PARALLEL_12 else 0
        label = f"axes {axis_label(names, i)} and {axis_label(names, i + 1)}"
        if line_distance(z[i], p[i], z[i + 1], p[i + 1]) <= tol:
            return 0, f"{label} are one line"
        if _parallel(axes, other, i):
            return 0, f"axes 1-3 are parallel ({label} and {axis_label(names, other)})"
        if point_line_distance(z[2], p[2], W) <= tol:
            return 0, f"axis {a3} passes through the wrist centre: it does not move it"
        return kind, ""
    # Neither pair parallel (else the loop returned).
    if meet_reason(axes, names, 0, 1) is None:
        # Axes 1 and 2 meet, but axis 3 passes through their point or the wrist centre.
        neither = f"neither axes {a1}, {a2} nor {a2}, {a3} are parallel"
        return 0, f"{structure_reason(axes, names)}, and {neither}"
    if point_line_distance(z[2], p[2], W) <= tol:
        return 0, f"axis {a3} passes through the wrist centre: it does not move it"
    if meet_reason(axes, names, 1, 2) is None:
        return SECOND_PAIR, ""
    return GENERAL, ""


def axes_plan(robot: Robot) -> AxesPlan:
    """Whether (and how) ``spherical_axes`` solves ``robot``: in order, else read backwards.

    Args:
        robot: the robot.
    """
    return _plan_of(robot, _arm_plan)


def _plan_of(robot: Robot, plan: Callable[[Axes, Axes, tuple[str, ...]], AxesPlan]) -> AxesPlan:
    """``plan(axes, back, names)``: ``robot``'s axes in order and read backwards, its names.

    Unfit (saying why) for a robot without six revolute joints.
    """
    reason = revolute_chain_reason(robot, 6)
    if reason is not None:
        return _unfit(reason)
    axes = joint_axes(robot)
    return plan(axes, reversed_axes(axes), robot.chain_names)


def _arm_plan(axes: Axes, back: Axes, names: tuple[str, ...]) -> AxesPlan:
    """:func:`axes_plan` on the axes in order and read backwards (:func:`_plan_of`)."""
    kind, why = arm_kind(axes, names)
    kind_back, why_back = arm_kind(back, names[::-1])
    # The quartic only where neither reading has an arm of subproblems.
    if kind and not (kind == GENERAL and kind_back not in (0, GENERAL)):
        return AxesPlan(kind, False, *_arrays(axes), tolerance_block(), "")
    if kind_back:
        return AxesPlan(kind_back, True, *_arrays(back), tolerance_block(), "")
    return _unfit(f"{why}; read backwards: {why_back}")


def _unfit(reason: str) -> AxesPlan:
    """The plan of a robot the family does not fit: kind 0, ``reason`` why (one line)."""
    empty = np.empty((0, 3))
    return AxesPlan(0, False, empty, empty, np.eye(4), np.empty(0), reason)


def _arrays(axes: Axes) -> tuple[FloatArray, FloatArray, FloatArray]:
    return (
        np.ascontiguousarray(axes.directions, dtype=np.float64),
        np.ascontiguousarray(axes.points, dtype=np.float64),
        np.ascontiguousarray(axes.tool, dtype=np.float64),
    )


DOF = 6
# Layout of the compiled kernels' parameter vector (pack_axes_params, flat float64): the
# arm's kind and the form's direction, then the blocks of
# optik.analytic._compiled.AxesOffsets (limits, chain, axes and tool at q = 0, wrist centre,
# tolerances).
AT_ARM = 0  # (1,) the arm's kind
AT_REVERSE = 1  # (1,) 1.0 when the closed form solves the chain read backwards
_AT = axes_offsets(DOF, 2)
AT_KIND, AT_LOWER, AT_UPPER, AT_CHAIN, AT_DIRECTIONS, AT_POINTS, AT_TOOL, AT_WRIST, AT_TOLS = _AT
AXES_LAYOUT: Layout = _AT.layout
"""Where :func:`optik.analytic._pipeline.postprocess_rows` finds the robot's data."""


def pack_axes_params(robot: Robot, plan: AxesPlan) -> FloatArray:
    """The flat parameter vector of :func:`solve` and :func:`solve_batch` (layout above).

    Args:
        robot: the robot (fits the family).
        plan: its :func:`axes_plan`.
    """
    head = (plan.kind, 1.0 if plan.reverse else 0.0)
    return pack_axes_vector(
        robot, head, plan.directions, plan.points, plan.tool, plan.tols, axes_wrist_centre(robot)
    )


@_jit
def _scratch(
    params: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``(z, p, M, Ti, work)`` of :func:`_candidates_into`, made once per call or batch.

    ``z``, ``p`` (6, 3) and ``M`` (4, 4) the axes and tool of the chain solved (copied
    from ``params``); ``Ti`` (4, 4) the inverse target; ``work`` (2, 8, 6): the reversed
    reference and the branches of the chain read backwards.
    """
    z, p, M = axes_block(params, AT_DIRECTIONS, DOF)
    return z, p, M, np.empty((4, 4)), np.empty((2, MAX_BRANCHES, DOF))


@_inline
def _candidates_into(
    params: np.ndarray,
    T: np.ndarray,
    ref: np.ndarray,
    rows: np.ndarray,
    scratch: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray],
    kind: int,
) -> int:
    """Raw branches of world target ``T`` (4, 4) into ``rows`` (>= 8, 6), in joint order.

    Read backwards (``params[AT_REVERSE]``) the chain's target is ``T^-1``, its
    reference ``ref`` reversed, and its branches are turned back into the robot's order.
    One call site of :func:`axes_candidates` for both readings: numba links a callee's
    code into its caller, and a second site doubled the compile time of every pipeline
    above it (the arm kernels optimised again). ``kind`` is the arm's kind
    (``params[AT_ARM]``); inlined into a pipeline of :func:`kind_pipeline`, where it is a
    constant, only that kind's kernel is compiled.
    """
    z, p, M, Ti, work = scratch
    tols = params[AT_TOLS:]
    reverse = params[AT_REVERSE] != 0.0
    target, reference, out = T, ref, rows
    if reverse:
        inverse_into(T, Ti)
        back = work[0, 0]
        for j in range(DOF):
            back[j] = ref[DOF - 1 - j]
        target, reference, out = Ti, back, work[1]
    n = axes_candidates(AxesQuery(z, p, M, target, reference, tols), kind, out)
    if reverse:
        for r in range(n):
            for j in range(DOF):
                rows[r, j] = out[r, DOF - 1 - j]
    return n


class KindPipeline(NamedTuple):
    """The compiled kernels of one arm kind (:func:`kind_pipeline`).

    Attributes:
        solve: ``solve(params, T, ref, flags, out) -> code or n``: every branch of one
            target, the closed form then the steps of
            :func:`optik.analytic._pipeline.postprocess_rows` (arguments, flags and
            return codes of :func:`optik.analytic._pipeline.solve`; ``ref`` (6,) in rad,
            ``out`` (8, 6)).
        solve_batch: ``solve_batch(params, T, ref, flags) -> (Q, counts)``: validated
            targets ``T`` (N, 4, 4) serially (outputs of
            :func:`optik.analytic._pipeline.solve_batch`: ``Q`` (N, 8, 6), ``counts``
            (N,)).
        candidates: ``candidates(params, T, ref, rows) -> n``: the raw branches alone of
            world target ``T`` (4, 4) into ``rows`` (>= 8, 6), in joint order
            (:func:`_candidates_into`; ``ref`` (6,) in rad).

    Each takes :func:`pack_axes_params`'s vector of a robot of this kind.
    """

    solve: Any
    solve_batch: Any
    candidates: Any


@_jit
def postprocess_axes(
    params: np.ndarray,
    T: np.ndarray,
    k: int,
    ref: np.ndarray,
    kr: int,
    sort: bool,
    within: bool,
    rows: np.ndarray,
    flat: np.ndarray,
    n: int,
    pre: np.ndarray,
    Q: np.ndarray,
    newton: np.ndarray,
) -> int:
    """:func:`optik.analytic._pipeline.postprocess_rows` of any arm kind's raw branches.

    A call, not inlined, shared by the pipelines of every kind (:func:`kind_pipeline`):
    its code (the wrap, the limits, the Newton step, the FK check, the sort) is compiled
    once, on the first call of any kind (or by ``optik warmup --groups axes_arms``), and
    every other kind's first call then compiles only its own closed form.
    Arguments and result as ``postprocess_rows`` with the layout of :func:`pack_axes_params`
    and the Newton step on. The caller owns every array for the whole call: the steps
    take borrowed views (:func:`optik._nrt.borrowed`), whose per-row calls count no
    references.
    """
    params, T, ref = borrowed(params), borrowed(T), borrowed(ref)
    rows, flat, pre = borrowed(rows), borrowed(flat), borrowed(pre)
    Q, newton = borrowed(Q), borrowed(newton)
    return postprocess_rows(
        params, AXES_LAYOUT, DOF, -1, 0.0, T, k, ref, kr, sort, within, rows, flat, n, pre, Q,
        True, newton,
    )  # fmt: skip


@functools.cache
def kind_pipeline(kind: int) -> KindPipeline:
    """The compiled pipeline of arm ``kind`` alone (a :class:`KindPipeline`).

    One pipeline per arm kind, so that a robot's first call compiles its own arm's
    closed form and not the six others: numba prunes the branches of
    :func:`axes_candidates` on the constant ``kind``, and caches each kind's kernels on
    disk under it.

    Args:
        kind: an arm kind (a key of :data:`KIND_NAMES`).

    Raises:
        OptikError: ``kind`` is not an arm kind.
    """
    if kind not in KIND_NAMES:
        raise OptikError(f"unknown arm kind {kind!r}; known: {sorted(KIND_NAMES)}")
    kind = int(kind)  # the closure's constant: numba keys the disk cache on its pickle

    @_jit
    def solve(
        params: np.ndarray, T: np.ndarray, ref: np.ndarray, flags: int, out: np.ndarray
    ) -> int:
        T1 = T[None]
        code = input_code(params, AT_TOLS, T1, ref)
        if code != 0:
            return code
        pre, flat, rows, newton = work_rows(DOF)
        n = _candidates_into(params, T, ref, rows, _scratch(params), kind)
        sort, within = flag_bits(flags)
        first = np.int64(0)  # not the literal 0: the batch's signature serves this call
        return postprocess_axes(
            params, T1, first, ref[None], first, sort, within, rows, flat, n, pre, out[None],
            newton,
        )  # fmt: skip

    @_jit
    def solve_each(
        params: np.ndarray,
        T: np.ndarray,
        ref: np.ndarray,
        sort: bool,
        within: bool,
        rows: np.ndarray,
        flat: np.ndarray,
        pre: np.ndarray,
        Q: np.ndarray,
        counts: np.ndarray,
        newton: np.ndarray,
        scratch: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray],
    ) -> None:
        # The batch's loop on borrowed views (optik._nrt): the caller owns every array
        # for the whole call, and the per-target calls then count no references.
        params, T, ref = borrowed(params), borrowed(T), borrowed(ref)
        rows, flat, pre = borrowed(rows), borrowed(flat), borrowed(pre)
        Q, newton = borrowed(Q), borrowed(newton)
        z, p, M, Ti, work = scratch
        scratch = (borrowed(z), borrowed(p), borrowed(M), borrowed(Ti), borrowed(work))
        for k in range(T.shape[0]):
            kr = 0 if ref.shape[0] == 1 else k
            n = _candidates_into(params, T[k], ref[kr], rows, scratch, kind)
            counts[k] = postprocess_axes(
                params, T, k, ref, kr, sort, within, rows, flat, n, pre, Q, newton
            )
            pad_rows(Q, k, counts[k])

    @_jit
    def solve_batch(
        params: np.ndarray, T: np.ndarray, ref: np.ndarray, flags: int
    ) -> tuple[np.ndarray, np.ndarray]:
        sort, within, pre, flat, rows, newton, Q, counts = batch_work(T.shape[0], DOF, flags)
        scratch = _scratch(params)
        solve_each(params, T, ref, sort, within, rows, flat, pre, Q, counts, newton, scratch)
        return Q, counts

    @_jit
    def candidates(params: np.ndarray, T: np.ndarray, ref: np.ndarray, rows: np.ndarray) -> int:
        return _candidates_into(params, T, ref, rows, _scratch(params), kind)

    return KindPipeline(solve, solve_batch, candidates)


@_inline
def axes_candidates(query: AxesQuery, kind: int, cand: np.ndarray) -> int:
    """Raw branches of arm ``kind`` and a spherical wrist into ``cand`` (>= 8, 6).

    Arguments as :func:`optik.analytic.parallel_arm.parallel_arm_candidates` (world
    frame; ``T`` the tool's target); returns the number of rows written. Inlined, so
    that a constant ``kind`` keeps one kernel (:func:`kind_pipeline`).
    """
    if kind == INTERSECTING:
        return pair_wrist_candidates(query, cand)
    if kind == SECOND_PAIR:
        return second_pair_candidates(query, cand)
    if kind == GENERAL:
        return general_arm_candidates(query, cand)
    if kind == THREE_INNER:
        return three_inner_candidates(query, cand)
    if kind == THREE_OUTER:
        return three_outer_candidates(query, cand)
    return parallel_arm_candidates(query, kind, cand)


@register
class SphericalAxes(PlannedFamily):
    """Six revolute joints: a spherical wrist (or shoulder) and an arm of subproblems."""

    name = "spherical_axes"
    plan = staticmethod(axes_plan)
    """How the family solves a robot (an :class:`AxesPlan`, cached per robot)."""

    def fits(self, robot: Robot) -> bool:
        """Whether ``robot``'s joint axes have the structure (module docstring)."""
        return robot.cached(self.plan).kind != 0

    def compiled(self, robot: Robot) -> CompiledPipeline | None:
        """:func:`solve` and :func:`solve_batch` on the robot's parameter vector.

        Args:
            robot: the robot (fits this family).
        """
        plan = robot.cached(self.plan)
        kernels = kind_pipeline(plan.kind)
        params = pack_axes_params(robot, plan)
        return CompiledPipeline(kernels.solve, kernels.solve_batch, params, robot.mid_limits)

    def candidates(
        self, robot: Robot, T_0_target: FloatArray, mode: str, q_ref: FloatArray
    ) -> list[FloatArray]:
        """Up to 8 raw branches, in the order of the arm kind's closed form.

        Args:
            robot: the robot (fits this family).
            T_0_target: 4x4 flange target in frame 0.
            mode: ``"pose"``.
            q_ref: (6,) reference for the angles a singularity leaves free.
        """
        plan = robot.cached(self.plan)
        T = robot.T_world_base @ T_0_target @ robot.T_flange_tool
        out = np.empty((MAX_BRANCHES, 6))
        n = kind_pipeline(plan.kind).candidates(
            pack_axes_params(robot, plan),
            np.ascontiguousarray(T, dtype=np.float64),
            np.ascontiguousarray(q_ref, dtype=np.float64),
            out,
        )
        return [np.array(row) for row in out[:n]]


# ---------------------------------------------------------------------- three parallel axes
def _parallel_run_reason(axes: Axes, names: tuple[str, ...], first: int) -> str | None:
    """Why axes ``first .. first + 2`` (0-based) are not three parallel, distinct lines."""
    z, p = axes.directions, axes.points
    label = [axis_label(names, i) for i in range(6)]
    for i in (first + 1, first + 2):
        if not _parallel(axes, first, i):
            return f"axes {label[first]} and {label[i]} are not parallel"
    for i, j in ((first, first + 1), (first + 1, first + 2), (first, first + 2)):
        if line_distance(z[i], p[i], z[j], p[j]) <= LENGTH_TOL * axes.size:
            return f"axes {label[i]} and {label[j]} are one line"
    return None


def _inner_reason(axes: Axes, names: tuple[str, ...]) -> str | None:
    """Why axes 2-4 as parallel lines are not three inner parallel ones (the rest)."""
    label = [axis_label(names, i) for i in range(6)]
    for i in (0, 4):
        if _parallel(axes, i, 1):
            return f"axis {label[i]} is parallel to axes 2-4 too"
    if _parallel(axes, 4, 5):
        return f"axes {label[4]} and {label[5]} are parallel"
    return None


def _outer_reason(axes: Axes, names: tuple[str, ...]) -> str | None:
    """Why axes 1-3 as parallel lines are not three outer parallel ones (the rest)."""
    label = [axis_label(names, i) for i in range(6)]
    if _parallel(axes, 3, 0):
        return f"axis {label[3]} is parallel to axes 1-3 too"
    why = meet_reason(axes, names, 4, 5)
    if why is not None:
        return why
    C = meeting(axes, 4, 5)
    if point_line_distance(axes.directions[3], axes.points[3], C) <= LENGTH_TOL * axes.size:
        return f"axis {label[3]} passes through the point of axes {label[4]}, {label[5]}"
    return None


def _inner_arrays(axes: Axes) -> tuple[FloatArray, FloatArray, FloatArray]:
    """The kernel's arrays, with axis 6's point moved off axis 5 by the arm's size.

    The heights condition of ``three_inner_candidates`` turns axis 6's point about axis
    5; the point where the two axes come closest would not move.
    """
    z, p, tool = _arrays(axes)
    z5, z6 = z[4], z[5]
    w = p[5] - p[4]
    b = float(z5 @ z6)
    closest = (b * float(z5 @ w) - float(z6 @ w)) / (1.0 - b * b)
    p = p.copy()
    p[5] = p[5] + (closest + axes.size) * z6
    return z, p, tool


def parallel_plan(robot: Robot) -> AxesPlan:
    """Whether (and how) ``three_parallel`` solves ``robot``.

    In this order: axes 2-4 parallel, the same read backwards (axes 3-5), axes 1-3
    parallel with axes 5, 6 meeting, the same read backwards (axes 4-6, axes 1, 2 meeting).

    Args:
        robot: the robot.
    """
    return _plan_of(robot, _three_parallel_plan)


def _three_parallel_plan(axes: Axes, back: Axes, names: tuple[str, ...]) -> AxesPlan:
    """:func:`parallel_plan` on the axes in order and read backwards (:func:`_plan_of`)."""
    whys = []
    for kind, first, test, arrays in (
        (THREE_INNER, 1, _inner_reason, _inner_arrays),
        (THREE_OUTER, 0, _outer_reason, _arrays),
    ):
        for reverse, seen, order in ((False, axes, names), (True, back, names[::-1])):
            why = _parallel_run_reason(seen, order, first) or test(seen, order)
            if why is None:
                return AxesPlan(kind, reverse, *arrays(seen), tolerance_block(), "")
            whys.append(why)
    inner, inner_back, outer, outer_back = whys
    return _unfit(
        f"{inner}; read backwards: {inner_back}; "
        f"as outer axes: {outer}; read backwards: {outer_back}"
    )


@register
class ThreeParallelAxes(SphericalAxes):
    """Six revolute joints with three parallel axes and any other twists.

    Axes 2-4 or 3-5 parallel, or 1-3 (4-6) parallel beside a meeting pair 5, 6 (1, 2). The
    compiled pipeline of ``spherical_axes`` with the arm kinds :data:`THREE_INNER`
    and :data:`THREE_OUTER` (:mod:`optik.analytic.three_parallel`); detected after
    ``ur``, which keeps the arms with its right angles.
    """

    name = "three_parallel"
    plan = staticmethod(parallel_plan)


__all__ = [
    "GENERAL",
    "INTERSECTING",
    "SECOND_PAIR",
    "THREE_INNER",
    "THREE_OUTER",
    "AxesPlan",
    "KindPipeline",
    "SphericalAxes",
    "ThreeParallelAxes",
    "arm_kind",
    "axes_plan",
    "kind_pipeline",
    "pack_axes_params",
    "parallel_plan",
]
