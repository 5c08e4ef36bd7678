"""The samples of a capability map: voxel centres on a lattice, orientations on a sphere.

Voxel centres lie on the lattice ``c + k * voxel`` (``k`` integer per axis) anchored at
the reach sphere's centre ``c``, so the centre itself is a voxel centre and the grid is
symmetric about it; ``bounds`` keeps the centres inside a box. Tool-axis directions are
the Fibonacci sphere of ``n`` points (nearly uniform, deterministic); a full pose adds
``rolls`` evenly spaced rotations about the tool axis.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from optik._checks import FloatArray, as_float_array, check_int, check_length_array, check_real
from optik.errors import ArgumentError, OptikError, ShapeError

MAX_VOXELS = 200_000_000
"""Largest number of voxels of one map grid (the box, inside the sphere or not)."""

MAX_ORIENTATIONS = 100_000
"""Largest ``orientations`` (and ``rolls``) of a map."""

MAX_SAMPLES = 100_000
"""Largest number of samples per voxel, ``orientations * rolls`` (the (M, 3, 3) rotations
take 72 bytes each, and every chunk solves M samples per voxel)."""

AXES = ("x", "y", "z")


def lattice(
    centre: FloatArray, radius: float, voxel: Any, bounds: Any = None
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Voxel centre coordinates (m) along x, y and z.

    Args:
        centre: (3,) the reach sphere's centre (m), the lattice's anchor.
        radius: the reach sphere's radius (m).
        voxel: edge length of a voxel (m), > 0 and at most ``radius``.
        bounds: ``[[xmin, xmax], [ymin, ymax], [zmin, zmax]]`` (m), or ``None`` for the
            sphere's bounding box.

    Raises:
        OptikError: ``voxel`` not positive, not finite or larger than ``radius``;
            ``bounds`` not (3, 2), not finite, beyond :data:`~optik._checks.MAX_LENGTH_M`,
            inverted or holding no voxel centre on an axis; more than :data:`MAX_VOXELS`
            voxels.
    """
    v = check_real("voxel", voxel, positive=True)
    if v > radius:
        raise ArgumentError("voxel", voxel, f"at most the reach radius {radius:.6g} m")
    if bounds is None:
        box = np.column_stack([centre - radius, centre + radius])
    else:
        box = as_float_array("bounds", bounds)
        if box.shape != (3, 2):
            raise ShapeError(
                "bounds", "(3, 2): [[xmin, xmax], [ymin, ymax], [zmin, zmax]]", box.shape
            )
        if not np.all(np.isfinite(box)):
            raise OptikError("bounds: values must be finite (m)")
        check_length_array("bounds", box)
    # The lattice indices k0..k1 of each axis, in floating point: with a tiny voxel they
    # overflow an integer (or reach inf), so the count is checked before any allocation.
    ranges = []
    for i, name in enumerate(AXES):
        lo, hi, c = float(box[i, 0]), float(box[i, 1]), float(centre[i])
        if lo > hi:
            raise OptikError(f"bounds: {name}min {lo:g} m is above {name}max {hi:g} m")
        # A small slack keeps a bound that is a lattice point (up to rounding) inside.
        k0 = float(np.ceil((lo - c) / v - 1e-9))
        k1 = float(np.floor((hi - c) / v + 1e-9))
        if k1 < k0:
            raise OptikError(
                f"bounds: no voxel centre between {name} = {lo:g} and {hi:g} m "
                f"(centres lie at {c:g} + k * {v:g} m)"
            )
        ranges.append((k0, k1))
    count = math.prod(k1 - k0 + 1.0 for k0, k1 in ranges)  # inf or NaN when overflowing
    if not count <= MAX_VOXELS:
        shown = f"{count:.3g}" if math.isfinite(count) else "too many"
        raise OptikError(
            f"voxel {v:g} m and bounds give {shown} voxels, more than {MAX_VOXELS}: "
            "give a larger voxel or smaller bounds"
        )
    # k0 + arange(n) equals arange(k0, k1 + 1) (exact integers), without an int of k0.
    axes = [
        centre[i] + v * (k0 + np.arange(int(k1 - k0) + 1, dtype=np.float64))
        for i, (k0, k1) in enumerate(ranges)
    ]
    return axes[0], axes[1], axes[2]


