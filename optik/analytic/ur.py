"""UR-type arms: three parallel axes (joints 2-4) and no spherical wrist.

The DH structure of Universal Robots' arms (``alpha = 90, 0, 0, 90, -90, 0`` deg,
``a1 = a4 = a5 = a6 = 0``). With ``h = d2 + d3 + d4`` (the offset along the parallel axes):

1. ``p5 = p - d6 z6``; joint 1 from ``s1 p5x - c1 p5y = h`` (two shoulders).
2. In frame 1 (``T_16 = A1^-1 T``): ``cos q5 = T_16[2, 2]`` and
   ``sin q5 (cos q6, -sin q6) = T_16[2, :2]``, so ``q5 = atan2(+-|T_16[2, :2]|, T_16[2, 2])``
   (two wrists) and ``q6 = atan2(-+T_16[2, 1], +-T_16[2, 0])`` (free when ``sin q5 = 0``).
3. ``T_14 = T_16 A6^-1 A5^-1``; joints 2 and 3 are a planar two-link arm reaching the
   origin of frame 4 (two elbows) and ``q4 = atan2(T_14[1, 0], T_14[0, 0]) - q2 - q3``.

Up to eight branches, all from the trig equation and atan2, in this order: shoulder
(``q1`` roots ascending), wrist (``sin q5 >= 0`` first), elbow (``q3`` roots ascending).

Robots built otherwise (URDF, modified DH) or whose table differs fit when their joint
axes do: axes 1 and 2 perpendicular and intersecting, axes 2, 3 and 4 parallel with the
same direction, axis 5 perpendicular to axis 4 and meeting it, axis 6 perpendicular to
axis 5 and meeting it. The equivalent table of :mod:`optik.analytic.geometry` (twist signs
chosen as above) then carries the closed form.

The closed form is compiled: :func:`ur_candidates` is its one implementation, and
:func:`optik.analytic.analytic_ik` runs it together with the wrapping, limit filter and FK
check in one compiled call (:mod:`optik.analytic._pipeline`).
"""

from __future__ import annotations

import math

import numpy as np

from optik._kernels import Rows12
from optik._math import atan2, sincos, trig_roots, wrap_angle
from optik._numba import inline as _inline
from optik._numba import jit as _jit
from optik.analytic import _compiled
from optik.analytic._base import ELBOW_REACH_TOL, deg, opposite, register
from optik.analytic._compiled import (
    CompiledFamily,
    closed_form_tols,
    cos_sin,
    dh_rot,
    dh_row,
    store_branch,
    times_inverse_dh,
)
from optik.analytic._subproblems import elbow_roots
from optik.model import DHJoint

_ALPHAS_DEG = (90.0, 0.0, 0.0, 90.0, -90.0, 0.0)
_SIGNS = (1, 0, 0, 1, -1)  # twist signs of the equivalent table: +90, -, -, +90, -90
_ALPHA_MEANING = (
    "axes 1 and 2 perpendicular",
    "axes 2 and 3 parallel, same direction",
    "axes 3 and 4 parallel, same direction",
    "axes 4 and 5 perpendicular",
    "axes 5 and 6 perpendicular",
    "no twist after axis 6",
)
_A_MEANING = {
    0: "axes 1 and 2 do not intersect",
    3: "axes 4 and 5 do not intersect",
    4: "axes 5 and 6 do not intersect",
    5: "the last frame is offset from axis 6",
}


def rows_reason(rows: tuple[DHJoint, ...]) -> str | None:
    """Why a DH table is not of the UR type, or ``None`` when it is."""
    if len(rows) != 6:
        return f"{len(rows)} DH rows (the UR type has 6)"
    for i, r in enumerate(rows):
        if r.kind != "revolute" or r.mimic is not None:
            return f"joint {i + 1} is not an independent revolute joint"
    for i, (r, a) in enumerate(zip(rows, _ALPHAS_DEG, strict=True)):
        if abs(r.alpha - math.radians(a)) >= 1e-12:
            return (
                f"alpha{i + 1} = {deg(r.alpha)}, needs {a:g} deg ({_ALPHA_MEANING[i]})"
                f"{opposite(r.alpha)}"
            )
    for i, meaning in _A_MEANING.items():
        if abs(rows[i].a) >= 1e-12:
            return f"a{i + 1} = {rows[i].a:.6g} m, needs 0 ({meaning})"
    return None


