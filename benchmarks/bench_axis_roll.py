"""The tool-axis task on closed-form robots: the roll's closed form against ``dls``.

Run: ``python benchmarks/bench_axis_roll.py [-n 200] [--seed 5] [--rounds 3]
[--robots ur5,puma560]``; ``--robots general_arm`` takes a spherical wrist after a general
arm (:data:`GENERAL_ARM`).

Targets: the FK poses of ``n`` configurations drawn uniformly inside the limits, each
turned by a uniform random roll about its tool z axis (reachable in ``mode="axis"`` by
construction); ``q0`` is the source configuration plus N(0, 0.5 rad) noise, clipped into
the limits. Per target, in a seeded random order, these queries are timed with
``time.perf_counter`` around the call:

- ``closed form``: ``solve_ik(robot, T, mode="axis", q0=q0)`` (the roll's closed form,
  :mod:`optik.analytic.roll`: the answer nearest ``q0`` over the grid, refined);
- ``dls``: ``solve_ik(..., solver="dls", warm_start="q0")``, the numeric axis solve that
  ``solver="auto"`` ran before the closed form (the first answer from ``q0``);
- ``dls nearest``: the same with ``select="nearest"`` (every restart, the nearest kept),
  the numeric query that claims what the closed form gives.

Garbage collection is off inside a round; the first queries of each kind run untimed
(numba compiles on first use). Reported per robot and kind: success (judged here from FK:
1e-6 m, 1e-6 rad between the tool axes, limits), median time (µs), the ratio of each
median to ``dls``'s, and the median distance of the answer to ``q0`` (rad). The ratios in
one process are what carries over on a shared machine, not the times.
"""

from __future__ import annotations

import argparse
import gc
import math
import os
import platform
import statistics
import sys
import time
from collections.abc import Callable

import numpy as np

import optik
from optik.spatial import rot_z

KINDS = ("closed form", "dls", "dls nearest")


def _solved(robot: optik.Robot, q: np.ndarray, T: np.ndarray) -> bool:
    F = robot.fk(q)
    if not np.all(q >= robot.lower - 1e-12) or not np.all(q <= robot.upper + 1e-12):
        return False
    a, b = F[:3, 2], T[:3, 2]
    angle = math.atan2(float(np.linalg.norm(np.cross(a, b))), float(a @ b))
    return float(np.linalg.norm(F[:3, 3] - T[:3, 3])) <= 1e-6 and angle <= 1e-6


def _targets(robot: optik.Robot, n: int, seed: int) -> list[tuple[np.ndarray, np.ndarray]]:
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(n):
        q = rng.uniform(robot.lower, robot.upper)
        T = robot.fk(q)
        T[:3, :3] = T[:3, :3] @ rot_z(rng.uniform(-math.pi, math.pi))
        out.append((T, np.clip(q + rng.normal(0.0, 0.5, robot.dof), robot.lower, robot.upper)))
    return out


GENERAL_ARM = "general_arm"
"""The name of a robot that is no problem: ``bench_general_arm``'s "no parallel, no
intersecting" arm (``spherical_axes``, the quartic) with its moved base and offset tool,
whose rolls leave reach and whose branches meet wrist singularities along the roll."""


def _robot(name: str) -> optik.Robot:
    """A problem's robot, or the general arm (:data:`GENERAL_ARM`)."""
    if name == GENERAL_ARM:
        from bench_general_arm import ARMS, build

        return build(ARMS["no parallel, no intersecting"])
    return optik.load_problem(name).robot


def bench(name: str, n: int, seed: int, rounds: int) -> None:
    """Time the three kinds on robot ``name`` and print one row per kind."""
    robot = _robot(name)
    targets = _targets(robot, n, seed)
    calls: dict[str, Callable[[np.ndarray, np.ndarray], optik.IKResult]] = {
        "closed form": lambda T, q0: optik.solve_ik(robot, T, mode="axis", q0=q0),
        "dls": lambda T, q0: optik.solve_ik(
            robot, T, mode="axis", q0=q0, solver="dls", warm_start="q0"
        ),
        "dls nearest": lambda T, q0: optik.solve_ik(
            robot, T, mode="axis", q0=q0, solver="dls", warm_start="q0", select="nearest"
        ),
    }
    for call in calls.values():  # compile, untimed
        for T, q0 in targets[:3]:
            call(T, q0)
    times: dict[str, list[float]] = {k: [] for k in KINDS}
    ok = dict.fromkeys(KINDS, 0)
    distance: dict[str, list[float]] = {k: [] for k in KINDS}
    order_rng = np.random.default_rng(seed + 1)
    for round_ in range(rounds):
        gc.collect()
        gc.disable()
        try:
            for T, q0 in targets:
                for kind in order_rng.permutation(KINDS):
                    start = time.perf_counter()
                    res = calls[kind](T, q0)
                    times[kind].append(time.perf_counter() - start)
                    if round_ == 0:
                        good = _solved(robot, res.q, T)
                        ok[kind] += good
                        if good:
                            distance[kind].append(float(np.linalg.norm(res.q - q0)))
        finally:
            gc.enable()
    reference = statistics.median(times["dls"])
    print(f"\n{name}: {n} axis targets, {rounds} rounds")
    print(f"{'kind':<12} {'success':>8} {'median us':>10} {'/ dls':>7} {'|q - q0| median':>16}")
    for kind in KINDS:
        median = statistics.median(times[kind])
        print(
            f"{kind:<12} {ok[kind] / n:>8.1%} {median * 1e6:>10.0f} {median / reference:>7.2f} "
            f"{statistics.median(distance[kind]):>16.4f}"
        )


def main(argv: list[str] | None = None) -> int:
    """Run the benchmark and print its report."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("-n", type=int, default=200, help="targets per robot (no unit)")
    parser.add_argument("--seed", type=int, default=5, help="target seed (no unit)")
    parser.add_argument("--rounds", type=int, default=3, help="passes over the targets")
    parser.add_argument(
        "--robots",
        default="ur5,puma560",
        help=f"comma-separated problems, or {GENERAL_ARM!r} (see the module)",
    )
    args = parser.parse_args(argv)
    print(f"optik {optik.__version__}, Python {platform.python_version()}, {sys.platform}")
    print(f"load average before: {os.getloadavg()}")
    for name in args.robots.split(","):
        bench(name, args.n, args.seed, args.rounds)
    print(f"\nload average after: {os.getloadavg()}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
