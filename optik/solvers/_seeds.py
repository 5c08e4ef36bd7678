"""A per-robot table of configurations and their poses, for starting numeric IK nearby.

Starting Levenberg–Marquardt from a table entry whose pose is near the target halves the
iterations on random targets and makes restarts rarer (measured on the Panda: 36 -> 18
iterations per solve with 256 entries). Larger tables start closer still, so the table is
large and clustered: its entries are grouped by k-means on their pose features, and a
query scans the cluster centres, then the members of the nearest cluster only (see
:func:`optik.solvers._starts.table_candidates`). The table is drawn and clustered
with fixed seeds, so results stay deterministic.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from optik._checks import FloatArray
from optik.model import Robot
from optik.solvers._base import search_length
from optik.solvers._starts import ROTATION_WEIGHT, StartSequence, table_order
from optik.task import Task, as_task, balanced_search

TABLE_SIZE = 8192
"""Entries per robot. Measured on 20,000 random Panda poses (the quick stall rule of
:mod:`optik.solvers._lm_kernel`): 256 entries scanned whole, 14.0 iterations per solve;
clustered, 8,192 entries 11.2 iterations, 16,384 entries 10.6, 32,768 entries 9.9. Past
8,192 the clustering (a one-time cost per robot, 0.1 s here) and the table's memory
grow faster than the saving."""

TABLE_CLUSTERS = 64
"""k-means clusters of the table (about 128 entries each): a query scans 64 centres and
one cluster, about as much work as a 256-entry table."""

KMEANS_ITERATIONS = 8
"""Lloyd iterations of the clustering: starts only need to be near, not nearest."""

_TABLE_SEED = 20240611


def pose_features(T: FloatArray) -> FloatArray:
    """(N, 12) features of poses (N, 4, 4): position, then ``sqrt(w) R`` row by row.

    Squared feature distances are ``||p - p'||^2 + w ||R - R'||_F^2`` with
    ``w = ROTATION_WEIGHT``; position mode compares the first three columns only.
    """
    out = np.empty((len(T), 12))
    out[:, :3] = T[:, :3, 3]
    out[:, 3:] = math.sqrt(ROTATION_WEIGHT) * T[:, :3, :3].reshape(len(T), 9)
    return out


class SeedTable(NamedTuple):
    """Configurations and their pose features, sorted by cluster.

    The compiled solvers take the fields as one tuple (:meth:`kernel_args`).

    Attributes:
        q: (M, dof) joint vectors, uniform inside the limits (rad / m).
        features: (12, M) pose features (:func:`pose_features`, one feature per row: the
            layout the compiled scan reads fastest).
        centroids: (12, C) cluster centres, in the same feature space.
        offsets: (C + 1,) int64; cluster ``c`` holds entries ``offsets[c]:offsets[c + 1]``.
    """

    q: FloatArray
    features: FloatArray
    centroids: FloatArray
    offsets: np.ndarray

    def kernel_args(self) -> tuple[FloatArray, FloatArray, FloatArray, np.ndarray]:
        """The four arrays as a plain tuple, the compiled solvers' ``table`` argument.

        Not the NamedTuple itself: numba's dispatcher types one about 1 us more slowly.
        """
        return self.q, self.features, self.centroids, self.offsets


def _kmeans(
    features: FloatArray, clusters: int, rng: np.random.Generator
) -> tuple[FloatArray, np.ndarray]:
    """Lloyd's k-means of ``features`` (M, d): ``(centres (clusters, d), labels (M,))``."""
    centres = features[rng.choice(len(features), clusters, replace=False)].copy()

    def nearest(centres: FloatArray) -> np.ndarray:
        # ||f - c||^2 less ||f||^2, which is the same for every centre of a row: one
        # (M, clusters) array, updated in place (the whole distance took four times as
        # long, most of a new robot's first solve).
        d = features @ (-2.0 * centres.T)
        d += np.sum(centres**2, axis=1)
        return np.argmin(d, axis=1)

    for _ in range(KMEANS_ITERATIONS):
        labels = nearest(centres)
        counts = np.bincount(labels, minlength=clusters)
        filled = counts > 0  # an empty cluster keeps its centre
        for j in range(features.shape[1]):
            sums = np.bincount(labels, weights=features[:, j], minlength=clusters)
            centres[filled, j] = sums[filled] / counts[filled]
    return centres, nearest(centres)


