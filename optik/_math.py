"""Compiled math shared by every kernel: the one implementation of each primitive.

Sine and cosine together (:func:`sincos`), angle wrapping (:func:`wrap_angle`,
:func:`mod_two_pi`), the roots of the trig equation ``a cos t + b sin t = c``
(:func:`trig_roots`), the rotation log and angle (:func:`log_rotation`,
:func:`rotation_angle`), the defects of a rotation and a pose (:func:`rotation_defects`,
:func:`pose_defect`, :func:`first_bad_pose`) and an SPD solve by Cholesky
(:func:`cholesky_solve`). The Python API (:mod:`optik.trig`, :mod:`optik.spatial`)
validates its arguments and calls these; the FK kernels, the closed forms and the
solvers call them directly. There are no numpy twins to keep in step.

Every function here is serial and ``nogil``. numba freezes a global's value into its
on-disk cache, so tolerances are passed as arguments, never read from other modules.
"""

from __future__ import annotations

import math

import numpy as np

from optik._numba import inline, jit

_TWO_PI = 2.0 * math.pi


# ---------------------------------------------------------------------- sine and cosine
# sin and cos together, without a libm call: the kernels of fdlibm / musl (__sin, __cos:
# minimax polynomials on [-pi/4, pi/4], < 1 ulp) after a Cody-Waite reduction by pi/2 with
# a two-part constant. libm's sin and cos are opaque calls (about 20 ns each here, and
# they serialise the FK chain); these inline and vectorise (about 4 ns per pair). On
# |x| < _SINCOS_RANGE they differ from libm by at most 2e-16 (absolute) everywhere and by
# at most 1 ulp away from the zeros of sin and cos (tests/test_analytic_batch.py checks
# both); beyond that range, and for NaN or infinities, libm is used.
_S1 = -1.66666666666666324348e-01
_S2 = 8.33333333332248946124e-03
_S3 = -1.98412698298579493134e-04
_S4 = 2.75573137070700676789e-06
_S5 = -2.50507602534068634195e-08
_S6 = 1.58969099521155010221e-10
_C1 = 4.16666666666666019037e-02
_C2 = -1.38888888888741095749e-03
_C3 = 2.48015872894767294178e-05
_C4 = -2.75573143513906633035e-07
_C5 = 2.08757232129817482790e-09
_C6 = -1.13596475577881948265e-11
_INVPIO2 = 6.36619772367581382433e-01  # 2 / pi
_PIO2_1 = 1.57079632673412561417e00  # first 33 bits of pi / 2
_PIO2_1T = 6.07710050650619224932e-11  # pi / 2 - _PIO2_1
_TOINT = 1.5 / 2.220446049250313e-16  # adding and subtracting it rounds to an integer
_SINCOS_RANGE = 1.0e5
"""Largest |x| (rad) for the inline sine and cosine (the reduction error stays < 1e-20)."""


@inline
def _sin_kernel(x: float, y: float) -> float:
    """sin(x + y) for |x + y| <= pi / 4, ``y`` the tail of ``x`` (musl __sin)."""
    z = x * x
    w = z * z
    r = _S2 + z * (_S3 + z * _S4) + z * w * (_S5 + z * _S6)
    v = z * x
    return x - ((z * (0.5 * y - v * r) - y) - v * _S1)


@inline
def _cos_kernel(x: float, y: float) -> float:
    """cos(x + y) for |x + y| <= pi / 4, ``y`` the tail of ``x`` (musl __cos)."""
    z = x * x
    w = z * z
    r = z * (_C1 + z * (_C2 + z * _C3)) + w * w * (_C4 + z * (_C5 + z * _C6))
    hz = 0.5 * z
    w = 1.0 - hz
    return w + (((1.0 - w) - hz) + (z * r - x * y))


@inline
def _sincos_core(x: float) -> tuple[float, float]:
    """``(sin x, cos x)`` for |x| < _SINCOS_RANGE, without branches (so loops vectorise).

    ``x = n pi / 2 + y0 + y1``: ``x - n _PIO2_1`` is exact (Sterbenz; the product is exact
    as ``_PIO2_1`` has 33 significant bits), the tail ``n _PIO2_1T`` leaves an error below
    1e-20 on this range; then the quadrant ``n mod 4`` picks and signs the kernels.
    """
    fn = x * _INVPIO2 + _TOINT - _TOINT
    r = x - fn * _PIO2_1
    w = fn * _PIO2_1T
    y0 = r - w
    y1 = (r - y0) - w
    n = np.int64(fn)
    s = _sin_kernel(y0, y1)
    c = _cos_kernel(y0, y1)
    odd = (n & 1) != 0
    sn = c if odd else s
    cs = s if odd else c
    sn = -sn if (n & 2) != 0 else sn
    cs = -cs if ((n + 1) & 2) != 0 else cs
    return sn, cs


