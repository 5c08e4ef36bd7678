"""Compiled Paden–Kahan subproblems on joint axes: rotations of points about lines.

The closed forms found from the joint axes (:mod:`optik.analytic.pair_wrist`) reduce to
three questions about rotations ``R(w, t)`` about unit directions ``w`` (right-handed,
rad); vectors are 3-tuples of floats (m, or unitless directions):

- :func:`sp1_angle`: the angle ``t`` with ``R(w, t) u = v`` (subproblem 1);
- :func:`sp2_angles`: the angles ``(ta, tb)`` with ``R(wa, ta) R(wb, tb) p = q``, two
  axes through one point (subproblem 2): up to two pairs;
- :func:`distance_angles`: the angle ``t`` that puts a point rotated about a line at a
  given distance from a centre (subproblem 3): up to two angles;
- :func:`plane_angles`: the angle ``t`` that puts a point rotated about a line at a
  given height along a direction (subproblem 4): up to two angles.
- :func:`reach_angles`: subproblem 3, then 1: two lines in a row that carry a point to
  a target point, up to two pairs.

Each is solved as a trig equation ``a cos t + b sin t = c`` normalised to ``a^2 + b^2``
of order 1 (:func:`optik._math.trig_roots`, with its tangent and free-angle rules), then
by ``atan2`` of projections, never by a square root of a difference of squares: near a
singularity (a point on an axis) the angle stays accurate to rounding, and the rotated
point to rounding in absolute terms. An angle that the data leave free (a point on its
axis, within ``axis_tol`` relative) takes the caller's reference.

Every function is serial and ``nogil``; tolerances come as arguments (numba freezes
globals into its cache).
"""

from __future__ import annotations

import math

import numpy as np

from optik._math import atan2, sincos, trig_roots
from optik._numba import inline as _inline
from optik._numba import jit as _jit

Vec3 = tuple[float, float, float]
"""A vector (or point) in scalars."""
Rot9 = tuple[float, float, float, float, float, float, float, float, float]
"""A 3x3 rotation, row-major, in scalars."""
RootTols = tuple[float, float, float, float]
"""The tolerances of a root solve, ``(trig_tol, eps, free_tol, reach_tol)``: those of
:func:`optik._math.trig_roots`, then the relative slack of the tangent root
(:func:`roots_or_tangent`)."""


@_inline
def vec_at(a: np.ndarray, i: int) -> Vec3:
    """Row ``i`` of an (n, 3) array ``a`` as a vector."""
    return (a[i, 0], a[i, 1], a[i, 2])


@_inline
def six_rows(
    a: np.ndarray,
) -> tuple[Vec3, Vec3, Vec3, Vec3, Vec3, Vec3]:
    """The six rows of a (6, 3) array ``a`` (joint directions or points) as vectors."""
    return vec_at(a, 0), vec_at(a, 1), vec_at(a, 2), vec_at(a, 3), vec_at(a, 4), vec_at(a, 5)


@_inline
def dot(a: Vec3, b: Vec3) -> float:
    """``a . b``."""
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


@_inline
def cross(a: Vec3, b: Vec3) -> Vec3:
    """``a x b``."""
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


@_inline
def sub(a: Vec3, b: Vec3) -> Vec3:
    """``a - b``."""
    return (a[0] - b[0], a[1] - b[1], a[2] - b[2])


@_inline
def axpy(s: float, a: Vec3, b: Vec3) -> Vec3:
    """``s a + b``."""
    return (s * a[0] + b[0], s * a[1] + b[1], s * a[2] + b[2])


@_inline
def norm(a: Vec3) -> float:
    """``|a|``."""
    return math.sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2])


@_inline
def unit(a: Vec3) -> Vec3:
    """``a / |a|`` (``a`` not zero)."""
    na = norm(a)
    return (a[0] / na, a[1] / na, a[2] / na)


@_inline
def perp(w: Vec3, a: Vec3) -> Vec3:
    """The component of ``a`` perpendicular to the unit direction ``w``."""
    return axpy(-dot(w, a), w, a)


@_inline
def rotate(w: Vec3, s: float, c: float, v: Vec3) -> Vec3:
    """``R(w, t) v`` from ``s, c = sin t, cos t`` (Rodrigues: ``v c + (w x v) s + ...``)."""
    k = dot(w, v) * (1.0 - c)
    x = cross(w, v)
    return (
        v[0] * c + x[0] * s + w[0] * k,
        v[1] * c + x[1] * s + w[1] * k,
        v[2] * c + x[2] * s + w[2] * k,
    )


