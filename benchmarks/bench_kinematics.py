"""Speed of forward kinematics and Jacobians: optik's compiled kernels vs plain numpy.

Run: ``python benchmarks/bench_kinematics.py [--batch 100000] [--repeat 7]``

For the Panda (problems/panda.toml, modified DH, 7 joints) it times, after a warm-up:

- single calls ``robot.fk(q)``, ``robot.jacobian(q)``, ``robot.fk_jacobian(q)`` and the
  pair ``fk`` + ``jacobian`` (µs per call, median over repeats);
- batched ``robot.fk(Q)`` and ``robot.fk_jacobian(Q)`` for ``Q`` of ``--batch``
  configurations (configurations per second, one core: the kernels are serial);

and the same chain product written here in plain numpy, per call (4x4 matmuls in a
Python loop) and vectorized over the batch (``np.matmul`` over ``(N, 4, 4)`` stacks),
to show whether the compiled kernels pay for themselves. Targets: one ``fk`` plus one
``jacobian`` call within 20 µs; batched FK at >= 1,000,000 configurations per second.
No assertions: speed is reported, never tested.
"""

from __future__ import annotations

import os

# One core for numpy as well (BLAS threads would make the comparison unfair).
for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import math  # noqa: E402
import platform  # noqa: E402
import statistics  # noqa: E402
import time  # noqa: E402
from collections.abc import Callable, Sequence  # noqa: E402
from dataclasses import dataclass  # noqa: E402
from pathlib import Path  # noqa: E402

import numba  # noqa: E402
import numpy as np  # noqa: E402
from numpy.typing import NDArray  # noqa: E402

from optik.model import Robot  # noqa: E402
from optik.problems import load_problem  # noqa: E402

Array = NDArray[np.float64]
PANDA = Path(__file__).resolve().parent.parent / "problems" / "panda.toml"


# ---------------------------------------------------------------------- plain numpy reference
@dataclass(frozen=True)
class NumpyChain:
    """The modified-DH chain ``T = A_1(q_1) ... A_n(q_n) T_tool`` in plain numpy.

    Revolute joints only (the Panda); ``A_i = Rx(alpha) Tx(a) Rz(theta + q_i) Tz(d)``.
    """

    a: Array
    alpha: Array
    d: Array
    theta: Array
    tool: Array

    @classmethod
    def from_robot(cls, robot: Robot) -> NumpyChain:
        """The chain of a modified-DH robot with revolute joints."""
        assert robot.dh is not None and robot.convention == "mdh"
        rows = robot.dh
        return cls(
            a=np.array([r.a for r in rows]),
            alpha=np.array([r.alpha for r in rows]),
            d=np.array([r.d for r in rows]),
            theta=np.array([r.theta for r in rows]),
            tool=robot.T_flange_tool.copy(),
        )

    def _link(self, i: int, q: float) -> Array:
        ct, st = math.cos(self.theta[i] + q), math.sin(self.theta[i] + q)
        ca, sa = math.cos(self.alpha[i]), math.sin(self.alpha[i])
        a, d = self.a[i], self.d[i]
        return np.array(
            [
                [ct, -st, 0.0, a],
                [st * ca, ct * ca, -sa, -sa * d],
                [st * sa, ct * sa, ca, ca * d],
                [0.0, 0.0, 0.0, 1.0],
            ]
        )

    def fk(self, q: Array) -> Array:
        """Tool pose (4, 4): one 4x4 matmul per joint."""
        T = np.eye(4)
        for i in range(q.shape[0]):
            T = T @ self._link(i, q[i])
        return T @ self.tool

    def fk_jacobian(self, q: Array) -> tuple[Array, Array]:
        """Tool pose and geometric Jacobian (6, n); joint i turns about z of frame i."""
        T = np.eye(4)
        axes = np.empty((q.shape[0], 3))
        origins = np.empty((q.shape[0], 3))
        for i in range(q.shape[0]):
            T = T @ self._link(i, q[i])
            axes[i] = T[:3, 2]
            origins[i] = T[:3, 3]
        T = T @ self.tool
        J = np.empty((6, q.shape[0]))
        J[:3] = np.cross(axes, T[:3, 3] - origins).T
        J[3:] = axes.T
        return T, J

    def _links_batch(self, i: int, q: Array) -> Array:
        N = q.shape[0]
        ct, st = np.cos(self.theta[i] + q), np.sin(self.theta[i] + q)
        ca, sa = math.cos(self.alpha[i]), math.sin(self.alpha[i])
        A = np.zeros((N, 4, 4))
        A[:, 0, 0], A[:, 0, 1], A[:, 0, 3] = ct, -st, self.a[i]
        A[:, 1, 0], A[:, 1, 1], A[:, 1, 2], A[:, 1, 3] = st * ca, ct * ca, -sa, -sa * self.d[i]
        A[:, 2, 0], A[:, 2, 1], A[:, 2, 2], A[:, 2, 3] = st * sa, ct * sa, ca, ca * self.d[i]
        A[:, 3, 3] = 1.0
        return A

    def fk_batch(self, Q: Array) -> Array:
        """Tool poses (N, 4, 4), vectorized over the batch (one stacked matmul per joint)."""
        T = self._links_batch(0, Q[:, 0])
        for i in range(1, Q.shape[1]):
            T = np.matmul(T, self._links_batch(i, Q[:, i]))
        return np.matmul(T, self.tool)

    def fk_jacobian_batch(self, Q: Array) -> tuple[Array, Array]:
        """Tool poses (N, 4, 4) and Jacobians (N, 6, n), vectorized over the batch."""
        N, n = Q.shape
        axes = np.empty((N, n, 3))
        origins = np.empty((N, n, 3))
        T = np.broadcast_to(np.eye(4), (N, 4, 4))
        for i in range(n):
            T = np.matmul(T, self._links_batch(i, Q[:, i]))
            axes[:, i] = T[:, :3, 2]
            origins[:, i] = T[:, :3, 3]
        T = np.matmul(T, self.tool)
        J = np.empty((N, 6, n))
        J[:, :3] = np.swapaxes(np.cross(axes, T[:, None, :3, 3] - origins), 1, 2)
        J[:, 3:] = np.swapaxes(axes, 1, 2)
        return T, J