@jit
def sincos(x: float) -> tuple[float, float]:
    """``(sin x, cos x)``: inline kernels on |x| < _SINCOS_RANGE, libm elsewhere (and NaN)."""
    if abs(x) < _SINCOS_RANGE:
        return _sincos_core(x)
    return math.sin(x), math.cos(x)


# ---------------------------------------------------------------------- arc tangent
# atan2 without a libm call: fdlibm / musl's atan (a reduction of |t| to four intervals
# around 0, 0.5, 1, 1.5 and infinity, then an odd polynomial of degree 21 on |t| <= 7/16,
# < 1 ulp) and its quadrant rules. libm's atan2 is an opaque call of about 20 ns here,
# a fifth of a closed form's time (about 30 calls a pose), and this one about 14 ns (the
# batches of the closed forms run 2 % to 10 % faster). It is within 2 ulp of the exact
# angle (1.5 seen; libm's 0.75: tests/test_math_atan2.py); NaN, infinities, zeros and
# extreme magnitudes, rare in the kernels, go to libm for its signed special cases.
_ATAN_HI = (
    4.63647609000806093515e-01,  # atan(0.5), then its rounding error in _ATAN_LO
    7.85398163397448278999e-01,  # atan(1)
    9.82793723247329054082e-01,  # atan(1.5)
    1.57079632679489655800e00,  # atan(inf) = pi / 2
)
_ATAN_LO = (
    2.26987774529616870924e-17,
    3.06161699786838301793e-17,
    1.39033110312309984516e-17,
    6.12323399573676603587e-17,
)
_AT0 = 3.33333333333329318027e-01
_AT1 = -1.99999999998764832476e-01
_AT2 = 1.42857142725034663711e-01
_AT3 = -1.11111104054623557880e-01
_AT4 = 9.09088713343650656196e-02
_AT5 = -7.69187620504482999495e-02
_AT6 = 6.66107313738753120669e-02
_AT7 = -5.83357013379057348645e-02
_AT8 = 4.97687799461593236017e-02
_AT9 = -3.65315727442169155270e-02
_AT10 = 1.62858201153657823623e-02
_PI_LO = 1.2246467991473531772e-16  # pi - math.pi


@inline
def _atan_series(t: float) -> float:
    """``atan(t) - t`` for |t| <= 7/16 (the odd polynomial of fdlibm / musl's atan)."""
    z = t * t
    w = z * z
    s1 = z * (_AT0 + w * (_AT2 + w * (_AT4 + w * (_AT6 + w * (_AT8 + w * _AT10)))))
    s2 = w * (_AT1 + w * (_AT3 + w * (_AT5 + w * (_AT7 + w * _AT9))))
    return -t * (s1 + s2)


@jit
def atan2(y: float, x: float) -> float:
    """``math.atan2(y, x)`` (rad, in [-pi, pi]), without a libm call on the common range.

    Where ``|x|`` and ``|y|`` both lie in (1e-290, 1e290): fdlibm's reduction, each
    interval's argument in one division of ``|y|`` and ``|x|`` (not of their rounded
    ratio), within 2 ulp of the exact angle. Elsewhere (zeros, NaN, infinities, extreme
    magnitudes, where a product could overflow): libm's, with its signed special cases.
    """
    ax = abs(x)
    ay = abs(y)
    if not (1e-290 < ax < 1e290 and 1e-290 < ay < 1e290):
        return math.atan2(y, x)
    # fdlibm's reduction of t = ay / ax, each interval's argument in one division.
    if ay < 0.4375 * ax:
        t = ay / ax
        z = t + _atan_series(t) if ay >= 7.450580596923828e-09 * ax else t
    else:
        if ay < 1.1875 * ax:
            if ay < 0.6875 * ax:
                i = 0
                t = (2.0 * ay - ax) / (2.0 * ax + ay)
            else:
                i = 1
                t = (ay - ax) / (ay + ax)
        elif ay < 2.4375 * ax:
            i = 2
            t = (ay - 1.5 * ax) / (ax + 1.5 * ay)
        else:
            i = 3
            t = -ax / ay
        z = _ATAN_HI[i] - ((-_atan_series(t) - _ATAN_LO[i]) - t)
    if x < 0.0:
        z = math.pi - (z - _PI_LO)
    return math.copysign(z, y)


