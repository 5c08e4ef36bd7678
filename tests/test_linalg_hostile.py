"""Edge cases of optik.linalg: near-singular square matrices, extreme scales, the limits.

Every reference is independent of the code under test: numpy's ``pinv``, ``lstsq``,
``solve`` and ``svd``/``cond`` on the same (or the unscaled) problem.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
import pytest

from optik.errors import ArgumentError, OptikError, SingularMatrixError
from optik.linalg import (
    CONDITION_CEILING,
    MAX_CONDITION,
    generalized_inverse,
    generalized_solve,
    least_squares,
    min_norm,
    solve_square,
)

Solver = Callable[..., np.ndarray]
ALL_SOLVERS: list[Solver] = [min_norm, least_squares, solve_square, generalized_solve]


def rel_err(actual: np.ndarray, expected: np.ndarray) -> float:
    """Relative 2-norm error over the whole array; inf when ``actual`` is not finite."""
    actual = np.asarray(actual)
    if not np.isfinite(actual).all():
        return float("inf")
    unit = float(np.max(np.abs(expected)))  # norms of 1e-300 entries would underflow
    return float(np.linalg.norm((actual - expected) / unit) / np.linalg.norm(expected / unit))


def with_condition(rng: np.random.Generator, n: int, kappa: float) -> np.ndarray:
    """Random ``n x n`` matrix ``U diag(s) V^T`` with ``s`` log-spaced from 1 to 1/kappa."""
    U, _ = np.linalg.qr(rng.standard_normal((n, n)))
    V, _ = np.linalg.qr(rng.standard_normal((n, n)))
    return (U * np.logspace(0.0, -np.log10(kappa), n)) @ V.T


# ------------------------------------------------ square matrices near singularity

NEAR_SINGULAR = np.array([[1.0, 1.0], [1.0, 1.0 + 1e-13]])  # cond_2 ~ 4e13


@pytest.mark.parametrize("solver", ALL_SOLVERS)
def test_square_near_singular_matrix_is_refused(solver: Solver) -> None:
    kappa = float(np.linalg.cond(NEAR_SINGULAR))
    assert kappa > 10 * MAX_CONDITION  # the premise, by numpy
    with pytest.raises(SingularMatrixError) as info:
        solver(NEAR_SINGULAR, np.array([1.0, 2.0]))
    assert info.value.condition_number == pytest.approx(kappa, rel=0.01)


def test_square_near_singular_inverse_is_refused() -> None:
    with pytest.raises(SingularMatrixError, match="max_condition"):
        generalized_inverse(NEAR_SINGULAR)
    with pytest.raises(SingularMatrixError):
        generalized_inverse(np.stack([np.eye(2), NEAR_SINGULAR, np.eye(2)]))


@pytest.mark.parametrize("n", [2, 3, 6])
def test_square_refused_exactly_above_max_condition(n: int) -> None:
    # Matrices on both sides of 1e12 (by numpy's cond): every one above is refused, every
    # one below returns numpy's solve within the LU accuracy.
    rng = np.random.default_rng(100 + n)
    b = rng.standard_normal(n)
    refused = answered = 0
    for kappa in np.logspace(6.0, 16.0, 41):
        A = with_condition(rng, n, float(kappa))
        true_kappa = float(np.linalg.cond(A))
        if true_kappa > 1.01 * MAX_CONDITION:
            with pytest.raises(SingularMatrixError):
                solve_square(A, b)
            refused += 1
        elif true_kappa < 0.99 * MAX_CONDITION:
            x = solve_square(A, b)
            assert rel_err(x, np.linalg.solve(A, b)) < 64 * np.finfo(float).eps * true_kappa
            answered += 1
    assert refused >= 10 and answered >= 10


def test_small_max_condition_is_enforced_for_well_conditioned_matrices() -> None:
    # cond_2 ~ 20, well inside the fast path, must still be refused under max_condition=10.
    rng = np.random.default_rng(7)
    A = with_condition(rng, 6, 20.0)
    wide = np.hstack([A, np.zeros((6, 1))])
    kappa = float(np.linalg.cond(wide))
    for solver, matrix in ((min_norm, wide), (least_squares, wide.T), (solve_square, A)):
        with pytest.raises(SingularMatrixError) as info:
            solver(matrix, np.ones(matrix.shape[0]), max_condition=10.0)
        assert info.value.condition_number == pytest.approx(kappa, rel=1e-6)
        x = solver(matrix, np.ones(matrix.shape[0]), max_condition=1e3)
        expected = np.linalg.pinv(matrix) @ np.ones(matrix.shape[0])
        assert rel_err(x, expected) < 1e-12


# ------------------------------------------------------------------- extreme scales

B_FIXED = np.array([[1.0, 2.0, 3.0], [4.0, 5.0, 7.0]])
b_FIXED = np.array([1.0, 2.0])
B_RANDOM = np.random.default_rng(2).normal(size=(2, 3))
b_RANDOM = np.random.default_rng(3).normal(size=2)
SCALES = [1e-160, 1e-200, 1e-300, 1e-308, 1e-310, 2.0**-1060, 1e160, 1e300, 2.0**1000]


def posed(M: np.ndarray, scale: float) -> np.ndarray:
    """``M * scale`` as float64 stores it, brought back to unit scale.

    Subnormal products keep few bits (``2^-1060`` leaves ~14), so the reference is the
    problem actually posed; dividing back costs one rounding (relative 1e-16).
    """
    return (M * scale) / scale


@pytest.mark.parametrize("scale", SCALES)
@pytest.mark.parametrize(("B", "b"), [(B_FIXED, b_FIXED), (B_RANDOM, b_RANDOM)])
def test_min_norm_is_scale_invariant(scale: float, B: np.ndarray, b: np.ndarray) -> None:
    expected = np.linalg.pinv(posed(B, scale)) @ posed(b, scale)  # x does not scale
    assert rel_err(min_norm(B * scale, b * scale), expected) < 1e-12
    assert rel_err(generalized_solve(B * scale, b * scale), expected) < 1e-12


@pytest.mark.parametrize("scale", SCALES)
def test_least_squares_is_scale_invariant(scale: float) -> None:
    A = B_RANDOM.T
    c = np.r_[b_RANDOM, 1.0]
    expected = np.linalg.lstsq(posed(A, scale), posed(c, scale), rcond=None)[0]
    assert rel_err(least_squares(A * scale, c * scale), expected) < 1e-12


@pytest.mark.parametrize("scale", SCALES)
def test_square_solve_is_scale_invariant(scale: float) -> None:
    A = np.random.default_rng(5).normal(size=(4, 4))
    c = np.random.default_rng(6).normal(size=4)
    expected = np.linalg.solve(posed(A, scale), posed(c, scale))
    assert rel_err(solve_square(A * scale, c * scale), expected) < 1e-12


@pytest.mark.parametrize("scale", SCALES)
@pytest.mark.parametrize("shape", [(2, 3), (3, 2), (3, 3)])
def test_generalized_inverse_scales_inversely(scale: float, shape: tuple[int, int]) -> None:
    A = np.random.default_rng(11).normal(size=shape)
    with np.errstate(over="ignore"):
        expected = np.linalg.pinv(posed(A, scale)) / scale  # inf where A^+ overflows
    if np.isfinite(expected).all():
        assert rel_err(generalized_inverse(A * scale), expected) < 1e-12
    else:  # entries of A^+ beyond 1.8e308: an error, never inf
        with pytest.raises(OptikError, match="float64"):
            generalized_inverse(A * scale)


def test_scaled_matrix_with_unit_right_hand_side() -> None:
    # Tiny A and an O(1) b: x ~ 1e160, representable, must be right.
    x = min_norm(B_FIXED * 1e-160, b_FIXED)
    expected = np.linalg.pinv(posed(B_FIXED, 1e-160)) @ b_FIXED
    assert rel_err(x * 1e-160, expected) < 1e-12


def test_scaled_stack_mixes_scales() -> None:
    rng = np.random.default_rng(17)
    A = rng.standard_normal((5, 6, 7))
    b = rng.standard_normal((5, 6))
    scales = np.array([1.0, 1e-300, 1e300, 1e-160, 2.0**-1060])
    x = min_norm(A * scales[:, None, None], b * scales[:, None])
    for i, scale in enumerate(scales):
        expected = np.linalg.pinv(posed(A[i], scale)) @ posed(b[i], scale)
        # the fast path's accuracy for cond_2 <~ 1e3 (module docstring): 1e-10
        assert rel_err(x[i], expected) < 1e-10, scale


@pytest.mark.parametrize("scale", [2.0**-400, 2.0**-500, 2.0**300, 2.0**330])
def test_damping_scales_with_the_matrix(scale: float) -> None:
    # Damping is in the units of A: (A s, b s, lambda s) has the answer of (A, b, lambda).
    rng = np.random.default_rng(23)
    A = rng.standard_normal((6, 7))
    A[5] = A[4]  # rank deficient: only the damping makes the answer unique
    b = rng.standard_normal(6)
    lam = 0.3
    stacked = np.vstack([A, lam * np.eye(7)])
    expected = np.linalg.lstsq(stacked, np.r_[b, np.zeros(7)], rcond=None)[0]
    x = min_norm(A * scale, b * scale, damping=lam * scale)
    assert rel_err(x, expected) < 1e-12
    P = generalized_inverse(A.T * scale, damping=lam * scale)  # tall, same Gram size
    assert rel_err((P.T @ b) * scale, expected) < 1e-12  # P = A^+ / scale


def test_answer_beyond_float_range_raises() -> None:
    # x ~ 1e600 cannot be represented: an error, never inf.
    with pytest.raises(OptikError, match="float64"):
        min_norm(B_FIXED * 1e-300, b_FIXED * 1e300)
    with pytest.raises(OptikError, match="float64"):
        solve_square(np.eye(2) * 1e-300, np.ones(2) * 1e300)


# --------------------------------------------------------------- max_condition = inf


@pytest.mark.parametrize("bad", [np.inf, float("nan"), -np.inf])
@pytest.mark.parametrize(
    "call",
    [
        lambda mc: min_norm(np.zeros((2, 3)), np.ones(2), max_condition=mc),
        lambda mc: min_norm(np.ones((2, 3)), np.ones(2), max_condition=mc),
        lambda mc: least_squares(np.zeros((3, 2)), np.ones(3), max_condition=mc),
        lambda mc: generalized_inverse(np.zeros((3, 2)), max_condition=mc),
        lambda mc: solve_square(np.eye(2), np.ones(2), max_condition=mc),
    ],
)
def test_non_finite_max_condition_is_refused(bad: float, call: Callable[[float], Any]) -> None:
    with pytest.raises(ArgumentError, match="max_condition") as info:
        call(bad)
    assert info.value.name == "max_condition"


def test_max_condition_has_a_finite_ceiling() -> None:
    # Past ~1/eps a computed cond_2 is noise (numpy: ones((2, 3)) computes to ~2e16), so a
    # larger max_condition would let an exactly rank-deficient A through; it is refused.
    assert np.linalg.cond(np.ones((2, 3))) > 1e15
    with pytest.raises(ArgumentError, match="max_condition"):
        min_norm(np.ones((2, 3)), np.ones(2), max_condition=1e300)
    for A in (np.zeros((2, 3)), np.ones((2, 3))):
        with pytest.raises(SingularMatrixError):
            min_norm(A, np.ones(2), max_condition=CONDITION_CEILING)
        with pytest.raises(SingularMatrixError):
            generalized_inverse(A.T, max_condition=CONDITION_CEILING)


# --------------------------------------------------------------- the damping threshold

RANK_DEFICIENT = np.array([[1.0, 2.0, 3.0], [2.0, 4.0, 6.0]])  # rank 1


@pytest.mark.parametrize("damping", [1e-160, 2.3e-162, 1e-155, 0.99 * 2.0**-511, 1e-300])
def test_damping_below_threshold_is_no_damping(damping: float) -> None:
    # lambda < 2^-511 (lambda^2 below the normal range) counts as no damping: a
    # rank-deficient A is refused exactly as with damping=0 ...
    for solver in (min_norm, generalized_solve):
        with pytest.raises(SingularMatrixError):
            solver(RANK_DEFICIENT, np.array([1.0, 2.0]), damping=damping)
    # ... and a full-rank A gets the undamped answer.
    expected = np.linalg.pinv(B_FIXED) @ b_FIXED
    assert rel_err(min_norm(B_FIXED, b_FIXED, damping=damping), expected) < 1e-14


def test_damping_at_threshold_is_damping() -> None:
    # lambda = 2^-511: lambda^2 = 2^-1022 is normal, so the damped (never raising) form applies.
    x = min_norm(np.zeros((2, 3)), np.array([1.0, 2.0]), damping=2.0**-511)
    assert np.array_equal(x, np.zeros(3))  # A^T (0 + l^2 I)^-1 b with A = 0