# ---------------------------------------------------------------------- the compiled closed form
@_inline
def _ur_wrist_origin(
    dh: np.ndarray, T16: Rows12, c5t: float, sn5t: float, c6t: float, sn6t: float
) -> tuple[float, float, float]:
    """Frame 4 of a UR-type arm from ``T_16`` and joints 5 and 6 (cosine, sine).

    Returns its origin's (x, y) in the plane of joints 2-4 and the angle of its first
    column (theta2 + theta3 + theta4).
    """
    a5, _, d5, _, _, ca5, sa5, _ = dh_row(dh, 4)
    a6, _, d6, _, _, ca6, sa6, _ = dh_row(dh, 5)
    T15 = times_inverse_dh(T16, c6t, sn6t, ca6, sa6, a6, d6)
    T14 = times_inverse_dh(T15, c5t, sn5t, ca5, sa5, a5, d5)
    return T14[3], T14[7], atan2(T14[4], T14[0])


@_jit
def _ur_reachable_q6(dh: np.ndarray, T16: Rows12, c5t: float, sn5t: float, t6_ref: float) -> float:
    """At the wrist singularity, a theta6 (rad) whose elbow can reach, nearest ``t6_ref``.

    It puts the elbow's squared reach ``x^2 + y^2`` at the middle of its range
    ``[(a2 - a3)^2, (a2 + a3)^2]``, or as near as it gets (then on the range if any q6 is).

    With axes 4 and 6 aligned, the origin of frame 4 circles axis 6 as q6 turns, in the
    plane of the parallel joints, so ``x^2 + y^2 = A + B cos t6 + C sin t6`` exactly.
    """
    a2 = dh_row(dh, 1)[0]
    a3 = dh_row(dh, 2)[0]
    x, y, _ = _ur_wrist_origin(dh, T16, c5t, sn5t, 1.0, 0.0)
    r0 = x * x + y * y
    x, y, _ = _ur_wrist_origin(dh, T16, c5t, sn5t, 0.0, 1.0)
    r1 = x * x + y * y
    x, y, _ = _ur_wrist_origin(dh, T16, c5t, sn5t, -1.0, 0.0)
    r2 = x * x + y * y
    A = 0.5 * (r0 + r2)
    B = 0.5 * (r0 - r2)
    C = r1 - A
    R = math.sqrt(B * B + C * C)
    middle = 0.5 * ((a2 - a3) ** 2 + (a2 + a3) ** 2)
    if R < 1e-300:
        return t6_ref
    phi = atan2(C, B)
    off = math.acos(min(max((middle - A) / R, -1.0), 1.0))
    best = t6_ref
    gap = np.inf
    for t in (phi + off, phi - off):
        d = abs(wrap_angle(t - t6_ref))
        if d < gap:
            gap = d
            best = t6_ref + wrap_angle(t - t6_ref)
    return best


@_inline
def _ur_elbow(
    dh: np.ndarray,
    T16: Rows12,
    t1: float,
    t5: float,
    t6: float,
    c5t: float,
    sn5t: float,
    c6t: float,
    sn6t: float,
    ref: np.ndarray,
    kr: int,
    tols: np.ndarray,
    cand: np.ndarray,
    n: int,
) -> int:
    """The elbow branches (joints 2-4, a planar two-link arm) for given joints 1, 5, 6.

    Writes rows ``n`` onwards of ``cand``; returns the new row count.
    """
    a2, _, _, th2, _, _, _, _ = dh_row(dh, 1)
    a3, _, _, th3, _, _, _, _ = dh_row(dh, 2)
    th1, th4, th5, th6 = dh_row(dh, 0)[3], dh_row(dh, 3)[3], dh_row(dh, 4)[3], dh_row(dh, 5)[3]
    trig_tol, eps, free_tol, _ = closed_form_tols(tols)
    x, y, t234 = _ur_wrist_origin(dh, T16, c5t, sn5t, c6t, sn6t)
    phi = atan2(y, x)
    n3, t3a, t3b = elbow_roots(
        2 * a2 * a3,
        0.0,
        x * x + y * y - a2 * a2 - a3 * a3,
        th3 + ref[kr, 2],
        (trig_tol, eps, free_tol, ELBOW_REACH_TOL),
    )
    for i3 in range(n3):
        t3 = t3a if i3 == 0 else t3b
        sn3, c3 = sincos(t3)
        t2 = phi - atan2(a3 * sn3, a2 + a3 * c3)
        t4 = t234 - t2 - t3
        n = store_branch(cand, n, (t1 - th1, t2 - th2, t3 - th3, t4 - th4, t5 - th5, t6 - th6))
    return n


