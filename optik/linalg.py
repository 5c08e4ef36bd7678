"""Closed-form generalized inverses for the inverse Jacobian (seed 000, section V).

For ``A x = b`` with ``A`` of shape ``(m, n)`` (seed 000, eq. 44-74):

* ``m < n`` (redundant arm): the minimum-norm solution ``x = A^T (A A^T)^-1 b`` (eq. 48,
  62), computed as ``x = A^T u`` with ``(A A^T) u = b`` (eq. 58-60).
* ``m > n``: the least-squares solution ``x = (A^T A)^-1 (A^T b)`` (eq. 47, 73), with
  ``A^T b`` multiplied first because it is cheaper than eq. 46 (see
  :func:`multiplication_count`).
* ``m = n``: ``x = A^-1 b`` by an LU solve.

No inverse is ever formed: each closed form is evaluated by factorizing the small Gram
matrix (Cholesky) and solving.

Accuracy and the two solution paths
-----------------------------------
The Gram matrix squares the condition number, ``cond(A A^T) = cond(A)^2``, and the Gram
(normal equation) solution carries a relative error of about ``cond(A)^2 * eps``
(measured against exact rational answers: at most ``0.44 cond(A)^2 eps``, see
``docs/theory.md``). Every call therefore takes, per matrix of the stack:

1. the **Gram path** (fast; one compiled loop over the stack): Cholesky ``G = L L^T`` of
   the (damped) Gram matrix, two triangular solves, and a *rigorous upper bound*
   ``kappa_up >= cond_2(G)`` from ``L`` (two comparison-matrix solves, see
   ``_gram_kernel``). It is accepted only when ``kappa_up <= GRAM_CONDITION_LIMIT``
   (1e6), so its relative error stays below about ``0.5e6 * eps ~ 1e-10``;
2. otherwise (bound too high, ``G`` not numerically positive definite, overflow) the
   **orthogonal path**: a singular value decomposition of ``A`` itself, accurate to
   about ``cond(A) * eps`` (measured: at most ``8.4 cond(A) eps``). Undamped, it raises
   :class:`~optik.errors.SingularMatrixError` (carrying ``cond_2(A)``) when
   ``cond_2(A) > max_condition`` (default :data:`MAX_CONDITION` = 1e12: past it fewer
   than about three significant digits are guaranteed, so the matrix is treated as
   numerically rank deficient rather than returning a silent garbage answer).

A square undamped ``A`` is solved by LU (accurate to ``~cond(A) eps``, no squaring); the
same bound, corrected for the rounding of ``A A^T`` (:func:`_condition_bound`), screens
its condition, and singular values decide for the matrices it cannot clear.
``max_condition`` must be finite, in ``[1, CONDITION_CEILING]`` (1e14).

Scale: a matrix or right-hand-side column whose largest entry is outside ``[2^-65,
2^64)`` is multiplied by the power of two (exact) bringing it to ``[0.5, 1)`` before any
Gram matrix, factor or SVD, and the answer scaled back. So any finite entries (subnormal
included) give the unscaled problem's answer, and neither the condition test nor the
damping depends on the scale. An answer beyond float64 raises ``OptikError``.

With ``damping = lambda > 0`` the damped closed forms ``A^T (A A^T + lambda^2 I)^-1 b``
and ``(A^T A + lambda^2 I)^-1 A^T b`` are returned instead. They are the same vector (the
push-through identity ``A^T (A A^T + l^2 I)^-1 = (A^T A + l^2 I)^-1 A^T``), so the smaller
Gram matrix is used whatever the shape, and no error is raised for rank deficiency.
``lambda`` is in the units of ``A`` and scales with it (the power of two above divides
``A`` and ``lambda`` alike). A damping ``lambda < 2^-511 ~ 1.49e-154`` (its square below
float64's normal range) counts as no damping, whatever the scale of ``A``: the undamped
rules (shape, ``max_condition``) apply.

Shapes: ``A`` is ``(..., m, n)``; ``b`` is ``(..., m)`` (one right-hand side per matrix)
or ``(..., m, k)`` (``k`` right-hand sides); the batch axes ``...`` of ``A`` and ``b`` must
be equal (no broadcasting, so a vector and a matrix right-hand side are never confused).
The answer is ``(..., n)`` or ``(..., n, k)``. Units follow the caller: for a Jacobian
``J`` (rows m/s and rad/s per joint unit) and a twist, ``x`` is in joint units.
"""

from __future__ import annotations

import math
from typing import Any, Final, Literal

import numpy as np
from numpy.typing import NDArray

from optik._checks import FloatArray, as_float_array, check_finite, check_real
from optik._math import cholesky_factor, cholesky_substitute
from optik._numba import jit
from optik.errors import NonFiniteError, OptikError, ShapeError, SingularMatrixError

BoolArray = NDArray[np.bool_]
IndexArray = NDArray[np.intp]