@_inline
def turn_point(w: Vec3, on_axis: Vec3, t: float, x: Vec3) -> Vec3:
    """``x`` turned by ``t`` (rad) about the line through ``on_axis`` along unit ``w``."""
    s, c = sincos(t)
    return axpy(1.0, rotate(w, s, c, sub(x, on_axis)), on_axis)


@_inline
def rotation(w: Vec3, t: float) -> Rot9:
    """``R(w, t)`` as a row-major 9-tuple (``w`` a unit direction, ``t`` in rad)."""
    s, c = sincos(t)
    k = 1.0 - c
    return (
        c + w[0] * w[0] * k,
        w[0] * w[1] * k - w[2] * s,
        w[0] * w[2] * k + w[1] * s,
        w[1] * w[0] * k + w[2] * s,
        c + w[1] * w[1] * k,
        w[1] * w[2] * k - w[0] * s,
        w[2] * w[0] * k - w[1] * s,
        w[2] * w[1] * k + w[0] * s,
        c + w[2] * w[2] * k,
    )


@_inline
def apply(R: Rot9, v: Vec3) -> Vec3:
    """``R v``."""
    return (
        R[0] * v[0] + R[1] * v[1] + R[2] * v[2],
        R[3] * v[0] + R[4] * v[1] + R[5] * v[2],
        R[6] * v[0] + R[7] * v[1] + R[8] * v[2],
    )


@_inline
def apply_t(R: Rot9, v: Vec3) -> Vec3:
    """``R^T v``: :func:`apply` of the transpose (inlined, the tuple costs nothing)."""
    return apply((R[0], R[3], R[6], R[1], R[4], R[7], R[2], R[5], R[8]), v)


@_jit
def sp1_angle(w: Vec3, u: Vec3, v: Vec3, free: float, axis_tol: float) -> float:
    """The angle ``t`` (rad, in (-pi, pi]) that turns ``u`` onto ``v`` about ``w``.

    Only the components perpendicular to ``w`` count (the caller makes the others agree).
    When either is shorter than ``axis_tol`` times ``max(|u|, |v|)`` (a point on the axis)
    every angle does: ``free`` is returned.
    """
    up = perp(w, u)
    vp = perp(w, v)
    size = max(norm(u), norm(v))
    if not (norm(up) > axis_tol * size and norm(vp) > axis_tol * size):
        return free
    return atan2(dot(w, cross(up, vp)), dot(up, vp))


@_jit
def sp2_angles(
    wa: Vec3,
    wb: Vec3,
    p: Vec3,
    q: Vec3,
    ref_a: float,
    ref_b: float,
    gap_tol: float,
    axis_tol: float,
) -> tuple[int, float, float, float, float]:
    """Angles with ``R(wa, ta) R(wb, tb) p = q`` (axes through the origin, not parallel).

    Returns ``(count, ta_1, tb_1, ta_2, tb_2)`` (count 0, 1 or 2). The middle point
    ``m = R(wb, tb) p = R(wa, -ta) q`` has ``wa . m = wa . q``, ``wb . m = wb . p`` and
    ``|m| = |p|``: ``m = x wa + y wb + g n`` with ``n`` the unit normal ``wa x wb / s``
    and ``g^2 = r_q^2 - (wb . p - k wa . q)^2 / s^2`` (``k = wa . wb``, ``s^2 = 1 - k^2``,
    ``r_q`` the distance of ``q`` from axis a), or the same with the roles of ``p`` and
    ``q`` exchanged: the one of the smaller distance, formed as a product
    ``(r - d)(r + d)`` so that a point near its axis keeps ``g`` accurate (at a wrist
    near alignment, ``g`` is the sine of the small angle). ``g^2`` below
    ``-gap_tol |p|^2``: no solution; else ``g = +-sqrt(max(g^2, 0))``, positive first
    (one solution when 0). The angles then follow by :func:`sp1_angle`; a point on its
    axis (relative ``axis_tol``) leaves its angle free, at ``ref_a`` or ``ref_b``.
    ``|p| = |q|`` is assumed (the caller's FK check decides otherwise).
    """
    size = max(norm(p), norm(q))
    if not size > 0.0:
        return 1, ref_a, ref_b, ref_a, ref_b
    k = dot(wa, wb)
    qa = dot(wa, q)
    pb = dot(wb, p)
    rq = norm(perp(wa, q))
    rp = norm(perp(wb, p))
    if rq <= axis_tol * size:  # q on axis a: ta free
        s, c = sincos(ref_a)
        tb = sp1_angle(wb, p, rotate(wa, -s, c, q), ref_b, axis_tol)
        return 1, ref_a, tb, ref_a, tb
    if rp <= axis_tol * size:  # p on axis b: tb free
        s, c = sincos(ref_b)
        ta = sp1_angle(wa, rotate(wb, s, c, p), q, ref_a, axis_tol)
        return 1, ta, ref_b, ta, ref_b
    nrm = cross(wa, wb)
    sn = norm(nrm)
    nrm = (nrm[0] / sn, nrm[1] / sn, nrm[2] / sn)
    den = sn * sn
    x = (qa - k * pb) / den
    y = (pb - k * qa) / den
    if rq <= rp:
        d = abs(pb - k * qa) / sn
        g2 = (rq - d) * (rq + d)
    else:
        d = abs(qa - k * pb) / sn
        g2 = (rp - d) * (rp + d)
    if g2 < -gap_tol * size * size:
        return 0, 0.0, 0.0, 0.0, 0.0
    g = math.sqrt(g2) if g2 > 0.0 else 0.0
    count = 2 if g > 0.0 else 1
    base = axpy(y, wb, (x * wa[0], x * wa[1], x * wa[2]))
    m1 = axpy(g, nrm, base)
    m2 = axpy(-g, nrm, base)
    ta1 = sp1_angle(wa, m1, q, ref_a, axis_tol)
    tb1 = sp1_angle(wb, p, m1, ref_b, axis_tol)
    ta2 = sp1_angle(wa, m2, q, ref_a, axis_tol)
    tb2 = sp1_angle(wb, p, m2, ref_b, axis_tol)
    return count, ta1, tb1, ta2, tb2


