"""5-D (tool-axis) IK on the Panda: optik's ``mode="axis"`` against RTB ``ik_LM`` with a mask.

Run: ``python benchmarks/bench_tasks.py [-n 500] [--batch-n 20000] [--seed 0]`` with RTB
installed (``pip install roboticstoolbox-python``); without it the optik rows still run.

What is compared. optik's axis task: the tool point on the target point and the tool z
axis along the target's z, the roll about it free (the position error and the angle
between the two axes, both judged in the target frame). RTB's ``mask`` weights the
error ``[p* - p; rotvec(R* R^T)]`` in the **base** frame: ``mask=[1, 1, 1, 1, 1, 0]``
frees the rotation about the base z axis, not about the tool axis. The two tasks are the
same only when the target's tool axis is parallel to the base z axis: then a rotation
about the base z is a roll about the tool axis, and RTB's masked error vanishes exactly
when the tool axis is aligned (``R* R^T`` a rotation about the base z). So the targets
here are **vertical drilling** targets: the tool z pointing straight down, a random roll.
For a tilted axis RTB's mask would solve another task (it would have to rotate the base
frame per target); that is not measured.

Targets: ``n`` configurations with the tool z pointing down, inside the limits: from
uniform random starts, optik's ``dls`` with weights ``[0, 0, 0, 1, 1, 0]`` (tool z along
-z, position free) moves each to the vertical manifold; the FK position of each is a
target point (reachable by construction), with a uniform random roll about the vertical
axis, so the 6-D pose with that roll is in general *not* reachable. Every method starts
from mid-limits (optik's default seed table, RTB ``q0`` = mid-limits).

Success is judged here, from optik's forward kinematics of the returned ``q``: position
error <= 1e-6 m, angle between the tool z and -z <= 1e-6 rad, every joint inside its
limits (1e-12). RTB is asked for the same accuracy: ``tol = ½·tol²`` on its ``E = ½ eᵀ W
e`` (``joint_limits=True``, ``ilimit=30``, ``slimit=100``, Chan damping); its default
``tol=1e-6`` is a second row. Queries are timed one by one with ``time.perf_counter``,
methods interleaved per target in a random order, after a warm-up. optik's full-pose
query of the reachable FK pose (the configuration's own roll) is a reference row.

``solve_ik_batch(mode="axis")`` solves ``--batch-n`` targets in one call, 1 and 2
threads; its full-pose row solves the FK poses.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import gc  # noqa: E402
import math  # noqa: E402
import platform  # noqa: E402
import statistics  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from collections.abc import Callable  # noqa: E402
from dataclasses import dataclass, field  # noqa: E402
from pathlib import Path  # noqa: E402

import numba  # noqa: E402
import numpy as np  # noqa: E402
from numpy.typing import NDArray  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))

import _peers  # noqa: E402

import optik  # noqa: E402
from optik.spatial import rot_z  # noqa: E402

Array = NDArray[np.float64]
TOL = 1e-6
LIMIT_TOL = 1e-12
DOWN = np.array([0.0, 0.0, -1.0])
MASK = [1.0, 1.0, 1.0, 1.0, 1.0, 0.0]
WARMUP = 3


def vertical_targets(robot: optik.Robot, n: int, seed: int) -> tuple[Array, Array]:
    """(n, 4, 4) rolled vertical-drilling targets and the (n, 4, 4) FK poses they come from.

    See the module docstring: random in-limit starts moved onto "tool z down" by
    ``dls`` with the position free (to 1e-10 rad, verified here); the target keeps the
    FK position, its rotation is exactly "z down" with a uniform random roll.
    """
    rng = np.random.default_rng(seed)
    down = np.eye(4)
    down[:3, :3] = np.diag([1.0, -1.0, -1.0])  # tool z along -z
    rolled, poses = [], []
    while len(rolled) < n:
        q0 = rng.uniform(robot.lower, robot.upper)
        res = optik.solve_ik(
            robot,
            down,
            weights=[0, 0, 0, 1, 1, 0],
            solver="dls",
            q0=q0,
            warm_start="q0",
            restarts=0,
            tol=1e-10,
        )
        F = robot.fk(res.q)
        if _axis_angle(F[:3, 2], DOWN) > 1e-10 or not robot.within_limits(res.q):
            continue
        T = F.copy()  # the tool z exactly vertical, so that RTB's mask is the same task
        T[:3, :3] = down[:3, :3] @ rot_z(rng.uniform(-math.pi, math.pi))
        rolled.append(T)
        poses.append(F)
    return np.array(rolled), np.array(poses)


def _axis_angle(a: Array, b: Array) -> float:
    return math.atan2(float(np.linalg.norm(np.cross(a, b))), float(a @ b))


def judge(robot: optik.Robot, q: Array | None, T: Array, full: bool) -> bool:
    """The benchmark's verdict from optik's FK: the 5-D task (or the full pose)."""
    if q is None or not np.all(np.isfinite(q)):
        return False
    if not (np.all(q >= robot.lower - LIMIT_TOL) and np.all(q <= robot.upper + LIMIT_TOL)):
        return False
    F = robot.fk(q)
    if np.linalg.norm(F[:3, 3] - T[:3, 3]) > TOL:
        return False
    if full:
        return optik.spatial.rotation_angle(T[:3, :3].T @ F[:3, :3]) <= TOL
    return _axis_angle(F[:3, 2], T[:3, 2]) <= TOL


@dataclass
class Method:
    """One timed method: its row name, settings, one query ``call(k)`` -> q and its record."""

    name: str
    settings: str
    call: Callable[[int], Array | None]
    full: bool = False
    times: list[float] = field(default_factory=list)
    ok: list[bool] = field(default_factory=list)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("-n", type=int, default=500, help="single queries (no unit)")
    parser.add_argument("--batch-n", type=int, default=20_000, help="batch size (no unit)")
    parser.add_argument("--seed", type=int, default=0, help="seed (no unit)")
    args = parser.parse_args()

    robot = optik.load_problem("panda").robot
    load_before = os.getloadavg()
    t0 = time.perf_counter()
    targets, poses = vertical_targets(robot, args.n, args.seed)
    print(
        f"optik 5-D benchmark (Panda, vertical drilling targets); python "
        f"{platform.python_version()}, numpy {np.__version__}, numba {numba.__version__}, "
        f"{os.cpu_count()} CPUs; load {load_before[0]:.2f} {load_before[1]:.2f}; "
        f"n={args.n} targets drawn in {time.perf_counter() - t0:.1f} s"
    )
    mid = robot.mid_limits
    methods = [
        Method(
            "optik solve_ik axis",
            "mode='axis' (tool z), solver auto (= dls), tol 1e-6",
            lambda k: optik.solve_ik(robot, targets[k], mode="axis").q,
        ),
        Method(
            "optik solve_ik pose (reference)",
            "the reachable FK pose (its own roll), full 6-D, tol 1e-6",
            lambda k: optik.solve_ik(robot, poses[k]).q,
            full=True,
        ),
    ]
    try:
        for tol, label in ((0.5 * TOL * TOL, "tol=½·tol² (same accuracy)"), (1e-6, "tol=1e-6")):
            peer = _peers.RTBLM("rtb", "roboticstoolbox", "roboticstoolbox-python", tol=tol)
            peer.load()
            notes = peer.prepare("panda", robot, Path("."), args.seed)
            ets = peer._ets  # the checked model (FK = optik's, optik's limits)

            def rtb(k: int, ets: object = ets, tol: float = tol) -> Array:
                sol = ets.ik_LM(  # type: ignore[attr-defined]
                    targets[k], q0=mid, ilimit=30, slimit=100, tol=tol, mask=MASK,
                    joint_limits=True,
                )  # fmt: skip
                return np.asarray(sol.q, dtype=float)

            methods.append(
                Method(
                    f"rtb ik_LM mask {label}",
                    f"ETS.ik_LM C++ {peer.version}, mask {MASK} (base frame), "
                    f"joint_limits, q0 mid-limits; {'; '.join(notes)}",
                    rtb,
                )
            )
    except _peers.PeerUnavailable as exc:
        print(f"RTB not run: {exc}")

    for m in methods:  # warm-up: numba compiles on first call
        for k in range(WARMUP):
            m.call(k)
    rng = np.random.default_rng(args.seed + 1)
    gc.disable()
    try:
        for k in range(args.n):
            for i in rng.permutation(len(methods)):
                m = methods[i]
                start = time.perf_counter()
                q = m.call(k)
                m.times.append(time.perf_counter() - start)
                m.ok.append(judge(robot, q, poses[k] if m.full else targets[k], m.full))
            if k % 100 == 99:
                gc.collect()
    finally:
        gc.enable()

    print(f"\n{'method':<40}{'n':>6}{'success':>9}{'median ms':>11}{'p95 ms':>9}  settings")
    for m in methods:
        times = np.array(m.times) * 1e3
        print(
            f"{m.name:<40}{len(m.ok):>6}{100 * np.mean(m.ok):>8.1f}%{np.median(times):>11.3f}"
            f"{np.percentile(times, 95):>9.3f}  {m.settings}"
        )
    axis = methods[0]
    for m in methods[1:]:
        ratio = statistics.median(axis.times) / statistics.median(m.times)
        print(f"  median time optik axis / {m.name}: {ratio:.3f}")

    # Batches: more targets drawn the same way.
    batch_targets, batch_poses = vertical_targets(robot, args.batch_n, args.seed + 2)
    print(f"\nsolve_ik_batch, {args.batch_n} targets (median of 5 runs)")
    for threads in (1, 2):
        for label, T, mode, full in (
            ("axis", batch_targets, "axis", False),
            ("pose (reference, the FK poses)", batch_poses, "pose", True),
        ):
            optik.solve_ik_batch(robot, T[:64], mode=mode, threads=threads)  # warm-up
            runs = []
            result = None
            for _ in range(5):
                start = time.perf_counter()
                result = optik.solve_ik_batch(robot, T, mode=mode, threads=threads)
                runs.append(time.perf_counter() - start)
            assert result is not None
            ok = np.mean([judge(robot, result.q[k], T[k], full) for k in range(len(T))])
            wall = statistics.median(runs)
            print(
                f"  {label:<32} threads {threads}: {wall:.3f} s, {len(T) / wall:,.0f} solves/s, "
                f"{1e6 * wall / len(T):.1f} µs per target, success {100 * ok:.2f}% (judged here)"
            )
    load_after = os.getloadavg()
    print(f"\nload after {load_after[0]:.2f} {load_after[1]:.2f}")


if __name__ == "__main__":
    main()