__all__ = [
    "CONDITION_CEILING",
    "GRAM_CONDITION_LIMIT",
    "MAX_CONDITION",
    "MAX_DAMPING",
    "condition_number",
    "generalized_inverse",
    "generalized_solve",
    "least_squares",
    "min_norm",
    "multiplication_count",
    "solve_square",
]

#: Default bound on ``cond_2(A)`` above which an undamped solve raises
#: :class:`~optik.errors.SingularMatrixError`. The orthogonal path's relative error is
#: at most ``~10 cond(A) eps``, so 1e12 still guarantees ~3 significant digits.
MAX_CONDITION: Final[float] = 1e12

#: Largest accepted ``max_condition``. Past ``~1/eps`` a computed ``cond_2`` is rounding
#: noise (an exactly rank-1 ``ones((2, 3))`` computes to 2e16) and the orthogonal path's
#: relative error ``~10 cond(A) eps`` exceeds 0.2, so a larger value would only let
#: rank-deficient matrices through with meaningless answers.
CONDITION_CEILING: Final[float] = 1e14

#: Smallest damping that counts as damping: ``2^-511``, whose square is the smallest
#: normal float64. A smaller ``lambda`` counts as 0, at any scale of ``A``.
MIN_DAMPING: Final[float] = 2.0**-511

#: Largest accepted ``damping`` (a sanity range: its square is formed only scaled).
MAX_DAMPING: Final[float] = 1e100

#: Binary exponents ``e`` of ``max |A|`` (and of each ``b`` column) with ``|e| <= 64`` are
#: left unscaled: there no Gram entry, factor or answer can over- or underflow.
_SAFE_EXPONENT: Final[int] = 64

#: Largest accepted upper bound on ``cond_2(G)`` of the Gram matrix ``G`` for the fast
#: Gram path; beyond it the SVD path is used. Keeps the Gram path's relative error below
#: about ``0.5 * GRAM_CONDITION_LIMIT * eps ~ 1e-10`` (``cond(A) <= 1e3`` on that path).
GRAM_CONDITION_LIMIT: Final[float] = 1e6


# --------------------------------------------------------------------------- validation


def _check_matrix(A: Any) -> FloatArray:
    """Return ``A`` as a finite float64 array of shape ``(..., m, n)``, m, n >= 1."""
    array = as_float_array("A", A)
    if array.ndim < 2 or array.shape[-1] < 1 or array.shape[-2] < 1:
        raise ShapeError("A", "(..., m, n) with m, n >= 1", array.shape)
    return _finite("A", array)


def _check_rhs(b: Any, A: FloatArray) -> tuple[FloatArray, bool]:
    """Return ``b`` as finite float64 and whether it is a single vector per matrix."""
    array = as_float_array("b", b)
    rows = A.shape[:-1]  # (..., m)
    if array.shape == rows:
        vector = True
    elif array.ndim == A.ndim and array.shape[:-1] == rows and array.shape[-1] >= 1:
        vector = False
    else:
        batch = ", ".join(str(d) for d in rows)
        raise ShapeError("b", f"({batch}) or ({batch}, k)", array.shape)
    return _finite("b", array), vector


def _finite(name: str, array: FloatArray) -> FloatArray:
    """:func:`check_finite`, after a cheap screen.

    The sum of squares (one BLAS dot) is finite only if every entry is (NaN and inf
    propagate), so the elementwise scan runs only when it is not (a NaN/inf entry, or
    finite entries above ~1e154 whose squares overflow, which the scan then clears).
    """
    total = np.vdot(array, array)  # a BLAS call: overflow sets no numpy warning
    if not np.isfinite(total):
        check_finite(name, array)
    return array


def _check_scalars(damping: Any, max_condition: Any) -> tuple[float, float]:
    """Validate the keyword scalars; return ``(lambda, max_condition)`` as floats.

    ``lambda`` is returned as 0 below :data:`MIN_DAMPING` (its square is not a normal
    float: no damping); above :data:`MAX_DAMPING` it is rejected. ``max_condition`` must be
    finite in ``[1, CONDITION_CEILING]``: ``inf`` or NaN would let a singular matrix through
    to a NaN or meaningless answer.
    """
    lam = check_real("damping", damping, allow_nan=True, allow_inf=True)
    if not math.isfinite(lam):
        raise NonFiniteError("damping")
    check_real("damping", lam, nonnegative=True, maximum=MAX_DAMPING)
    limit = check_real("max_condition", max_condition, minimum=1.0, maximum=CONDITION_CEILING)
    return (lam if lam >= MIN_DAMPING else 0.0), limit


# ------------------------------------------------------------------- compiled Gram kernel
# numpy has no batched Cholesky that reports failures per matrix (np.linalg.cholesky
# raises for the whole stack without saying which matrix failed) and no batched
# triangular solve. One compiled loop over the stack does the whole Gram path per matrix,
# so a failure stays with its matrix, a stack of one costs ~2 us and a stack of 10,000
# 6x7 matrices ~5 ms, and single and batched calls run the very same code.


