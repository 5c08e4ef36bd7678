"""The one start policy of numeric IK: the sequence of starting configurations.

Every numeric solver, compiled or not, with or without a deadline, in a single query or a
batch, takes its starts from :func:`start_into`:

1. the *given* starts, in order: the closed-form branches inside the limits, nearest
   ``q0`` first (when the robot has a closed form), else ``q0`` when the caller gave one;
2. then the entries of the robot's seed table (:mod:`optik.solvers._seeds`) in the
   cluster whose centre is nearest the target, nearest first (:func:`table_order`; the
   solvers rank them lazily, :func:`nearest_table`, since most queries use one or two):
   the first :data:`TABLE_FIRST` starts after the given ones, then every other start;
3. between those, and once the cluster is used up, uniform draws inside the limits
   (``[-pi, pi]`` for a continuous joint).

Start ``k`` is a pure function of ``k``, the given starts, the table order and ``seed``:
the draws come from a counter-based generator (SplitMix64 of ``seed``, ``k`` and the
joint index), not from a stream, so a caller may run attempts ``0..k`` in one compiled
call or in slices (between which it checks a deadline, or lets Ctrl-C through) and get
the same starts, and a batch's answers do not depend on how it is split into threads.
"""

from __future__ import annotations

import math

import numpy as np

from optik._checks import FloatArray
from optik._nrt import borrowed
from optik._numba import jit

TABLE_FIRST = 4
"""Starts taken from the seed table, nearest first, before draws alternate with them."""

ROTATION_WEIGHT = 0.05
"""Weight (m^2) of the squared Frobenius rotation distance when ranking table poses:
``||R_i - R*||_F^2 = 4 (1 - cos a)``, so 0.3 m counts like about 1 rad."""

SQRT_ROTATION_WEIGHT = math.sqrt(ROTATION_WEIGHT)

_GOLDEN = np.uint64(0x9E3779B97F4A7C15)
_MIX1 = np.uint64(0xBF58476D1CE4E5B9)
_MIX2 = np.uint64(0x94D049BB133111EB)
_UNIT = 1.0 / 9007199254740992.0  # 2^-53


@jit
def _splitmix(x: np.uint64) -> np.uint64:
    """SplitMix64's output function: a bijective 64-bit mix (Steele et al. 2014)."""
    x = (x ^ (x >> np.uint64(30))) * _MIX1
    x = (x ^ (x >> np.uint64(27))) * _MIX2
    return x ^ (x >> np.uint64(31))


@jit
def uniform_draw(seed: int, k: int, i: int) -> float:
    """A uniform number in [0, 1) for start ``k``, joint ``i`` of the stream ``seed``."""
    h = _splitmix(np.uint64(seed) * _GOLDEN + np.uint64(k))
    h = _splitmix(h + np.uint64(i + 1) * _GOLDEN)
    return float(h >> np.uint64(11)) * _UNIT


@jit
def start_into(
    k: int,
    given: np.ndarray,
    nearest: NearestTable,
    table_q: np.ndarray,
    lower: np.ndarray,
    upper: np.ndarray,
    seed: int,
    out: np.ndarray,
) -> int:
    """Write start ``k`` into ``out`` (dof,); return its source: 0 given, 1 table, 2 draw.

    Args:
        k: the start's index (0 is the first attempt).
        given: (G, dof) starts taken first, in order (may be empty).
        nearest: the target's table entries, ranked on demand (:func:`nearest_table`).
        table_q: (T, dof) seed-table configurations.
        lower: (dof,) lower limits; ``-inf`` draws from ``-pi``.
        upper: (dof,) upper limits; ``+inf`` draws up to ``pi``.
        seed: the stream of the uniform draws.
        out: (dof,) the start.
    """
    n_given = given.shape[0]
    if k < n_given:
        out[:] = given[k]
        return 0
    j = k - n_given
    entry = -1
    if j < TABLE_FIRST:
        entry = j
    elif (j - TABLE_FIRST) % 2 == 0:
        entry = TABLE_FIRST + (j - TABLE_FIRST) // 2
    index = nearest_entry(nearest, entry) if entry >= 0 else -1
    if index >= 0:
        out[:] = table_q[index]
        return 1
    for i in range(lower.shape[0]):
        lo = lower[i] if np.isfinite(lower[i]) else -np.pi
        hi = upper[i] if np.isfinite(upper[i]) else np.pi
        out[i] = lo + (hi - lo) * uniform_draw(seed, k, i)
    return 2


NearestTable = tuple[np.ndarray, np.ndarray, np.ndarray]
"""A target's table entries ranked on demand: ``(index (n,), left (n,), ranked (n,))`` --
the entries' table indices, their squared distances (``-1`` once ranked), and the table
indices nearest first (``-1`` where not ranked yet)."""


@jit
def nearest_table(
    features: np.ndarray,
    centroids: np.ndarray,
    offsets: np.ndarray,
    target: np.ndarray,
    mask: np.ndarray,
) -> NearestTable:
    """The entries of the cluster nearest ``target``, to be ranked by :func:`nearest_entry`.

    Ranking all of them (a sort of ~128 distances, 8 us) costs more than most solves need:
    they take one or two entries, each found by one scan.
    """
    index, distances = table_candidates(features, centroids, offsets, target, mask)
    return index, distances, np.full(index.shape[0], -1, dtype=np.int64)


