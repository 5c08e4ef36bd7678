"""Tests of optik.trig: the equation a cos t + b sin t = c (seed 000, eq. 19-22)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from optik.errors import NonFiniteError, OptikError, ShapeError
from optik.trig import TRIG_TOL, solve_trig, solve_trig_batch, solve_trig_zero, wrap_angle

coefficient = st.floats(min_value=-10.0, max_value=10.0, allow_nan=False)
angle = st.floats(min_value=-math.pi, max_value=math.pi, allow_nan=False)


def residual(a: float, b: float, c: float, t: float) -> float:
    return abs(a * math.cos(t) + b * math.sin(t) - c)


def angular_distance(s: float, t: float) -> float:
    """Distance between two angles on the circle, in [0, pi]."""
    return abs(math.remainder(s - t, 2.0 * math.pi))


def assert_well_formed(roots: tuple[float, ...]) -> None:
    """In (-pi, pi], strictly ascending, finite."""
    for t in roots:
        assert math.isfinite(t) and -math.pi < t <= math.pi, roots
    assert list(roots) == sorted(roots) and len(set(roots)) == len(roots), roots


# ----------------------------------------------------------------------- round trips


@settings(max_examples=400, deadline=None, derandomize=True)
@given(a=coefficient, b=coefficient, t=angle)
def test_generated_angle_is_recovered(a: float, b: float, t: float) -> None:
    r = math.hypot(a, b)
    c = a * math.cos(t) + b * math.sin(t)
    roots = solve_trig(a, b, c)
    assert_well_formed(roots)
    if r <= TRIG_TOL:  # degenerate coefficients: the free-joint answer
        assert roots == (0.0,)
        return
    assert roots, (a, b, c)
    for u in roots:
        assert residual(a, b, c, u) <= 2.0 * TRIG_TOL * max(1.0, r) + 1e-15 * max(1.0, r)
    if 1.0 - (c / r) ** 2 > 1e-6 and r - abs(c) > 2.0 * TRIG_TOL * max(1.0, r):
        # Clearly two roots (and beyond the tangent band, absolute below r = 1: a = b =
        # 1e-12 is a tangent): well conditioned (d t = d c / (r |sin(t - phi)|)), so the
        # generating angle is recovered to rounding level and both roots are exact.
        assert len(roots) == 2
        assert min(angular_distance(u, t) for u in roots) <= 1e-9
        for u in roots:
            assert residual(a, b, c, u) <= 1e-14 * max(1.0, r)
    # Nearer tangency only the residual, which is the IK position error, is
    # resolvable; it is checked above.


@settings(max_examples=400, deadline=None, derandomize=True)
@given(a=coefficient, b=coefficient, c=coefficient)
def test_every_returned_angle_solves_and_none_means_none(a: float, b: float, c: float) -> None:
    r = math.hypot(a, b)
    roots = solve_trig(a, b, c)
    assert_well_formed(roots)
    for u in roots:
        # documented worst case (tangent / degenerate bands): 2 tol max(1, r), plus
        # the rounding of the residual itself
        assert residual(a, b, c, u) <= 2.0 * TRIG_TOL * max(1.0, r) + 1e-15 * max(1.0, r)
    if not roots:
        # no solution: |c| exceeds r beyond the tolerance band
        assert abs(c) - r > TRIG_TOL * max(r, 1.0) * 0.5 or r <= TRIG_TOL
    if len(roots) == 2:
        assert c * c < r * r


@pytest.mark.parametrize(
    ("a", "b", "c", "expected"),
    [
        (1.0, 0.0, 0.5, (-math.pi / 3, math.pi / 3)),  # cos t = 1/2
        (0.0, 2.0, 1.0, (math.pi / 6, 5 * math.pi / 6)),  # sin t = 1/2
        (0.0, -1.0, 0.0, (0.0, math.pi)),  # sin t = 0
        (1.0, 1.0, 1.0, (0.0, math.pi / 2)),  # cos t + sin t = 1
        (-3.0, 0.0, 0.0, (-math.pi / 2, math.pi / 2)),  # cos t = 0, a < 0
        (-1.0, 0.0, 0.5, (-2 * math.pi / 3, 2 * math.pi / 3)),  # cos t = -1/2
    ],
)
def test_known_values(a: float, b: float, c: float, expected: tuple[float, float]) -> None:
    roots = solve_trig(a, b, c)
    assert len(roots) == 2
    assert roots == pytest.approx(expected, abs=1e-14)


# --------------------------------------------------------------------- boundary cases


@pytest.mark.parametrize("phi", [-3.0, -1.0, 0.0, 0.7, 2.5, math.pi])
@pytest.mark.parametrize("r", [1e-3, 0.3, 1.0, 250.0])
def test_tangent_root_is_single_and_correct(phi: float, r: float) -> None:
    a, b = r * math.cos(phi), r * math.sin(phi)
    # c = +r: t = phi; c = -r: t = phi + pi
    for c, t in ((r, phi), (-r, phi + math.pi)):
        roots = solve_trig(a, b, c)
        assert len(roots) == 1
        assert angular_distance(roots[0], t) <= 1e-7
        assert -math.pi < roots[0] <= math.pi


def test_tangent_band_edges() -> None:
    # For r = 2 the band on (|c| - r) / r is +/- 1e-12.
    r = 2.0
    inside = r * (1.0 + 5e-13)  # one root
    outside = r * (1.0 + 1e-10)  # no root
    below = r * (1.0 - 1e-10)  # clearly two roots
    assert len(solve_trig(r, 0.0, inside)) == 1
    assert solve_trig(r, 0.0, outside) == ()
    assert len(solve_trig(r, 0.0, below)) == 2
    # with tol = 0 the exact rules apply
    assert solve_trig(r, 0.0, inside, tol=0.0) == ()
    # below 1 the band is absolute: r = 0.1, |c| - r = 5e-13 is inside, 5e-12 is not
    assert len(solve_trig(0.1, 0.0, 0.1 + 5e-13)) == 1
    assert solve_trig(0.1, 0.0, 0.1 + 5e-12) == ()


@pytest.mark.parametrize("r", [1e-9, 1e-7, 1e-5])
def test_small_coefficients_keep_their_roots(r: float) -> None:
    # A wrist centre 1e-7 m from a shoulder axis: r = 1e-7, c = 0 has the two roots
    # phi +/- pi/2. A test on r^2 (1e-14 < 1e-12) would call it free or tangent and
    # return an angle a right angle off; the linear rule keeps both roots.
    phi = 0.7
    roots = solve_trig(r * math.cos(phi), r * math.sin(phi), 0.0, free_value=2.0)
    assert roots == pytest.approx(sorted((phi - math.pi / 2, phi + math.pi / 2)), abs=1e-9)
    # and a near-tangent right-hand side keeps two roots while |c| - r exceeds the band
    c = r * (1.0 - 1e-3)
    assert len(solve_trig(r * math.cos(phi), r * math.sin(phi), c)) == 2


def test_no_solution() -> None:
    assert solve_trig(1.0, 1.0, 1.5) == ()  # r = 1.414
    assert solve_trig(3.0, -4.0, -5.001) == ()
    assert solve_trig(1e-3, 0.0, 1.0) == ()


def test_degenerate_coefficients() -> None:
    # a = b = c = 0: every angle solves it; the caller's value comes back, wrapped.
    assert solve_trig(0.0, 0.0, 0.0) == (0.0,)
    assert solve_trig(0.0, 0.0, 0.0, free_value=0.25) == (0.25,)
    (t,) = solve_trig(0.0, 0.0, 0.0, free_value=1.5 * math.pi)
    assert t == pytest.approx(-0.5 * math.pi, abs=1e-15)
    # a = b = 0 != c: no angle
    assert solve_trig(0.0, 0.0, 1.0) == ()
    assert solve_trig(0.0, 0.0, -1e-3) == ()
    # round-off sized coefficients count as zero (r <= tol and |c| <= tol) ...
    assert solve_trig(1e-13, -2e-13, 1e-13, free_value=0.5) == (0.5,)
    assert solve_trig(1e-13, -2e-13, 1e-11) == ()
    # ... unless tol = 0, where the exact equation has two roots
    roots = solve_trig(1e-9, 0.0, 0.0, tol=0.0)
    assert roots == pytest.approx((-math.pi / 2, math.pi / 2), abs=1e-15)


def test_tiny_magnitudes_do_not_underflow() -> None:
    # a * a underflows below 1e-154: r was 0 (or inexact) and the roots lost (tol=0).
    assert solve_trig(2e-170, 0.0, 1e-170, tol=0.0) == pytest.approx(
        (-math.pi / 3, math.pi / 3), abs=1e-14
    )
    assert solve_trig(1e-170, 0.0, 0.0, tol=0.0) == pytest.approx(
        (-math.pi / 2, math.pi / 2), abs=1e-14
    )
    for t in solve_trig(3e-160, 4e-160, 1e-160, tol=0.0):
        assert abs(3.0 * math.cos(t) + 4.0 * math.sin(t) - 1.0) <= 1e-14


def test_large_magnitudes_do_not_overflow() -> None:
    roots = solve_trig(1e200, 0.0, 5e199)
    assert roots == pytest.approx((-math.pi / 3, math.pi / 3), abs=1e-14)
    assert solve_trig(1e200, 0.0, 2e200) == ()


# -------------------------------------------------------------------------- eq. 21-22


@settings(max_examples=200, deadline=None, derandomize=True)
@given(a=coefficient, b=coefficient)
def test_zero_right_hand_side_matches_independent_formula(a: float, b: float) -> None:
    # a cos t + b sin t = 0  <=>  (cos t, sin t) = +/-(-b, a) / r
    roots = solve_trig_zero(a, b, free_value=0.1)
    if math.hypot(a, b) <= TRIG_TOL:
        assert roots == (0.1,)
        return
    expected = [math.atan2(a, -b), math.atan2(-a, b)]
    assert len(roots) == 2
    for v in expected:
        assert min(angular_distance(u, v) for u in roots) <= 1e-14
    assert angular_distance(roots[0], roots[1]) == pytest.approx(math.pi, abs=1e-14)


# ------------------------------------------------------------------------------ batch


def test_batch_matches_scalar() -> None:
    rng = np.random.default_rng(7)
    n = 600
    a = rng.uniform(-5, 5, n)
    b = rng.uniform(-5, 5, n)
    r = np.hypot(a, b)
    c = r * rng.uniform(-1.3, 1.3, n)  # mix of two roots and none
    # add exact tangents, degenerate coefficients and clear misses
    a[:20], b[:20], c[:20] = 0.0, 0.0, 0.0
    a[20:40], b[20:40], c[20:40] = 0.0, 0.0, 2.0
    c[40:60] = r[40:60]
    c[60:80] = -r[60:80]
    free = rng.uniform(-7, 7, n)
    t_plus, t_minus, valid = solve_trig_batch(a, b, c, free_value=free)
    assert t_plus.shape == t_minus.shape == valid.shape == (n,)
    assert np.isfinite(t_plus).all() and np.isfinite(t_minus).all()
    for i in range(n):
        roots = solve_trig(a[i], b[i], c[i], free_value=free[i])
        assert bool(valid[i]) == bool(roots), i
        if not roots:
            assert t_plus[i] == 0.0 and t_minus[i] == 0.0
            continue
        batch = sorted({float(t_plus[i]), float(t_minus[i])})
        assert len(batch) == len(roots), i
        assert batch == pytest.approx(list(roots), abs=1e-14), i


def test_batch_branch_signs_and_broadcasting() -> None:
    # t+ = atan2(b, a) + atan2(sqrt(r^2 - c^2), c): for cos t = 1/2, t+ = +pi/3.
    t_plus, t_minus, valid = solve_trig_batch(1.0, 0.0, 0.5)
    assert t_plus.shape == ()
    assert float(t_plus) == pytest.approx(math.pi / 3, abs=1e-15)
    assert float(t_minus) == pytest.approx(-math.pi / 3, abs=1e-15)
    assert bool(valid)
    a = np.array([[1.0], [2.0], [0.0]])  # (3, 1)
    b = np.array([[0.0, 1.0, -1.0, 0.5]])  # (1, 4)
    t_plus, t_minus, valid = solve_trig_batch(a, b, 0.0, free_value=0.3)
    assert t_plus.shape == (3, 4)
    for i in range(3):
        for j in range(4):
            ai, bj = float(a[i, 0]), float(b[0, j])
            if ai == 0.0 and bj == 0.0:
                assert t_plus[i, j] == t_minus[i, j] == pytest.approx(0.3)
            else:
                assert residual(ai, bj, 0.0, float(t_plus[i, j])) < 1e-14
                assert residual(ai, bj, 0.0, float(t_minus[i, j])) < 1e-14
    assert valid.all()


def test_batch_invalid_entries_are_zero_not_nan() -> None:
    t_plus, t_minus, valid = solve_trig_batch([1.0, 0.0, 1e200], [0.0, 0.0, 0.0], [3.0, 1.0, 3e200])
    assert not valid.any()
    assert (t_plus == 0.0).all() and (t_minus == 0.0).all()


# ------------------------------------------------------------------------ wrap / errors


@pytest.mark.parametrize(
    ("t", "expected"),
    [
        (math.pi, math.pi),
        (-math.pi, math.pi),
        (3 * math.pi, math.pi),
        (2 * math.pi + 0.5, 0.5),
        (-2 * math.pi - 0.5, -0.5),
        (-1.0, -1.0),
        (0.0, 0.0),
    ],
)
def test_wrap_angle(t: float, expected: float) -> None:
    assert wrap_angle(t) == pytest.approx(expected, abs=1e-15)
    assert -math.pi < wrap_angle(t) <= math.pi


def test_bad_input_raises_optik_errors() -> None:
    with pytest.raises(NonFiniteError):
        solve_trig(float("nan"), 1.0, 0.0)
    with pytest.raises(NonFiniteError):
        solve_trig(1.0, 1.0, float("inf"))
    with pytest.raises(ShapeError):
        solve_trig([1.0, 2.0], 1.0, 0.0)  # type: ignore[arg-type]
    with pytest.raises(OptikError):
        solve_trig(1.0, 0.0, 0.5, tol=-1.0)
    with pytest.raises(NonFiniteError):
        solve_trig_batch([1.0, np.nan], 0.0, 0.0)
    with pytest.raises(ShapeError):
        solve_trig_batch(np.ones(3), np.ones(4), 0.0)
