"""Where a campaign's chunks run: the one seam between optik's work and Dask.

A campaign (a capability map, a batch of targets, a base-placement check) cuts its work
into chunks, each a pure function call ``fn(chunk)`` whose answer depends on the chunk
alone (its per-sample seeds come from the global sample index, never from the worker or
the order). :func:`run_chunks` hands the chunks that a store has not yet finished to an
:class:`Engine`; where the store allows it, each chunk is written, whole, by the thread or
worker that computed it, and only a small :class:`Written` receipt comes back (see
:class:`ChunkStore`). The engines:

- in-process (the default): the chunks run on a pool of threads of this process, as
  many as numba's thread count (``numba.get_num_threads()``), each chunk solved by
  :func:`optik.solve_ik_batch` with ``threads=1`` (the compiled kernel releases the
  GIL); a run of a single chunk solves it on numba's threads instead. Whole chunks per
  thread, rather than every chunk split over the threads, keep a thread from waiting for
  the slowest part of a small call;
- ``workers=N``: a :class:`distributed.LocalCluster` of N worker processes with one
  thread each, bound to 127.0.0.1, without a dashboard, and without the diagnostics that
  would take CPU from the IK (:data:`QUIET_CLUSTER`);
- ``scheduler="tcp://host:port"``: any running Dask cluster (``dask scheduler`` and
  ``dask worker``); an address that does not answer within ``connect_timeout_s`` is an
  :class:`~optik.errors.OptikError`, never a hang;
- ``client=``: a :class:`distributed.Client` the caller already holds (not closed here).

On Dask each chunk's IK runs on one thread (``threads=1``): the workers are the
parallelism. A worker that dies mid-run is replaced by its nanny and Dask recomputes the
chunks it held, so the answers, and the files, are the same.
"""

from __future__ import annotations

import contextlib
import copy
import functools
import math
import multiprocessing
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import FIRST_COMPLETED, Future, ThreadPoolExecutor, wait
from dataclasses import dataclass, field
from typing import Any, Protocol, TypeVar

import numba

from optik._checks import check_int, check_real
from optik._closing import Closing
from optik._progress import Progress
from optik.campaign._deps import require
from optik.errors import ArgumentError, OptikError

T = TypeVar("T")
R = TypeVar("R")

ProgressOption = bool | Callable[[int, int], object] | None
"""A campaign's ``progress`` argument: a bar on or off (``None``: when stderr is a
terminal), or a callable ``progress(done, total)`` (chunks)."""

MAX_WORKERS = 1024
"""Largest ``workers`` of a local cluster."""

MAX_CHUNKS = 100_000
"""Largest number of chunks of one campaign (a larger ``chunk`` gives fewer).

Each chunk costs the client about 1-2.5 KB of bookkeeping before any is solved, and a
Zarr map reads every chunk's marker file at each start or resume (about 0.1 ms each: a map
of 251,001 chunks spent 25 s reading them, one of a million chunks 155 s and 2.6 GB
before its first chunk). At this limit that start-up stays near 10 s and 250 MB."""

WORKER_PRELOAD = "optik.campaign._worker"
"""The preload module of the workers of a local cluster (they leave Ctrl-C to the client)."""

CONNECT_TIMEOUT_S = 5.0
"""How long to wait for a scheduler given by address before giving up (s)."""

QUIET_CLUSTER: dict[str, Any] = {
    "distributed.worker.profile.enabled": False,
    "distributed.admin.tick.interval": "1s",
    "distributed.admin.system-monitor.interval": "5s",
    "distributed.worker.memory.monitor-interval": "1s",
}
"""Dask settings of the local clusters optik starts (:func:`open_engine` with ``workers``).

Their workers share the machine's cores with the scheduler, the nannies and the client,
and every core runs IK: Dask's own diagnostics, by default a statistical profiler that
samples each worker every 10 ms, event-loop ticks every 20 ms in every server and system
monitors every 0.5 s, took about 6 % of a 2-core machine even with no task running
(CPU time of the processes of an idle 2-worker cluster: 1.3 s in 10 s, 0.13 s with
these). A nanny still checks its worker's memory every second."""


