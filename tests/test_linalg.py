"""Tests of optik.linalg: closed-form generalized inverses (seed 000, section V).

References are independent of the code under test: numpy.linalg.pinv / lstsq, exact
rational arithmetic (fractions), the optimality (KKT) conditions of each program with the
singular vectors the test matrices are built from, and the Penrose conditions.
"""

from __future__ import annotations

import itertools
from collections.abc import Callable
from fractions import Fraction

import numpy as np
import pytest

from optik.errors import NonFiniteError, OptikError, ShapeError, SingularMatrixError
from optik.linalg import (
    GRAM_CONDITION_LIMIT,
    MAX_CONDITION,
    condition_number,
    generalized_inverse,
    generalized_solve,
    least_squares,
    min_norm,
    multiplication_count,
    solve_square,
)

EPS = float(np.finfo(np.float64).eps)
DECADES = [10.0**e for e in range(2, 11)]  # condition numbers 1e2 .. 1e10
SHAPES = [(6, 7), (7, 6), (6, 6), (3, 8), (8, 3), (1, 4), (4, 1), (1, 1)]
STACKS = [(), (5,), (40,), (2, 3)]  # single, short (LAPACK loop), long (stack-last), 2-D


# ----------------------------------------------------------------------------- helpers


def tolerance(kappa: float) -> float:
    """Documented relative accuracy for a matrix with ``cond_2(A) = kappa``.

    The Gram path is taken only when its bound on ``cond_2(G) = kappa^2`` is at most
    ``GRAM_CONDITION_LIMIT``, and is accurate to ``~0.5 kappa^2 eps``; otherwise the SVD
    path is accurate to ``~10 kappa eps`` (docs/theory.md, measured against exact rational
    answers). The factors 4 and 64 leave a margin of about 8x over the worst measured.
    """
    if kappa * kappa <= GRAM_CONDITION_LIMIT:
        return 4.0 * EPS * max(kappa, 1.0) ** 2
    return 64.0 * EPS * kappa


def assert_rel_close(actual: np.ndarray, expected: np.ndarray, rtol: float, what: str = "") -> None:
    """Per-solution relative error (2-norm over the last axis) <= rtol; rejects NaN/inf."""
    actual = np.asarray(actual)
    expected = np.asarray(expected)
    assert actual.shape == expected.shape, (what, actual.shape, expected.shape)
    assert np.isfinite(actual).all(), f"{what}: non-finite values in the answer"
    assert np.isfinite(expected).all(), f"{what}: non-finite values in the reference"
    scale = np.maximum(np.linalg.norm(expected, axis=-1, keepdims=True), np.finfo(float).tiny)
    err = float((np.linalg.norm(actual - expected, axis=-1, keepdims=True) / scale).max())
    assert err <= rtol, f"{what}: relative error {err:.3g} > {rtol:.3g}"


def random_orthogonal(rng: np.random.Generator, stack: tuple[int, ...], n: int) -> np.ndarray:
    q, r = np.linalg.qr(rng.standard_normal((*stack, n, n)))
    return q * np.sign(np.diagonal(r, axis1=-2, axis2=-1))[..., None, :]