@jit
def _gram_kernel(  # pragma: no cover - compiled; its answers are tested through callers
    A: FloatArray,
    B: FloatArray,
    lam: float,
    identity: bool,
    X: FloatArray,
    ok: BoolArray,
    kappa_up: FloatArray,
    exponents: IndexArray,
) -> None:
    """Gram path for every matrix of the stack ``A`` (N, m, n), writing into ``X``.

    Wide (``m <= n``): ``G = A A^T + lambda^2 I`` and ``X = A^T G^-1 B``; tall: ``G = A^T A
    + lambda^2 I`` and ``X = G^-1 (A^T B)`` with ``A^T B`` formed first (eq. 47).
    ``identity`` means ``B = I`` (then ``X = A^+``; ``B`` is ignored), solved without
    forming ``G^-1``: tall, ``G X = A^T``; wide, ``A^T G^-1 = (G^-1 A)^T``.

    Scaling: with ``e`` the binary exponent of ``max |A_i|`` (``exponents[i, 0]``; 0 when
    ``|e| <= _SAFE_EXPONENT``), it works on ``K = 2^-e A_i`` with ``2^-e lambda``, and on
    each column of ``B`` times its own ``2^-f`` (likewise); the answer column is
    ``2^(f - e)`` times the scaled one (``2^-e`` for ``A^+``). Powers of two are exact,
    and ``G`` stays clear of overflow and underflow for any finite input.

    With ``K`` the scaled factor (``A`` wide, ``A^T`` tall, ``p x q``) and
    ``G = K K^T = L L^T`` (:func:`optik._math.cholesky_factor`), it also computes the
    rigorous bound ``kappa_up >= cond_2(L L^T)``: with the comparison matrix ``M(L)``
    (``|l_jj|`` on the diagonal, ``-|l_jk|`` off it), ``|L^-1| <= M(L)^-1`` entrywise
    (Higham, *Accuracy and Stability of Numerical Algorithms*, 2nd ed., Thm. 8.12), so
    ``||L^-1||_inf <= max z`` and ``||L^-1||_1 <= max w`` for ``M(L) z = e``,
    ``M(L)^T w = e``. For SPD ``G``, ``||G||_2 <= trace G`` and ``||G^-1||_2 =
    ||L^-1||_2^2 <= ||L^-1||_1 ||L^-1||_inf``::

        cond_2(G) <= trace(G) * max(z) * max(w) =: kappa_up.

    The comparison solves add positive terms only, so they are accurate to the last
    digits. Measured on random 6x7 stacks the bound is 2.6x-30x (median 9x) above
    ``cond_2(G)``. It bounds the *computed* ``L L^T``; :func:`_condition_bound` turns it
    into a bound on ``cond_2(A)``.

    Args:
        A: (N, m, n) C-contiguous matrices, any finite entries.
        B: (N, m, k) right-hand sides (ignored when ``identity``).
        lam: ``lambda >= 0``, in the units of ``A``.
        identity: solve for ``A^+`` (``k = m``).
        X: (N, n, k) output.
        ok: (N,) output, False where ``G`` is not numerically positive definite (a
            pivot is not positive, or not finite) or the answer is not finite (then the
            SVD path takes it and reports an answer beyond float64).
        kappa_up: (N,) output, the bound above (``inf`` where not ``ok``).
        exponents: (N, 1 + kb) output, ``e`` above (0 for a zero matrix), then ``f`` of
            each of the ``kb`` columns of ``B`` (none for ``A^+``); ``X`` may have fewer
            columns (0: the bound and the exponents alone).
    """
    N, m, n = A.shape
    wide = m <= n
    p = m if wide else n
    q = n if wide else m
    k = X.shape[2]
    kk = q if identity else k  # columns of the right-hand side R
    K = np.empty((p, q))
    G = np.empty((p, p))
    L = np.zeros((p, p + 1))
    R = np.empty((p, kk))
    kb = 0 if identity else B.shape[2]  # columns of B (more than k: exponents only)
    Bs = np.empty((m, kb))
    shift = np.zeros(kb, dtype=np.int64)  # f - e per column of X
    column = np.empty(p)
    z = np.empty(p)
    w = np.empty(p)
    for i in range(N):
        ok[i] = False
        kappa_up[i] = np.inf
        amax = 0.0
        for r in range(p):
            for c in range(q):
                a = A[i, r, c] if wide else A[i, c, r]
                K[r, c] = a
                amax = max(amax, abs(a))
        e = math.frexp(amax)[1]
        e = 0 if abs(e) <= _SAFE_EXPONENT else e
        exponents[i, 0] = e
        if e != 0:
            # 2^-e as two normal factors: 2^-e alone overflows for subnormal A (e < -1023).
            f1 = math.ldexp(1.0, (-e) // 2)
            f2 = math.ldexp(1.0, -e - (-e) // 2)
            for r in range(p):
                for c in range(q):
                    K[r, c] = K[r, c] * f1 * f2
        lam_s = lam if e == 0 else math.ldexp(lam, -e)
        lam2 = lam_s * lam_s  # inf for a huge lambda / tiny A: G fails, the SVD path filters
        for c in range(kb):
            bmax = 0.0
            for r in range(m):
                Bs[r, c] = B[i, r, c]
                bmax = max(bmax, abs(B[i, r, c]))
            f = math.frexp(bmax)[1]
            f = 0 if abs(f) <= _SAFE_EXPONENT else f
            exponents[i, 1 + c] = f
            shift[c] = f - e
            if f != 0:
                g1 = math.ldexp(1.0, (-f) // 2)
                g2 = math.ldexp(1.0, -f - (-f) // 2)
                for r in range(m):
                    Bs[r, c] = Bs[r, c] * g1 * g2

        # G = K K^T + lam2 I (lower triangle), then its Cholesky factor.
        trace = 0.0
        for r in range(p):
            for j in range(r + 1):
                s = 0.0
                for c in range(q):
                    s += K[r, c] * K[j, c]
                G[r, j] = s
            G[r, r] += lam2
            trace += G[r, r]
        if not cholesky_factor(G, L):
            continue

        # kappa_up = trace(G) max(z) max(w), see the docstring.
        z_max = 0.0
        for r in range(p):
            s = 1.0
            for c in range(r):
                s += abs(L[r, c]) * z[c]
            z[r] = s * L[r, p]
            z_max = max(z_max, z[r])
        w_max = 0.0
        for r in range(p - 1, -1, -1):
            s = 1.0
            for c in range(r + 1, p):
                s += abs(L[c, r]) * w[c]
            w[r] = s * L[r, p]
            w_max = max(w_max, w[r])
        kappa_up[i] = trace * z_max * w_max

        # Right-hand side R (p, kk), then R <- G^-1 R column by column.
        for r in range(p):
            for c in range(kk):
                if identity:
                    R[r, c] = K[r, c]  # A (wide) or A^T (tall), never I: see docstring
                elif wide:
                    R[r, c] = Bs[r, c]
                else:
                    s = 0.0  # eq. 47: A^T b first
                    for t in range(m):
                        s += K[r, t] * Bs[t, c]
                    R[r, c] = s
        for c in range(kk):
            for r in range(p):
                column[r] = R[r, c]
            cholesky_substitute(L, column, column)
            for r in range(p):
                R[r, c] = column[r]

        finite = True
        for r in range(n):
            for c in range(k):
                if not wide:
                    x = R[r, c]
                elif identity:
                    x = R[c, r]  # A^+ = (G^-1 A)^T
                else:
                    x = 0.0  # x = A^T u
                    for t in range(m):
                        x += K[t, r] * R[t, c]
                d = -e if identity else shift[c]
                x = x if d == 0 else math.ldexp(x, d)  # exact unless it over/underflows
                finite = finite and abs(x) < np.inf
                X[i, r, c] = x
        ok[i] = finite


def _gram_bound_and_solve(
    A: FloatArray, B: FloatArray | None, lam: float, k: int
) -> tuple[FloatArray, BoolArray, FloatArray, IndexArray]:
    """Run :func:`_gram_kernel` on a flat stack; ``B`` None means the identity.

    Returns ``X`` (N, n, k), ``ok`` (N,), ``kappa_up`` (N,) and the scaling exponents
    (N, 1 + B's columns; see the kernel). ``k = 0`` gives the factorization test, the
    bound and the exponents alone.
    """
    N, m, n = A.shape
    X = np.empty((N, n, k))
    ok = np.empty(N, dtype=np.bool_)
    kappa_up = np.empty(N)
    # One compiled signature: C-contiguous float64 stacks only.
    rhs = np.empty((N, m, 0)) if B is None else np.ascontiguousarray(B)
    exponents = np.empty((N, 1 + rhs.shape[2]), dtype=np.int64)
    _gram_kernel(np.ascontiguousarray(A), rhs, lam, B is None, X, ok, kappa_up, exponents)
    return X, ok, kappa_up, exponents


def _condition_bound(kappa_up: FloatArray, ok: BoolArray, m: int, n: int) -> FloatArray:
    """Rigorous upper bounds on ``cond_2(A)`` from :func:`_gram_kernel`'s ``kappa_up``.

    ``kappa_up`` bounds ``cond_2`` of the computed ``L L^T = G + E``, ``||E||_2 <= c u
    trace(G)`` (``u = 2^-53``, ``c = 2 (m + n + 2)``: rounding of ``G``, of its Cholesky
    factor, Higham Thm. 10.3, and of the bound, with a margin of ~2; underflow adds
    ``~p q 2^-1074``, nothing against ``u trace(G)`` in the safe range). By Weyl::

        cond_2(A)^2 <= kappa_up (1 + c u) / (1 - c u kappa_up)

    (docs/theory.md), used only where ``c u kappa_up <= 0.5`` (``kappa_up <~ 1e14``);
    elsewhere, and where not ``ok``, the bound is ``inf``: the caller computes the exact
    ``cond_2``. Shapes (N,).
    """
    cu = 2.0 * (m + n + 2) * 2.0**-53
    trusted = ok & (cu * kappa_up <= 0.5)
    k = np.where(trusted, kappa_up, 0.0)  # no sqrt of a negative: no warning to silence
    bound: FloatArray = np.where(trusted, np.sqrt(k * (1.0 + cu) / (1.0 - cu * k)), np.inf)
    return bound


def _representable(X: FloatArray) -> FloatArray:
    """Return ``X`` after checking it is finite, else raise :class:`OptikError`.

    Every path works scaled, so only a true answer beyond float64 (scaled back by a power
    of two) can be ``inf`` here.
    """
    if not math.isfinite(np.vdot(X, X)) and not np.isfinite(X).all():
        raise OptikError("the solution x is beyond float64 (|x| > 1.8e308); rescale A or b")
    return X


def _ldexp(M: FloatArray, e: IndexArray) -> FloatArray:
    """``M * 2^e`` exactly (inf where it overflows, no warning); ``e`` broadcasts to ``M``."""
    with np.errstate(over="ignore", under="ignore"):
        scaled: FloatArray = np.ldexp(M, e)
    return scaled


# --------------------------------------------------------------------------- other paths


def _svd_solve(
    A: FloatArray,
    B: FloatArray | None,
    lam: float,
    max_condition: float,
    exponent: IndexArray,
    where: IndexArray,
    batch_shape: tuple[int, ...],
) -> FloatArray:
    """Orthogonal path: ``x = V diag(f) U^T b`` from the thin SVD ``A = U diag(s) V^T``.

    ``f = 1 / s`` undamped (after checking ``cond_2(A) <= max_condition``) and
    ``f = s / (s^2 + lambda^2)`` damped. ``B`` None means the identity. ``A``, ``lambda``
    and ``B``'s columns are scaled as in :func:`_gram_kernel` (``A`` by ``2^-exponent``).
    ``where`` holds the flat stack indices of these matrices, for the error message.
    """
    K = _ldexp(A, -exponent[:, None, None])
    try:
        U, s, Vt = np.linalg.svd(K, full_matrices=False)
    except np.linalg.LinAlgError as exc:  # pragma: no cover - LAPACK non-convergence
        raise SingularMatrixError(float("inf"), f"SVD did not converge ({exc})") from exc
    with np.errstate(divide="ignore", invalid="ignore", over="ignore", under="ignore"):
        kappa = np.where(s[:, -1] > 0.0, s[:, 0] / s[:, -1], np.inf)
        if lam == 0.0:
            if np.any(kappa > max_condition):
                j = int(np.argmax(kappa))
                index = np.unravel_index(int(where[j]), batch_shape) if batch_shape else ()
                raise SingularMatrixError(
                    float(kappa[j]),
                    f"A{list(index) if index else ''} is numerically rank deficient: "
                    f"cond_2(A) exceeds max_condition={max_condition:.3g}; pass damping > 0 "
                    "for the damped least-squares answer",
                )
            f = 1.0 / s
        else:
            # s / (s^2 + l^2) written so that a huge l (scaled: l / 2^e) gives 0, not NaN.
            lam2 = np.ldexp(lam, -exponent)[:, None] ** 2
            f = np.where(s > 0.0, 1.0 / (s + lam2 / s), 0.0)
    Ut = np.swapaxes(U, -1, -2)
    V = np.swapaxes(Vt, -1, -2)
    if B is None:
        return _representable(_ldexp(V @ (f[:, :, None] * Ut), -exponent[:, None, None]))
    column_exponent = np.frexp(np.max(np.abs(B), axis=-2))[1]  # (N, k), max|b| < 2^f
    C = Ut @ _ldexp(B, -column_exponent[:, None, :])  # (N, r, k)
    shift = (column_exponent - exponent[:, None])[:, None, :]
    return _representable(_ldexp(V @ (f[:, :, None] * C), shift))


def _gram_solve(
    A: FloatArray,
    B: FloatArray | None,
    lam: float,
    max_condition: float,
    batch_shape: tuple[int, ...],
) -> FloatArray:
    """Generalized solve of a flat stack ``A`` (N, m, n), ``B`` (N, m, k) or None (= I).

    Wide (m <= n): ``X = A^T U`` with ``(A A^T + l^2 I) U = B``; tall (m > n):
    ``(A^T A + l^2 I) X = A^T B`` with ``A^T B`` formed first (eq. 47). Matrices whose
    Gram matrix is not accepted (see module docstring) go to the SVD path; undamped, so do
    those whose bound does not clear ``max_condition`` (which can be below the Gram
    path's ``cond_2(A) <~ 1e3``), so that the SVD's exact ``cond_2`` decides. Undamped, the
    caller guarantees the shape matches the requested closed form. Returns (N, n, k).
    """
    _, m, n = A.shape
    k = m if B is None else B.shape[-1]
    X, ok, kappa_up, exponents = _gram_bound_and_solve(A, B, lam, k)
    accepted = ok & (kappa_up <= GRAM_CONDITION_LIMIT)
    # Accepted means cond_2(A) <= ~sqrt(GRAM_CONDITION_LIMIT) (1e3): only a max_condition
    # below about that needs the per-matrix bound.
    if lam == 0.0 and max_condition < 2.0 * math.sqrt(GRAM_CONDITION_LIMIT):
        accepted &= _condition_bound(kappa_up, ok, m, n) <= max_condition
    if not accepted.all():
        bad = np.flatnonzero(~accepted)
        X[bad] = _svd_solve(
            A[bad],
            None if B is None else B[bad],
            lam,
            max_condition,
            exponents[bad, 0],
            bad,
            batch_shape,
        )
    return X


def _lu_solve(
    A: FloatArray,
    B: FloatArray | None,
    max_condition: float,
    batch_shape: tuple[int, ...],
) -> FloatArray:
    """Square undamped solve ``X = A^-1 B`` by LU, after checking ``cond_2(A)``.

    LU (partial pivoting) is accurate to ``~cond(A) eps``; ``cond_2(A)`` is only checked,
    first by :func:`_condition_bound` (~10x cheaper than singular values), then exactly
    where that does not clear ``max_condition`` (always for ``cond_2(A) >~ 1e7``). Input
    far from unit scale is solved scaled, as in :func:`_gram_kernel`.
    """
    N, m, _ = A.shape
    rhs = np.broadcast_to(np.eye(m), (N, m, m)) if B is None else B
    screen_rhs = np.empty((N, m, 0)) if B is None else B  # I needs no scaling
    _, ok, kappa_up, exponents = _gram_bound_and_solve(A, screen_rhs, 0.0, 0)
    exponent, column_exponent = exponents[:, 0], exponents[:, 1:]
    kappa = _condition_bound(kappa_up, ok, m, m)
    unsure = np.flatnonzero(~(kappa <= max_condition))
    if unsure.size:
        kappa[unsure] = _condition_flat(_ldexp(A[unsure], -exponent[unsure, None, None]))
    if np.any(kappa > max_condition):
        j = int(np.argmax(kappa))
        index = np.unravel_index(j, batch_shape) if batch_shape else ()
        raise SingularMatrixError(
            float(kappa[j]),
            f"A{list(index) if index else ''} is numerically singular: cond_2(A) exceeds "
            f"max_condition={max_condition:.3g}; pass damping > 0 for the damped answer",
        )
    if B is None:
        column_exponent = np.zeros((N, 1), dtype=np.int64)
    is_far = (exponent != 0) | np.any(column_exponent != 0, axis=1)
    try:
        if not is_far.any():
            X: FloatArray = np.linalg.solve(A, rhs).astype(np.float64, copy=False)
            return X
        X = np.empty((N, m, rhs.shape[-1]))
        near, far = np.flatnonzero(~is_far), np.flatnonzero(is_far)
        X[near] = np.linalg.solve(A[near], rhs[near])
        e = exponent[far][:, None, None]
        f = column_exponent[far][:, None, :]
        Xs = np.linalg.solve(_ldexp(A[far], -e), _ldexp(rhs[far], -f))
        # Unscaled (|exponents| <= 64, cond_2 <= 1e14) answers cannot overflow; these can.
        X[far] = _representable(_ldexp(Xs.astype(np.float64, copy=False), f - e))
    except np.linalg.LinAlgError as exc:  # pragma: no cover - excluded by the check above
        raise SingularMatrixError(float("inf"), "LU found an exactly singular matrix") from exc
    return X


def _condition_flat(A: FloatArray) -> FloatArray:
    """``cond_2`` of each matrix of a flat stack (N, m, n), ``inf`` when rank deficient."""
    s = np.linalg.svd(A, compute_uv=False)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        kappa: FloatArray = np.where(s[:, -1] > 0.0, s[:, 0] / s[:, -1], np.inf)
    return kappa


# ---------------------------------------------------------------------------- dispatch

_Kind = Literal["min_norm", "least_squares", "square", "any"]


def _solve(
    A: Any,
    b: Any,
    damping: float,
    max_condition: float,
    kind: _Kind,
) -> FloatArray:
    """Validate, flatten the stack, dispatch on shape and damping, restore the shape."""
    A_arr = _check_matrix(A)
    lam, max_condition = _check_scalars(damping, max_condition)
    m, n = A_arr.shape[-2:]
    if b is None:
        B_arr, vector, k = None, False, m
    else:
        B_arr, vector = _check_rhs(b, A_arr)
        k = 1 if vector else B_arr.shape[-1]
    if lam == 0.0:
        if kind == "min_norm" and m > n:
            raise ShapeError("A", "(..., m, n) with m <= n (or damping > 0)", A_arr.shape)
        if kind == "least_squares" and m < n:
            raise ShapeError("A", "(..., m, n) with m >= n (or damping > 0)", A_arr.shape)
        if kind == "square" and m != n:
            raise ShapeError("A", "(..., n, n) (or damping > 0)", A_arr.shape)

    batch_shape = A_arr.shape[:-2]
    N = math.prod(batch_shape)
    out_shape = (*batch_shape, n) if vector else (*batch_shape, n, k)
    if N == 0:
        return np.zeros(out_shape)
    A3 = A_arr.reshape(N, m, n)
    B3 = None if B_arr is None else B_arr.reshape(N, m, k)
    if lam == 0.0 and m == n:
        X = _lu_solve(A3, B3, max_condition, batch_shape)
    else:
        X = _gram_solve(A3, B3, lam, max_condition, batch_shape)
    result: FloatArray = X.reshape(out_shape)
    return result


# ------------------------------------------------------------------------------ public


def min_norm(
    A: Any, b: Any, *, damping: float = 0.0, max_condition: float = MAX_CONDITION
) -> FloatArray:
    """Minimum-norm solution of the underdetermined system ``A x = b`` (m <= n).

    Solves ``min ||x||^2 s.t. A x = b`` in closed form, ``x = A^T (A A^T)^-1 b`` (seed 000,
    eq. 48/62), as ``x = A^T u`` with ``(A A^T) u = b`` solved by Cholesky; a square ``A``
    is solved directly by LU. With ``damping = lambda > 0`` it returns the damped
    minimum-norm answer ``A^T (A A^T + lambda^2 I)^-1 b`` for any shape, which minimizes
    ``||A x - b||^2 + lambda^2 ||x||^2``.

    Args:
        A: matrix or stack of matrices, shape ``(..., m, n)``, ``m <= n`` unless damped.
        b: right-hand side, shape ``(..., m)`` or ``(..., m, k)``; the same batch axes.
        damping: ``lambda >= 0``, in the units of ``A`` (``b / x``); below ``2^-511``
            (~1.5e-154) it counts as 0, no damping.
        max_condition: undamped, ``cond_2(A)`` above this raises (default 1e12); finite,
            in ``[1, CONDITION_CEILING]`` (1e14).

    Returns:
        ``x`` of shape ``(..., n)`` or ``(..., n, k)``.

    Raises:
        ShapeError: ``A`` or ``b`` has a wrong shape, or ``m > n`` undamped.
        NonFiniteError: ``A``, ``b`` or ``damping`` holds NaN or infinity.
        SingularMatrixError: undamped and ``cond_2(A) > max_condition`` (rank deficient);
            its ``condition_number`` is the worst ``cond_2(A)`` in the stack.
        ArgumentError: ``damping`` is not a real number in ``[0, MAX_DAMPING]``, or
            ``max_condition`` not a real number in ``[1, CONDITION_CEILING]``.
        OptikError: an entry of the answer exceeds float64 (``|x| > 1.8e308``).
    """
    return _solve(A, b, damping, max_condition, "min_norm")


def least_squares(
    A: Any, b: Any, *, damping: float = 0.0, max_condition: float = MAX_CONDITION
) -> FloatArray:
    """Least-squares solution of the overdetermined system ``A x = b`` (m >= n).

    Solves ``min ||A x - b||^2`` in closed form, ``x = (A^T A)^-1 (A^T b)`` (seed 000,
    eq. 47/73), forming ``A^T b`` first (cheaper than eq. 46) and solving the normal
    equations by Cholesky; a square ``A`` is solved directly by LU. With
    ``damping = lambda > 0`` it returns ``(A^T A + lambda^2 I)^-1 A^T b`` for any shape,
    the minimizer of ``||A x - b||^2 + lambda^2 ||x||^2`` (damped least squares).

    The result and the errors are those of :func:`min_norm` (a ``ShapeError`` for
    ``m < n`` undamped).

    Args:
        A: matrix or stack of matrices, shape ``(..., m, n)``, ``m >= n`` unless damped.
        b: right-hand side, shape ``(..., m)`` or ``(..., m, k)``; the same batch axes.
        damping: ``lambda >= 0``, as for :func:`min_norm`.
        max_condition: as for :func:`min_norm` (default 1e12); no unit.
    """
    return _solve(A, b, damping, max_condition, "least_squares")


def solve_square(
    A: Any, b: Any, *, damping: float = 0.0, max_condition: float = MAX_CONDITION
) -> FloatArray:
    """Solve the square system ``A x = b`` directly, ``x = A^-1 b`` (LU, no inverse formed).

    ``cond_2(A)`` is checked first (singular values), so a (near-)singular matrix raises
    instead of returning an LU answer dominated by rounding. With ``damping > 0`` it
    returns the damped answer ``(A^T A + lambda^2 I)^-1 A^T b`` (any shape then).

    The arguments, the result and the errors are those of :func:`min_norm`, with ``A``
    of shape ``(..., n, n)`` (any ``(..., m, n)`` when damped; a ``ShapeError`` for a
    non-square ``A`` undamped).
    """
    return _solve(A, b, damping, max_condition, "square")


def generalized_solve(
    A: Any, b: Any, *, damping: float = 0.0, max_condition: float = MAX_CONDITION
) -> FloatArray:
    """Solve ``A x = b`` by the closed form its shape calls for, ``x = A^+ b``.

    Dispatches to :func:`min_norm` (m < n), :func:`solve_square` (m = n) or
    :func:`least_squares` (m > n); with ``damping > 0`` all three return the same damped
    answer ``(A^T A + lambda^2 I)^-1 A^T b``.

    The arguments, the result and the errors are those of :func:`min_norm`, with ``A``
    of any shape ``(..., m, n)``, ``m, n >= 1``.
    """
    return _solve(A, b, damping, max_condition, "any")


def generalized_inverse(
    A: Any, *, damping: float = 0.0, max_condition: float = MAX_CONDITION
) -> FloatArray:
    """The generalized inverse ``A^+`` of a full-rank ``A``, dispatching on shape.

    ``A^T (A A^T)^-1`` for ``m < n`` (right inverse), ``A^-1`` for ``m = n`` and
    ``(A^T A)^-1 A^T`` for ``m > n`` (left inverse) — for full rank all equal the
    Moore-Penrose pseudoinverse. Computed by solving with the identity as right-hand side
    (``(A^T A) X = A^T`` for ``m > n``), never by inverting the Gram matrix and
    multiplying. With ``damping = lambda > 0``: ``(A^T A + lambda^2 I)^-1 A^T``.

    Args:
        A: shape ``(..., m, n)``.
        damping: ``lambda >= 0``, as for :func:`min_norm`.
        max_condition: as for :func:`min_norm`.

    Returns:
        ``A^+`` of shape ``(..., n, m)``.

    Raises:
        ShapeError: ``A`` is not ``(..., m, n)`` with ``m, n >= 1``.
        NonFiniteError: ``A`` holds NaN or infinity.
        SingularMatrixError: undamped and ``cond_2(A) > max_condition``.
        ArgumentError: ``damping`` or ``max_condition`` out of range (see :func:`min_norm`).
        OptikError: an entry of ``A^+`` exceeds float64.
    """
    return _solve(A, None, damping, max_condition, "any")


def condition_number(A: Any) -> FloatArray:
    """Spectral condition number ``cond_2(A) = s_max / s_min`` of each matrix.

    ``s_min`` is the smallest of the ``min(m, n)`` singular values, so this is the
    condition number relevant to :func:`min_norm` and :func:`least_squares`; it is
    ``inf`` when ``s_min = 0`` (including the zero matrix).

    Args:
        A: shape ``(..., m, n)``.

    Returns:
        Array of shape ``(...)`` (a 0-d array for one matrix).

    Raises:
        ShapeError: ``A`` is not ``(..., m, n)`` with ``m, n >= 1``.
        NonFiniteError: ``A`` holds NaN or infinity.
    """
    A_arr = _check_matrix(A)
    batch_shape = A_arr.shape[:-2]
    N = math.prod(batch_shape)
    if N == 0:
        return np.zeros(batch_shape)
    kappa: FloatArray = _condition_flat(A_arr.reshape(N, *A_arr.shape[-2:])).reshape(batch_shape)
    return kappa


def multiplication_count(
    m: int,
    n: int,
    order: Literal["eq46", "eq47"],
    *,
    k: int = 1,
    include_gram: bool = False,
) -> int:
    """Scalar multiplications to form the least-squares product from ``(A^T A)^-1``.

    ``A`` is ``m x n``, ``B`` is ``m x k``; the inverse ``(A^T A)^-1`` (``n x n``) is
    taken as given, its cost being the same in both orders (schoolbook products, a
    ``p x q`` times ``q x r`` product costing ``p q r``):

    * ``"eq46"``: ``((A^T A)^-1 A^T) B`` costs ``n^2 m + n m k``;
    * ``"eq47"``: ``(A^T A)^-1 (A^T B)`` costs ``n m k + n^2 k``.

    Their difference is ``n^2 (m - k)``: for one right-hand side (``k = 1``) eq. 47 is
    never worse, and strictly cheaper once ``m > 1``. ``include_gram`` adds the ``n^2 m``
    of forming ``A^T A`` (without exploiting symmetry) to both.

    Args:
        m: rows of ``A`` (>= 1).
        n: columns of ``A`` (>= 1).
        order: ``"eq46"`` or ``"eq47"``.
        k: columns of ``B`` (>= 1).
        include_gram: also count ``A^T A``.

    Returns:
        The number of scalar multiplications.

    Raises:
        OptikError: a dimension below 1 or an unknown ``order``.
    """
    for name, value in (("m", m), ("n", n), ("k", k)):
        if int(value) != value or value < 1:
            raise OptikError(f"{name} must be an integer >= 1, got {value!r}")
    m, n, k = int(m), int(n), int(k)
    if order == "eq46":
        count = n * n * m + n * m * k
    elif order == "eq47":
        count = n * m * k + n * n * k
    else:
        raise OptikError(f"order must be 'eq46' or 'eq47', got {order!r}")
    return count + (n * n * m if include_gram else 0)
