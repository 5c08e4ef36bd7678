"""Seven-joint closed forms around a held joint (KUKA iiwa, Franka Panda): speed, sweeps.

Run: ``python benchmarks/bench_free_joint.py [--arms iiwa panda] [--single 500]
[--batch 20000] [--repeat 9] [--targets 300] [--sweeps 4 8 16] [--no-speed]
[--no-warm-start] [--no-peers]``

The arms: the iiwa of pybullet's ``pybullet_data`` (``kuka_iiwa/model.urdf``, the ``test``
extra), loaded with ``Robot.from_urdf``, and the Panda of ``problems/panda.toml`` (modified
DH, the hand as tool). Targets are the poses of configurations drawn uniformly inside the
limits (numpy generator, seeded), so each is reachable inside them.

**Speed** (``--no-speed`` skips it). The iiwa with joint 3 held (the closed form of the six
others in order) and joint 7 held (the chain read backwards); the Panda with joint 7 held
(read backwards). After a warm-up, optik and EAIK alternating within each timed run:

- ``analytic_ik(robot, T, free_joint=..., free_value=v)``: every branch with the joint at
  ``v``, wrapped into the limits, filtered by them and verified by FK (µs per pose), and
  the same with ``within_limits=False``;
- ``analytic_ik_batch(robot, T, free_joint=..., free_value=values)`` (poses per second);
- EAIK (``pip install eaik``): ``HPRobot(H, P, fixed_axes=[(j, v)]).IK(T)`` per pose and
  ``IK_batched(..., num_worker_threads=1)``, on the joint axes optik finds (directions
  ``H``, offsets ``P`` between joint points; the targets turned into EAIK's end frame
  beforehand, outside the timing). EAIK fixes the joint when the robot is built, so its
  poses all have the joint at one value ``v``; optik is timed on the same poses with
  that value. EAIK ignores the limits and does not verify its branches.

Times are wall medians over runs (``time.perf_counter``) and, beside them, the CPU time
of the thread (``time.thread_time``; the load of a shared machine spares it). The
branches per pose (without limits) turn a time per pose into a time per solution, the
unit of GeoFIK's published figure (about 0.08 ms per solution for the Panda, C++, q7
given).

**Warm start** (``--no-warm-start`` skips it). On ``--targets`` targets, in one process,
per target in a random order (the iiwa sweeps its joint 3, the Panda its joint 7):

- ``seed table``: ``solve_ik(robot, T)`` as today (the numeric solver from the seed
  table's entry nearest the target, restarts from seeded random configurations);
- ``sweep K + solve_ik``: ``analytic_ik_batch`` of the target with the joint held at
  ``K`` values spread over its range (one compiled call), the branch nearest mid-limits
  as ``q0`` of ``solve_ik`` (no branch: ``solve_ik`` as today); the time includes the
  sweep;
- ``sweep K alone``: the sweep's branch itself (FK-verified to 1e-9, inside the limits),
  no numeric solve;
- ``kernel sweep ...``: the same with the compiled loop alone (see :func:`sweep_start`).

Success is decided here from optik's FK of the returned ``q`` (position and rotation
angle <= 1e-6, every joint inside its limits). Reported: success rate, mean iterations
and restarts (``IKResult``), median and 95th percentile of the time per query.
No assertions: the figures are reported.
"""

from __future__ import annotations

import os

# One core for numpy as well.
for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import math  # noqa: E402
import platform  # noqa: E402
import statistics  # noqa: E402
import time  # noqa: E402
from collections.abc import Callable, Sequence  # noqa: E402
from pathlib import Path  # noqa: E402
from typing import Any, NamedTuple  # noqa: E402

import numba  # noqa: E402
import numpy as np  # noqa: E402
from numpy.typing import NDArray  # noqa: E402

from optik import Robot, analytic_ik, analytic_ik_batch, load_problem, solve_ik  # noqa: E402
from optik.analytic.geometry import joint_axes  # noqa: E402

Array = NDArray[np.float64]
TOL = 1e-6
GEOFIK_MS_PER_SOLUTION = 0.08  # published, Panda, per solution


class Arm(NamedTuple):
    """A seven-joint arm of the benchmark: the joints held for speed, the one swept."""

    label: str
    robot: Robot
    held: tuple[int, ...]
    swept: int


