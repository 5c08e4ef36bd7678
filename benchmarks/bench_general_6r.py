"""Any six revolute joints (``general_6r``): branches, completeness and time, on the xArm6.

Run: ``python benchmarks/bench_general_6r.py [--poses 200] [--check 20] [--starts 100]
[--seed 0]``

The arm is pybullet's xArm6 (``pybullet_data/xarm/xarm6_robot.urdf``, the ``test``
extra), which fits no decomposition (EAIK reports it "Unknown"). Targets are the poses of
configurations drawn uniformly inside the limits (numpy generator, seeded).

- branch counts: ``analytic_ik(..., within_limits=False)`` (every branch, FK-verified to
  1e-9) and inside the limits, over ``--poses`` poses; whether the configuration each pose
  came from is among them;
- completeness, on ``--check`` of the poses: the distinct answers (joint limits lifted,
  angles wrapped) that scipy's ``least_squares`` finds on ``Robot.fk`` from ``--starts``
  random starts, and how many of them the closed form misses (an independent search);
- time per pose of ``analytic_ik`` (wall median; thread CPU median beside it), and of
  ``solve_ik`` (which keeps ``dls`` for this family: ``AnalyticFamily.fast`` is
  ``False``) and ``solve_ik_all(k=16)`` (every branch, from the closed form) on the same
  targets, alternating per target: answers verified by FK, median and 95th percentile.

No assertions: the figures are reported.
"""

from __future__ import annotations

import argparse
import math
import statistics
import time
from pathlib import Path

import numpy as np
import pybullet_data
from scipy.optimize import least_squares

import optik
from optik.analytic import family_of


def _xarm6() -> optik.Robot:
    path = Path(pybullet_data.getDataPath()) / "xarm" / "xarm6_robot.urdf"
    return optik.Robot.from_urdf(path, "world", "link6")


def _wrapped(q: np.ndarray) -> np.ndarray:
    return np.arctan2(np.sin(q), np.cos(q))


def _distance(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.max(np.abs(_wrapped(a - b))))


def _searched(robot: optik.Robot, T: np.ndarray, starts: int, rng: np.random.Generator) -> list:
    def residual(q: np.ndarray) -> np.ndarray:
        F = robot.fk(q)
        return np.concatenate([F[:3, 3] - T[:3, 3], (F[:3, :3] - T[:3, :3]).ravel()])

    found: list[np.ndarray] = []
    for q0 in rng.uniform(-math.pi, math.pi, (starts, 6)):
        fit = least_squares(residual, q0, xtol=1e-15, ftol=1e-15, gtol=1e-15)
        if np.max(np.abs(fit.fun)) <= 1e-10 and all(
            _distance(fit.x, other) > 1e-6 for other in found
        ):
            found.append(_wrapped(fit.x))
    return found


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--poses", type=int, default=200)
    parser.add_argument("--check", type=int, default=20)
    parser.add_argument("--starts", type=int, default=100)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    robot = _xarm6()
    family = family_of(robot)
    print(f"xArm6 family: {family.name if family else None}")
    rng = np.random.default_rng(args.seed)
    Q = rng.uniform(robot.lower, robot.upper, (args.poses, 6))
    targets = robot.fk(Q)

    every, inside, found_own = [], [], 0
    for q, T in zip(Q, targets, strict=True):
        branches = optik.analytic_ik(robot, T, within_limits=False)
        every.append(len(branches))
        inside.append(len(optik.analytic_ik(robot, T)))
        found_own += any(_distance(b, q) < 1e-9 for b in branches)
    counts = {int(n): every.count(n) for n in sorted(set(every))}
    print(f"branches per pose (all): {counts}")
    print(f"branches per pose (in limits): mean {np.mean(inside):.2f}, min {min(inside)}")
    print(f"pose's own configuration among the branches: {found_own}/{args.poses}")

    missed = total = 0
    for T in targets[: args.check]:
        branches = optik.analytic_ik(robot, T, within_limits=False)
        answers = _searched(robot, T, args.starts, rng)
        total += len(answers)
        missed += sum(min(_distance(a, b) for b in branches) > 1e-6 for a in answers)
    print(
        f"scipy least_squares ({args.starts} starts) on {args.check} poses: {total} distinct "
        f"answers, {missed} missing from the closed form's branches"
    )

    for T in targets[:5]:  # warm
        optik.analytic_ik(robot, T)
        optik.solve_ik(robot, T)
        optik.solve_ik_all(robot, T, k=16)
    wall, cpu = [], []
    for T in targets:
        w, c = time.perf_counter(), time.thread_time()
        optik.analytic_ik(robot, T)
        cpu.append(time.thread_time() - c)
        wall.append(time.perf_counter() - w)
    print(
        f"analytic_ik per pose: {statistics.median(wall) * 1e3:.3f} ms wall, "
        f"{statistics.median(cpu) * 1e3:.3f} ms CPU (medians)"
    )
    # solve_ik keeps its numeric solver for a family that is not fast (general_6r);
    # solve_ik_all takes every branch from the closed form.
    times: dict[str, list[float]] = {"solve_ik": [], "solve_ik_all": []}
    success = {"solve_ik": 0, "solve_ik_all": 0}
    for T in targets:
        start = time.perf_counter()
        result = optik.solve_ik(robot, T)
        times["solve_ik"].append(time.perf_counter() - start)
        success["solve_ik"] += _verified(robot, result.q, T)
        start = time.perf_counter()
        answers = optik.solve_ik_all(robot, T, k=16)
        times["solve_ik_all"].append(time.perf_counter() - start)
        success["solve_ik_all"] += bool(answers) and all(_verified(robot, a.q, T) for a in answers)
    for name, label in (("solve_ik", "solve_ik (dls)"), ("solve_ik_all", "solve_ik_all (k=16)")):
        t = np.array(times[name]) * 1e3
        print(
            f"{label:20s}: verified {success[name]}/{args.poses}, median "
            f"{np.median(t):.3f} ms, p95 {np.percentile(t, 95):.3f} ms"
        )


def _verified(robot: optik.Robot, q: np.ndarray, T: np.ndarray) -> bool:
    """Whether ``q`` reaches ``T`` (1e-6 m and rad) inside the limits, by optik's FK."""
    F = robot.fk(q)
    cosine = (np.trace(F[:3, :3].T @ T[:3, :3]) - 1.0) / 2.0
    angle = math.acos(min(1.0, max(-1.0, cosine)))
    position = float(np.linalg.norm(F[:3, 3] - T[:3, 3]))
    return position <= 1e-6 and angle <= 1e-6 and bool(robot.within_limits(q))


if __name__ == "__main__":
    main()