@_jit
def ur_candidates(
    dh: np.ndarray, T: np.ndarray, ref: np.ndarray, kr: int, tols: np.ndarray, cand: np.ndarray
) -> int:
    """Raw branches of a UR-type arm (three parallel axes, joints 2-4) into ``cand``.

    A family kernel (:data:`optik.analytic._compiled.CandidateKernel`): up to 8 rows of
    joint angles (rad), in the family's order: shoulder, then wrist (``sin q5 >= 0``
    first), then elbow.
    """
    trig_tol, eps, free_tol, wrist_tol = closed_form_tols(tols)
    a1, _, d1, th1, _, ca1, sa1, _ = dh_row(dh, 0)
    th5 = dh_row(dh, 4)[3]
    _, _, d6, th6, _, _, _, _ = dh_row(dh, 5)
    h = dh_row(dh, 1)[2] + dh_row(dh, 2)[2] + dh_row(dh, 3)[2]
    # 1. p5 = p - d6 z6; joint 1 from s1 p5x - c1 p5y = h.
    p5x = T[0, 3] - d6 * T[0, 2]
    p5y = T[1, 3] - d6 * T[1, 2]
    n = 0
    n1, t1a, t1b = trig_roots(-p5y, p5x, h, th1 + ref[kr, 0], trig_tol, eps, free_tol)
    for i1 in range(n1):
        t1 = t1a if i1 == 0 else t1b
        # 2. T_16 = A1^-1 T (its top rows, a row-major 12-tuple).
        theta1 = th1 + (t1 - th1)
        st1, ct1 = sincos(theta1)
        R1 = dh_rot(ct1, st1, ca1, sa1)
        px = a1 * ct1
        py = a1 * st1
        pz = d1
        p0 = R1[0] * px + R1[3] * py + R1[6] * pz  # R1^T p
        p1 = R1[1] * px + R1[4] * py + R1[7] * pz
        p2 = R1[2] * px + R1[5] * py + R1[8] * pz
        T16 = (
            R1[0] * T[0, 0] + R1[3] * T[1, 0] + R1[6] * T[2, 0],
            R1[0] * T[0, 1] + R1[3] * T[1, 1] + R1[6] * T[2, 1],
            R1[0] * T[0, 2] + R1[3] * T[1, 2] + R1[6] * T[2, 2],
            R1[0] * T[0, 3] + R1[3] * T[1, 3] + R1[6] * T[2, 3] - p0,
            R1[1] * T[0, 0] + R1[4] * T[1, 0] + R1[7] * T[2, 0],
            R1[1] * T[0, 1] + R1[4] * T[1, 1] + R1[7] * T[2, 1],
            R1[1] * T[0, 2] + R1[4] * T[1, 2] + R1[7] * T[2, 2],
            R1[1] * T[0, 3] + R1[4] * T[1, 3] + R1[7] * T[2, 3] - p1,
            R1[2] * T[0, 0] + R1[5] * T[1, 0] + R1[8] * T[2, 0],
            R1[2] * T[0, 1] + R1[5] * T[1, 1] + R1[8] * T[2, 1],
            R1[2] * T[0, 2] + R1[5] * T[1, 2] + R1[8] * T[2, 2],
            R1[2] * T[0, 3] + R1[5] * T[1, 3] + R1[8] * T[2, 3] - p2,
        )
        # cos q5 = T_16[2, 2] and sin q5 (c6, -s6) = T_16[2, :2]: atan2 of both keeps q5
        # accurate near 0 and pi, where the cosine alone is flat.
        s5_mag = math.sqrt(T16[8] * T16[8] + T16[9] * T16[9])
        c5 = T16[10]
        n_wrist = 1 if s5_mag < wrist_tol else 2
        for iw in range(n_wrist):
            sign = 1.0 if iw == 0 else -1.0
            singular = n_wrist == 1
            if singular:
                # Wrist singular (axes 4 and 6 aligned): q6 is free. It takes the
                # reference, unless the elbow then cannot reach; then the q6 whose elbow
                # reach is the middle of the elbow's range (nearest the reference of the
                # two): the second pass of the loop below.
                t5 = atan2(0.0, c5)
                sn5t, c5t = sincos(t5)
                t6 = th6 + ref[kr, 5]
                sn6t, c6t = sincos(t6)
            else:
                t5 = atan2(sign * s5_mag, c5)
                t6 = atan2(-sign * T16[9], sign * T16[8])
                theta5 = th5 + (t5 - th5)
                theta6 = th6 + (t6 - th6)
                c5t, sn5t = cos_sin(theta5, t5, c5, sign * s5_mag)
                c6t, sn6t = cos_sin(theta6, t6, sign * T16[8], -sign * T16[9])
            # One call site of the inlined elbow (each site is compiled anew).
            for attempt in range(2):
                before = n
                n = _ur_elbow(dh, T16, t1, t5, t6, c5t, sn5t, c6t, sn6t, ref, kr, tols, cand, n)
                if n != before or not singular or attempt == 1:
                    break
                t6 = _ur_reachable_q6(dh, T16, c5t, sn5t, t6)
                sn6t, c6t = sincos(t6)
    return n


@register
class URArm(CompiledFamily):
    """Universal Robots-type 6R arms (UR3/5/10 and e-series share the structure)."""

    name = "ur"
    kernel = _compiled.UR
    closed_form = ur_candidates
    mismatch = "robot {name!r} is not of the UR type"
    rows_test = staticmethod(rows_reason)
    twist_signs = _SIGNS