@_jit
def distance_angles(
    w: Vec3,
    on_axis: Vec3,
    point: Vec3,
    centre: Vec3,
    dist2: float,
    ref: float,
    roots: RootTols,
) -> tuple[int, float, float]:
    """Angles ``t`` with ``|R_line(t) point - centre|^2 = dist2``: ``(count, t_1, t_2)``.

    ``R_line(t)`` turns about the line through ``on_axis`` with unit direction ``w``. The
    rotated point is ``o + u cos t + (w x u) sin t`` (``o`` the foot of ``point`` on the
    line, ``u = point - o``), so the condition is ``2 d.u cos t + 2 d.(w x u) sin t =
    dist2 - |d|^2 - |u|^2`` with ``d = o - centre``, divided by ``|d|^2 + |u|^2``. Both
    ``d.u`` and ``d.(w x u)`` vanish (the distance does not depend on ``t``: ``centre`` or
    ``point`` on the line) -> :func:`optik._math.trig_roots`'s free rule, ``ref``.
    A distance beyond the reachable range by at most ``reach_tol`` of ``roots`` (relative, in the
    normalised equation) gives the tangent angle: axes that meet only to within the
    geometry's tolerance put a stretched arm's target just out of its exact reach.
    """
    foot, u, v = circle(w, on_axis, point)
    d = sub(foot, centre)
    scale = dot(d, d) + dot(u, u)
    if not scale > 0.0:
        return 1, ref, ref
    a = 2.0 * dot(d, u) / scale
    b = 2.0 * dot(d, v) / scale
    c = (dist2 - scale) / scale
    return roots_or_tangent(a, b, c, ref, roots)


@_inline
def reach_angles(
    wa: Vec3,
    pa: Vec3,
    wb: Vec3,
    pb: Vec3,
    point: Vec3,
    d: Vec3,
    ref_a: float,
    ref_b: float,
    roots: RootTols,
    axis_tol: float,
) -> tuple[int, float, float, float, float]:
    """Two axes in a row that carry ``point`` to ``pa + d``: ``(count, ta_1, tb_1, ta_2, tb_2)``.

    The lines through ``pa`` and ``pb`` (unit directions ``wa``, ``wb``, m) with
    ``R_a(ta) R_b(tb) point = pa + d``: ``tb`` puts ``point`` turned about line b at the
    distance ``|d|`` from ``pa`` (:func:`distance_angles`, up to two), then ``ta`` turns
    it onto ``d`` about line a (:func:`sp1_angle`; ``d`` is assumed at the point's height
    along ``wa``, which the caller's FK check judges). Count 0, 1 or 2, as
    :func:`sp2_angles`; a free angle takes ``ref_a`` or ``ref_b``.
    """
    count, tb1, tb2 = distance_angles(wb, pb, point, pa, dot(d, d), ref_b, roots)
    ta1 = ta2 = ref_a
    if count > 0:
        ta1 = sp1_angle(wa, sub(turn_point(wb, pb, tb1, point), pa), d, ref_a, axis_tol)
    if count > 1:
        ta2 = sp1_angle(wa, sub(turn_point(wb, pb, tb2, point), pa), d, ref_a, axis_tol)
    return count, ta1, tb1, ta2, tb2


