"""Branches of the closed forms found from a maker's URDF, against EAIK on the same file.

Run: ``python benchmarks/bench_geometry_eaik.py [--poses 200] [--seed 0] [--batch 20000]
[--repeat 7]``

Needs ``example-robot-data`` (the ``test`` extra: the makers' URDFs) and EAIK
(``pip install eaik``, the ``bench`` extra). For the UR3, UR5 and UR10 of
``ur_description`` (and any other arm of the package that both libraries solve), it draws
random in-limit configurations, forms the pose of each with each library's own forward
kinematics (EAIK's end frame need not be optik's ``tool0``), and compares:

- the number of branches: optik's ``analytic_ik(..., within_limits=False)`` (every branch,
  FK-verified to 1e-9) against EAIK's exact (not least-squares) solutions;
- whether each optik branch equals one of EAIK's after wrapping angles (1e-9), and the
  largest such difference; for a branch further from EAIK's nearest, which of the two
  reaches the pose closer in EAIK's own forward kinematics (the rounding of one or the
  other, next to a singularity);
- the time per pose of each (medians over the poses, one process, same poses);
- batched, ``--batch`` poses (default 20,000): ``analytic_ik_batch`` (every branch in
  the limits) against EAIK's ``IK_batched(..., num_worker_threads=1)`` on the same
  configurations' poses (each in its own end frame), alternating, best of ``--repeat``
  runs by the CPU time of the process (``time.process_time``: EAIK solves in a worker
  thread even with one, which the caller's thread time would miss; other processes on a
  shared machine only ever add wall time), as poses per second.

No assertions: the figures are reported.
"""

from __future__ import annotations

import argparse
import importlib.metadata
import math
import statistics
import time
from pathlib import Path
from typing import Any

import numpy as np

from optik import Robot
from optik.analytic import analytic_ik, analytic_ik_batch, explain_family, family_of

ARMS = (
    ("ur3", "ur_description/urdf/ur3_robot.urdf", "base_link", "tool0"),
    ("ur5", "ur_description/urdf/ur5_robot.urdf", "base_link", "tool0"),
    ("ur10", "ur_description/urdf/ur10_robot.urdf", "base_link", "tool0"),
    (
        "kinova j2s6s200",
        "kinova_description/robots/kinova.urdf",
        "j2s6s200_link_base",
        "j2s6s200_end_effector",
    ),
)


def robots_dir() -> Path:
    """The URDF folder of example-robot-data."""
    dist = importlib.metadata.distribution("example-robot-data")
    return Path(str(dist.locate_file("cmeel.prefix/share/example-robot-data/robots")))


def wrapped(a: np.ndarray, b: np.ndarray) -> float:
    """Max-abs angle difference after wrapping into (-pi, pi]."""
    return float(np.max(np.abs(np.remainder(a - b + math.pi, 2 * math.pi) - math.pi)))


def pose_error(A: np.ndarray, B: np.ndarray) -> float:
    """Max-abs entry of ``A - B`` (4x4 poses; metres and rotation entries)."""
    return float(np.max(np.abs(np.asarray(A) - np.asarray(B))))


