"""Capability-map throughput: in-process, on 1 and 2 local Dask workers, against plain batches.

Run: ``PYTHONPATH=$PWD python benchmarks/bench_map.py --voxel 0.08`` (a few minutes on two
cores; ``--voxel`` and ``--orientations`` scale it). Every map is written to Zarr in a
temporary folder, as ``optik map`` writes it (``--memory``: kept in memory instead). For
each robot it reports:

- IK queries per second of :func:`optik.capability_map` in-process (a thread per core),
  and on a local cluster of 1 and of 2 worker processes (1 thread each), and the 1 -> 2
  scaling;
- the same samples solved by one plain :func:`optik.solve_ik_batch` call over the whole
  grid (the same seeds, so the same work: the script checks that both reach the same
  samples), and the map's overhead against it, in wall time and in CPU time of the process;
- where the CPU goes on Dask: the CPU time (user + system, from ``psutil``) of each worker
  process, and of this process, which runs the client, the scheduler and the workers'
  nannies of a local cluster; per chunk for this process;
- the scaling that follows from those CPU times on an idle machine of 2 cores (see
  :func:`idle_scaling`): a figure that the load of a shared machine does not set, unlike
  the wall-clock one;
- Dask's per-task overhead (an empty task, round trip through the scheduler).

Each figure is one timed run after an untimed warm-up (numba's kernels, the workers'
imports, Zarr), so the load of a shared machine shows: it is printed before and after.
"""

from __future__ import annotations

import argparse
import os
import platform
import shutil
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numba
import numpy as np
import psutil

import optik
from optik.campaign import capability_map, open_engine
from optik.campaign import engine as engine_module


def _noop(x: int) -> int:
    return x


def _warm() -> None:
    for name in ("ur5", "panda"):
        robot = optik.load_problem(name).robot
        capability_map(robot, voxel=0.5, orientations=2, restarts=0)
        optik.solve_ik_batch(robot, robot.fk(robot.mid_limits)[None], restarts=0, threads=1)


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


def _cpu(pid: int) -> float:
    """CPU time (user + system, s) of a process so far."""
    times = psutil.Process(pid).cpu_times()
    return float(times.user + times.system)


class Timed:
    """Wall time and CPU time of this process and of the given worker processes."""

    def __init__(self, workers: list[int]) -> None:
        self.workers = workers
        self.wall = self.own = 0.0
        self.each: list[float] = []

    def run(self, fn: Callable[[], Any]) -> Any:
        """``fn()``, timed."""
        before = [_cpu(p) for p in self.workers]
        own, start = _cpu(os.getpid()), time.perf_counter()
        result = fn()
        self.wall = time.perf_counter() - start
        self.own = _cpu(os.getpid()) - own
        self.each = [_cpu(p) - b for p, b in zip(self.workers, before, strict=True)]
        return result


