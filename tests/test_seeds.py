"""The clustered seed table that starts numeric IK near the target."""

from __future__ import annotations

import numpy as np

from optik.problems import load_problem
from optik.solvers._seeds import (
    TABLE_CLUSTERS,
    TABLE_SIZE,
    nearest_seeds,
    pose_features,
    seed_table,
)
from optik.solvers._starts import table_candidates
from optik.task import make_task


def test_table_entries_are_in_limits_and_their_features_are_their_poses() -> None:
    panda = load_problem("panda").robot
    table = seed_table(panda)
    assert table.q.shape == (TABLE_SIZE, panda.dof)
    assert table.features.shape == (12, TABLE_SIZE)
    assert table.centroids.shape == (12, TABLE_CLUSTERS)
    assert np.all((table.q >= panda.lower) & (table.q <= panda.upper))
    # Round trip through forward kinematics, not the table's own code path.
    assert np.allclose(table.features.T, pose_features(panda.fk(table.q)), atol=1e-12)


def test_clusters_partition_the_table_by_nearest_centre() -> None:
    puma = load_problem("puma560").robot
    table = seed_table(puma)
    offsets = table.offsets
    assert offsets[0] == 0 and offsets[-1] == TABLE_SIZE and np.all(np.diff(offsets) >= 0)
    labels = np.repeat(np.arange(TABLE_CLUSTERS), np.diff(offsets))
    F, centres = table.features.T, table.centroids.T
    d = np.sum((F[:, None, :] - centres[None, :, :]) ** 2, axis=2)
    # Lloyd's assignment: every entry sits in the cluster of its nearest centre.
    assert np.array_equal(np.argmin(d, axis=1), labels)


def test_table_is_deterministic() -> None:
    a = load_problem("ur5").robot
    b = load_problem("ur5").robot  # a fresh robot: no cached table
    ta, tb = seed_table(a), seed_table(b)
    assert ta is not tb
    for x, y in zip(ta, tb, strict=True):
        assert np.array_equal(x, y)


def test_candidates_are_the_nearest_cluster_with_exact_distances(
    rng: np.random.Generator,
) -> None:
    panda = load_problem("panda").robot
    table = seed_table(panda)
    F, centres = table.features.T, table.centroids.T
    for _ in range(20):
        target = panda.fk(rng.uniform(panda.lower, panda.upper))
        f = pose_features(target[None])[0]
        for pose, width in ((True, 12), (False, 3)):
            mask = make_task("pose" if pose else "position").features
            index, d = table_candidates(
                table.features, table.centroids, table.offsets, target, mask
            )
            cluster = np.argmin(np.sum((centres[:, :width] - f[:width]) ** 2, axis=1))
            members = np.arange(table.offsets[cluster], table.offsets[cluster + 1])
            assert np.array_equal(index, members)
            expected = np.sum((F[members, :width] - f[:width]) ** 2, axis=1)
            np.testing.assert_allclose(d, expected, rtol=1e-12, atol=1e-15)


def test_nearest_seeds_are_ranked_by_pose_distance(rng: np.random.Generator) -> None:
    panda = load_problem("panda").robot
    target = panda.fk(rng.uniform(panda.lower, panda.upper))
    seeds = nearest_seeds(panda, target, "pose", 5)
    assert seeds.shape == (5, panda.dof)
    d = np.sum((pose_features(panda.fk(seeds)) - pose_features(target[None])) ** 2, axis=1)
    assert np.all(np.diff(d) >= 0)
