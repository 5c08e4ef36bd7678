"""Planning benchmarks: 1,000- and 20,001-waypoint lines and reachability of 100,000 points.

Run: ``python benchmarks/bench_planning.py``. Targets (issue): a 1,000-waypoint line for
the Puma 560 or UR5 planned in <= 1 s; reachability of 100,000 points (position only) in
<= 2 s on two cores. The trajectory of a 20,001-waypoint line, with and without the
robot (the departure from the path is measured with it), has no target. Prints medians
of repeated runs and the machine load.
"""

from __future__ import annotations

import os
import platform
import statistics
import time

import numba
import numpy as np

import optik
from optik.paths import line


def _median_time(fn, repeats: int) -> tuple[float, object]:  # type: ignore[no-untyped-def]
    times = []
    result = None
    for _ in range(repeats):
        start = time.perf_counter()
        result = fn()
        times.append(time.perf_counter() - start)
    return statistics.median(times), result


def main() -> None:
    print(
        f"optik planning benchmark; python {platform.python_version()}, numba {numba.__version__}, "
        f"{os.cpu_count()} CPUs, load {os.getloadavg()[0]:.2f}"
    )
    print(f"{'case':<52}{'median s':>10}  {'target':>8}  notes")
    for name, q0, q1 in [
        ("puma560", [0.2, 0.5, -0.8, 0.1, 0.6, 0.3], [0.6, 0.7, -1.0, 0.4, 0.2, -0.3]),
        ("ur5", [0.3, -1.2, 1.4, -0.4, 1.2, 0.2], [0.9, -1.0, 1.1, -0.2, 1.3, 0.6]),
    ]:
        robot = optik.load_problem(name).robot
        T0, T1 = robot.fk(np.array(q0)), robot.fk(np.array(q1))
        length = float(np.linalg.norm(T1[:3, 3] - T0[:3, 3]))
        poses = line(T0, T1, length / 999.0 * 1.000001)
        optik.plan_path(robot, poses[:5], max_joint_step=0.1)  # warm-up (compiles)
        seconds, plan = _median_time(
            lambda robot=robot, poses=poses: optik.plan_path(robot, poses, max_joint_step=0.1), 3
        )
        summary = plan.summary()  # type: ignore[attr-defined]
        print(
            f"{name} line, {len(poses)} waypoints (pose){'':<17}{seconds:>10.3f}  {'<= 1 s':>8}  "
            f"solved {summary['solved']}, flagged {summary['flagged']}"
        )
    # A long path timed: the trajectory's departure from the path measured with the robot.
    robot = optik.load_problem("puma560").robot
    q_now = np.array([-0.333, 3.713, -1.5713, 0.1582, 0.4196, 4.597])
    T0 = robot.fk(q_now)
    T1 = T0.copy()
    T1[:3, 3] += [0.05, 0.05, -0.05]
    poses = line(T0, T1, 0.0866 / 19_999)
    plan = optik.plan_path(robot, poses, max_joint_step=0.2, q_start=q_now)
    for given in (None, robot):
        seconds, trajectory = _median_time(
            lambda given=given: plan.to_trajectory(1.0, 2.0, robot=given), 3
        )
        label = f"puma560 {len(poses):,} wp, to_trajectory(robot={'puma560' if given else 'None'})"
        segments = len(trajectory.segments)  # type: ignore[attr-defined]
        print(f"{label:<52}{seconds:>10.3f}  {'-':>8}  {segments} segment(s)")
    for name in ("panda", "puma560"):
        robot = optik.load_problem(name).robot
        rng = np.random.default_rng(0)
        center, radius = robot.reach_sphere
        points = center + rng.uniform(-radius, radius, (100_000, 3))
        optik.reachability(robot, points[:100])
        for threads in (1, 2):
            numba.set_num_threads(threads)
            seconds, result = _median_time(
                lambda robot=robot, points=points: optik.reachability(robot, points), 3
            )
            reached = float(result.reachable.mean())  # type: ignore[attr-defined]
            print(
                f"{name} reachability, 100,000 points, {threads} thread(s){'':<8}{seconds:>10.3f}  "
                f"{'<= 2 s':>8}  reached {reached:.1%}"
            )
        numba.set_num_threads(numba.config.NUMBA_NUM_THREADS)


if __name__ == "__main__":
    main()