def compare(
    label: str, path: Path, base: str, tip: str, n: int, seed: int, batch: int, repeat: int
) -> None:
    """Print the comparison for one arm."""
    from eaik.IK_URDF import UrdfRobot

    robot = Robot.from_urdf(path, base, tip)
    print(explain_family(robot))
    eaik_robot = UrdfRobot(str(path))
    print(f"  EAIK: {eaik_robot.getKinematicFamily()}")
    rng = np.random.default_rng(seed)
    lower = np.maximum(robot.lower, -math.pi)
    upper = np.minimum(robot.upper, math.pi)
    Q = rng.uniform(lower, upper, (n, robot.dof))
    same_count = matched = total = 0
    worst = 0.0
    apart: list[tuple[float, float]] = []
    counts_optik: list[int] = []
    counts_eaik: list[int] = []
    t_optik: list[float] = []
    t_eaik: list[float] = []
    solvable = family_of(robot) is not None
    for q in Q:
        T_eaik = eaik_robot.fwdKin(q)
        t0 = time.perf_counter()
        sol = eaik_robot.IK(T_eaik)
        t_eaik.append(time.perf_counter() - t0)
        exact = [np.asarray(x) for x, ls in zip(sol.Q, sol.is_LS, strict=True) if not ls]
        counts_eaik.append(len(exact))
        if not solvable:
            continue
        T = robot.fk(q)
        t0 = time.perf_counter()
        branches = analytic_ik(robot, T, within_limits=False)
        t_optik.append(time.perf_counter() - t0)
        counts_optik.append(len(branches))
        same_count += len(branches) == len(exact)
        for b in branches:
            total += 1
            d, nearest = min(
                ((wrapped(b, e), i) for i, e in enumerate(exact)), default=(math.inf, -1)
            )
            worst = max(worst, d)
            matched += d < 1e-9
            if d >= 1e-9 and nearest >= 0:
                # Which of the two is nearer the pose, each in EAIK's own FK (its end frame).
                e = exact[nearest]
                apart.append(
                    (
                        pose_error(eaik_robot.fwdKin(b), T_eaik),
                        pose_error(eaik_robot.fwdKin(e), T_eaik),
                    )
                )
    print(f"  EAIK exact branches per pose: mean {np.mean(counts_eaik):.2f}")
    print(f"  EAIK IK per pose: median {1e6 * statistics.median(t_eaik):.1f} us")
    if not solvable:
        print("  optik: no closed form (see above)")
        return
    print(f"  optik branches per pose: mean {np.mean(counts_optik):.2f}")
    print(f"  poses with the same count: {same_count} / {n}")
    print(
        f"  optik branches equal to an EAIK one (1e-9): {matched} / {total}, max diff {worst:.1e}"
    )
    if apart:
        closer = sum(mine < theirs for mine, theirs in apart)
        print(
            f"  of the {len(apart)} further apart, optik's branch reaches the pose closer in"
            f" EAIK's FK: {closer}; pose errors (max abs of 4x4) optik <= "
            f"{max(m for m, _ in apart):.1e}, EAIK <= {max(t for _, t in apart):.1e}"
        )
    print(f"  optik analytic_ik per pose: median {1e6 * statistics.median(t_optik):.1f} us")
    if batch > 0:
        compare_batches(robot, eaik_robot, rng.uniform(lower, upper, (batch, robot.dof)), repeat)


def compare_batches(robot: Robot, eaik_robot: Any, Q: np.ndarray, repeat: int) -> None:
    """Print poses per second of ``analytic_ik_batch`` and EAIK's ``IK_batched``."""
    T = robot.fk(Q)
    T_eaik = [eaik_robot.fwdKin(q) for q in Q]
    analytic_ik_batch(robot, T[:10])
    eaik_robot.IK_batched(T_eaik[:10], num_worker_threads=1)
    calls = {
        "optik analytic_ik_batch": lambda: analytic_ik_batch(robot, T),
        "EAIK IK_batched (1 thread)": lambda: eaik_robot.IK_batched(T_eaik, num_worker_threads=1),
    }
    best = dict.fromkeys(calls, math.inf)
    for _ in range(repeat):
        for name, call in calls.items():
            t0 = time.process_time()
            call()
            best[name] = min(best[name], time.process_time() - t0)
    for name, seconds in best.items():
        print(f"  {name}: {len(Q) / seconds:,.0f} poses/s (best of {repeat}, process CPU time)")


def main() -> None:
    """Command-line entry point."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--poses", type=int, default=200)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--batch", type=int, default=20_000, help="poses per batch (0: none)")
    parser.add_argument("--repeat", type=int, default=7, help="timed batch runs (best)")
    args = parser.parse_args()
    root = robots_dir()
    for label, rel, base, tip in ARMS:
        compare(label, root / rel, base, tip, args.poses, args.seed, args.batch, args.repeat)


if __name__ == "__main__":
    main()
