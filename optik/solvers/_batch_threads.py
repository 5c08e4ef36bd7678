"""A batch of compiled LM solves split over Python threads.

The compiled batch (:func:`optik.solvers._lm_kernel.lm_solve_batch_serial`) releases the
GIL, so threads that each solve a contiguous piece of the batch run side by side. This
replaces a numba ``parallel=True`` kernel, whose compilation took longer than all the
other kernels together (about a minute of CPU on a first call), for the same answers:
target ``k`` uses the random stream ``seeds[k]`` whatever piece it falls in.
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor

import numpy as np

from optik.chain import KernelChain
from optik.solvers._lm_kernel import BATCH_CHUNK, BatchJob, BatchOutput, lm_solve_batch_serial

PIECES_PER_THREAD = 4
"""Pieces per thread: targets differ in cost (an unreachable one runs every restart), so
a few pieces per thread keep the threads busy until the end."""


def solve_batch(chain: KernelChain, batch: BatchJob, threads: int) -> BatchOutput:
    """Every target of ``batch`` (:data:`~optik.solvers._lm_kernel.BatchJob`) on ``threads``.

    Returns ``(q (N, dof), iterations (N,), restarts (N,), ok (N,))``, equal to
    :func:`~optik.solvers._lm_kernel.lm_solve_batch_serial`'s for any ``threads``.
    """
    targets, task, given, table, settings, seeds = batch
    n = targets.shape[0]
    pieces = min(threads * PIECES_PER_THREAD, max(1, n // BATCH_CHUNK))
    if threads <= 1 or pieces <= 1:
        return lm_solve_batch_serial(chain, batch)
    edges = np.linspace(0, n, pieces + 1).astype(np.int64)

    def piece(i: int) -> BatchOutput:
        a, b = int(edges[i]), int(edges[i + 1])
        own = given[a:b] if given.shape[0] == n else given  # per-target or shared starts
        job = (targets[a:b], task, own, table, settings, seeds[a:b])
        return lm_solve_batch_serial(chain, job)

    with ThreadPoolExecutor(max_workers=threads, thread_name_prefix="optik-batch") as pool:
        outputs = list(pool.map(piece, range(pieces)))
    Q, iterations, restarts, ok = (np.concatenate([out[j] for out in outputs]) for j in range(4))
    return Q, iterations, restarts, ok
