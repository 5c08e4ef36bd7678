"""Speed of optik's closed-form generalized inverses against numpy's SVD-based pinv.

Run: ``python benchmarks/bench_linalg.py [--batch 10000] [--repeat 15]``

For a stack of ``--batch`` random 6x7 Jacobian-shaped matrices (a 7-joint arm, a 6-D
task) it times, after a warm-up (which also loads numba's compiled kernel):

- ``optik.min_norm(A, b)``: ``x = A^T (A A^T)^-1 b`` by Cholesky of the 6x6 Gram matrix,
  with the rigorous condition bound that routes ill-conditioned matrices to the SVD;
- ``numpy.linalg.pinv(A) @ b`` on the same stack (target: optik >= 10x faster);
- ``numpy.linalg.lstsq`` in a Python loop (numpy has no batched lstsq);
- the least-squares side ``optik.least_squares`` on the transposed 7x6 stack, the square
  ``optik.solve_square`` on 6x6 (LU) against ``numpy.linalg.solve``, and single-matrix
  calls (the diff-IK inner loop).

Times are medians over ``--repeat`` runs, one core (BLAS threads pinned to 1 so no side
gets hidden parallelism). No assertions: speed is reported, never tested.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import platform  # noqa: E402
import statistics  # noqa: E402
import time  # noqa: E402
from collections.abc import Callable, Sequence  # noqa: E402

import numba  # noqa: E402
import numpy as np  # noqa: E402

from optik.linalg import least_squares, min_norm, solve_square  # noqa: E402


def median_seconds(fn: Callable[[], object], repeat: int) -> float:
    """Median wall time of ``fn()`` over ``repeat`` runs, after one warm-up call."""
    fn()
    times = []
    for _ in range(repeat):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def report(label: str, seconds: float, reference: float | None = None, unit: str = "ms") -> None:
    scale = 1e3 if unit == "ms" else 1e6
    ratio = f"  ({reference / seconds:5.1f}x faster than the reference)" if reference else ""
    print(f"  {label:<44s} {seconds * scale:9.2f} {unit}{ratio}")


def main(argv: Sequence[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--batch", type=int, default=10_000, help="matrices per stack")
    parser.add_argument("--repeat", type=int, default=15, help="timed runs per case")
    args = parser.parse_args(argv)
    N, repeat = args.batch, args.repeat

    print(
        f"python {platform.python_version()}, numpy {np.__version__}, numba {numba.__version__}, "
        f"{platform.machine()} / {platform.processor() or platform.system()}"
    )
    rng = np.random.default_rng(0)
    A = rng.standard_normal((N, 6, 7))
    b = rng.standard_normal((N, 6))
    cond = np.linalg.cond(A)
    print(
        f"stack of {N} random 6x7 matrices, cond_2 median {np.median(cond):.3g}, "
        f"max {cond.max():.3g}"
    )

    # Same answers first: a benchmark of a wrong result is worthless.
    x = min_norm(A, b)
    x_ref = (np.linalg.pinv(A) @ b[..., None])[..., 0]
    rel = np.linalg.norm(x - x_ref, axis=-1) / np.linalg.norm(x_ref, axis=-1)
    print(f"max relative difference min_norm vs pinv: {rel.max():.2e}")

    print(f"\nminimum norm, {N} x (6 x 7):")
    t_pinv = median_seconds(lambda: np.linalg.pinv(A) @ b[..., None], repeat)
    t_min = median_seconds(lambda: min_norm(A, b), repeat)
    t_loop = median_seconds(
        lambda: [np.linalg.lstsq(A[i], b[i], rcond=None) for i in range(N)], max(3, repeat // 5)
    )
    report("numpy.linalg.pinv(A) @ b  (reference)", t_pinv)
    report("optik.min_norm(A, b)", t_min, t_pinv)
    report("numpy.linalg.lstsq, Python loop", t_loop)

    print(f"\nleast squares, {N} x (7 x 6):")
    At = np.ascontiguousarray(np.swapaxes(A, -1, -2))
    c = rng.standard_normal((N, 7))
    t_pinv_t = median_seconds(lambda: np.linalg.pinv(At) @ c[..., None], repeat)
    t_ls = median_seconds(lambda: least_squares(At, c), repeat)
    report("numpy.linalg.pinv(A) @ b  (reference)", t_pinv_t)
    report("optik.least_squares(A, b)", t_ls, t_pinv_t)

    print(f"\nsquare, {N} x (6 x 6):")
    S = np.ascontiguousarray(A[..., :6])
    t_solve = median_seconds(lambda: np.linalg.solve(S, b[..., None]), repeat)
    t_sq = median_seconds(lambda: solve_square(S, b), repeat)
    t_cond = median_seconds(lambda: np.linalg.cond(S), repeat)
    report("numpy.linalg.solve (no condition check)", t_solve)
    report("numpy.linalg.cond (SVD, for comparison)", t_cond)
    report("optik.solve_square (checked)", t_sq)

    print("\nsingle matrix (the diff-IK inner loop):")
    A1, b1 = A[0], b[0]
    reps = max(200, 50 * repeat)
    t1_pinv = median_seconds(lambda: np.linalg.pinv(A1) @ b1, reps)
    t1_min = median_seconds(lambda: min_norm(A1, b1), reps)
    report("numpy.linalg.pinv(A) @ b  (reference)", t1_pinv, unit="us")
    report("optik.min_norm(A, b)", t1_min, t1_pinv, unit="us")


if __name__ == "__main__":
    main()
