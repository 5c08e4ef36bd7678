"""``solve_ik`` with a posture against a plain pose query on the Panda, interleaved.

Run: ``python benchmarks/bench_posture.py [-n 300] [--seed 3] [--rounds 3]``.

Targets: FK poses of ``n`` configurations drawn uniformly inside the limits (numpy
generator seeded by ``--seed``), so every target is reachable. Per target, in a seeded
random order, these queries are timed with ``time.perf_counter`` around the call:

- ``pose``: ``solve_ik(robot, T)`` (the reference);
- ``posture``: ``solve_ik(robot, T, posture=q_ref)`` with ``q_ref`` the mid-limits;
- ``posture W``: the same with ``joint_weights = [1, ..., 7]``;
- ``axis posture``: ``mode="axis"`` with the posture.

Garbage collection is off inside the loop (and runs between rounds); the first queries of
each kind run untimed (numba compiles on first use). Reported per kind: success (judged
here from FK: 1e-6 m and rad, limits), median and 95th percentile (µs), and the ratio of
each median to the ``pose`` median (target for ``posture``: <= 3). The machine's load
average is printed before and after: on a shared machine the ratios, not the times, are
what carries over.
"""

from __future__ import annotations

import argparse
import gc
import math
import os
import platform
import sys
import time
from collections.abc import Callable

import numpy as np

import optik
from optik.spatial import rotation_angle

KINDS = ("pose", "posture", "posture W", "axis posture")


def _solved(robot: optik.Robot, q: np.ndarray, T: np.ndarray, mode: str) -> bool:
    F = robot.fk(q)
    if not np.all(q >= robot.lower - 1e-12) or not np.all(q <= robot.upper + 1e-12):
        return False
    if mode == "axis":
        a, b = F[:3, 2], T[:3, 2]
        angle = math.atan2(float(np.linalg.norm(np.cross(a, b))), float(a @ b))
    else:
        angle = float(rotation_angle(F[:3, :3].T @ T[:3, :3]))
    return float(np.linalg.norm(F[:3, 3] - T[:3, 3])) <= 1e-6 and angle <= 1e-6


def main(argv: list[str] | None = None) -> int:
    """Run the benchmark and print its report."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("-n", type=int, default=300, help="targets (no unit)")
    parser.add_argument("--seed", type=int, default=3, help="target seed (no unit)")
    parser.add_argument("--rounds", type=int, default=3, help="passes over the targets (no unit)")
    args = parser.parse_args(argv)
    robot = optik.load_problem("panda").robot
    rng = np.random.default_rng(args.seed)
    Q = rng.uniform(robot.lower, robot.upper, size=(args.n, robot.dof))
    targets = [robot.fk(q) for q in Q]
    q_ref = robot.mid_limits
    weights = np.arange(1.0, robot.dof + 1.0)
    calls: dict[str, tuple[str, Callable[[np.ndarray], optik.IKResult]]] = {
        "pose": ("pose", lambda T: optik.solve_ik(robot, T)),
        "posture": ("pose", lambda T: optik.solve_ik(robot, T, posture=q_ref)),
        "posture W": (
            "pose",
            lambda T: optik.solve_ik(robot, T, posture=q_ref, joint_weights=weights),
        ),
        "axis posture": ("axis", lambda T: optik.solve_ik(robot, T, mode="axis", posture=q_ref)),
    }
    for _, call in calls.values():  # compile, untimed
        for T in targets[:3]:
            call(T)
    times: dict[str, list[float]] = {k: [] for k in KINDS}
    ok: dict[str, int] = dict.fromkeys(KINDS, 0)
    order_rng = np.random.default_rng(args.seed + 1)
    print(f"command: python {' '.join(sys.argv)}")
    print(
        f"optik {optik.__version__} from {os.path.dirname(optik.__file__)}; numpy {np.__version__}"
    )
    print(f"python {platform.python_version()} on {platform.machine()}, {os.cpu_count()} cores")
    print(f"load average before: {os.getloadavg()}")
    for _ in range(args.rounds):
        gc.collect()
        gc.disable()
        try:
            for T in targets:
                for index in order_rng.permutation(len(KINDS)):
                    kind = KINDS[index]
                    mode, call = calls[kind]
                    t0 = time.perf_counter()
                    res = call(T)
                    times[kind].append(time.perf_counter() - t0)
                    ok[kind] += _solved(robot, res.q, T, mode)
        finally:
            gc.enable()
    print(f"load average after: {os.getloadavg()}")
    reference = float(np.median(times["pose"]))
    total = args.n * args.rounds
    print(f"\nPanda, {args.n} targets x {args.rounds} rounds, interleaved per target")
    print(f"{'query':14s} {'success':>9s} {'median us':>10s} {'p95 us':>9s} {'/ pose':>7s}")
    for kind in KINDS:
        t = np.asarray(times[kind]) * 1e6
        median = float(np.median(t))
        print(
            f"{kind:14s} {ok[kind] / total:9.4f} {median:10.1f} "
            f"{float(np.percentile(t, 95)):9.1f} {median / (reference * 1e6):7.2f}"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