def iiwa() -> Arm:
    """The KUKA iiwa of ``pybullet_data``: joints 3 and 7 held, joint 3 swept."""
    import pybullet_data

    path = Path(pybullet_data.getDataPath()) / "kuka_iiwa" / "model.urdf"
    robot = Robot.from_urdf(path, "lbr_iiwa_link_0", "lbr_iiwa_link_7")
    return Arm("KUKA iiwa, pybullet_data", robot, (2, 6), 2)


def panda() -> Arm:
    """The Panda of ``problems/panda.toml``: joint 7 held and swept."""
    path = Path(__file__).resolve().parents[1] / "problems" / "panda.toml"
    return Arm("Franka Panda, problems/panda.toml", load_problem(path).robot, (6,), 6)


ARMS: dict[str, Callable[[], Arm]] = {"iiwa": iiwa, "panda": panda}


def in_limit_configurations(robot: Robot, n: int, seed: int) -> Array:
    """``n`` configurations drawn uniformly inside the limits."""
    return np.random.default_rng(seed).uniform(robot.lower, robot.upper, (n, robot.dof))


# ---------------------------------------------------------------------- speed
def timed_runs(
    methods: dict[str, Callable[[], object]], count: int, repeat: int
) -> dict[str, tuple[float, float]]:
    """Median wall and CPU seconds per pose of each method, the methods alternating."""
    for fn in methods.values():
        fn()
    wall: dict[str, list[float]] = {name: [] for name in methods}
    cpu: dict[str, list[float]] = {name: [] for name in methods}
    for _ in range(repeat):
        for name, fn in methods.items():
            w0, c0 = time.perf_counter(), time.thread_time()
            fn()
            cpu[name].append((time.thread_time() - c0) / count)
            wall[name].append((time.perf_counter() - w0) / count)
    return {n: (statistics.median(wall[n]), statistics.median(cpu[n])) for n in methods}


def eaik_robot(robot: Robot, joint: int, value: float) -> tuple[Any, Array] | None:
    """EAIK's robot on ``robot``'s joint axes with ``joint`` fixed at ``value``, or ``None``.

    Also returns the tool's rotation at ``q = 0``: EAIK's end frame has the world's
    orientation there, so a target ``T`` is ``[R_T R_0^T, p_T]`` for EAIK.
    """
    try:
        from eaik.IK_HP import HPRobot
    except ImportError:
        return None
    axes = joint_axes(robot)
    points = np.vstack([np.zeros(3), axes.points, axes.tool[:3, 3]])
    bot = HPRobot(axes.directions, np.diff(points, axis=0), fixed_axes=[(joint, value)])
    return bot, axes.tool[:3, :3]