@_inline
def circle(w: Vec3, on_axis: Vec3, point: Vec3) -> tuple[Vec3, Vec3, Vec3]:
    """The circle ``point`` runs on about a line: ``(o, u, w x u)``.

    ``o`` is the foot of ``point`` on the line through ``on_axis`` with unit direction
    ``w`` and ``u = point - o``: the point turned by ``t`` is ``o + u cos t + (w x u) sin t``.
    """
    foot = axpy(dot(w, sub(point, on_axis)), w, on_axis)
    u = sub(point, foot)
    return foot, u, cross(w, u)


@_inline
def roots_or_tangent(
    a: float,
    b: float,
    c: float,
    ref: float,
    roots: RootTols,
) -> tuple[int, float, float]:
    """:func:`optik._math.trig_roots` of ``a cos t + b sin t = c``, or its tangent root.

    A right-hand side beyond the reachable range ``sqrt(a^2 + b^2)`` by at most
    ``reach_tol`` (relative) gives the tangent angle: axes that meet only to within the
    geometry's tolerance put a stretched arm's target just out of its exact reach; the
    caller's FK check judges the miss.
    """
    trig_tol, eps, free_tol, reach_tol = roots
    n, t1, t2 = trig_roots(a, b, c, ref, trig_tol, eps, free_tol)
    r = math.sqrt(a * a + b * b)
    if n == 0 and r > eps and abs(c) <= r * (1.0 + reach_tol):
        t = atan2(b, a) + (0.0 if c > 0.0 else math.pi)
        t = atan2(math.sin(t), math.cos(t))
        return 1, t, t
    return n, t1, t2


@_inline
def elbow_roots(
    a: float,
    b: float,
    c: float,
    ref: float,
    roots: RootTols,
) -> tuple[int, float, float]:
    """:func:`roots_or_tangent` of an elbow's distance equation, made relative first.

    Its coefficients are squared lengths (m^2): an absolute band of 1e-11 is 3e-5 of a
    millimetre arm's ``2 a2 a3`` (the tangent root then 7e-3 rad off, beyond the FK
    check) and 1e-17 of a kilometre arm's. Divided by ``hypot(a, b) / 2`` the equation
    has ``r = 2``, where the closed forms' band is 1e-12 relative at every size.
    """
    r = math.sqrt(a * a + b * b)
    if r > 0.0 and math.isfinite(r):
        k = 2.0 / r
        return roots_or_tangent(a * k, b * k, c * k, ref, roots)
    return roots_or_tangent(a, b, c, ref, roots)


@_jit
def plane_angles(
    w: Vec3,
    on_axis: Vec3,
    point: Vec3,
    h: Vec3,
    height: float,
    ref: float,
    roots: RootTols,
) -> tuple[int, float, float]:
    """Angles ``t`` with ``h . R_line(t) point = height``: ``(count, t_1, t_2)``.

    ``R_line(t)`` turns about the line through ``on_axis`` with unit direction ``w``; ``h``
    is a unit direction. The rotated point is ``o + u cos t + (w x u) sin t`` (``o`` the
    foot of ``point`` on the line, ``u = point - o``), so the condition is
    ``h.u cos t + h.(w x u) sin t = height - h.o``, divided by ``|u| + |height - h.o|``
    (coefficients of order 1). Both ``h.u`` and ``h.(w x u)`` vanish (the height does
    not depend on ``t``: ``point`` on the line, or ``h`` along it) -> the free rule of
    :func:`optik._math.trig_roots`, ``ref``. A height beyond the reachable range by at
    most ``reach_tol`` of ``roots`` (relative) gives the tangent angle (:func:`roots_or_tangent`).
    """
    foot, u, v = circle(w, on_axis, point)
    rhs = height - dot(h, foot)
    scale = norm(u) + abs(rhs)
    if not scale > 0.0:
        return 1, ref, ref
    a = dot(h, u) / scale
    b = dot(h, v) / scale
    return roots_or_tangent(a, b, rhs / scale, ref, roots)


@_jit
def meeting_point(w1: Vec3, p1: Vec3, w2: Vec3, p2: Vec3) -> Vec3:
    """The midpoint of the common normal of two non-parallel lines (their meeting point).

    Lines through ``p1``, ``p2`` with unit directions ``w1``, ``w2``; for lines that meet
    it is the point they share.
    """
    k = dot(w1, w2)
    r = sub(p2, p1)
    den = 1.0 - k * k
    a = dot(r, w1)
    b = dot(r, w2)
    s = (a - k * b) / den
    t = (k * a - b) / den
    x1 = axpy(s, w1, p1)
    x2 = axpy(t, w2, p2)
    return (0.5 * (x1[0] + x2[0]), 0.5 * (x1[1] + x2[1]), 0.5 * (x1[2] + x2[2]))
