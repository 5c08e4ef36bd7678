"""Seven-joint arms around a held joint: the six others by a closed form from their axes.

With joint ``k`` held at ``v``, the chain's product of exponentials (joint axes at
``q = 0``, :func:`optik.analytic.geometry.joint_axes`) is a six-joint one: the axes after
``k`` and the tool's pose at ``q = 0`` turned about axis ``k`` by ``v`` (``R_k(v)
R_j(t) = (R_k(v) R_j(t) R_k(v)^-1) R_k(v)``, a rotation about the turned axis), the axes
before ``k`` as they are. When those six axes are a meeting pair, an elbow and a
spherical wrist (:mod:`optik.analytic.pair_wrist`) the closed form there gives every
branch; when the chain read backwards is (a spherical shoulder before the held joint,
a meeting pair after it: a joint of the wrist held), the same closed form solves the
reversed chain, ``T^-1 = M^-1 R_6(-q_6) ... R_1(-q_1)``, whose axes are the original
ones seen from the tool at ``q = 0``, with reversed directions, in reverse order.

For a spherical-shoulder, spherical-wrist arm (KUKA iiwa: axes 1-3 meet, axes 5-7 meet)
holding joint 1, 2 or 3 gives the direct form, joint 5, 6 or 7 the reversed one; holding
the elbow (joint 4) leaves the shoulder-wrist distance fixed: no closed form. The Franka
Panda holding joint 7 gives the reversed form: axes 6 and 5 meet at the wrist point,
axis 4 is the elbow, axes 3, 2 and 1 meet at the shoulder. Its offsets do not break it:
the two 0.0825 m elbow offsets only shape the shoulder-wrist distance as a function of
q4, and the 0.088 m between axes 6 and 7 moves with the held joint (the tool at q = 0
turned by it). Holding any other Panda joint leaves two axes that neither meet nor are
parallel at one end of the six: no closed form.

The structure is decided from the geometry, once per robot and held joint: it must hold
whatever the held value, and does when it holds at three distinct values (whether two
lines meet is a first-order trig polynomial in the angle that turns one of them: the
reciprocal product of their Plücker coordinates).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from optik._checks import FloatArray
from optik._nrt import borrowed
from optik._numba import inline as _inline
from optik._numba import jit as _jit
from optik.analytic._compiled import (
    MAX_BRANCHES,
    axes_offsets,
    axes_wrist_centre,
    pack_axes_vector,
    tolerance_block,
)
from optik.analytic._pipeline import Layout, postprocess_one, postprocess_rows
from optik.analytic._pipeline_args import batch_work, input_code, pad_rows, work_rows
from optik.analytic._subproblems import Vec3, apply, rotation, sub
from optik.analytic.geometry import Axes, joint_axes, reversed_axes, revolute_chain_reason
from optik.analytic.pair_wrist import AxesQuery, pair_wrist_candidates, structure_reason
from optik.model import Robot

CHECK_VALUES = (0.0, 2.0, -2.5)
"""Held values (rad) at which the structure is checked (distinct modulo 2 pi)."""

FREE_DOF = 7
"""Joint count of the arms solved around a held joint."""

# Layout of the compiled kernels' parameter vector (:func:`pack_free_params`, flat
# float64): the held joint and the form's direction, then the blocks of
# optik.analytic._compiled.AxesOffsets (limits, chain, axes and tool at q = 0, wrist centre,
# tolerances).
AT_HELD = 0  # (1,) the held joint's index
AT_REVERSE = 1  # (1,) 1.0 when the closed form solves the chain read backwards
_AT = axes_offsets(FREE_DOF, 2)
AT_KIND, AT_LOWER, AT_UPPER, AT_CHAIN, AT_DIRECTIONS, AT_POINTS, AT_TOOL, AT_WRIST, AT_TOLS = _AT
FREE_LAYOUT: Layout = _AT.layout
"""Where :func:`optik.analytic._pipeline.postprocess_rows` finds the robot's data."""


class FreeJointPlan(NamedTuple):
    """How a seven-joint robot is solved with one joint held (:func:`free_joint_plan`).

    Attributes:
        held: the held joint's index in ``q``.
        reverse: whether the closed form solves the chain read backwards.
        directions: (7, 3) unit joint directions at ``q = 0`` (world).
        points: (7, 3) a point on each axis (m).
        tool: (4, 4) world pose of the tool at ``q = 0``.
        reason: ``""`` when the six fit, else why not (then the arrays are unused).
        params: the compiled kernels' vector (:func:`pack_free_params`) when the six
            fit, else empty.
    """

    held: int
    reverse: bool
    directions: FloatArray
    points: FloatArray
    tool: FloatArray
    reason: str
    params: FloatArray