@dataclass
class Engine(Closing):
    """Runs chunk functions in this process or on a Dask cluster (see the module).

    Build one with :func:`open_engine` and close it (or use it as a context manager):
    closing shuts down a cluster the engine started, never a client the caller gave.

    Attributes:
        client: the :class:`distributed.Client`, or ``None`` in-process.
        description: where the work runs, in words (``"in-process"``, ``"2 local worker
            processes"``, ``"scheduler tcp://..."``).
    """

    client: Any = None
    description: str = "in-process"
    _owned: list[Any] = field(default_factory=list, repr=False)
    pool: int = 0
    """Threads that run chunks in-process (0: numba's thread count)."""
    local: bool = False
    """Whether the engine started the cluster (``workers=N``): its workers are quieted
    before it closes."""

    @property
    def distributed(self) -> bool:
        """Whether the chunks run on Dask workers."""
        return self.client is not None

    def threads_for(self, chunks: int) -> int | None:
        """Threads of :func:`optik.solve_ik_batch` inside a chunk of a run of ``chunks``.

        ``None`` (numba's thread count, inside the chunk) for an in-process run of one
        chunk; otherwise 1: chunks run side by side, and two parallel numba calls must
        never run at once (numba's ``workqueue`` threading layer does not allow it). The
        answers do not depend on it.

        Args:
            chunks: number of chunks of the run; no unit.
        """
        if self.distributed or chunks > 1:
            return 1
        return None

    @property
    def pool_size(self) -> int:
        """Chunks run at once in-process."""
        return self.pool if self.pool > 0 else int(numba.get_num_threads())

    def map_unordered(self, fn: Callable[[T], R], items: Sequence[T]) -> Iterator[tuple[int, R]]:
        """``(i, fn(items[i]))`` for every item, in the order the answers arrive.

        An exception raised by a chunk is raised here; the chunks not yet done are then
        cancelled.

        Args:
            fn: the function applied to each item (in a worker for a Dask run).
            items: the items, each given to ``fn``.
        """
        if self.client is None:
            yield from self._threaded(fn, items)
            return
        distributed = require("distributed", "a Dask run")
        futures = self.client.map(fn, list(items), pure=False)
        position = {future.key: i for i, future in enumerate(futures)}
        try:
            for future, result in distributed.as_completed(futures, with_results=True):
                yield position[future.key], result
                future.release()
        finally:
            self.client.cancel(futures)

    def _threaded(self, fn: Callable[[T], R], items: Sequence[T]) -> Iterator[tuple[int, R]]:
        """In-process: a pool of threads, at most ``2 * pool_size`` chunks in flight."""
        if self.pool_size <= 1 or len(items) <= 1:
            for i, item in enumerate(items):
                yield i, fn(item)
            return
        with ThreadPoolExecutor(self.pool_size, thread_name_prefix="optik-chunk") as pool:
            todo = iter(enumerate(items))
            running: dict[Future[R], int] = {}

            def submit() -> None:
                for i, item in todo:
                    running[pool.submit(fn, item)] = i
                    return

            try:
                for _ in range(2 * self.pool_size):
                    submit()
                while running:
                    finished, _ = wait(running, return_when=FIRST_COMPLETED)
                    for future in finished:
                        i = running.pop(future)
                        submit()
                        yield i, future.result()
            finally:
                for future in running:
                    future.cancel()

    def close(self) -> None:
        """Close the client and the cluster this engine started (not a caller's client)."""
        if self.local and self._owned:
            from optik.campaign._worker import quiet_logs

            with contextlib.suppress(Exception):  # a worker gone already has nothing to say
                self.client.run(quiet_logs, on_error="ignore")
        while self._owned:
            thing = self._owned.pop()
            with contextlib.suppress(Exception):  # shutting down: nothing left to save
                thing.close()


def refuse_reimported_script(workers: Any) -> None:
    """Refuse a local cluster started by a script that a worker process is importing again.

    Dask starts a local cluster's workers with Python's ``spawn``, which imports the
    caller's script again in each (as ``__mp_main__``): unguarded top-level code would
    start a cluster there too, and the run failed with "Nanny failed to start" (the cause
    buried among a dozen tracebacks) or "it exists" of its own output.

    Raises:
        OptikError: ``workers`` given while ``__main__`` is being imported again by a
            spawned process.
    """
    # Python's own test in multiprocessing.spawn: a spawned process still bootstrapping.
    bootstrapping = getattr(multiprocessing.current_process(), "_inheriting", False)
    if workers is not None and bootstrapping:
        raise OptikError(
            "workers: a local cluster was started while a worker process imports this "
            'script again; call it under `if __name__ == "__main__":` (Dask starts its '
            "worker processes by importing the script)"
        )


