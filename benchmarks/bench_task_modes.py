"""Task queries against a full-pose query through ``dls`` on one robot, interleaved in one run.

Run: ``PYTHONPATH=$PWD python benchmarks/bench_task_modes.py [--robot panda] [-n 300]``.

Targets come from the FK of seeded random in-limit configurations, so every task below
is reachable by construction (the source configuration solves it):

- ``pose``: the FK pose itself (the reference row);
- ``axis``: the FK pose turned by a random roll about its tool z axis, ``mode="axis"``;
- ``weights free z``: the FK pose moved by a random distance (±0.1 m) along its own z
  axis, ``weights=[1, 1, 0, 1, 1, 1]`` (the insertion depth free);
- ``frozen last`` / ``frozen first``: the FK pose with the last / first joint frozen at
  its source value;
- ``margin 0.1``: the FK pose of a configuration drawn 0.1 rad inside the limits, with
  ``limit_margin=0.1``;
- ``position``: the FK position, ``mode="position"``.

Each query is timed with the calling thread's CPU time (``time.thread_time``), methods
in a random order per target, after a warm-up; every answer is judged here from FK.
Printed per row: success, median and p95 µs, median / pose, mean iterations and
restarts. ``--batch`` adds ``solve_ik_batch`` throughput per task (one thread).
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import math  # noqa: E402
import statistics  # noqa: E402
import time  # noqa: E402
from collections.abc import Callable  # noqa: E402
from dataclasses import dataclass, field  # noqa: E402
from typing import Any  # noqa: E402

import numpy as np  # noqa: E402

import optik  # noqa: E402
from optik.spatial import rot_z  # noqa: E402

TOL = 1e-6


@dataclass
class Row:
    """One task: its name, keywords of ``solve_ik``, its targets and its record."""

    name: str
    keywords: dict[str, Any]
    targets: list[np.ndarray]
    judge: Callable[[optik.Robot, np.ndarray, np.ndarray], bool]
    times: list[float] = field(default_factory=list)
    ok: list[bool] = field(default_factory=list)
    iterations: list[int] = field(default_factory=list)
    restarts: list[int] = field(default_factory=list)


def _pose_ok(robot: optik.Robot, q: np.ndarray, T: np.ndarray) -> bool:
    F = robot.fk(q)
    return bool(
        np.linalg.norm(F[:3, 3] - T[:3, 3]) <= TOL
        and optik.spatial.rotation_angle(T[:3, :3].T @ F[:3, :3]) <= TOL
    )


def _axis_ok(robot: optik.Robot, q: np.ndarray, T: np.ndarray) -> bool:
    F = robot.fk(q)
    c = float(np.clip(F[:3, 2] @ T[:3, 2], -1.0, 1.0))
    s = float(np.linalg.norm(np.cross(F[:3, 2], T[:3, 2])))
    return bool(np.linalg.norm(F[:3, 3] - T[:3, 3]) <= TOL and math.atan2(s, c) <= TOL)


def _free_z_ok(robot: optik.Robot, q: np.ndarray, T: np.ndarray) -> bool:
    F = robot.fk(q)
    d = T[:3, :3].T @ (F[:3, 3] - T[:3, 3])
    return bool(
        np.linalg.norm(d[:2]) <= TOL
        and optik.spatial.rotation_angle(T[:3, :3].T @ F[:3, :3]) <= TOL
    )


def _position_ok(robot: optik.Robot, q: np.ndarray, T: np.ndarray) -> bool:
    return bool(np.linalg.norm(robot.fk(q)[:3, 3] - T[:3, 3]) <= TOL)


def build_rows(robot: optik.Robot, n: int, seed: int) -> list[Row]:
    """The rows of the module docstring, ``n`` targets each."""
    rng = np.random.default_rng(seed)
    lower, upper = robot.lower, robot.upper
    Q = rng.uniform(lower, upper, size=(n, robot.dof))
    Qm = rng.uniform(lower + 0.1, upper - 0.1, size=(n, robot.dof))
    poses = [robot.fk(q) for q in Q]
    names = robot.joint_names
    rolled, shifted = [], []
    for F in poses:
        R = F.copy()
        R[:3, :3] = F[:3, :3] @ rot_z(rng.uniform(-math.pi, math.pi))
        rolled.append(R)
        S = F.copy()
        S[:3, 3] = F[:3, 3] + rng.uniform(-0.1, 0.1) * F[:3, 2]
        shifted.append(S)
    rows = [
        Row("pose", {}, poses, _pose_ok),
        Row("axis", {"mode": "axis"}, rolled, _axis_ok),
        Row("weights free z", {"weights": [1, 1, 0, 1, 1, 1]}, shifted, _free_z_ok),
        Row("frozen last", {}, poses, _pose_ok),
        Row("frozen first", {}, poses, _pose_ok),
        Row("margin 0.1", {"limit_margin": 0.1}, [robot.fk(q) for q in Qm], _pose_ok),
        Row("position", {"mode": "position"}, poses, _position_ok),
    ]
    rows[3].keywords = {"frozen": [{names[-1]: float(q[-1])} for q in Q]}
    rows[4].keywords = {"frozen": [{names[0]: float(q[0])} for q in Q]}
    return rows


def _keywords(row: Row, k: int) -> dict[str, Any]:
    return {key: (value[k] if key == "frozen" else value) for key, value in row.keywords.items()}


def run(robot: optik.Robot, rows: list[Row], seed: int) -> None:
    """Time every row's queries, interleaved per target in a random order."""
    rng = np.random.default_rng(seed + 1)
    n = len(rows[0].targets)
    for row in rows:  # warm-up: compile every specialisation outside the timing
        optik.solve_ik(robot, row.targets[0], solver="dls", **_keywords(row, 0))
    for k in range(n):
        for i in rng.permutation(len(rows)):
            row = rows[i]
            keywords = _keywords(row, k)
            start = time.thread_time()
            res = optik.solve_ik(robot, row.targets[k], solver="dls", **keywords)
            row.times.append(time.thread_time() - start)
            ok = res.success and robot.within_limits(res.q)
            ok = ok and row.judge(robot, res.q, row.targets[k])
            if "frozen" in keywords:
                ((name, value),) = keywords["frozen"].items()
                ok = ok and float(res.q[robot.joint_names.index(name)]) == value
            row.ok.append(bool(ok))
            row.iterations.append(res.iterations)
            row.restarts.append(res.restarts)