def seed_table(robot: Robot) -> SeedTable:
    """The robot's clustered :class:`SeedTable` (built on first use, then cached)."""
    return robot.cached(build_seed_table)


def build_seed_table(
    robot: Robot, size: int = TABLE_SIZE, clusters: int = TABLE_CLUSTERS
) -> SeedTable:
    """A clustered :class:`SeedTable` of ``size`` uniform configurations inside the limits."""
    rng = np.random.default_rng(_TABLE_SEED)
    lower = np.where(np.isfinite(robot.lower), robot.lower, -math.pi)
    upper = np.where(np.isfinite(robot.upper), robot.upper, math.pi)
    Q = rng.uniform(lower, upper, (size, robot.dof))
    features = pose_features(robot.fk(Q))
    # Clustered in the arm's size, as the starts are ranked (a millimetre arm's clusters
    # would group rotations alone, a kilometre arm's positions alone); a linear scale
    # of each feature, so the centres are the clusters' means in either.
    scale = np.ones(12)
    scale[:3] = math.sqrt(_writable_mask(robot, "pose")[0])
    centres, labels = _kmeans(features * scale, min(clusters, size), rng)
    centres /= scale
    order = np.argsort(labels, kind="stable")
    offsets = np.searchsorted(labels[order], np.arange(len(centres) + 1))
    cached = SeedTable(
        np.ascontiguousarray(Q[order]),
        np.ascontiguousarray(features[order].T),
        np.ascontiguousarray(centres.T),
        offsets.astype(np.int64),
    )
    return cached


def nearest_seeds(robot: Robot, target: FloatArray, mode: str | Task, count: int) -> FloatArray:
    """Up to ``count`` table configurations near ``target``, nearest first.

    The entries of the cluster whose centre is nearest (the starts the solvers take first
    after the given ones: :mod:`optik.solvers._starts`), ranked by their own distance.
    """
    table = seed_table(robot)
    order = table_order(
        table.features, table.centroids, table.offsets, np.asarray(target, float),
        _writable_mask(robot, mode),
    )  # fmt: skip
    return table.q[order[:count]]


def start_sequence(
    robot: Robot,
    target: FloatArray,
    mode: str | Task,
    given: FloatArray | list[FloatArray],
    seed: int,
    bounds: tuple[FloatArray, FloatArray] | None = None,
) -> StartSequence:
    """The starts of one query (:mod:`optik.solvers._starts`): ``given``, table, draws.

    ``bounds`` (default: the robot's limits) is the box the draws fill.
    """
    table = seed_table(robot)
    G = np.asarray(given, dtype=np.float64).reshape(-1, robot.dof)
    lower, upper = (robot.lower, robot.upper) if bounds is None else bounds
    T = np.ascontiguousarray(target, dtype=np.float64)
    mask = _writable_mask(robot, mode)
    return StartSequence(G, table.kernel_args(), T, mask, lower, upper, seed)


def _writable_mask(robot: Robot, mode: str | Task) -> FloatArray:
    """The task's feature weights (12,) for ``robot``, as a writable copy.

    Those of its search measured in the arm's size (:func:`optik.task.balanced_search`),
    as the compiled ``dls`` ranks them. The compiled kernels get a writable mask from
    compiled callers (``task_features``); a read-only one (``Task.features``) would
    compile them once more for that type.
    """
    return balanced_search(as_task(mode), search_length(robot)).features.copy()
