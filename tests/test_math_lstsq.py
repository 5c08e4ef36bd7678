"""optik._math.householder_lstsq against numpy's least squares."""

from __future__ import annotations

import numpy as np
import pytest

from optik._math import householder_lstsq


@pytest.mark.parametrize(("f", "m"), [(6, 6), (6, 3), (9, 7), (12, 1)])
def test_householder_lstsq_equals_numpy(f: int, m: int) -> None:
    rng = np.random.default_rng(f * 10 + m)
    for _ in range(20):
        A = rng.normal(size=(f, m))
        b = rng.normal(size=f)
        expected = np.linalg.lstsq(A, b, rcond=None)[0]
        y = np.empty(m)
        assert householder_lstsq(A.copy(), b.copy(), y)
        np.testing.assert_allclose(y, expected, rtol=1e-10, atol=1e-12)


def test_householder_lstsq_reports_a_zero_column() -> None:
    A = np.array([[1.0, 0.0], [2.0, 0.0], [3.0, 0.0]])
    y = np.empty(2)
    assert not householder_lstsq(A, np.ones(3), y)