def report(rows: list[Row]) -> None:
    """Print the table of the module docstring."""
    base = statistics.median(rows[0].times)
    print("| task | success | median µs | p95 µs | median / pose | iterations | restarts |")
    print("| --- | ---: | ---: | ---: | ---: | ---: | ---: |")
    for row in rows:
        t = np.array(row.times) * 1e6
        print(
            f"| {row.name} | {np.mean(row.ok):.3f} | {np.median(t):.1f} | "
            f"{np.percentile(t, 95):.1f} | {np.median(t) / (base * 1e6):.2f} | "
            f"{np.mean(row.iterations):.1f} | {np.mean(row.restarts):.2f} |"
        )


def batch(robot: optik.Robot, rows: list[Row]) -> None:
    """``solve_ik_batch`` throughput per row without per-target keywords (one thread)."""
    print("\n| task (batch, 1 thread) | targets/s | / pose |")
    print("| --- | ---: | ---: |")
    base = None
    for row in rows:
        if "frozen" in row.keywords or "limit_margin" in row.keywords:
            continue
        targets = np.array(row.targets * max(1, 4000 // len(row.targets)))
        optik.solve_ik_batch(robot, targets[:64], threads=1, **row.keywords)
        start = time.perf_counter()
        optik.solve_ik_batch(robot, targets, threads=1, **row.keywords)
        rate = len(targets) / (time.perf_counter() - start)
        base = base or rate
        print(f"| {row.name} | {rate:.0f} | {rate / base:.2f} |")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robot", default="panda", help="problem name (no unit)")
    parser.add_argument("-n", type=int, default=300, help="targets per task (no unit)")
    parser.add_argument("--seed", type=int, default=0, help="seed (no unit)")
    parser.add_argument("--batch", action="store_true", help="add solve_ik_batch throughput")
    args = parser.parse_args()
    robot = optik.load_problem(args.robot).robot
    print(f"{robot.name}, {args.n} targets per task, load {os.getloadavg()[0]:.2f}")
    rows = build_rows(robot, args.n, args.seed)
    run(robot, rows, args.seed)
    report(rows)
    if args.batch:
        batch(robot, rows)
    print(f"load after: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