@jit
def nearest_entry(nearest: NearestTable, entry: int) -> int:
    """Table index of the ``entry``-th nearest entry (0 is the nearest), -1 past the last.

    Equal to ``table_order(...)[entry]`` (ties to the earlier entry, as a stable sort);
    entries with a NaN distance are never ranked. Ranks the entries up to ``entry`` on
    first use, in place.
    """
    index, left, ranked = nearest
    if entry >= ranked.shape[0]:
        return -1
    if ranked[entry] < 0:
        e = entry
        while e > 0 and ranked[e - 1] < 0:
            e -= 1
        for r in range(e, entry + 1):
            best = -1
            value = np.inf
            for i in range(left.shape[0]):
                d = left[i]
                if d >= 0.0 and (best < 0 or d < value):
                    best = i
                    value = d
            if best < 0:
                return -1
            left[best] = -1.0
            ranked[r] = index[best]
    return ranked[entry]


@jit
def table_candidates(
    features: np.ndarray,
    centroids: np.ndarray,
    offsets: np.ndarray,
    target: np.ndarray,
    mask: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """The seed-table entries of the cluster nearest ``target``, with their distances.

    ``features`` (12, M) and ``centroids`` (12, C) are pose features (position, then
    ``sqrt(ROTATION_WEIGHT) R`` row by row: :func:`optik.solvers._seeds.pose_features`),
    so squared distances are ``||p_i - p*||^2 + w ||R_i - R*||_F^2`` over the features
    that ``mask`` (12,) weights (:func:`optik.task.task_features`: all twelve for a full
    pose, the first three for a point, the tool axis's column for ``axis``; 1 each, the
    position's ``1 / L^2`` for an arm measured in its size ``L``), zero weights skipped.
    Returns ``(indices (k,), squared distances (k,))``; both are empty when no distance
    is finite (a target whose coordinates overflow).
    Loops run over contiguous rows of one feature, which vectorise.
    """
    features = borrowed(features)
    centroids = borrowed(centroids)
    f = np.empty(12)
    for j in range(12):
        f[j] = target[j, 3] if j < 3 else SQRT_ROTATION_WEIGHT * target[(j - 3) // 3, (j - 3) % 3]
    to_centre = np.zeros(centroids.shape[1])
    for j in range(12):
        w = mask[j]
        if w == 0.0:
            continue
        row = centroids[j]
        for c in range(row.shape[0]):
            x = row[c] - f[j]
            to_centre[c] += w * x * x
    nearest = -1
    value = np.inf
    for c in range(to_centre.shape[0]):
        if to_centre[c] < value:
            value = to_centre[c]
            nearest = c
    if nearest < 0:
        return np.empty(0, dtype=np.int64), np.empty(0)
    lo = offsets[nearest]
    n = offsets[nearest + 1] - lo
    index = np.empty(n, dtype=np.int64)
    for t in range(n):
        index[t] = lo + t
    distances = np.zeros(n)
    for j in range(12):
        w = mask[j]
        if w == 0.0:
            continue
        row = features[j, lo : lo + n]
        for t in range(n):
            x = row[t] - f[j]
            distances[t] += w * x * x
    return index, distances


@jit
def table_order(
    features: np.ndarray,
    centroids: np.ndarray,
    offsets: np.ndarray,
    target: np.ndarray,
    mask: np.ndarray,
) -> np.ndarray:
    """Indices of the table entries nearest ``target`` (its nearest cluster), nearest first."""
    index, distances = table_candidates(features, centroids, offsets, target, mask)
    return index[np.argsort(distances, kind="mergesort")]


class StartSequence:
    """The starts of one query, as :func:`start_into` defines them (see the module).

    Args:
        given: the starts taken first, in order (closed-form branches, or ``q0``).
        table: the robot's seed table, ``(q (T, dof), features (12, T), centroids (12,
            C), offsets (C + 1,))`` (:class:`optik.solvers._seeds.SeedTable`).
        target: (4, 4) the target pose, which ranks the table's entries.
        mask: (12,) the weights of the pose features that rank them
            (:func:`optik.task.task_features` of the search measured in the arm's size).
        lower: (dof,) lower limits.
        upper: (dof,) upper limits.
        seed: stream of the uniform draws.
    """

    def __init__(
        self,
        given: FloatArray,
        table: tuple[FloatArray, FloatArray, FloatArray, np.ndarray],
        target: FloatArray,
        mask: FloatArray,
        lower: FloatArray,
        upper: FloatArray,
        seed: int,
    ) -> None:
        dof = lower.shape[0]
        self.given = np.ascontiguousarray(np.asarray(given, dtype=np.float64).reshape(-1, dof))
        self.table = table
        self.target = target
        self.mask = mask
        self.lower = lower
        self.upper = upper
        self.seed = seed
        self._nearest: NearestTable | None = None

    @property
    def nearest(self) -> NearestTable:
        """The target's table entries, ranked on demand (built on first use).

        The compiled solvers rank them themselves (:func:`nearest_table` inside the
        kernel costs less than passing the ranking in and out of it).
        """
        if self._nearest is None:
            _, features, centroids, offsets = self.table
            self._nearest = nearest_table(features, centroids, offsets, self.target, self.mask)
        return self._nearest

    def start(self, k: int) -> FloatArray:
        """Start ``k`` (dof,), a new array."""
        out = np.empty(self.lower.shape[0])
        table_q = self.table[0]
        start_into(k, self.given, self.nearest, table_q, self.lower, self.upper, self.seed, out)
        return out


__all__ = [
    "ROTATION_WEIGHT",
    "TABLE_FIRST",
    "NearestTable",
    "StartSequence",
    "nearest_entry",
    "nearest_table",
    "start_into",
    "table_candidates",
    "table_order",
    "uniform_draw",
]