def speed(robot: Robot, joint: int, single: int, batch: int, repeat: int, peers: bool) -> None:
    """Print the speed table of one held joint."""
    name = robot.joint_names[joint]
    value = 0.5 * float(robot.lower[joint] + robot.upper[joint]) + 0.3
    Q = in_limit_configurations(robot, single, seed=joint)
    Q[:, joint] = value
    poses = robot.fk(Q)
    Qb = in_limit_configurations(robot, batch, seed=100 + joint)
    big = robot.fk(Qb)
    values = Qb[:, joint].copy()
    counts = analytic_ik_batch(
        robot, poses, within_limits=False, free_joint=name, free_value=value
    ).counts
    per_pose = float(np.mean(counts))

    def optik_single() -> None:
        for T in poses:
            analytic_ik(robot, T, free_joint=name, free_value=value)

    def optik_single_all() -> None:
        for T in poses:
            analytic_ik(robot, T, within_limits=False, free_joint=name, free_value=value)

    singles: dict[str, Callable[[], object]] = {
        "optik analytic_ik (limits, FK-verified)": optik_single,
        "optik analytic_ik (no limits, FK-verified)": optik_single_all,
    }
    batches: dict[str, Callable[[], object]] = {
        f"optik analytic_ik_batch, N = {batch:,}": lambda: analytic_ik_batch(
            robot, big, free_joint=name, free_value=values
        )
    }
    made = eaik_robot(robot, joint, value) if peers else None
    eaik_note = "EAIK not run"
    if made is not None:
        bot, R0 = made
        turned = poses.copy()
        turned[:, :3, :3] = poses[:, :3, :3] @ R0.T
        listed = list(turned)
        theirs = [int(np.sum(~np.asarray(bot.IK(T).is_LS, dtype=bool))) for T in listed]
        eaik_note = (
            f"EAIK exact solutions per pose {np.mean(theirs):.2f}; optik without limits "
            f"{per_pose:.2f}; equal counts on {int(np.sum(np.array(theirs) == counts))}"
            f"/{len(poses)} poses"
        )

        def eaik_single() -> None:
            for T in listed:
                bot.IK(T)

        singles["EAIK IK (fixed joint, no limits, not verified)"] = eaik_single
        batches[f"EAIK IK_batched, 1 thread, N = {single:,}"] = lambda: bot.IK_batched(
            listed, num_worker_threads=1
        )
    s = timed_runs(singles, single, repeat)
    b = timed_runs({k: v for k, v in batches.items() if k.startswith("optik")}, batch, 3)
    b |= timed_runs({k: v for k, v in batches.items() if k.startswith("EAIK")}, single, 3)
    print(f"joint {joint + 1} ({name}) held; {per_pose:.2f} branches per pose (no limits)")
    print(f"  {'operation':<50}{'wall us/pose':>13}{'cpu us/pose':>13}{'cpu us/solution':>17}")
    for label, (wall, cpu) in (s | b).items():
        print(f"  {label:<50}{wall * 1e6:13.2f}{cpu * 1e6:13.2f}{cpu * 1e6 / per_pose:17.2f}")
    print(f"  {eaik_note}")
    print(
        f"  GeoFIK (published, Panda, q7 given, C++): "
        f"{GEOFIK_MS_PER_SOLUTION * 1e3:.0f} us per solution"
    )


# ---------------------------------------------------------------------- warm start
def succeeded(robot: Robot, q: Array, T: Array) -> bool:
    """Success from optik's FK: position and rotation angle within TOL, inside limits."""
    F = robot.fk(q)
    R = F[:3, :3].T @ T[:3, :3]
    vee = np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])
    angle = math.atan2(float(np.linalg.norm(vee)) / 2, (float(np.trace(R)) - 1) / 2)
    inside = bool(np.all(q >= robot.lower - 1e-12) and np.all(q <= robot.upper + 1e-12))
    return float(np.linalg.norm(F[:3, 3] - T[:3, 3])) <= TOL and angle <= TOL and inside


def sweep_start(robot: Robot, T: Array, joint: int, K: int, kernel: bool) -> Array | None:
    """The branch nearest mid-limits over ``K`` held values of ``joint``, or ``None``.

    ``kernel``: the compiled loop alone (optik's private
    ``optik.analytic.free_joint.solve_batch``, what a warm start inside ``solve_ik``
    would call), without ``analytic_ik_batch``'s per-target fallback (polish, other
    references) for the held values that give no branch.
    """
    lo, hi = float(robot.lower[joint]), float(robot.upper[joint])
    values = lo + (np.arange(K) + 0.5) / K * (hi - lo)
    mid = robot.mid_limits
    poses = np.ascontiguousarray(np.broadcast_to(T, (K, 4, 4)))
    if kernel:
        from optik.analytic import free_joint
        from optik.analytic.held_joint import free_plan

        params = free_plan(robot, joint).params
        Q, counts = free_joint.solve_batch(params, poses, mid.reshape(1, -1), values, 3)
        first = Q[counts > 0, 0]
    else:
        batch = analytic_ik_batch(
            robot, poses, q_ref=mid, free_joint=robot.joint_names[joint], free_value=values
        )
        first = batch.first[batch.solved]  # each row's branch nearest mid-limits
    if len(first) == 0:
        return None
    return np.asarray(first[np.argmin(np.linalg.norm(first - mid, axis=1))])