# ---------------------------------------------------------------------- timing
@dataclass(frozen=True)
class Timing:
    """Seconds per call: median and best over the timed runs."""

    median: float
    best: float


def seconds_per_call(fn: Callable[[], object], repeat: int, min_time: float = 0.2) -> Timing:
    """Time one call of ``fn`` (s) over ``repeat`` runs, after a warm-up call.

    Each run loops ``fn`` enough times to last about ``min_time`` seconds; the result
    holds the median and the best of the runs' mean times.
    """
    fn()
    start = time.perf_counter()
    fn()
    once = max(time.perf_counter() - start, 1e-9)
    number = max(1, int(min_time / once))
    runs = []
    for _ in range(repeat):
        start = time.perf_counter()
        for _ in range(number):
            fn()
        runs.append((time.perf_counter() - start) / number)
    return Timing(statistics.median(runs), min(runs))


@dataclass
class Row:
    """One line of the result table: optik and numpy timings of one operation."""

    operation: str
    optik: Timing
    numpy: Timing
    batch: int | None = None  # None: per call (report µs); else configurations per call
    target: str = ""
    met: bool | None = None
    max_diff: float = math.nan

    def value(self, seconds: float) -> float:
        """µs per call, or configurations per second for a batch."""
        return seconds * 1e6 if self.batch is None else self.batch / seconds


def print_table(rows: Sequence[Row]) -> None:
    """Print the results as a plain-text table."""
    header = (
        f"{'operation':<30}{'unit':<11}{'optik':>10}{'(best)':>10}{'numpy':>10}{'speed-up':>10}"
        f"  {'target':<12}{'met':<5}{'max |diff|':>10}"
    )
    print(header)
    print("-" * len(header))
    for r in rows:
        unit = "us/call" if r.batch is None else "configs/s"
        fmt = "{:10.2f}" if r.batch is None else "{:10.3g}"
        cells = [fmt.format(r.value(t)) for t in (r.optik.median, r.optik.best, r.numpy.median)]
        speedup = r.numpy.median / r.optik.median
        met = "-" if r.met is None else ("yes" if r.met else "NO")
        print(
            f"{r.operation:<30}{unit:<11}{''.join(cells)}{speedup:>9.1f}x"
            f"  {r.target:<12}{met:<5}{r.max_diff:>10.1e}"
        )