# ---------------------------------------------------------------------- scalar helpers
@jit
def wrap_angle(t: float) -> float:
    """``t`` in (-pi, pi]: the exact steps of :func:`optik.trig.wrap_angle`."""
    if -math.pi < t <= math.pi:
        return t  # fmod would return t unchanged (and costs a libm call)
    w = np.fmod(t, _TWO_PI)
    if w > math.pi:
        return w - _TWO_PI
    if w <= -math.pi:
        return w + _TWO_PI
    return w


@jit
def mod_two_pi(x: float) -> float:
    """``numpy.remainder(x, 2 pi)``, bit for bit, in [0, 2 pi] (2 pi only by rounding).

    numpy forms ``fmod(x, 2 pi)`` (exact), adds ``2 pi`` to a negative result and turns a
    zero into +0. For ``0 <= x < 2 pi`` that is ``x``; for ``2 pi <= x < 4 pi`` it is
    ``x - 2 pi``, exact by Sterbenz's lemma; for ``-2 pi < x < 0`` it is ``x + 2 pi``:
    the common cases skip the libm call.
    """
    if 0.0 < x < _TWO_PI:
        return x
    if _TWO_PI <= x < 2.0 * _TWO_PI:
        return x - _TWO_PI
    if -_TWO_PI < x < 0.0:
        return x + _TWO_PI
    rem = np.fmod(x, _TWO_PI)
    if rem == 0.0:
        return 0.0
    if rem < 0.0:
        return rem + _TWO_PI
    return rem


@jit
def trig_branches(
    a: float, b: float, c: float, free: float, tol: float
) -> tuple[int, float, float]:
    """The two branches of ``a cos t + b sin t = c``: ``(count, t_plus, t_minus)``.

    ``t+- = atan2(b, a) +- atan2(sqrt(r^2 - c^2), c)`` (seed 000, eq. 20), each wrapped
    into (-pi, pi] and kept in that order, so a caller can follow one branch. The tests
    are linear in the coefficients, so they mean the same at every size of ``r``:

    - ``r = hypot(a, b) <= tol``: every angle solves it, ``(1, free, free)``, when
      ``|c| <= tol``; else no root;
    - otherwise ``gap = (r - |c|) / max(r, 1)`` (absolute below 1: SI inputs round
      absolutely there): ``gap < -tol`` no root; ``|gap| <= tol`` one tangent root
      ``atan2(b, a) + atan2(0, c)`` (count 1, both branches equal); else two, the square
      root formed as ``(r - |c|)(r + |c|)`` without the cancellation of ``a^2 + b^2 -
      c^2`` (and relative to ``r^2`` when ``r >= 1``, so it cannot overflow).

    Every angle returned leaves a residual ``|a cos t + b sin t - c|`` of at most
    ``2 tol max(r, 1)``. (A test on ``r^2`` instead would call ``r = 1e-7``, ``c = 0`` a
    tangent or free case and return an angle a right angle off the roots.)
    Where there is no root both angles are 0.
    """
    r = math.sqrt(a * a + b * b)  # hypot's value without its libm call (O(1) coefficients)
    if not 1e-150 < r < 1e150:  # a * a overflowed or underflowed (or a NaN): libm's is exact
        r = math.hypot(a, b)
    ac = abs(c)
    if r <= tol:
        if ac <= tol:
            return 1, free, free
        return 0, 0.0, 0.0
    gap = (r - ac) / r if r >= 1.0 else r - ac
    if gap < -tol:
        return 0, 0.0, 0.0
    # atan2(+0, a) is 0 or pi: skip the libm call when b is +0 (a constant b = 0 is common).
    phi = (0.0 if a > 0.0 else math.pi) if b == 0.0 and math.copysign(1.0, b) > 0.0 else atan2(b, a)
    if gap <= tol:
        t = wrap_angle(phi + math.atan2(0.0, c))  # tangent: the root is taken as 0
        return 1, t, t
    if r >= 1.0 or r < 1e-150:  # relative to r: nothing squared over- or underflows
        rho = ac / r
        root = r * math.sqrt((1.0 - rho) * (1.0 + rho))
    else:
        root = math.sqrt((r - ac) * (r + ac))
    psi = atan2(root, c)
    return 2, wrap_angle(phi + psi), wrap_angle(phi - psi)