def _turned(axes: Axes, k: int, v: float) -> Axes:
    """The six axes (and tool at ``q = 0``) left when joint ``k`` is held at ``v``."""
    R = np.array(rotation(tuple(axes.directions[k].tolist()), v)).reshape(3, 3)
    centre = axes.points[k]
    keep = [j for j in range(len(axes.directions)) if j != k]
    z = np.array([axes.directions[j] if j < k else R @ axes.directions[j] for j in keep])
    p = np.array(
        [axes.points[j] if j < k else R @ (axes.points[j] - centre) + centre for j in keep]
    )
    E = np.eye(4)
    E[:3, :3] = R
    E[:3, 3] = centre - R @ centre
    return Axes(z, p, E @ axes.tool, axes.size)


def free_joint_plan(robot: Robot, k: int) -> FreeJointPlan:
    """Whether (and how) ``robot`` with joint ``k`` held has the pair-wrist closed form."""
    axes = joint_axes(robot)
    empty = np.empty((0, 3))
    base = FreeJointPlan(k, False, axes.directions, axes.points, axes.tool, "", np.empty(0))
    reason = revolute_chain_reason(robot, FREE_DOF)
    if reason is not None:
        return base._replace(directions=empty, points=empty, reason=reason)
    names = tuple(n for j, n in enumerate(robot.chain_names) if j != k)
    reasons = []
    for reverse in (False, True):
        why = None
        for v in CHECK_VALUES:
            six = _turned(axes, k, v)
            if reverse:
                why = structure_reason(reversed_axes(six), names[::-1])
            else:
                why = structure_reason(six, names)
            if why is not None:
                why = f"{why} (joint {robot.chain_names[k]!r} at {v:g} rad)"
                break
        if why is None:
            plan = base._replace(reverse=reverse)
            return plan._replace(params=pack_free_params(robot, plan))
        reasons.append(why)
    return base._replace(
        reason=f"the other six joints in order: {reasons[0]}; read backwards: {reasons[1]}"
    )


def pack_free_params(robot: Robot, plan: FreeJointPlan) -> FloatArray:
    """The flat parameter vector of the compiled kernels for ``robot`` and ``plan``.

    Everything :func:`solve` needs, in one argument (the layout above): the held joint
    and the form's direction, the limits, the robot's own chain transforms ``_K`` (the FK
    check uses the kinematics of ``Robot.fk``), the joint axes and the tool at ``q = 0``,
    and the tolerances (read from their home modules: numba freezes globals).
    """
    head = (plan.held, 1.0 if plan.reverse else 0.0)
    return pack_axes_vector(
        robot, head, plan.directions, plan.points, plan.tool, tolerance_block(),
        axes_wrist_centre(robot),
    )  # fmt: skip


