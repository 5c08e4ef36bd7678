"""Input validation shared by every layer: shapes and finiteness, with optik errors."""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from optik.errors import NonFiniteError, ShapeError

FloatArray = NDArray[np.float64]


def as_float_array(name: str, value: Any) -> FloatArray:
    """Convert ``value`` to a float64 array, raising :class:`ShapeError` for ragged input."""
    try:
        return np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ShapeError(name, "a numeric array", ()) from exc


def check_finite(name: str, array: FloatArray) -> FloatArray:
    """Raise :class:`NonFiniteError` naming the first NaN/inf entry of ``array``."""
    if not np.isfinite(array).all():
        bad = np.argwhere(~np.isfinite(array))[0]
        raise NonFiniteError(name, tuple(int(i) for i in bad))
    return array


def finite_array(
    name: str, value: Any, trailing: tuple[int, ...], batch: bool = False
) -> FloatArray:
    """Return ``value`` as a finite float64 array of shape ``trailing`` (or ``(N, *trailing)``).

    Args:
        name: argument name used in error messages.
        value: array-like input.
        trailing: required trailing shape, e.g. ``(4, 4)``.
        batch: also accept one leading batch axis.
    """
    array = as_float_array(name, value)
    nd = len(trailing)
    ok = array.shape == trailing or (batch and array.ndim == nd + 1 and array.shape[1:] == trailing)
    if not ok:
        dims = ", ".join(str(t) for t in trailing)
        expected = f"({dims})" + (f" or (N, {dims})" if batch else "")
        raise ShapeError(name, expected, array.shape)
    return check_finite(name, array)