def conditioned(
    rng: np.random.Generator, stack: tuple[int, ...], m: int, n: int, kappa: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``A = U diag(s) V^T`` with ``s`` log-spaced from 1 to ``1/kappa``; returns A, U, V."""
    r = min(m, n)
    U = random_orthogonal(rng, stack, m)
    V = random_orthogonal(rng, stack, n)
    s = np.logspace(0.0, -np.log10(kappa), r) if r > 1 else np.ones(1)
    S = np.zeros((m, n))
    S[np.arange(r), np.arange(r)] = s
    return U @ S @ np.swapaxes(V, -1, -2), U, V


def pinv_solution(A: np.ndarray, b: np.ndarray) -> np.ndarray:
    return (np.linalg.pinv(A, rcond=1e-300) @ b[..., None])[..., 0]


def lstsq_solution(A: np.ndarray, b: np.ndarray) -> np.ndarray:
    flat_A = A.reshape(-1, *A.shape[-2:])
    flat_b = b.reshape(-1, A.shape[-2])
    x = [np.linalg.lstsq(Ai, bi, rcond=None)[0] for Ai, bi in zip(flat_A, flat_b, strict=True)]
    return np.array(x).reshape(*A.shape[:-2], A.shape[-1])


def solver_for(m: int, n: int) -> Callable[..., np.ndarray]:
    return min_norm if m < n else least_squares if m > n else solve_square


def exact_solution(A: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The closed form of the shape in exact rational arithmetic (no rounding at all)."""
    m, n = A.shape
    Af = [[Fraction(float(v)) for v in row] for row in A]
    bf = [Fraction(float(v)) for v in b]

    def solve(M: list[list[Fraction]], v: list[Fraction]) -> list[Fraction]:
        size = len(M)
        W = [[*row, v[i]] for i, row in enumerate(M)]
        for col in range(size):
            piv = next(r for r in range(col, size) if W[r][col] != 0)
            W[col], W[piv] = W[piv], W[col]
            for r in range(size):
                if r != col and W[r][col] != 0:
                    f = W[r][col] / W[col][col]
                    W[r] = [x - f * y for x, y in zip(W[r], W[col], strict=True)]
        return [W[i][size] / W[i][i] for i in range(size)]

    if m < n:  # x = A^T (A A^T)^-1 b
        G = [[sum(Af[i][k] * Af[j][k] for k in range(n)) for j in range(m)] for i in range(m)]
        u = solve(G, bf)
        return np.array([float(sum(Af[i][j] * u[i] for i in range(m))) for j in range(n)])
    if m > n:  # x = (A^T A)^-1 A^T b
        G = [[sum(Af[k][i] * Af[k][j] for k in range(m)) for j in range(n)] for i in range(n)]
        rhs = [sum(Af[k][i] * bf[k] for k in range(m)) for i in range(n)]
        return np.array([float(v) for v in solve(G, rhs)])
    return np.array([float(v) for v in solve(Af, bf)])


# ------------------------------------------------------------------ random full rank


@pytest.mark.parametrize("stack", STACKS)
@pytest.mark.parametrize(("m", "n"), SHAPES)
def test_matches_pinv_and_lstsq(stack: tuple[int, ...], m: int, n: int) -> None:
    rng = np.random.default_rng(hash((stack, m, n)) % 2**32)
    A = rng.standard_normal((*stack, m, n))
    b = rng.standard_normal((*stack, m))
    kappa = float(np.max(np.linalg.cond(A))) if A.size else 1.0
    x = solver_for(m, n)(A, b)
    assert x.shape == (*stack, n)
    assert_rel_close(x, pinv_solution(A, b), tolerance(kappa) + 16 * EPS * kappa, "vs pinv")
    assert_rel_close(generalized_solve(A, b), x, 1e-15 * max(kappa, 1.0) ** 2, "dispatch")
    if m >= n:
        assert_rel_close(x, lstsq_solution(A, b), tolerance(kappa) + 16 * EPS * kappa, "lstsq")


@pytest.mark.parametrize(("m", "n"), [(6, 7), (7, 6), (6, 6)])
def test_matrix_right_hand_side_is_column_by_column(m: int, n: int) -> None:
    rng = np.random.default_rng(3)
    A = rng.standard_normal((30, m, n))
    B = rng.standard_normal((30, m, 4))
    X = solver_for(m, n)(A, B)
    assert X.shape == (30, n, 4)
    expected = np.linalg.pinv(A) @ B
    kappa = float(np.linalg.cond(A).max())
    for j in range(4):
        assert_rel_close(X[..., j], expected[..., j], tolerance(kappa) + 16 * EPS * kappa)


# ------------------------------------------------------------------ ill-conditioned


@pytest.mark.parametrize("kappa", DECADES)
@pytest.mark.parametrize(("m", "n"), [(6, 7), (7, 6), (6, 6), (2, 9)])
@pytest.mark.parametrize("stack", [(4,), (32,)])
def test_condition_decades_against_pinv_and_kkt(
    kappa: float, m: int, n: int, stack: tuple[int, ...]
) -> None:
    rng = np.random.default_rng(int(np.log10(kappa)) * 100 + m * 10 + n + stack[0])
    A, _, V = conditioned(rng, stack, m, n, kappa)
    b = rng.standard_normal((*stack, m))
    x = solver_for(m, n)(A, b)
    # pinv is itself accurate only to ~kappa eps: add its share to the tolerance.
    assert_rel_close(x, pinv_solution(A, b), tolerance(kappa) + 16 * EPS * kappa, "pinv")

    # Optimality (KKT) conditions, with the singular vectors the matrices are built from.
    x_norm = np.linalg.norm(x, axis=-1)
    if m <= n:
        # min ||x|| s.t. A x = b: feasible, and x = A^T u lies in the row space, i.e. has
        # no component along the null space V[:, m:].
        residual = np.linalg.norm((A @ x[..., None])[..., 0] - b, axis=-1)
        assert (residual <= 64 * EPS * kappa * x_norm).all()
        null = np.swapaxes(V[..., :, m:], -1, -2) @ x[..., None]
        assert (np.linalg.norm(null[..., 0], axis=-1) <= 64 * EPS * kappa * x_norm).all()
    else:
        # min ||A x - b||: the residual is orthogonal to the columns, A^T (A x - b) = 0.
        r = (A @ x[..., None])[..., 0] - b
        grad = np.linalg.norm((np.swapaxes(A, -1, -2) @ r[..., None])[..., 0], axis=-1)
        scale = np.linalg.norm(r, axis=-1) + x_norm  # ||A|| = 1
        assert (grad <= 64 * EPS * kappa * scale).all()


@pytest.mark.parametrize("kappa", [1e2, 1e5, 1e8, 1e10])
@pytest.mark.parametrize(("m", "n"), [(6, 7), (7, 6), (5, 5)])
def test_condition_decades_against_exact_rational_answer(kappa: float, m: int, n: int) -> None:
    rng = np.random.default_rng(int(np.log10(kappa)) + 7 * m + n)
    A, _, _ = conditioned(rng, (3,), m, n, kappa)
    b = rng.standard_normal((3, m))
    x = solver_for(m, n)(A, b)
    exact = np.array([exact_solution(A[i], b[i]) for i in range(3)])
    assert_rel_close(x, exact, tolerance(kappa), "exact")


# ------------------------------------------------------------- generalized inverse


@pytest.mark.parametrize("stack", [(), (3,), (40,)])
@pytest.mark.parametrize(("m", "n"), SHAPES)
def test_penrose_conditions(stack: tuple[int, ...], m: int, n: int) -> None:
    rng = np.random.default_rng(m * 31 + n + len(stack))
    A, _, _ = conditioned(rng, stack, m, n, 1e3)
    P = generalized_inverse(A)
    assert P.shape == (*stack, n, m)
    tol = 64 * EPS * 1e3 * 1e3  # ||A|| = 1, ||P|| = 1e3
    AP, PA = A @ P, P @ A
    assert np.abs(AP @ A - A).max() <= tol  # A P A = A
    assert np.abs(PA @ P - P).max() <= tol * 1e3  # P A P = P (entries of P are ~1e3)
    assert np.abs(AP - np.swapaxes(AP, -1, -2)).max() <= tol  # (A P)^T = A P
    assert np.abs(PA - np.swapaxes(PA, -1, -2)).max() <= tol  # (P A)^T = P A
    assert np.abs(P - np.linalg.pinv(A)).max() <= tol * 1e3


# ------------------------------------------------------------------- batch vs single


@pytest.mark.parametrize(("m", "n"), [(6, 7), (7, 6), (6, 6), (3, 8)])
@pytest.mark.parametrize("damping", [0.0, 0.05])
def test_batched_equals_per_matrix(m: int, n: int, damping: float) -> None:
    rng = np.random.default_rng(11 + m + n)
    # a mixture of conditions, so one stack is split between the Gram and SVD paths
    kappas = [10.0 ** rng.uniform(0, 9) for _ in range(48)]
    A = np.stack([conditioned(rng, (), m, n, k)[0] for k in kappas])
    b = rng.standard_normal((48, m))
    if damping == 0.0:
        batched = solver_for(m, n)(A, b)
        single = np.stack([solver_for(m, n)(A[i], b[i]) for i in range(48)])
    else:
        batched = generalized_solve(A, b, damping=damping)
        single = np.stack([generalized_solve(A[i], b[i], damping=damping) for i in range(48)])
    for i, kappa in enumerate(kappas):
        assert_rel_close(batched[i], single[i], 2 * tolerance(kappa), f"matrix {i}")


def test_multi_axis_batch_shape() -> None:
    rng = np.random.default_rng(5)
    A = rng.standard_normal((2, 3, 4, 6, 7))
    b = rng.standard_normal((2, 3, 4, 6))
    x = min_norm(A, b)
    assert x.shape == (2, 3, 4, 7)
    assert_rel_close(x[1, 2, 3], pinv_solution(A[1, 2, 3], b[1, 2, 3]), 1e-10)


def test_empty_stack() -> None:
    assert min_norm(np.zeros((0, 6, 7)), np.zeros((0, 6))).shape == (0, 7)
    assert generalized_inverse(np.zeros((0, 7, 6))).shape == (0, 6, 7)


# ------------------------------------------------------------------ rank deficiency


@pytest.mark.parametrize(("m", "n"), [(6, 7), (7, 6), (6, 6)])
@pytest.mark.parametrize("stack", [(), (3,), (40,)])
def test_singular_raises_with_condition_number(m: int, n: int, stack: tuple[int, ...]) -> None:
    rng = np.random.default_rng(17)
    A = rng.standard_normal((*stack, m, n))
    # make one matrix rank deficient: a duplicated row (wide/square) or column (tall)
    target = A[(0,) * len(stack)]
    if m <= n:
        target[1] = target[0]
    else:
        target[:, 1] = target[:, 0]
    b = rng.standard_normal((*stack, m))
    with pytest.raises(SingularMatrixError) as info:
        solver_for(m, n)(A, b)
    assert info.value.condition_number > MAX_CONDITION
    with pytest.raises(SingularMatrixError):
        generalized_inverse(A)


@pytest.mark.parametrize(("m", "n"), [(6, 7), (7, 6), (6, 6)])
@pytest.mark.parametrize("stack", [(), (3,), (40,)])
def test_nearly_singular_raises_in_any_stack(m: int, n: int, stack: tuple[int, ...]) -> None:
    # Not exactly singular (LU and Cholesky may run through): only the condition check
    # stands between the caller and an answer with no correct digit.
    rng = np.random.default_rng(19)
    A = rng.standard_normal((*stack, m, n))
    bad, _, _ = conditioned(rng, (), m, n, 1e14)
    A[(-1,) * len(stack)] = bad
    b = rng.standard_normal((*stack, m))
    with pytest.raises(SingularMatrixError) as info:
        solver_for(m, n)(A, b)
    assert info.value.condition_number == pytest.approx(1e14, rel=0.05)


def test_zero_matrix_has_infinite_condition() -> None:
    with pytest.raises(SingularMatrixError) as info:
        min_norm(np.zeros((3, 5)), np.ones(3))
    assert info.value.condition_number == np.inf
    assert condition_number(np.zeros((3, 5))) == np.inf


@pytest.mark.parametrize(("m", "n"), [(6, 7), (7, 6), (6, 6)])
def test_max_condition_is_enforced_and_reported(m: int, n: int) -> None:
    rng = np.random.default_rng(23)
    A, _, _ = conditioned(rng, (), m, n, 1e8)
    b = rng.standard_normal(m)
    solver_for(m, n)(A, b)  # 1e8 < 1e12: accepted by default
    with pytest.raises(SingularMatrixError) as info:
        solver_for(m, n)(A, b, max_condition=1e6)
    assert info.value.condition_number == pytest.approx(1e8, rel=1e-6)


def test_condition_number_matches_numpy() -> None:
    rng = np.random.default_rng(29)
    for m, n in [(6, 7), (7, 6), (5, 5)]:
        A, _, _ = conditioned(rng, (4,), m, n, 1e6)
        assert condition_number(A) == pytest.approx(np.linalg.cond(A), rel=1e-6)
        assert condition_number(A[0]).shape == ()


# --------------------------------------------------------------------------- damping


def stacked_damped_reference(A: np.ndarray, b: np.ndarray, lam: float) -> np.ndarray:
    """argmin ||A x - b||^2 + lam^2 ||x||^2 as the plain least-squares problem
    [A; lam I] x ~ [b; 0], solved by lstsq (an orthogonal method, not normal equations)."""
    n = A.shape[-1]
    big = np.vstack([A, lam * np.eye(n)])
    return np.linalg.lstsq(big, np.concatenate([b, np.zeros(n)]), rcond=None)[0]


@pytest.mark.parametrize(("m", "n"), [(6, 7), (7, 6), (6, 6), (2, 5)])
@pytest.mark.parametrize("lam", [1e-3, 0.1, 10.0])
@pytest.mark.parametrize("rank_deficient", [False, True])
@pytest.mark.parametrize("stack", [(3,), (40,)])
def test_damped_closed_form(
    m: int, n: int, lam: float, rank_deficient: bool, stack: tuple[int, ...]
) -> None:
    rng = np.random.default_rng(int(lam * 1000) + m + n + len(stack))
    A = rng.standard_normal((*stack, m, n))
    if rank_deficient:
        A[..., -1, :] = A[..., 0, :]  # no error when damped: the answer is well defined
    b = rng.standard_normal((*stack, m))
    expected = np.stack([stacked_damped_reference(A[i], b[i], lam) for i in range(stack[0])])
    # The damped answer solves the least-squares problem [A; lam I] x ~ [b; 0], whose
    # relative sensitivity is kappa + kappa^2 ||r|| / (||A~|| ||x||) (Higham, ASNA,
    # Thm. 20.1), kappa = cond_2([A; lam I]): with b far from the range of A the residual
    # term dominates, for the reference as for the code under test.
    s = np.linalg.svd(A, compute_uv=False)
    norm_big = np.sqrt(s[:, 0] ** 2 + lam**2)
    kappa = np.sqrt((s[:, 0] ** 2 + lam**2) / (s[:, -1] ** 2 + lam**2))
    r = np.concatenate([(A @ expected[..., None])[..., 0] - b, lam * expected], axis=-1)
    sensitivity = kappa + kappa**2 * np.linalg.norm(r, axis=-1) / (
        norm_big * np.linalg.norm(expected, axis=-1)
    )
    # plus the documented accuracy of the method for cond(A~) = kappa (Gram or SVD path)
    tol = max(tolerance(float(k)) for k in kappa) + 64 * EPS * float(sensitivity.max())
    for solver in (min_norm, least_squares, generalized_solve, solve_square):
        assert_rel_close(solver(A, b, damping=lam), expected, tol, solver.__name__)
    P = generalized_inverse(A, damping=lam)
    assert_rel_close((P @ b[..., None])[..., 0], expected, tol, "generalized_inverse")


def test_tiny_damping_still_never_raises_and_matches_svd_filter() -> None:
    rng = np.random.default_rng(31)
    A = rng.standard_normal((6, 7))
    A[5] = A[4]  # rank 5
    b = rng.standard_normal(6)
    lam = 1e-9
    U, s, Vt = np.linalg.svd(A, full_matrices=False)
    expected = Vt.T @ ((s / (s**2 + lam**2)) * (U.T @ b))  # Tikhonov filter factors
    assert_rel_close(min_norm(A, b, damping=lam), expected, 1e-6)


# ------------------------------------------------------------------- scale extremes


@pytest.mark.parametrize("scale", [1e-200, 1e-100, 1e100, 1e200])
@pytest.mark.parametrize(("m", "n"), [(6, 7), (7, 6)])
@pytest.mark.parametrize("stack", [(), (40,)])
def test_extreme_scales_route_around_gram_overflow(
    scale: float, m: int, n: int, stack: tuple[int, ...]
) -> None:
    # The Gram matrix of A * 1e200 overflows and that of A * 1e-200 underflows; the answer
    # must still be right (x scales as 1 / scale, b is kept O(1)).
    rng = np.random.default_rng(37)
    A = rng.standard_normal((*stack, m, n))
    b = rng.standard_normal((*stack, m))
    kappa = float(np.max(np.linalg.cond(A)))
    x = solver_for(m, n)(A * scale, b)
    assert_rel_close(x * scale, pinv_solution(A, b), tolerance(kappa) + 16 * EPS * kappa)


# --------------------------------------------------------------------------- errors


def test_bad_shapes_raise_shape_error() -> None:
    with pytest.raises(ShapeError) as info:
        min_norm(np.ones(3), np.ones(3))
    assert info.value.name == "A"
    with pytest.raises(ShapeError) as info:
        min_norm(np.ones((3, 5)), np.ones(4))
    assert info.value.name == "b"
    with pytest.raises(ShapeError):
        min_norm(np.ones((2, 3, 5)), np.ones((3, 3)))  # batch axes differ
    with pytest.raises(ShapeError):
        min_norm(np.ones((0, 5)), np.ones(0))
    with pytest.raises(ShapeError):
        min_norm(np.ones((5, 3)), np.ones(5))  # tall, undamped
    with pytest.raises(ShapeError):
        least_squares(np.ones((3, 5)), np.ones(3))  # wide, undamped
    with pytest.raises(ShapeError):
        solve_square(np.ones((3, 5)), np.ones(3))
    with pytest.raises(ShapeError):
        generalized_inverse([[1.0, 2.0], [3.0]])  # ragged


def test_non_finite_input_raises_non_finite_error() -> None:
    A = np.eye(3)
    A[1, 2] = np.nan
    with pytest.raises(NonFiniteError) as info:
        solve_square(A, np.ones(3))
    assert info.value.name == "A" and info.value.index == (1, 2)
    with pytest.raises(NonFiniteError) as info:
        min_norm(np.ones((2, 3)), np.array([1.0, np.inf]))
    assert info.value.name == "b"
    with pytest.raises(NonFiniteError):
        min_norm(np.ones((2, 3)), np.ones(2), damping=np.nan)
    # huge but finite entries are not rejected by the fast screen
    assert np.isfinite(solve_square(np.eye(2) * 1e300, np.ones(2))).all()


def test_bad_parameters_raise_optik_error() -> None:
    with pytest.raises(OptikError):
        min_norm(np.eye(2), np.ones(2), damping=-1.0)
    with pytest.raises(OptikError):
        min_norm(np.eye(2), np.ones(2), max_condition=0.5)


# ------------------------------------------------------------ multiplication counts


class Counted:
    """A scalar that counts its multiplications (to check the closed-form counts)."""

    count = 0

    def __init__(self, value: float) -> None:
        self.value = value

    def __mul__(self, other: Counted) -> Counted:
        Counted.count += 1
        return Counted(self.value * other.value)

    def __add__(self, other: Counted) -> Counted:
        return Counted(self.value + other.value)


def naive_matmul(X: list[list[Counted]], Y: list[list[Counted]]) -> list[list[Counted]]:
    out = []
    for row in X:
        out_row = []
        for j in range(len(Y[0])):
            acc = row[0] * Y[0][j]
            for k in range(1, len(Y)):
                acc = acc + row[k] * Y[k][j]
            out_row.append(acc)
        out.append(out_row)
    return out


def counted_product(m: int, n: int, k: int, order: str) -> tuple[int, np.ndarray]:
    rng = np.random.default_rng(m * 100 + n * 10 + k)
    A = rng.standard_normal((m, n))
    B = rng.standard_normal((m, k))
    Ginv = np.linalg.inv(A.T @ A)  # given; its cost is the same in both orders

    def wrap(M: np.ndarray) -> list[list[Counted]]:
        return [[Counted(float(v)) for v in row] for row in M]

    Counted.count = 0
    if order == "eq46":
        X = naive_matmul(naive_matmul(wrap(Ginv), wrap(A.T)), wrap(B))
    else:
        X = naive_matmul(wrap(Ginv), naive_matmul(wrap(A.T), wrap(B)))
    return Counted.count, np.array([[v.value for v in row] for row in X])


@pytest.mark.parametrize(("m", "n", "k"), [(2, 1, 1), (5, 3, 1), (7, 6, 1), (6, 2, 3), (4, 4, 9)])
def test_multiplication_counts_match_instrumented_products(m: int, n: int, k: int) -> None:
    c46, x46 = counted_product(m, n, k, "eq46")
    c47, x47 = counted_product(m, n, k, "eq47")
    assert multiplication_count(m, n, "eq46", k=k) == c46
    assert multiplication_count(m, n, "eq47", k=k) == c47
    assert np.allclose(x46, x47)  # same product, different order
    gram = multiplication_count(m, n, "eq47", k=k, include_gram=True)
    assert gram - c47 == n * n * m


def test_eq47_is_never_worse_for_least_squares() -> None:
    for n in range(1, 30):
        for m in range(n + 1, 60):
            for gram in (False, True):
                c46 = multiplication_count(m, n, "eq46", include_gram=gram)
                c47 = multiplication_count(m, n, "eq47", include_gram=gram)
                assert c47 < c46, (m, n)
    # with more right-hand sides than rows the order flips (n^2 (m - k) < 0)
    assert multiplication_count(3, 2, "eq47", k=5) > multiplication_count(3, 2, "eq46", k=5)


def test_multiplication_count_rejects_bad_arguments() -> None:
    with pytest.raises(OptikError):
        multiplication_count(0, 3, "eq47")
    with pytest.raises(OptikError):
        multiplication_count(5, 3, "eq48")  # type: ignore[arg-type]


def test_counts_exceed_none_of_the_seed_printed_formulas_silently() -> None:
    # The seed prints m(n^2 + (m + 1) n) for eq. 46 and m(n^2 + 2 n) for eq. 47; neither
    # is the count of either product (see docs/theory.md). Guard against regressions that
    # would reintroduce them.
    for m, n in itertools.product(range(3, 9), range(2, 6)):
        if m <= n:
            continue
        printed47 = m * (n * n + 2 * n)
        printed46 = m * (n * n + (m + 1) * n)
        assert multiplication_count(m, n, "eq47") != printed47
        assert multiplication_count(m, n, "eq46") != printed46