@jit
def trig_roots(
    a: float, b: float, c: float, free: float, trig_tol: float, eps: float, free_tol: float
) -> tuple[int, float, float]:
    """Roots of ``a cos t + b sin t = c`` for a joint: ``(count, t_low, t_high)``.

    First the closed forms' singular-coefficient rule: with ``|a|, |b| <= eps * scale``
    (``scale = max(|a|, |b|, |c|, 1)``) the joint is free, ``(1, free, free)``, when
    ``|c| <= free_tol * scale``, else there is no root. Otherwise :func:`trig_branches`
    with tolerance ``trig_tol`` (:data:`optik.analytic._base.TANGENT_TOL` for the closed
    forms, a tenth of it where ``r >= 1``; :data:`optik.trig.TRIG_TOL` for
    :func:`optik.solve_trig`), the roots in ascending order. A negative ``eps`` switches
    the first rule and the tenth off (:func:`optik.solve_trig`).
    """
    scale = max(abs(a), abs(b), abs(c), 1.0)
    if abs(a) <= eps * scale and abs(b) <= eps * scale:
        if abs(c) <= free_tol * scale:
            return 1, free, free
        return 0, 0.0, 0.0
    tol = trig_tol
    if eps >= 0.0 and a * a + b * b >= 1.0:
        # The closed forms' band is absolute below 1 (a URDF's ideal arm misses by about
        # 1e-11 m) and relative beyond: 1e-11 of a 150 m shoulder offset left the tangent
        # root 1.5e-9 m off, past the FK check. A tenth of it is 1e-12 relative there.
        tol = 0.1 * trig_tol
    count, t1, t2 = trig_branches(a, b, c, free, tol)
    if t1 <= t2:
        return count, t1, t2
    return count, t2, t1


@jit
def trig_branches_batch(
    a: np.ndarray, b: np.ndarray, c: np.ndarray, free: np.ndarray, tol: float, out: np.ndarray
) -> None:
    """:func:`trig_branches` over flat arrays (``free`` wrapped into (-pi, pi] first).

    ``out`` (3, N) receives the counts, ``t_plus`` and ``t_minus``.
    """
    for k in range(a.shape[0]):
        n, tp, tm = trig_branches(a[k], b[k], c[k], wrap_angle(free[k]), tol)
        out[0, k] = n
        out[1, k] = tp
        out[2, k] = tm


@jit
def rotation_angles(R: np.ndarray, out: np.ndarray) -> None:
    """:func:`rotation_angle` of every rotation of a stack ``R`` (N, 3, 3) into ``out`` (N,)."""
    for k in range(R.shape[0]):
        out[k] = rotation_angle(R[k])


@jit
def log_rotation(R: np.ndarray, out: np.ndarray) -> None:
    """Rotation vector of the 3x3 rotation ``R`` into ``out`` (3,), stable near 0 and pi."""
    vx = 0.5 * (R[2, 1] - R[1, 2])
    vy = 0.5 * (R[0, 2] - R[2, 0])
    vz = 0.5 * (R[1, 0] - R[0, 1])
    s = np.sqrt(vx * vx + vy * vy + vz * vz)
    c = 0.5 * (R[0, 0] + R[1, 1] + R[2, 2] - 1.0)
    theta = np.arctan2(s, c)
    if theta < 1e-6:
        k = 1.0 + theta * theta / 6.0
        out[0] = vx * k
        out[1] = vy * k
        out[2] = vz * k
        return
    if theta < np.pi - 1e-3:
        k = theta / s
        out[0] = vx * k
        out[1] = vy * k
        out[2] = vz * k
        return
    # Near pi the skew part vanishes; the axis comes from the symmetric part.
    best = 0
    for i in range(1, 3):
        if R[i, i] > R[best, best]:
            best = i
    for i in range(3):
        out[i] = 0.5 * (R[i, best] + R[best, i])
    out[best] = R[best, best] - c
    norm = np.sqrt(out[0] ** 2 + out[1] ** 2 + out[2] ** 2)
    if norm <= 0.0:
        norm = 1.0
    sign = 1.0 if out[0] * vx + out[1] * vy + out[2] * vz >= 0.0 else -1.0
    k = sign * theta / norm
    for i in range(3):
        out[i] *= k