def open_engine(
    *,
    client: Any = None,
    workers: int | None = None,
    scheduler: str | None = None,
    connect_timeout_s: float = CONNECT_TIMEOUT_S,
) -> Engine:
    """The engine of a campaign: in-process, a local cluster, a scheduler or a client.

    Args:
        client: a :class:`distributed.Client` to use (the caller closes it).
        workers: start a local cluster of this many worker processes (1 thread each,
            127.0.0.1, no dashboard), closed with the engine.
        scheduler: the address of a running Dask scheduler (``"tcp://host:8786"``).
        connect_timeout_s: how long to wait for ``scheduler`` (s).

    Raises:
        OptikError: more than one of ``client``, ``workers`` and ``scheduler``;
            ``workers`` not an integer in [1, MAX_WORKERS]; ``scheduler`` not a string or
            not answering within ``connect_timeout_s``; ``client`` not a Dask client;
            the cluster extra not installed.
    """
    options = (("client", client), ("workers", workers), ("scheduler", scheduler))
    given = [name for name, value in options if value is not None]
    if len(given) > 1:
        raise OptikError(f"give at most one of client, workers and scheduler, not {given}")
    if not given:
        return Engine()
    distributed = require("distributed", "a Dask run")
    if client is not None:
        if not isinstance(client, distributed.Client):
            raise ArgumentError("client", client, "a distributed.Client")
        return Engine(client, f"client {client.scheduler.address}")
    if workers is not None:
        n = check_int("workers", workers, minimum=1, maximum=MAX_WORKERS)
        refuse_reimported_script(workers)
        dask = require("dask", "a Dask run")
        with dask.config.set(QUIET_CLUSTER):  # read by the scheduler and nannies as they start
            # A nanny hands its settings on to every worker it starts, a replacement too; its
            # own copy, since leaving this block restores the global settings in place.
            settings = {"distributed": copy.deepcopy(dask.config.get("distributed"))}
            try:
                cluster = distributed.LocalCluster(
                    n_workers=n,
                    threads_per_worker=1,
                    processes=True,
                    host="127.0.0.1",
                    dashboard_address=None,
                    # The scheduler's HTTP server (/health, /metrics) still starts: on a
                    # free port of 127.0.0.1, not Dask's default 8787, whose being taken
                    # (another cluster) printed a warning.
                    scheduler_kwargs={"dashboard_address": "127.0.0.1:0"},
                    silence_logs=40,  # logging.ERROR: a worker's restart is no news to the user
                    config=settings,
                    preload=[WORKER_PRELOAD],  # workers ignore Ctrl-C: the client stops it
                )
            except RuntimeError as exc:  # distributed's "Nanny failed to start."
                raise OptikError(
                    f"workers: the local cluster's worker processes did not start ({exc}); "
                    'a script must start it under `if __name__ == "__main__":` (its '
                    "workers import the script again)"
                ) from exc
        local = distributed.Client(cluster)
        plural = "es" if n != 1 else ""
        return Engine(local, f"{n} local worker process{plural}", [cluster, local], local=True)
    if not isinstance(scheduler, str) or not scheduler.strip():
        raise ArgumentError("scheduler", scheduler, "a scheduler address ('tcp://host:port')")
    wait = check_real("connect_timeout_s", connect_timeout_s, positive=True)
    try:
        remote = distributed.Client(scheduler, timeout=wait)
    except Exception as exc:  # refused, timed out, or not speaking Dask's protocol
        raise OptikError(
            f"scheduler {scheduler!r}: no Dask scheduler answered within {wait:g} s ({exc})"
        ) from None
    return Engine(remote, f"scheduler {scheduler}", [remote])


@dataclass(frozen=True)
class Written:
    """The receipt of a chunk that its worker wrote to the store itself.

    Attributes:
        index: the chunk's position in the campaign.
    """

    index: int


class ChunkWriter(Protocol):
    """Writes a chunk where it was computed (picklable: it travels to Dask workers)."""

    def __call__(self, index: int, result: Any) -> bool:
        """Write chunk ``index`` whole and return True, or return False.

        False, having marked nothing done, when the store is not this run's from here
        (another machine's file system, or a store since replaced) or cannot be written
        from here: the answer then travels back and :meth:`ChunkStore.write` writes it.
        """
        ...  # pragma: no cover


class ChunkStore(Protocol):
    """Where a campaign keeps its finished chunks (a Zarr map, Parquet part files, memory).

    A store may also have ``writer() -> ChunkWriter | None``: the writer with which the
    workers write their own chunks. Without it, or when it gives ``None`` (a store in
    memory), the answers travel back and :meth:`write` writes them.
    """

    def finished(self) -> set[int]:
        """Indices of the chunks already written whole."""
        ...  # pragma: no cover

    def write(self, index: int, result: Any) -> None:
        """Write chunk ``index`` whole, or not at all (in the process that runs the campaign)."""
        ...  # pragma: no cover


def compute_and_write(
    fn: Callable[[T], Any], writer: ChunkWriter | None, item: tuple[int, T]
) -> Any:
    """Where a chunk runs: ``fn(chunk)``, written by ``writer`` when it can.

    Args:
        fn: the chunk function.
        writer: the store's writer, or ``None``.
        item: ``(index, chunk)``.

    Returns:
        A :class:`Written` receipt if ``writer`` wrote the answer, else the answer.
    """
    index, chunk = item
    result = fn(chunk)
    if writer is not None and writer(index, result):
        return Written(index)
    return result