def idle_scaling(one: Timed, two: Timed, cores: int = 2) -> float:
    """The 1 -> 2 worker scaling on an idle machine of ``cores`` cores, from CPU times.

    With one worker the map takes the worker's CPU time (this process, the client, the
    scheduler and the nanny, runs on another core). With two workers on two cores, every
    process shares them: the map takes at least the CPU time of all of them over the
    cores, and at least the busiest worker's. The end of the run (one worker finishing the
    last chunk alone) and the scheduler's latency are left out, so this is an upper bound
    of what a clock would show.
    """
    t1 = max(max(one.each), one.own)
    t2 = max((sum(two.each) + two.own) / cores, max(two.each))
    return t1 / t2


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robots", default="ur5,panda")
    parser.add_argument("--voxel", type=float, default=0.15, help="m")
    parser.add_argument("--orientations", type=int, default=40)
    parser.add_argument("--mode", default="pose")
    parser.add_argument("--restarts", type=int, default=3)
    parser.add_argument("--chunk", type=int, default=4)
    parser.add_argument("--workers", default="1,2")
    parser.add_argument("--memory", action="store_true", help="keep the maps in memory")
    parser.add_argument(
        "--dask-defaults",
        action="store_true",
        help="start the local clusters with Dask's default settings, diagnostics included "
        "(instead of optik.campaign.engine.QUIET_CLUSTER)",
    )
    args = parser.parse_args()
    if args.dask_defaults:
        engine_module.QUIET_CLUSTER = {}
    print(
        f"optik map benchmark; python {platform.python_version()}, numba {numba.__version__}, "
        f"{os.cpu_count()} CPUs, load {os.getloadavg()[0]:.2f}"
    )
    print(
        f"settings: voxel {args.voxel} m, {args.orientations} orientations, mode {args.mode}, "
        f"restarts {args.restarts}, chunk {args.chunk}, "
        + ("in memory" if args.memory else "written to Zarr")
        + (", Dask's default settings" if args.dask_defaults else "")
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
    folder = Path(tempfile.mkdtemp(prefix="bench-map-"))
    runs = iter(range(10**6))

    def make_map(robot: Any, **more: Any) -> Any:
        out = None if args.memory else folder / f"map-{next(runs)}.zarr"
        return capability_map(robot, out=out, **options, **more)  # read lazily from out

    rows: dict[str, dict[str, float]] = {r.name: {} for r in robots}
    reference: dict[str, Any] = {}
    timings: dict[tuple[str, int], Timed] = {}
    try:
        for robot in robots:
            make_map(robot)  # warm-up: the kernels, the Jacobian, Zarr
            timed = Timed([])
            ds = timed.run(lambda robot=robot: make_map(robot)).load()
            queries = int(ds.inside.sum()) * ds.sizes["orientation"]
            chunks = len(range(0, ds.sizes["x"], args.chunk)) * len(
                range(0, ds.sizes["y"], args.chunk)
            )
            row = rows[robot.name]
            row.update(queries=queries, chunks=chunks, **{"in-process": queries / timed.wall})
            row["in-process cpu"] = timed.own
            reference[robot.name] = ds
            poses = _grid_poses(ds)
            optik.solve_ik_batch(robot, poses[:1000], mode=args.mode, restarts=args.restarts)
            plain = Timed([])
            result = plain.run(
                lambda robot=robot, poses=poses: optik.solve_ik_batch(
                    robot, poses, mode=args.mode, restarts=args.restarts, max_iter=100
                )
            )
            same = np.array_equal(
                result.success.reshape(ds.reached.shape) & ds.inside.values[..., None],
                ds.reached.values,
            )
            row["plain batch"] = queries / plain.wall
            row["plain cpu"] = plain.own
            print(
                f"{robot.name}: {queries} queries in {chunks} chunks; map in-process "
                f"{timed.wall:.2f} s ({timed.own:.2f} s CPU), plain solve_ik_batch over the "
                f"grid {plain.wall:.2f} s ({plain.own:.2f} s CPU); same reached samples: {same}"
            )
        overhead_us = float("nan")
        for n in (int(w) for w in args.workers.split(",")):
            with open_engine(workers=n) as engine:
                client = engine.client
                client.run(_warm)
                pids = sorted(client.run(os.getpid).values())
                start = time.perf_counter()
                client.gather(client.map(_noop, range(200), pure=False))
                overhead_us = (time.perf_counter() - start) / 200 * 1e6
                for robot in robots:
                    make_map(robot, client=client)  # warm-up: Zarr on the workers
                    timed = Timed(pids)
                    ds = timed.run(lambda robot=robot, c=client: make_map(robot, client=c))
                    ds = ds.load()
                    timings[(robot.name, n)] = timed
                    same = np.array_equal(ds.reached.values, reference[robot.name].reached.values)
                    row = rows[robot.name]
                    row[f"{n} worker(s)"] = row["queries"] / timed.wall
                    print(
                        f"{robot.name}: {n} worker(s) {timed.wall:.2f} s (identical map: "
                        f"{same}); CPU s: workers "
                        + ", ".join(f"{c:.2f}" for c in timed.each)
                        + f", client + scheduler + nannies {timed.own:.2f} "
                        f"({timed.own / row['chunks'] * 1e3:.1f} ms per chunk); "
                        f"load {os.getloadavg()[0]:.2f}"
                    )
            print(f"dask per-task overhead on {n} worker(s): {overhead_us:.0f} us (200 tasks)")
    finally:
        shutil.rmtree(folder, ignore_errors=True)
    print()
    columns = ["in-process", "plain batch", *(f"{w} worker(s)" for w in args.workers.split(","))]
    print(f"{'robot':<10}{'queries':>9}" + "".join(f"{c + ' q/s':>20}" for c in columns))
    for name, row in rows.items():
        cells = "".join(f"{row.get(c, float('nan')):>20.0f}" for c in columns)
        print(f"{name:<10}{int(row['queries']):>9}{cells}")
    for name, row in rows.items():
        overhead = row["plain batch"] / row["in-process"] - 1.0
        cpu_overhead = row["in-process cpu"] / row["plain cpu"] - 1.0
        line = (
            f"{name}: map overhead against the plain batch {overhead:+.1%} wall, "
            f"{cpu_overhead:+.1%} CPU"
        )
        if "1 worker(s)" in row and "2 worker(s)" in row:
            line += f"; scaling 1 -> 2 workers {row['2 worker(s)'] / row['1 worker(s)']:.2f}x"
        if (name, 1) in timings and (name, 2) in timings:
            scale = idle_scaling(timings[(name, 1)], timings[(name, 2)])
            line += f" (from CPU times, idle 2-core machine: {scale:.2f}x)"
        line += f"; per query in-process {1e6 / row['in-process']:.0f} us"
        if (name, 1) in timings:
            per_query = max(timings[(name, 1)].each) / row["queries"]
            line += f", on one worker {per_query * 1e6:.0f} us CPU"
        print(line)
    print(f"load after: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
