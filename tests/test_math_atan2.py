"""The compiled ``atan2`` of :mod:`optik._math` against libm and extended precision.

The closed forms call it about thirty times a pose in place of libm's. The reference for
its error is numpy's ``arctan2`` in ``longdouble`` (x87 extended precision on x86-64: 11
more bits than a double, so an error is measured to a few thousandths of an ulp).
"""

from __future__ import annotations

import math

import numba
import numpy as np
import pytest

from optik import _math

LONG = np.longdouble
pytestmark = pytest.mark.skipif(
    np.finfo(LONG).nmant < 63, reason="needs an extended-precision longdouble reference"
)


@numba.njit(cache=False)
def _atan2_all(y: np.ndarray, x: np.ndarray) -> np.ndarray:
    out = np.empty(y.size)
    for i in range(y.size):
        out[i] = _math.atan2(y[i], x[i])
    return out


def _ulps(values: np.ndarray, y: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Error of ``values`` in ulps of the exact ``atan2(y, x)`` (rounded to double)."""
    exact = np.arctan2(y.astype(LONG), x.astype(LONG))
    return np.abs(values.astype(LONG) - exact) / np.spacing(np.abs(exact.astype(np.float64)))


def test_atan2_is_within_one_ulp_of_the_exact_angle_over_wide_magnitudes() -> None:
    rng = np.random.default_rng(7)
    n = 400_000
    y = rng.standard_normal(n) * 10.0 ** rng.uniform(-40.0, 40.0, n)
    x = rng.standard_normal(n) * 10.0 ** rng.uniform(-40.0, 40.0, n)
    y[: n // 2] = rng.uniform(-1.0, 1.0, n // 2)  # the kernels' range: unit vectors' entries
    x[: n // 2] = rng.uniform(-1.0, 1.0, n // 2)
    ours = _atan2_all(y, x)
    libm = np.arctan2(y, x)
    # Dividing |y| by |x| rounds once before the series: up to 1 ulp of the angle where it
    # falls a binade below the ratio (t near 0.25), and the sum rounds again (1.46 seen).
    assert float(np.max(_ulps(ours, y, x))) <= 2.0
    assert float(np.max(np.abs(ours - libm) / np.spacing(np.abs(libm)))) <= 2.0


@pytest.mark.parametrize("ratio", [2.0**-27, 0.4375, 0.6875, 1.1875, 2.4375, 2.0**66])
def test_atan2_is_accurate_at_each_reduction_boundary(ratio: float) -> None:
    # |y| / |x| just below, at and just above each interval's edge, in all four quadrants.
    offsets = np.arange(-40, 41)
    t = ratio + offsets * np.spacing(ratio)
    x = np.repeat(np.array([1.0, 3.7, -1.0, -0.37]), t.size)
    y = np.tile(t, 4) * np.abs(x) * np.repeat(np.array([1.0, -1.0, 1.0, -1.0]), t.size)
    ours = _atan2_all(y, x)
    assert float(np.max(_ulps(ours, y, x))) <= 2.0


def test_atan2_special_cases_are_libms_with_their_signs() -> None:
    values = [0.0, -0.0, 1.0, -1.0, 1e-300, -1e-300, 1e300, -1e300, 5e-324, math.inf,
              -math.inf, math.nan]  # fmt: skip
    for y in values:
        for x in values:
            ours = _math.atan2(y, x)
            theirs = math.atan2(y, x)
            if math.isnan(theirs):
                assert math.isnan(ours), (y, x)
            else:
                assert ours == theirs and math.copysign(1.0, ours) == math.copysign(1.0, theirs), (
                    y,
                    x,
                    ours,
                    theirs,
                )


def test_atan2_quadrants_match_the_angle_of_the_point() -> None:
    angles = np.linspace(-math.pi, math.pi, 2001)[1:]  # (-pi, pi]
    ours = _atan2_all(np.sin(angles), np.cos(angles))
    assert np.max(np.abs(ours - angles)) < 1e-15