@jit
def rotation_angle(R: np.ndarray) -> float:
    """Rotation angle in [0, pi] of the 3x3 rotation ``R``, accurate for tiny angles.

    ``atan2(||vee(R - R^T)|| / 2, (trace R - 1) / 2)``; ``arccos`` of the trace loses all
    precision below about 2e-8 rad.
    """
    sx = R[2, 1] - R[1, 2]
    sy = R[0, 2] - R[2, 0]
    sz = R[1, 0] - R[0, 1]
    s = 0.5 * np.sqrt(sx * sx + sy * sy + sz * sz)
    c = 0.5 * (R[0, 0] + R[1, 1] + R[2, 2] - 1.0)
    return float(np.arctan2(s, c))


@jit
def pose_error(T: np.ndarray, G: np.ndarray) -> tuple[float, float]:
    """``(||p - p*||, angle(R*^T R))`` of a pose ``T`` against a target ``G`` (4x4 each)."""
    dx = T[0, 3] - G[0, 3]
    dy = T[1, 3] - G[1, 3]
    dz = T[2, 3] - G[2, 3]
    # R*^T R: only its trace and skew part enter the angle.
    r00 = G[0, 0] * T[0, 0] + G[1, 0] * T[1, 0] + G[2, 0] * T[2, 0]
    r11 = G[0, 1] * T[0, 1] + G[1, 1] * T[1, 1] + G[2, 1] * T[2, 1]
    r22 = G[0, 2] * T[0, 2] + G[1, 2] * T[1, 2] + G[2, 2] * T[2, 2]
    r01 = G[0, 0] * T[0, 1] + G[1, 0] * T[1, 1] + G[2, 0] * T[2, 1]
    r10 = G[0, 1] * T[0, 0] + G[1, 1] * T[1, 0] + G[2, 1] * T[2, 0]
    r02 = G[0, 0] * T[0, 2] + G[1, 0] * T[1, 2] + G[2, 0] * T[2, 2]
    r20 = G[0, 2] * T[0, 0] + G[1, 2] * T[1, 0] + G[2, 2] * T[2, 0]
    r12 = G[0, 1] * T[0, 2] + G[1, 1] * T[1, 2] + G[2, 1] * T[2, 2]
    r21 = G[0, 2] * T[0, 1] + G[1, 2] * T[1, 1] + G[2, 2] * T[2, 1]
    sx = r21 - r12
    sy = r02 - r20
    sz = r10 - r01
    s = 0.5 * np.sqrt(sx * sx + sy * sy + sz * sz)
    c = 0.5 * (r00 + r11 + r22 - 1.0)
    return float(np.sqrt(dx * dx + dy * dy + dz * dz)), float(np.arctan2(s, c))


@jit
def worst_rotation_defects(R: np.ndarray) -> tuple[float, float]:
    """Over a stack ``R`` (N, 3, 3): the largest ``max |R^T R - I|`` and the det farthest from 1."""
    worst_err = 0.0
    worst_det = 1.0
    for k in range(R.shape[0]):
        err, det = rotation_defects(R[k])
        worst_err = max(worst_err, err)
        if abs(det - 1.0) > abs(worst_det - 1.0) or not np.isfinite(det):
            worst_det = det
    return worst_err, worst_det


@jit
def rotation_defects(R: np.ndarray) -> tuple[float, float]:
    """``(max |R^T R - I|, det R)`` of a 3x3 ``R``: how far it is from a proper rotation."""
    a, b, c = R[0, 0], R[0, 1], R[0, 2]
    d, e, f = R[1, 0], R[1, 1], R[1, 2]
    g, h, i = R[2, 0], R[2, 1], R[2, 2]
    err = max(
        abs(a * a + d * d + g * g - 1.0),
        abs(b * b + e * e + h * h - 1.0),
        abs(c * c + f * f + i * i - 1.0),
        abs(a * b + d * e + g * h),
        abs(a * c + d * f + g * i),
        abs(b * c + e * f + h * i),
    )
    det = a * (e * i - f * h) - b * (d * i - f * g) + c * (d * h - e * g)
    return err, det


