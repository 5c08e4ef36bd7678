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
- the scaling that follows from those CPU times on an idle machine of 2 cores,
  ``2 W1 / (W1 + C2)`` (see :func:`idle_scaling`): a figure that the load of a shared
  machine hardly moves, unlike the wall-clock one;
- Dask's per-task overhead (an empty task, round trip through the scheduler).

The configurations run interleaved, ``--rounds`` times (each round: in-process and the
plain batch for every robot, then a cluster of 1 worker, then one of 2, each started
afresh), after untimed warm-ups (numba's kernels, the workers' imports, Zarr); the report
gives medians over the rounds. The load of a shared machine still shows in the wall-clock
figures: it is printed with every run.
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

    ``S = 2 W1 / (W1 + C2)``: ``W1`` is the CPU time of the single worker over its map,
    ``C2`` that of this process (client, scheduler, nannies) over the map on 2 workers.
    With one worker the map takes ``W1``: this process runs on the other core. With two,
    the workers share the chunks, ``W1`` in all, and this process competes with them for
    the 2 cores: ``(W1 + C2) / 2``. The 2 workers' own CPU time is not used: on a loaded
    machine it differs from ``W1`` by up to 10 % either way from run to run (printed as
    the ratio ``W2 / W1``), for the same chunks. Left out: the run's serial start and end
    and the last chunk's tail (one worker finishing alone), which a clock would show, and
    this process's cost per second of wall time, which a loaded machine inflates.
    """
    w1 = sum(one.each)
    return cores * w1 / (w1 + two.own)


def _median(values: list[float]) -> float:
    return float(np.median(values)) if values else float("nan")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robots", default="ur5,panda")
    parser.add_argument("--voxel", type=float, default=0.15, help="m")
    parser.add_argument("--orientations", type=int, default=40)
    parser.add_argument("--mode", default="pose")
    parser.add_argument("--restarts", type=int, default=3)
    parser.add_argument("--chunk", type=int, default=4)
    parser.add_argument("--rounds", type=int, default=3, help="interleaved rounds (medians)")
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
        f"restarts {args.restarts}, chunk {args.chunk}, {args.rounds} rounds, "
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

    queries: dict[str, int] = {}
    chunks: dict[str, int] = {}
    reference: dict[str, Any] = {}
    poses: dict[str, np.ndarray] = {}
    # (robot, configuration) -> one Timed per round
    timings: dict[tuple[str, str], list[Timed]] = {}
    overhead_us: dict[int, list[float]] = {1: [], 2: []}

    def record(robot: Any, config: str, timed: Timed, reached: np.ndarray) -> None:
        timings.setdefault((robot.name, config), []).append(timed)
        same = np.array_equal(reached, reference[robot.name].reached.values)
        workers = ", ".join(f"{c:.2f}" for c in timed.each)
        print(
            f"  {robot.name} {config}: {timed.wall:.2f} s, CPU {timed.own:.2f} s here"
            + (f" and {workers} s in the workers" if workers else "")
            + f" (identical map: {same}); load {os.getloadavg()[0]:.2f}",
            flush=True,
        )

    try:
        for robot in robots:
            ds = make_map(robot).load()  # warm-up: the kernels, the Jacobian, Zarr
            reference[robot.name] = ds
            queries[robot.name] = int(ds.inside.sum()) * ds.sizes["orientation"]
            nx, ny = ds.sizes["x"], ds.sizes["y"]
            chunks[robot.name] = len(range(0, nx, args.chunk)) * len(range(0, ny, args.chunk))
            poses[robot.name] = _grid_poses(ds)
            optik.solve_ik_batch(robot, poses[robot.name][:1000], restarts=args.restarts)
        for round_ in range(args.rounds):
            print(f"round {round_ + 1}", flush=True)
            for robot in robots:
                timed = Timed([])
                ds = timed.run(lambda robot=robot: make_map(robot)).load()
                record(robot, "in-process", timed, ds.reached.values)
                plain = Timed([])
                result = plain.run(
                    lambda robot=robot: optik.solve_ik_batch(
                        robot,
                        poses[robot.name],
                        mode=args.mode,
                        restarts=args.restarts,
                        max_iter=100,
                    )
                )
                ds = reference[robot.name]
                reached = result.success.reshape(ds.reached.shape) & ds.inside.values[..., None]
                record(robot, "plain batch", plain, reached)  # the same samples reached?
            # One cluster at a time: an idle cluster's scheduler and nannies run in this
            # process and would count in the other's figures.
            for n in (1, 2):
                with open_engine(workers=n) as engine:
                    client = engine.client
                    client.run(_warm)
                    pids = sorted(client.run(os.getpid).values())
                    start = time.perf_counter()
                    client.gather(client.map(_noop, range(200), pure=False))
                    overhead_us[n].append((time.perf_counter() - start) / 200 * 1e6)
                    for robot in robots:
                        make_map(robot, client=client)  # warm-up: Zarr on the workers
                        timed = Timed(pids)
                        ds = timed.run(lambda robot=robot, c=client: make_map(robot, client=c))
                        record(robot, f"{n} worker(s)", timed, ds.reached.values)
    finally:
        shutil.rmtree(folder, ignore_errors=True)
    print()
    for n, values in overhead_us.items():
        print(f"dask per-task overhead on {n} worker(s): {_median(values):.0f} us (200 tasks)")
    columns = ["in-process", "plain batch", "1 worker(s)", "2 worker(s)"]
    print(
        f"{'robot':<10}{'queries':>9}{'chunks':>8}" + "".join(f"{c + ' q/s':>20}" for c in columns)
    )
    for robot in robots:
        name = robot.name
        rates = [queries[name] / _median([t.wall for t in timings[(name, c)]]) for c in columns]
        cells = "".join(f"{rate:>20.0f}" for rate in rates)
        print(f"{name:<10}{queries[name]:>9}{chunks[name]:>8}{cells}")
    print("(medians over the rounds; each ratio below is the median of the rounds' ratios)")
    for robot in robots:
        name = robot.name
        maps, plains = timings[(name, "in-process")], timings[(name, "plain batch")]
        ones, twos = timings[(name, "1 worker(s)")], timings[(name, "2 worker(s)")]
        wall = _median([m.wall / p.wall - 1.0 for m, p in zip(maps, plains, strict=True)])
        cpu = _median([m.own / p.own - 1.0 for m, p in zip(maps, plains, strict=True)])
        scaling = _median([a.wall / b.wall for a, b in zip(ones, twos, strict=True)])
        idle = _median([idle_scaling(a, b) for a, b in zip(ones, twos, strict=True)])
        spread = ", ".join(
            f"{sum(b.each) / sum(a.each):.2f}" for a, b in zip(ones, twos, strict=True)
        )
        client = _median([t.own / chunks[name] * 1e3 for t in twos])
        per_query = _median([max(t.each) / queries[name] * 1e6 for t in ones])
        print(
            f"{name}: map overhead against the plain batch {wall:+.1%} wall, {cpu:+.1%} CPU; "
            f"scaling 1 -> 2 workers {scaling:.2f}x wall, {idle:.2f}x from the CPU times "
            f"(2 W1 / (W1 + C2), idle 2-core machine; W2 / W1 by round: {spread}); on 2 "
            f"workers this process used {client:.1f} ms of CPU per chunk; one worker "
            f"{per_query:.1f} us of CPU per query"
        )
    print(f"load after: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