def run_chunks(
    engine: Engine,
    fn: Callable[[T], Any],
    chunks: Sequence[T],
    store: ChunkStore,
    *,
    progress: Callable[[int, int], object] | None = None,
    finished: set[int] | None = None,
) -> int:
    """Compute every chunk ``store`` has not finished, and write each as it arrives.

    Args:
        engine: where to run (:func:`open_engine`).
        fn: the chunk function, ``fn(chunks[i])`` -> the answer ``store.write`` takes; on
            Dask it must be picklable (a module-level function or a ``functools.partial``
            of one).
        chunks: every chunk of the campaign, chunk ``i`` at position ``i``.
        store: the finished chunks and where to write new ones (by the workers when
            the store has a ``writer()`` that gives one; see :class:`ChunkStore`).
        progress: called as ``progress(done, total)`` after each chunk is written
            (finished chunks of an earlier run count as done from the start).
        finished: the chunks already finished, if the caller has read them
            (default: ``store.finished()``).

    Returns:
        The number of chunks computed by this call.
    """
    total = len(chunks)
    done = store.finished() if finished is None else finished
    pending = [i for i in range(total) if i not in done]
    if progress is not None:
        progress(total - len(pending), total)
    computed = 0
    # The worker writes its own chunk (the client's core stays free for the scheduler and
    # the other workers); only what it could not write comes back to be written here.
    writer = getattr(store, "writer", None)
    task = functools.partial(compute_and_write, fn, None if writer is None else writer())
    for k, result in engine.map_unordered(task, [(i, chunks[i]) for i in pending]):
        if not isinstance(result, Written):
            store.write(pending[k], result)
        computed += 1
        if progress is not None:
            progress(total - len(pending) + computed, total)
    return computed


def run_chunks_with_progress(
    engine: Engine,
    fn: Callable[[T], Any],
    chunks: Sequence[T],
    store: ChunkStore,
    progress: ProgressOption,
    note: str,
    finished: set[int] | None = None,
) -> int:
    """:func:`run_chunks` with a campaign's ``progress`` option.

    Args:
        engine: where to run (:func:`open_engine`).
        fn: the chunk function (see :func:`run_chunks`).
        chunks: every chunk of the campaign.
        store: the finished chunks and where to write new ones.
        progress: a callable ``progress(done, total)`` is called as :func:`run_chunks`
            calls it; otherwise a :class:`~optik._progress.Progress` bar of the chunks,
            on, off or (``None``) drawn when stderr is a terminal.
        note: what runs, shown beside the bar with where (``"map ur5"`` ->
            ``"map ur5 (in-process)"``).
        finished: the chunks already finished (default: ``store.finished()``).

    Returns:
        The number of chunks computed by this call.
    """
    if callable(progress):
        return run_chunks(engine, fn, chunks, store, progress=progress, finished=finished)
    label = f"{note} ({engine.description})"
    with Progress(len(chunks), enabled=progress) as bar:
        return run_chunks(
            engine,
            fn,
            chunks,
            store,
            progress=lambda done, total: bar.advance(done - bar.done, note=label),
            finished=finished,
        )


def chunk_count(total: int, chunk: int) -> int:
    """Number of chunks of ``chunk`` items that cover ``total`` items."""
    return max(math.ceil(total / chunk), 0)


def check_chunk_count(count: int, what: str, smallest: int) -> None:
    """Refuse a campaign of more than :data:`MAX_CHUNKS` chunks, before any work.

    Args:
        count: the campaign's number of chunks.
        what: how ``chunk`` gives them, in words (``"10 targets in chunks of 1 make"``).
        smallest: the smallest ``chunk`` within the limit, suggested.

    Raises:
        OptikError: ``count`` above :data:`MAX_CHUNKS` (the message names ``chunk``).
    """
    if count > MAX_CHUNKS:
        raise OptikError(
            f"chunk: {what} {count} chunks, more than {MAX_CHUNKS} (each costs memory and "
            f"start-up time before any is solved): give chunk={smallest} or more"
        )


__all__ = [
    "CONNECT_TIMEOUT_S",
    "MAX_CHUNKS",
    "MAX_WORKERS",
    "QUIET_CLUSTER",
    "ChunkStore",
    "ChunkWriter",
    "Engine",
    "ProgressOption",
    "Written",
    "check_chunk_count",
    "chunk_count",
    "compute_and_write",
    "open_engine",
    "run_chunks",
    "run_chunks_with_progress",
]
