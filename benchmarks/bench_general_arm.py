"""The arms found from the axes with any twists (a quartic or skew axes) against EAIK.

Run: ``python benchmarks/bench_general_arm.py [--poses 500] [--seed 0] [--batch 20000]
[--repeat 7]``

Needs EAIK (``pip install eaik``, the ``bench`` extra). Four arms built from standard DH
rows with a moved base and tool: EAIK's "spherical, no parallel, no intersecting"
(optik's quartic, :mod:`optik.analytic.general_arm`), "spherical, second two
intersecting" (subproblems, :func:`optik.analytic.pair_wrist.second_pair_candidates`),
"three inner parallel" with twists of 50-70 deg (the ``three_parallel`` family, a quartic
too) and "three parallel, two intersecting" (``three_parallel``, subproblems); EAIK gets
the same joint axes (``HPRobot``). For random configurations it compares, pose by pose
and interleaved:

- the branches: optik's ``analytic_ik(..., within_limits=False)`` against EAIK's
  distinct solutions that reach the pose (1e-8; EAIK flags every branch of its
  "no parallel, no intersecting" class least-squares, exact or not), their counts and
  the largest difference after wrapping;
- the time per pose of each (medians, ``time.perf_counter``);
- batched: ``analytic_ik_batch`` against ``IK_batched(..., num_worker_threads=1)``, best
  of ``--repeat`` runs by process CPU time (``bench_geometry_eaik.compare_batches``).

No assertions: the figures are reported.
"""

from __future__ import annotations

import argparse
import math
import statistics
import time

import numpy as np
from bench_geometry_eaik import compare_batches, wrapped
from scipy.spatial.transform import Rotation

from optik import Robot
from optik.analytic import analytic_ik, explain_family
from optik.analytic.geometry import joint_axes

WRIST = [(0.0, -90.0, 0.45, 0.0), (0.0, 90.0, 0.0, 0.3), (0.0, 0.0, 0.1, 0.0)]
ARMS = {
    "no parallel, no intersecting": [
        (0.1, 60.0, 0.4, 0.2),
        (0.5, 40.0, 0.1, 0.1),
        (0.05, 75.0, 0.0, -0.3),
        *WRIST,
    ],
    "second two intersecting": [
        (0.1, 60.0, 0.4, 0.2),
        (0.0, 40.0, 0.1, 0.1),
        (0.05, 75.0, 0.0, -0.3),
        *WRIST,
    ],
    "three inner parallel": [
        (0.1, 60.0, 0.3, 0.2),
        (0.4, 0.0, 0.1, 0.1),
        (0.35, 0.0, 0.05, -0.3),
        (0.05, 70.0, 0.1, 0.0),
        (0.03, -50.0, 0.1, 0.3),
        (0.0, 0.0, 0.1, 0.0),
    ],
    "three parallel, two intersecting": [
        (0.4, 0.0, 0.3, 0.2),
        (0.35, 0.0, 0.1, 0.1),
        (0.05, 65.0, 0.05, -0.3),
        (0.1, 55.0, 0.2, 0.0),
        (0.0, -60.0, 0.0, 0.3),
        (0.0, 0.0, 0.1, 0.0),
    ],
}
"""Standard DH rows (a m, alpha deg, d m, theta rad)."""


def build(spec: list[tuple[float, float, float, float]]) -> Robot:
    """The arm with a tilted, shifted base and a turned, offset tool."""
    base = np.eye(4)
    base[:3, :3] = Rotation.from_euler("xyz", [0.2, -0.3, 0.9]).as_matrix()
    base[:3, 3] = (0.3, -0.2, 0.1)
    tool = np.eye(4)
    tool[:3, :3] = Rotation.from_euler("zx", [0.4, -0.7]).as_matrix()
    tool[:3, 3] = (0.02, 0.03, 0.12)
    rows = [
        {"a": a, "alpha": math.radians(al), "d": d, "theta": th, "lower": -3.2, "upper": 3.2}
        for a, al, d, th in spec
    ]
    return Robot.from_dh(rows, base=base, tool=tool)


def compare(label: str, robot: Robot, n: int, seed: int, batch: int, repeat: int) -> None:
    """Print the comparison for one arm."""
    from eaik.IK_HP import HPRobot

    axes = joint_axes(robot)
    points = np.vstack([np.zeros(3), axes.points, axes.tool[:3, 3]])
    eaik_robot = HPRobot(axes.directions, np.diff(points, axis=0))
    print(f"arm {label!r}: {explain_family(robot).splitlines()[0]}")
    print(f"  EAIK: {eaik_robot.getKinematicFamily()}")
    rng = np.random.default_rng(seed)
    t_optik: list[float] = []
    t_eaik: list[float] = []
    same = branches_total = 0
    worst = 0.0
    for q in rng.uniform(-math.pi, math.pi, (n, 6)):
        T = robot.fk(q)
        T_eaik = eaik_robot.fwdKin(q)
        t0 = time.perf_counter()
        sol = eaik_robot.IK(T_eaik)
        t_eaik.append(time.perf_counter() - t0)
        t0 = time.perf_counter()
        branches = analytic_ik(robot, T, within_limits=False)
        t_optik.append(time.perf_counter() - t0)
        reaching: list[np.ndarray] = []
        for x in map(np.asarray, sol.Q):
            if np.abs(robot.fk(x) - T).max() < 1e-8 and all(wrapped(x, r) > 1e-6 for r in reaching):
                reaching.append(x)
        same += len(reaching) == len(branches)
        branches_total += len(branches)
        for b in branches:
            worst = max(worst, min((wrapped(b, r) for r in reaching), default=math.inf))
    print(f"  poses with the same branch count: {same} / {n} ({branches_total} branches)")
    print(f"  largest difference to an EAIK branch: {worst:.1e} rad")
    print(f"  optik analytic_ik per pose: median {1e6 * statistics.median(t_optik):.1f} us")
    print(f"  EAIK IK per pose: median {1e6 * statistics.median(t_eaik):.1f} us")
    if batch > 0:
        compare_batches(robot, eaik_robot, rng.uniform(-math.pi, math.pi, (batch, 6)), repeat)


def main() -> None:
    """Command-line entry point."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--poses", type=int, default=500, help="poses compared one by one")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--batch", type=int, default=20_000, help="poses per batch (0: none)")
    parser.add_argument("--repeat", type=int, default=7, help="timed batch runs (best)")
    args = parser.parse_args()
    for label, spec in ARMS.items():
        compare(label, build(spec), args.poses, args.seed, args.batch, args.repeat)


if __name__ == "__main__":
    main()