def warm_start(robot: Robot, joint: int, n: int, sweeps: Sequence[int], seed: int) -> None:
    """Print the warm-start table: today's seed table against the free-joint sweep."""
    targets = robot.fk(in_limit_configurations(robot, n, seed))
    rng = np.random.default_rng(seed + 1)

    def today(T: Array) -> tuple[Array, int, int]:
        res = solve_ik(robot, T)
        return res.q, res.iterations, res.restarts

    def swept(K: int, then_solve: bool, kernel: bool) -> Callable[[Array], tuple[Array, int, int]]:
        def method(T: Array) -> tuple[Array, int, int]:
            q0 = sweep_start(robot, T, joint, K, kernel)
            if not then_solve:
                return (np.full(robot.dof, np.nan) if q0 is None else q0), 0, 0
            res = solve_ik(robot, T) if q0 is None else solve_ik(robot, T, q0=q0)
            return res.q, res.iterations, res.restarts

        return method

    methods: dict[str, Callable[[Array], tuple[Array, int, int]]] = {"seed table": today}
    for K in sweeps:
        methods[f"sweep {K} + solve_ik"] = swept(K, True, False)
        methods[f"sweep {K} alone"] = swept(K, False, False)
        methods[f"kernel sweep {K} + solve_ik"] = swept(K, True, True)
        methods[f"kernel sweep {K} alone"] = swept(K, False, True)
    for fn in methods.values():  # warm-up: numba loads its kernels
        for T in targets[:3]:
            fn(T)
    stats: dict[str, dict[str, list[float]]] = {
        m: {"ok": [], "it": [], "re": [], "wall": [], "cpu": []} for m in methods
    }
    names = list(methods)
    for T in targets:
        for m in rng.permutation(names):
            w0, c0 = time.perf_counter(), time.thread_time()
            q, it, re = methods[m](T)
            cpu, wall = time.thread_time() - c0, time.perf_counter() - w0
            ok = bool(np.all(np.isfinite(q))) and succeeded(robot, q, T)
            for key, v in (("ok", ok), ("it", it), ("re", re), ("wall", wall), ("cpu", cpu)):
                stats[m][key].append(float(v))
    print(
        f"{n} reachable targets (FK of in-limit configurations), tol {TOL:g}; sweeps hold "
        f"joint {joint + 1} at K values spread over its range"
    )
    print(
        f"  {'method':<30}{'success':>9}{'iters':>8}{'restarts':>10}{'wall med':>10}"
        f"{'wall p95':>10}{'cpu med':>10}{'cpu p95':>10}   (times in us)"
    )
    for m, s in stats.items():
        wall = np.array(s["wall"]) * 1e6
        cpu = np.array(s["cpu"]) * 1e6
        print(
            f"  {m:<30}{np.mean(s['ok']):9.1%}{np.mean(s['it']):8.1f}{np.mean(s['re']):10.2f}"
            f"{np.median(wall):10.0f}{np.percentile(wall, 95):10.0f}"
            f"{np.median(cpu):10.0f}{np.percentile(cpu, 95):10.0f}"
        )


def main(argv: Sequence[str] | None = None) -> None:
    """Run the benchmark and print the tables."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--single", type=int, default=500, help="poses per single-call run")
    parser.add_argument("--batch", type=int, default=20_000, help="poses per batch")
    parser.add_argument("--repeat", type=int, default=9, help="timed runs (median)")
    parser.add_argument("--targets", type=int, default=300, help="warm-start targets")
    parser.add_argument("--sweeps", type=int, nargs="+", default=[4, 8, 16], help="K values")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--speed", action=argparse.BooleanOptionalAction, default=True)
    parser.add_argument("--warm-start", action=argparse.BooleanOptionalAction, default=True)
    parser.add_argument("--peers", action=argparse.BooleanOptionalAction, default=True)
    parser.add_argument("--arms", nargs="+", choices=sorted(ARMS), default=["iiwa", "panda"])
    args = parser.parse_args(argv)
    print(
        f"optik free-joint benchmark; python "
        f"{platform.python_version()}, numpy {np.__version__}, numba {numba.__version__}, "
        f"{platform.machine()}, {os.cpu_count()} CPUs; 1-min load {os.getloadavg()[0]:.2f}"
    )
    for key in args.arms:
        arm = ARMS[key]()
        print(f"== {arm.label}")
        if args.speed:
            for joint in arm.held:
                speed(arm.robot, joint, args.single, args.batch, args.repeat, args.peers)
        if args.warm_start:
            warm_start(arm.robot, arm.swept, args.targets, args.sweeps, args.seed)
    print(f"1-min load at the end {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