def run(batch: int, repeat: int) -> list[Row]:
    """Time every operation; returns the table rows."""
    robot = load_problem(PANDA).robot
    ref = NumpyChain.from_robot(robot)
    rng = np.random.default_rng(0)
    q = rng.uniform(robot.lower, robot.upper)
    Q = rng.uniform(robot.lower, robot.upper, size=(batch, robot.dof))

    # Warm-up: numba loads (or compiles) each kernel on first use.
    robot.fk(q), robot.fk_jacobian(q), robot.fk(Q[:2]), robot.fk_jacobian(Q[:2])

    T_ref, J_ref = ref.fk_jacobian(q)
    diff_T = float(np.max(np.abs(robot.fk(q) - ref.fk(q))))
    diff_J = float(np.max(np.abs(robot.jacobian(q) - J_ref)))
    diff_TJ = max(float(np.max(np.abs(robot.fk(q) - T_ref))), diff_J)

    t_fk = seconds_per_call(lambda: robot.fk(q), repeat)
    t_jac = seconds_per_call(lambda: robot.jacobian(q), repeat)
    t_both = seconds_per_call(lambda: (robot.fk(q), robot.jacobian(q)), repeat)
    t_fkj = seconds_per_call(lambda: robot.fk_jacobian(q), repeat)
    n_fk = seconds_per_call(lambda: ref.fk(q), repeat)
    n_fkj = seconds_per_call(lambda: ref.fk_jacobian(q), repeat)
    n_both = seconds_per_call(lambda: (ref.fk(q), ref.fk_jacobian(q)), repeat)
    rows = [
        Row("fk(q)", t_fk, n_fk, max_diff=diff_T),
        Row("jacobian(q)", t_jac, n_fkj, max_diff=diff_J),
        Row("fk(q) + jacobian(q)", t_both, n_both, target="<= 20 us",
            met=t_both.median <= 20e-6, max_diff=diff_TJ),
        Row("fk_jacobian(q)", t_fkj, n_fkj, max_diff=diff_TJ),
    ]  # fmt: skip

    diff_batch = float(np.max(np.abs(robot.fk(Q) - ref.fk_batch(Q))))
    Tj, Jj = robot.fk_jacobian(Q)
    Tn, Jn = ref.fk_jacobian_batch(Q)
    diff_batch_j = float(max(np.max(np.abs(Tj - Tn)), np.max(np.abs(Jj - Jn))))
    b_fk = seconds_per_call(lambda: robot.fk(Q), repeat, min_time=0.5)
    b_fkj = seconds_per_call(lambda: robot.fk_jacobian(Q), repeat, min_time=0.5)
    nb_fk = seconds_per_call(lambda: ref.fk_batch(Q), max(3, repeat // 2), min_time=0.5)
    nb_fkj = seconds_per_call(lambda: ref.fk_jacobian_batch(Q), max(3, repeat // 2), 0.5)
    rows += [
        Row(f"fk(Q), N = {batch:,}", b_fk, nb_fk, batch, ">= 1e6 /s",
            batch / b_fk.median >= 1e6, diff_batch),
        Row(f"fk_jacobian(Q), N = {batch:,}", b_fkj, nb_fkj, batch, max_diff=diff_batch_j),
    ]  # fmt: skip
    return rows


def main(argv: Sequence[str] | None = None) -> None:
    """Run the benchmark and print the table."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--batch", type=int, default=100_000, help="batch size (default 1e5)")
    parser.add_argument("--repeat", type=int, default=7, help="timed runs per entry (median)")
    args = parser.parse_args(argv)

    print(
        f"optik kinematics benchmark: Panda (7R, modified DH); python {platform.python_version()},"
        f" numpy {np.__version__}, numba {numba.__version__}, {platform.machine()},"
        f" {os.cpu_count()} CPUs (kernels run on one core)"
    )
    print(
        f"optik = median of {args.repeat} timed runs (best run in brackets); numpy = the same"
        " product in plain numpy (median)"
    )
    print()
    print_table(run(args.batch, args.repeat))
    print()
    print("speed-up: numpy median time / optik median time (same work per call)")
    print("max |diff|: optik vs the numpy product, largest entry (m, rad)")


if __name__ == "__main__":
    main()