@jit
def pose_defect(T: np.ndarray, k: int, rot_tol: float, row_tol: float) -> int:
    """0 when ``T[k]`` is a valid 4x4 pose, else its first defect (the one pose check).

    1: a NaN or infinite entry; 2: last row differs from ``(0, 0, 0, 1)`` by more than
    ``row_tol``; 3: ``max |R^T R - I| > rot_tol`` or ``|det R - 1| > 10 rot_tol`` (the
    formulas of :func:`optik.spatial.check_rotation` for one 3x3).
    """
    for i in range(4):
        for j in range(4):
            if not math.isfinite(T[k, i, j]):
                return 1
    bottom = max(abs(T[k, 3, 0]), abs(T[k, 3, 1]), abs(T[k, 3, 2]), abs(T[k, 3, 3] - 1.0))
    if bottom > row_tol:
        return 2
    err, det = rotation_defects(T[k, :3, :3])
    if err > rot_tol or abs(det - 1.0) > 10.0 * rot_tol:
        return 3
    return 0


@jit
def first_bad_pose(T: np.ndarray, rot_tol: float, row_tol: float) -> int:
    """Index of the first invalid pose of a batch ``T`` (N, 4, 4), or -1 if none is.

    Each pose is checked by :func:`pose_defect`.
    """
    for k in range(T.shape[0]):
        if pose_defect(T, k, rot_tol, row_tol) != 0:
            return k
    return -1


@inline
def cholesky_factor(A: np.ndarray, L: np.ndarray) -> bool:
    """Factor SPD ``A`` (n, n) as ``L L^T`` into ``L`` (n, n + 1); False if not SPD.

    The lower triangle of ``L[:, :n]`` is the factor; its last column keeps the
    reciprocals of the diagonal, so the factorisation and the triangular solves multiply
    instead of dividing (n divisions in all). A pivot that is not positive and finite
    (also NaN) makes ``A`` not numerically positive definite. The upper triangle of
    ``L[:, :n]`` is not written.
    """
    n = A.shape[0]
    for i in range(n):
        for j in range(i + 1):
            s = A[i, j]
            for k in range(j):
                s -= L[i, k] * L[j, k]
            if i == j:
                if not (s > 0.0 and s < np.inf):
                    return False
                d = np.sqrt(s)
                L[i, i] = d
                L[i, n] = 1.0 / d
            else:
                L[i, j] = s * L[j, n]
    return True


@inline
def cholesky_substitute(L: np.ndarray, b: np.ndarray, x: np.ndarray) -> None:
    """Solve ``L L^T x = b`` with a factor from :func:`cholesky_factor` (``x`` may be ``b``)."""
    n = L.shape[0]
    for i in range(n):
        s = b[i]
        for k in range(i):
            s -= L[i, k] * x[k]
        x[i] = s * L[i, n]
    for i in range(n - 1, -1, -1):
        s = x[i]
        for k in range(i + 1, n):
            s -= L[k, i] * x[k]
        x[i] = s * L[i, n]


@jit
def cholesky_solve(A: np.ndarray, b: np.ndarray, x: np.ndarray, L: np.ndarray) -> bool:
    """Solve SPD ``A x = b`` by Cholesky (``L`` is n x (n + 1) scratch); False if not SPD."""
    if not cholesky_factor(A, L):
        return False
    cholesky_substitute(L, b, x)
    return True


@jit
def householder_lstsq(A: np.ndarray, b: np.ndarray, y: np.ndarray) -> bool:
    """``y = argmin ||A y - b||`` for ``A`` (f, m), ``f >= m``, by Householder QR.

    ``A`` and ``b`` are overwritten. Returns False on a zero column (rank deficiency
    found; the caller then takes the full proof).
    """
    f, m = A.shape
    for k in range(m):
        norm = 0.0
        for i in range(k, f):
            norm += A[i, k] * A[i, k]
        norm = math.sqrt(norm)
        if norm == 0.0:
            return False
        alpha = -norm if A[k, k] >= 0.0 else norm
        A[k, k] -= alpha
        vnorm2 = 0.0
        for i in range(k, f):
            vnorm2 += A[i, k] * A[i, k]
        if vnorm2 > 0.0:
            for j in range(k + 1, m):
                dot = 0.0
                for i in range(k, f):
                    dot += A[i, k] * A[i, j]
                factor = 2.0 * dot / vnorm2
                for i in range(k, f):
                    A[i, j] -= factor * A[i, k]
            dot = 0.0
            for i in range(k, f):
                dot += A[i, k] * b[i]
            factor = 2.0 * dot / vnorm2
            for i in range(k, f):
                b[i] -= factor * A[i, k]
        A[k, k] = alpha
    for k in range(m - 1, -1, -1):
        acc = b[k]
        for j in range(k + 1, m):
            acc -= A[k, j] * y[j]
        y[k] = acc / A[k, k]
    return True
