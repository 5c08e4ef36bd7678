"""``solve_ik`` with a frozen joint: the closed form around it against the numeric search.

Run: ``python benchmarks/bench_frozen.py [-n 200] [--turned 50] [--seed 5]``

Queries (one process, the two methods alternating per target, after a warm-up):

- **Panda, q7 frozen at the pose's own value** (``-n`` poses of configurations drawn
  uniformly inside the limits): ``solve_ik(panda, T, frozen={q7: v})``, which answers
  with the closed form around q7 (solver ``"analytic"``), against the same call with
  ``warm_start="q0"`` (``dls`` from the seed table, the closed form not used).
- **Panda, q7 turned 1.5 rad away** (``--turned`` poses): the closed form answers or
  proves the pose out of reach at that q7 (``"unreachable"`` / ``"outside_limits"``,
  after its ``dls`` cross-check); ``dls`` searches until its restarts run out.
- **Puma 560, joint 6 frozen at the pose's own value**: the six-joint family's branch
  holding the joint, against ``warm_start="q0"``.

Success is decided here from optik's FK of the returned ``q`` (position and rotation
angle <= 1e-6, every joint inside its limits, the frozen joint at its value). Reported
per row: success, the statuses, median and 95th percentile of the wall time per query
(``time.perf_counter``) and of the thread's CPU time (``time.thread_time``).
No assertions: the figures are reported.
"""

from __future__ import annotations

import argparse
import os
import platform
import time
from collections import Counter
from typing import Any

import numpy as np

import optik
from optik import Robot, load_problem
from optik.spatial import rotation_angle

TOL = 1e-6


def _solved(robot: Robot, q: np.ndarray, T: np.ndarray, k: int, value: float) -> bool:
    reached = robot.fk(q)
    return bool(
        np.linalg.norm(reached[:3, 3] - T[:3, 3]) <= TOL
        and rotation_angle(reached[:3, :3].T @ T[:3, :3]) <= TOL
        and robot.within_limits(q)
        and q[k] == value
    )


def _row(label: str, outcomes: list[tuple[Any, float, float]], check: Any) -> str:
    wall = np.array([w for _, w, _ in outcomes]) * 1e6
    cpu = np.array([c for _, _, c in outcomes]) * 1e6
    ok = sum(check(r) for r, _, _ in outcomes)
    statuses = Counter(f"{r.solver}:{r.status}" for r, _, _ in outcomes)
    return (
        f"  {label:34s} success {ok:4d}/{len(outcomes):<4d} wall median {np.median(wall):7.0f} us"
        f" p95 {np.percentile(wall, 95):7.0f} us | cpu median {np.median(cpu):7.0f} us"
        f" p95 {np.percentile(cpu, 95):7.0f} us | {dict(statuses)}"
    )


def _compare(
    title: str, robot: Robot, targets: list[tuple[np.ndarray, float]], k: int, seed: int
) -> None:
    """Time the closed-form path and ``warm_start="q0"`` on ``targets``, interleaved."""
    name = robot.joint_names[k]
    methods = {"closed form (solver='auto')": {}, "dls (warm_start='q0')": {"warm_start": "q0"}}
    for T, value in targets[:3]:  # warm-up: kernels loaded, robot caches built
        for keywords in methods.values():
            optik.solve_ik(robot, T, frozen={name: value}, **keywords)
    outcomes: dict[str, list[tuple[Any, float, float]]] = {label: [] for label in methods}
    order = np.random.default_rng(seed)
    for T, value in targets:
        for label in order.permutation(list(methods)):
            wall, cpu = time.perf_counter(), time.thread_time()
            result = optik.solve_ik(robot, T, frozen={name: value}, **methods[label])
            cpu, wall = time.thread_time() - cpu, time.perf_counter() - wall
            outcomes[label].append((result, wall, cpu))
    print(f"{title} ({len(targets)} targets)")
    for label, rows in outcomes.items():
        checks = iter(targets)

        def check(result: Any, checks: Any = checks) -> bool:
            T, value = next(checks)
            return _solved(robot, result.q, T, k, value)

        print(_row(label, rows, check))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("-n", type=int, default=200, help="targets per row (default 200)")
    parser.add_argument("--turned", type=int, default=50, help="targets with q7 turned away")
    parser.add_argument("--seed", type=int, default=5, help="seed of the configurations")
    args = parser.parse_args()
    print(f"optik {optik.__version__}, Python {platform.python_version()}, {platform.machine()}")
    print(f"load average before: {os.getloadavg()[0]:.2f}")
    rng = np.random.default_rng(args.seed)
    panda = load_problem("panda").robot
    Q = rng.uniform(panda.lower, panda.upper, size=(max(args.n, args.turned), 7))
    own = [(panda.fk(q), float(q[6])) for q in Q[: args.n]]
    _compare("Panda, q7 frozen at the pose's own value", panda, own, 6, args.seed)
    turned = []
    for q in Q[: args.turned]:
        other = q[6] + 1.5 if q[6] + 1.5 <= panda.upper[6] else q[6] - 1.5
        turned.append((panda.fk(q), float(other)))
    _compare("Panda, q7 frozen 1.5 rad from the pose's own value", panda, turned, 6, args.seed)
    puma = load_problem("puma560").robot
    Qp = rng.uniform(puma.lower, puma.upper, size=(args.n, 6))
    _compare(
        "Puma 560, joint 6 frozen at the pose's own value",
        puma,
        [(puma.fk(q), float(q[5])) for q in Qp],
        5,
        args.seed,
    )
    print(f"load average after: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