# ---------------------------------------------------------------------- the compiled kernels
@_jit
def _scratch() -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Scratch of :func:`_candidates_into`, allocated once per call or batch.

    ``(axes, frames, refs, six)``: ``axes`` (4, 6, 3) the six axes' directions and
    points, then the same read backwards; ``frames`` (3, 4, 4) the tool at ``q = 0``, its
    inverse and the inverse target; ``refs`` (2, 6) the six references, then reversed;
    ``six`` (8, 6) the six-joint branches.
    """
    return (
        np.empty((4, 6, 3)),
        np.empty((3, 4, 4)),
        np.empty((2, 6)),
        np.empty((MAX_BRANCHES, 6)),
    )


@_jit
def _candidates_into(
    params: np.ndarray,
    value: float,
    T: np.ndarray,
    ref: np.ndarray,
    cand: np.ndarray,
    work: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray],
) -> int:
    """Raw seven-joint branches (the held joint at ``value``) of world target ``T`` (4, 4).

    The held joint's axis turns the axes after it (module docstring); the six are solved
    by :func:`optik.analytic.pair_wrist.pair_wrist_candidates`, directly or read
    backwards. ``params`` is :func:`pack_free_params`'s vector, ``ref`` (7,) gives the
    free angles' references, ``cand`` (>= 8, 7) receives the rows and ``work`` is
    :func:`_scratch`. Returns the number of rows written.
    """
    axes, frames, refs, six = work
    k = int(params[AT_HELD])
    z = axes[0]
    p = axes[1]
    M = frames[0]
    r6 = refs[0]
    R = rotation(_row3(params, AT_DIRECTIONS, k), value)
    c = _row3(params, AT_POINTS, k)
    j = 0
    for i in range(FREE_DOF):
        if i == k:
            continue
        r6[j] = ref[i]
        zi = _row3(params, AT_DIRECTIONS, i)
        pi = _row3(params, AT_POINTS, i)
        if i > k:
            zi = apply(R, zi)
            pi = apply(R, sub(pi, c))
            pi = (pi[0] + c[0], pi[1] + c[1], pi[2] + c[2])
        for a in range(3):
            z[j, a] = zi[a]
            p[j, a] = pi[a]
        j += 1
    # M = E tool with E the held joint's motion: rotation R about the line through c.
    Rc = apply(R, c)
    for a in range(3):
        for b in range(4):
            M[a, b] = (
                R[3 * a] * params[AT_TOOL + b]
                + R[3 * a + 1] * params[AT_TOOL + 4 + b]
                + R[3 * a + 2] * params[AT_TOOL + 8 + b]
            )
        M[a, 3] += c[a] - Rc[a]
    M[3, 0] = M[3, 1] = M[3, 2] = 0.0
    M[3, 3] = 1.0
    tols = params[AT_TOLS:]
    reverse = params[AT_REVERSE] != 0.0
    # One call site of the closed form for both readings: numba links a callee's code
    # into its caller, and a second site doubled the compile time of the pipelines.
    zs, ps, home, target, reference = z, p, M, T, r6
    if reverse:
        # Read backwards: axes seen from the tool at q = 0, reversed, in reverse order;
        # target T^-1, home M^-1.
        Mi = frames[1]
        Ti = frames[2]
        inverse_into(M, Mi)
        inverse_into(T, Ti)
        zr = axes[2]
        pr = axes[3]
        rr = refs[1]
        for i in range(6):
            src = 5 - i
            rr[i] = r6[src]
            for a in range(3):
                zr[i, a] = -(Mi[a, 0] * z[src, 0] + Mi[a, 1] * z[src, 1] + Mi[a, 2] * z[src, 2])
                pr[i, a] = (
                    Mi[a, 0] * p[src, 0] + Mi[a, 1] * p[src, 1] + Mi[a, 2] * p[src, 2] + Mi[a, 3]
                )
        zs, ps, home, target, reference = zr, pr, Mi, Ti, rr
    n = pair_wrist_candidates(AxesQuery(zs, ps, home, target, reference, tols), six)
    if reverse:
        for r in range(n):
            for i in range(3):
                six[r, i], six[r, 5 - i] = six[r, 5 - i], six[r, i]
    for r in range(n):
        j = 0
        for i in range(FREE_DOF):
            if i == k:
                cand[r, i] = value
            else:
                cand[r, i] = six[r, j]
                j += 1
    return n


@_jit
def free_joint_candidates(
    params: np.ndarray, value: float, T: np.ndarray, ref: np.ndarray, cand: np.ndarray
) -> int:
    """:func:`_candidates_into` with its own scratch (the raw branches, for Python callers).

    Args:
        params: :func:`pack_free_params`'s vector of the robot and held joint.
        value: the held joint's value (rad).
        T: (4, 4) world target of the tool.
        ref: (7,) references of the angles a singularity leaves free (rad).
        cand: (>= 8, 7) output rows (rad, not wrapped).

    Returns:
        The number of rows written (0 to 8).
    """
    return _candidates_into(params, value, T, ref, cand, _scratch())


@_inline
def _row3(params: np.ndarray, at: int, i: int) -> Vec3:
    """Row ``i`` of the (7, 3) block of ``params`` at offset ``at``."""
    o = at + 3 * i
    return (params[o], params[o + 1], params[o + 2])


@_jit
def inverse_into(T: np.ndarray, out: np.ndarray) -> None:
    """``out`` <- the inverse of a rigid transform ``T`` (4, 4): ``[R^T, -R^T t]``."""
    for a in range(3):
        for b in range(3):
            out[a, b] = T[b, a]
        out[a, 3] = -(T[0, a] * T[0, 3] + T[1, a] * T[1, 3] + T[2, a] * T[2, 3])
        out[3, a] = 0.0
    out[3, 3] = 1.0


@_jit
def solve(
    params: np.ndarray, T: np.ndarray, ref: np.ndarray, value: float, flags: int, out: np.ndarray
) -> int:
    """Every branch of one target with the held joint at ``value``: solve, wrap, verify, sort.

    The steps of :func:`optik.analytic._pipeline.postprocess_rows` on the branches of
    :func:`_candidates_into`; the held joint keeps exactly ``value``.

    Args:
        params: :func:`pack_free_params`'s vector.
        T: (4, 4) world target of the tool.
        ref: (7,) reference configuration (rad); its held entry is not used (``value``
            stands in for it).
        value: the held joint's value (rad), finite.
        flags: :data:`optik.analytic._pipeline_args.SORT` and / or ``WITHIN_LIMITS``.
        out: (8, 7) output rows.

    Returns:
        What :func:`optik.analytic._pipeline.solve` returns: the branch count (0 to 8) or
        its -1 / -2 input codes.
    """
    T1 = T[None]
    code = input_code(params, AT_TOLS, T1, ref)
    if code != 0:
        return code
    k = int(params[AT_HELD])
    ref1 = np.empty((1, FREE_DOF))
    for j in range(FREE_DOF):
        ref1[0, j] = ref[j]
    ref1[0, k] = value
    pre, flat, rows, newton = work_rows(FREE_DOF)
    n = _candidates_into(params, value, T, ref1[0], rows, _scratch())
    return postprocess_one(
        params, FREE_LAYOUT, FREE_DOF, k, value, T1, ref1, flags, rows, flat, n, pre, out,
        True, newton,
    )  # fmt: skip


@_jit
def solve_batch(
    params: np.ndarray, T: np.ndarray, ref: np.ndarray, values: np.ndarray, flags: int
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`solve` over validated targets ``T`` (N, 4, 4), serially.

    Args:
        params: :func:`pack_free_params`'s vector.
        T: (N, 4, 4) world targets of the tool, already validated.
        ref: (1, 7) one reference for every target, or (N, 7) one per target; finite.
        values: (1,) one held value for every target, or (N,) one per target; finite.
        flags: :data:`optik.analytic._pipeline_args.SORT` and / or ``WITHIN_LIMITS``.

    Returns:
        ``Q`` (N, 8, 7): branches, rows past each count filled with NaN; ``counts`` (N,).
    """
    sort, within, pre, flat, rows, newton, Q, counts = batch_work(T.shape[0], FREE_DOF, flags)
    work = _scratch()
    refs = np.empty((1, FREE_DOF))
    _solve_each(
        params, T, ref, values, sort, within, pre, flat, rows, newton, Q, counts, work, refs
    )
    return Q, counts


