"""Long chains (hyper-redundant arms): ``solve_ik`` against RTB ``ik_LM``, same process.

Run: ``python benchmarks/bench_wide_chains.py [--dofs 20,60,200,500,1000,2000] [-n 10]
[--peer-max-dof 500] [--seed 0]``.

Protocol, for each chain length: a spatial chain of ``dof`` revolute joints (DH rows: 2 cm
links, 1 cm offsets, twists alternating between +-0.5, +-0.8 and +-1.1 rad; limits
+-2.5 rad); ``n`` configurations drawn in +-0.3 rad (seeded), their FK poses as targets
(full pose, tolerance 1e-6 m and rad). optik's ``solve_ik`` starts from its default; RTB's
``ETS.ik_LM`` (C++, the model built by :mod:`optik.peers.rtb` and checked against optik's FK)
from mid-limits, up to 100 searches of 30 iterations. Success is judged here from optik's FK
of the returned ``q`` (errors <= 1e-6, inside the limits). Each method has one untimed
warm-up query per chain; the methods then alternate target by target. RTB runs on chains up
to ``--peer-max-dof`` joints (each of its iterations factors a ``dof x dof`` system).

Up to ``optik.solvers._lm_kernel.WIDE_CHAIN_DOF`` joints, optik's damped least squares
factor the joints' ``dof x dof`` system too; beyond it each step solves the task's 6 x 6
system (work linear in ``dof``).
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import platform  # noqa: E402
import statistics  # noqa: E402
import time  # noqa: E402
from collections.abc import Callable  # noqa: E402

import numpy as np  # noqa: E402
from scipy.spatial.transform import Rotation  # noqa: E402

import optik  # noqa: E402
from optik.model import DHJoint, Robot  # noqa: E402
from optik.peers import PeerUnavailable  # noqa: E402
from optik.peers.rtb import RTBPeer  # noqa: E402
from optik.solvers._lm_kernel import WIDE_CHAIN_DOF  # noqa: E402

TOL = 1e-6


def snake(dof: int) -> Robot:
    """The protocol's chain of ``dof`` revolute joints."""
    rows = [
        DHJoint(a=0.02, alpha=(0.5 + 0.3 * (i % 3)) * (-1) ** i, d=0.01, theta=0.1 * i)
        for i in range(dof)
    ]
    return Robot.from_dh(rows, limits=np.tile([-2.5, 2.5], (dof, 1)), name=f"snake{dof}")


def reached(robot: Robot, q: np.ndarray, target: np.ndarray) -> bool:
    """FK of ``q`` within TOL of ``target`` (position, rotation angle), ``q`` in the limits."""
    if q.shape != (robot.dof,) or not np.all(np.isfinite(q)):
        return False
    T = robot.fk(q)
    angle = Rotation.from_matrix(T[:3, :3].T @ target[:3, :3]).magnitude()
    inside = bool(np.all(robot.lower - 1e-12 <= q) and np.all(q <= robot.upper + 1e-12))
    return bool(np.linalg.norm(T[:3, 3] - target[:3, 3]) <= TOL and angle <= TOL and inside)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--dofs", default="20,60,200,500,1000,2000")
    parser.add_argument("-n", type=int, default=10)
    parser.add_argument("--peer-max-dof", type=int, default=500)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    print(
        f"optik {optik.__version__}, Python {platform.python_version()}, "
        f"{os.cpu_count()} CPUs, load {os.getloadavg()[0]:.2f}; WIDE_CHAIN_DOF={WIDE_CHAIN_DOF}; "
        f"n={args.n} targets per chain"
    )
    print(f"{'dof':>5} {'method':<22} {'success':>8} {'median ms':>10} {'p95 ms':>9}")
    for dof in (int(d) for d in args.dofs.split(",")):
        robot = snake(dof)
        rng = np.random.default_rng(args.seed + dof)
        targets = [robot.fk(rng.uniform(-0.3, 0.3, dof)) for _ in range(args.n + 1)]
        methods: dict[str, Callable[[np.ndarray], np.ndarray]] = {
            "optik solve_ik": lambda T, robot=robot: optik.solve_ik(robot, T, tol=TOL).q
        }
        if dof <= args.peer_max_dof:
            try:
                peer = RTBPeer(tol=TOL, seed=args.seed)
                peer.load()
                peer.prepare(robot)
                mid = robot.mid_limits
                methods["rtb ik_LM"] = lambda T, peer=peer, mid=mid: peer.solve(T, mid).q
            except PeerUnavailable as exc:
                print(f"RTB not run: {exc}")
        for solve in methods.values():
            solve(targets[-1])  # warm-up (numba compiles on first call)
        times: dict[str, list[float]] = {name: [] for name in methods}
        wins: dict[str, int] = dict.fromkeys(methods, 0)
        for T in targets[:-1]:
            for name, solve in methods.items():
                start = time.perf_counter()
                q = solve(T)
                times[name].append(time.perf_counter() - start)
                wins[name] += reached(robot, q, T)
        for name in methods:
            t = sorted(times[name])
            p95 = t[min(len(t) - 1, int(0.95 * len(t)))]
            print(
                f"{dof:>5} {name:<22} {wins[name]:>4}/{args.n:<3} "
                f"{1e3 * statistics.median(t):>10.3f} {1e3 * p95:>9.3f}"
            )


if __name__ == "__main__":
    main()
