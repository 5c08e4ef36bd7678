"""Capability-map throughput: in-process, on 1 and 2 local Dask workers, against plain batches.

Run: ``PYTHONPATH=$PWD python benchmarks/bench_map.py`` (about two minutes on two cores;
``--voxel`` and ``--orientations`` scale it). For each robot it reports:

- IK queries per second of :func:`optik.capability_map` in-process (numba's threads), and
  on a local cluster of 1 and of 2 worker processes (1 thread each), and the 1 -> 2
  scaling;
- the same samples solved by one plain :func:`optik.solve_ik_batch` call over the whole
  grid (the same seeds, so the same work: the script checks that both reach the same
  samples), and the map's overhead against it;
- Dask's per-task overhead (an empty task, round trip through the scheduler).

Each figure is one timed run after an untimed warm-up (numba's kernels and the workers'
imports), so the load of a shared machine shows: it is printed before and after.
"""

from __future__ import annotations

import argparse
import os
import platform
import time
from typing import Any

import numba
import numpy as np

import optik
from optik.campaign import capability_map, open_engine


def _noop(x: int) -> int:
    return x


def _warm() -> None:
    robot = optik.load_problem("ur5").robot
    capability_map(robot, voxel=0.5, orientations=2, restarts=0)


def _grid_poses(ds: Any) -> np.ndarray:
    """Every sample pose of the map's whole grid, in the map's global sample order."""
    R = ds.rotation.values
    X, Y, Z = np.meshgrid(ds.x.values, ds.y.values, ds.z.values, indexing="ij")
    P = np.stack([X, Y, Z], axis=-1).reshape(-1, 3)
    poses = np.zeros((len(P), len(R), 4, 4))
    poses[:, :, :3, :3] = R
    poses[:, :, :3, 3] = P[:, None, :]
    poses[:, :, 3, 3] = 1.0
    return poses.reshape(-1, 4, 4)


def _timed(fn: Any) -> tuple[float, Any]:
    start = time.perf_counter()
    result = fn()
    return time.perf_counter() - start, result


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robots", default="ur5,panda")
    parser.add_argument("--voxel", type=float, default=0.15, help="m")
    parser.add_argument("--orientations", type=int, default=40)
    parser.add_argument("--mode", default="pose")
    parser.add_argument("--restarts", type=int, default=3)
    parser.add_argument("--chunk", type=int, default=4)
    parser.add_argument("--workers", default="1,2")
    args = parser.parse_args()
    print(
        f"optik map benchmark; python {platform.python_version()}, numba {numba.__version__}, "
        f"{os.cpu_count()} CPUs, load {os.getloadavg()[0]:.2f}"
    )
    print(
        f"settings: voxel {args.voxel} m, {args.orientations} orientations, mode {args.mode}, "
        f"restarts {args.restarts}, chunk {args.chunk}"
    )
    _warm()
    robots = [optik.load_problem(name).robot for name in args.robots.split(",")]
    options = {
        "voxel": args.voxel,
        "orientations": args.orientations,
        "mode": args.mode,
        "restarts": args.restarts,
        "chunk": args.chunk,
    }
    rows: dict[str, dict[str, float]] = {r.name: {} for r in robots}
    reference: dict[str, Any] = {}
    for robot in robots:
        capability_map(robot, **options)  # warm-up: the parallel kernel and the Jacobian
        seconds, ds = _timed(lambda robot=robot: capability_map(robot, **options))
        queries = int(ds.inside.sum()) * ds.sizes["orientation"]
        rows[robot.name]["queries"] = queries
        rows[robot.name]["in-process"] = queries / seconds
        reference[robot.name] = ds
        poses = _grid_poses(ds)
        optik.solve_ik_batch(robot, poses[:1000], mode=args.mode, restarts=args.restarts)
        plain_s, plain = _timed(
            lambda robot=robot, poses=poses: optik.solve_ik_batch(
                robot, poses, mode=args.mode, restarts=args.restarts, max_iter=100
            )
        )
        same = np.array_equal(
            plain.success.reshape(ds.reached.shape) & ds.inside.values[..., None],
            ds.reached.values,
        )
        rows[robot.name]["plain batch"] = queries / plain_s
        rows[robot.name]["same samples reached"] = float(same)
        print(
            f"{robot.name}: {queries} queries; map in-process {seconds:.2f} s, plain "
            f"solve_ik_batch over the grid {plain_s:.2f} s (same reached samples: {same})"
        )
    overhead_us = float("nan")
    for n in (int(w) for w in args.workers.split(",")):
        with open_engine(workers=n) as engine:
            engine.client.run(_warm)
            start = time.perf_counter()
            futures = engine.client.map(_noop, range(200), pure=False)
            engine.client.gather(futures)
            overhead_us = (time.perf_counter() - start) / 200 * 1e6
            for robot in robots:
                seconds, ds = _timed(
                    lambda robot=robot, engine=engine: capability_map(
                        robot, client=engine.client, **options
                    )
                )
                same = np.array_equal(ds.reached.values, reference[robot.name].reached.values)
                rows[robot.name][f"{n} worker(s)"] = rows[robot.name]["queries"] / seconds
                print(f"{robot.name}: {n} worker(s) {seconds:.2f} s (identical map: {same})")
        print(f"dask per-task overhead on {n} worker(s): {overhead_us:.0f} us (200 empty tasks)")
    print()
    columns = ["in-process", "plain batch", *(f"{w} worker(s)" for w in args.workers.split(","))]
    print(f"{'robot':<10}{'queries':>9}" + "".join(f"{c + ' q/s':>20}" for c in columns))
    for name, row in rows.items():
        cells = "".join(f"{row.get(c, float('nan')):>20.0f}" for c in columns)
        print(f"{name:<10}{int(row['queries']):>9}{cells}")
    for name, row in rows.items():
        overhead = row["plain batch"] / row["in-process"] - 1.0
        line = f"{name}: map overhead against the plain batch {overhead:+.1%}"
        if "1 worker(s)" in row and "2 worker(s)" in row:
            line += f"; scaling 1 -> 2 workers {row['2 worker(s)'] / row['1 worker(s)']:.2f}x"
        line += f"; per query in-process {1e6 / row['in-process']:.0f} us"
        print(line)
    print(f"load after: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