@_jit
def _solve_each(
    params: np.ndarray,
    T: np.ndarray,
    ref: np.ndarray,
    values: np.ndarray,
    sort: bool,
    within: bool,
    pre: np.ndarray,
    flat: np.ndarray,
    rows: np.ndarray,
    newton: np.ndarray,
    Q: np.ndarray,
    counts: np.ndarray,
    work: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray],
    refs: np.ndarray,
) -> None:
    """:func:`solve_batch`'s loop over the targets, on borrowed views of its arrays.

    The caller owns every array for the whole call, so the loop passes views without an
    owner record (:func:`optik._nrt.borrowed`): the per-row calls (the FK, the Newton
    step) then count no references.
    """
    params, T, ref, values = borrowed(params), borrowed(T), borrowed(ref), borrowed(values)
    pre, flat, rows, newton = borrowed(pre), borrowed(flat), borrowed(rows), borrowed(newton)
    Q, refs = borrowed(Q), borrowed(refs)
    axes, frames, six_refs, six = work
    work = (borrowed(axes), borrowed(frames), borrowed(six_refs), borrowed(six))
    N = T.shape[0]
    k = int(params[AT_HELD])
    for i in range(N):
        kr = 0 if ref.shape[0] == 1 else i
        value = values[0] if values.shape[0] == 1 else values[i]
        for j in range(FREE_DOF):
            refs[0, j] = ref[kr, j]
        refs[0, k] = value
        n = _candidates_into(params, value, T[i], refs[0], rows, work)
        counts[i] = postprocess_rows(
            params, FREE_LAYOUT, FREE_DOF, k, value, T, i, refs, 0, sort, within, rows, flat,
            n, pre, Q, True, newton,
        )  # fmt: skip
        pad_rows(Q, i, counts[i])


__all__ = [
    "FREE_DOF",
    "FreeJointPlan",
    "free_joint_candidates",
    "free_joint_plan",
    "inverse_into",
    "pack_free_params",
    "solve",
    "solve_batch",
]