def fibonacci_sphere(n: int) -> FloatArray:
    """(n, 3) unit vectors on the Fibonacci sphere (golden-angle spiral, equal areas).

    Point ``i`` has ``z = 1 - (2 i + 1) / n`` and azimuth ``i * pi * (3 - sqrt 5)``.
    """
    i = np.arange(n, dtype=np.float64)
    z = 1.0 - (2.0 * i + 1.0) / n
    r = np.sqrt(np.maximum(1.0 - z * z, 0.0))
    phi = i * math.pi * (3.0 - math.sqrt(5.0))
    return np.column_stack([r * np.cos(phi), r * np.sin(phi), z])


def frames_with_axis(directions: FloatArray, axis: int) -> FloatArray:
    """(n, 3, 3) rotations whose column ``axis`` is each unit direction (right-handed).

    The next column (cyclically) is the world x axis made orthogonal to the direction
    (the world y axis where x is within about 25 degrees of it).
    """
    d = np.asarray(directions, dtype=np.float64)
    reference = np.where(np.abs(d[:, :1]) > 0.9, [[0.0, 1.0, 0.0]], [[1.0, 0.0, 0.0]])
    u = reference - np.sum(reference * d, axis=1, keepdims=True) * d
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    w = np.cross(d, u)
    R = np.empty((len(d), 3, 3))
    R[:, :, axis] = d
    R[:, :, (axis + 1) % 3] = u
    R[:, :, (axis + 2) % 3] = w
    return R


def rotations_about_axis(angles: FloatArray, axis: int) -> FloatArray:
    """(m, 3, 3) rotations by ``angles`` (rad) about the coordinate axis ``axis``."""
    c, s = np.cos(angles), np.sin(angles)
    a, b = (axis + 1) % 3, (axis + 2) % 3
    R = np.zeros((len(angles), 3, 3))
    R[:, axis, axis] = 1.0
    R[:, a, a] = c
    R[:, a, b] = -s
    R[:, b, a] = s
    R[:, b, b] = c
    return R


def orientations(mode: str, count: Any, rolls: Any, axis: str) -> FloatArray:
    """(M, 3, 3) the target rotations sampled at every voxel.

    ``"position"``: one identity (the orientation is not constrained). ``"axis"``:
    ``count`` frames whose tool axis ``axis`` runs over the Fibonacci sphere (the rotation
    about it is free). ``"pose"``: each of those turned by ``rolls`` angles ``2 pi j /
    rolls`` about the tool axis, direction-major (sample ``d * rolls + j``).

    Raises:
        OptikError: ``count`` or ``rolls`` not an integer in [1, MAX_ORIENTATIONS];
            ``rolls`` other than 1 outside pose mode; ``count * rolls`` above
            :data:`MAX_SAMPLES`.
    """
    n = check_int("orientations", count, minimum=1, maximum=MAX_ORIENTATIONS)
    m = check_int("rolls", rolls, minimum=1, maximum=MAX_ORIENTATIONS)
    if m != 1 and mode != "pose":
        raise OptikError(
            f"rolls: only a full pose has rotations about the tool axis (mode {mode!r}); "
            "give rolls=1"
        )
    if mode == "position":
        return np.eye(3)[None].copy()
    if n * m > MAX_SAMPLES:
        raise OptikError(
            f"orientations * rolls: {n} * {m} = {n * m} samples per voxel, more than "
            f"{MAX_SAMPLES}: give fewer orientations or rolls"
        )
    k = AXES.index(axis)
    base = frames_with_axis(fibonacci_sphere(n), k)
    if mode == "axis":
        return base
    turns = rotations_about_axis(2.0 * math.pi * np.arange(m) / m, k)
    return np.einsum("dij,rjk->drik", base, turns).reshape(n * m, 3, 3)


__all__ = [
    "MAX_ORIENTATIONS",
    "MAX_SAMPLES",
    "MAX_VOXELS",
    "fibonacci_sphere",
    "frames_with_axis",
    "lattice",
    "orientations",
    "rotations_about_axis",
]
