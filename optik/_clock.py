"""A clock that stops for one-time work: deadlines that never count compilation or setup.

optik's kernels compile on their first call in an environment and are loaded from
numba's on-disk cache afterwards. A kernel also compiles when the cache cannot serve it
(``NUMBA_CACHE_DIR`` set, another CPU or numba release, an edited source). Such a
compilation takes seconds, and a ``timeout_s`` measured on :func:`time.perf_counter` would
charge it to the caller. :func:`budget_clock` is :func:`time.perf_counter` minus the time
this process spent on one-time work:

- numba compilations (numba's ``"numba:compile"`` events);
- numba's cache: looking a kernel up, loading it on its first call in a process, saving
  a fresh compilation (tens of milliseconds in all, outside those events);
- a robot's derived data, built once per :class:`~optik.model.Robot` on first use
  (:meth:`~optik.model.Robot.cached`: the seed table's clustering, the closed-form
  family's detection, ...), and a CasADi solver built and compiled once per robot and
  task shape: :func:`one_time_setup`.

A deadline set and checked on it measures the caller's query alone.
"""

from __future__ import annotations

import functools
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any

from numba.core import caching, event


class _OneTimeTimer(event.Listener):
    """Sums each thread's wall time of outermost one-time work (nested work is inside it).

    A thread's clock leaves out that thread's own work only. Work in another thread (a
    second caller's compilation, another robot's setup) does not stop it, or one busy
    thread could hold off another's deadline for as long as it kept building. Work a
    thread began and has not ended is not counted: a thread reading a deadline is not
    inside one-time work, so such work is a start whose end never came (a listener ahead
    of this one raised, and numba skipped the rest), and counting it would stop the
    clock for good. An end that no start of its thread opened is ignored.
    """

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._open: dict[threading.Thread, _OpenWork] = {}
        self._done: dict[threading.Thread, float] = {}

    def enter(self, compiling: bool) -> None:
        with self._lock:
            work = self._open.setdefault(threading.current_thread(), _OpenWork())
            if work.depth == 0:
                work.started = time.perf_counter()
            work.depth += 1
            work.compiling += compiling

    def leave(self, compiling: bool) -> None:
        with self._lock:
            thread = threading.current_thread()
            work = self._open.get(thread)
            if work is None:
                return
            work.depth -= 1
            work.compiling = max(work.compiling - compiling, 0)
            if work.depth == 0:
                elapsed = time.perf_counter() - work.started
                self._done[thread] = self._done.get(thread, 0.0) + elapsed
                del self._open[thread]
                self._forget_ended()  # here, not in seconds(): deadlines read that often

    def on_start(self, event: Any) -> None:
        self.enter(True)

    def on_end(self, event: Any) -> None:
        self.leave(True)

    def compiling(self) -> bool:
        """Whether numba is compiling or using its cache, in any thread."""
        with self._lock:
            self._forget_ended()
            return any(work.compiling > 0 for work in self._open.values())

    def idle(self) -> bool:
        """Whether no thread is inside one-time work."""
        with self._lock:
            self._forget_ended()
            return not self._open

    def seconds(self) -> float:
        """The calling thread's finished one-time work so far (s)."""
        # No lock: one dict read is atomic, and only this thread adds to its own entry.
        return self._done.get(threading.current_thread(), 0.0)

    def _forget_ended(self) -> None:
        """Drop the work of threads that have ended (no clock of theirs is read again)."""
        for thread in [thread for thread in self._open if not thread.is_alive()]:
            del self._open[thread]
        for thread in [thread for thread in self._done if not thread.is_alive()]:
            del self._done[thread]


@dataclass
class _OpenWork:
    """One thread's one-time work under way: nesting depth, compilations among it, start (s)."""

    depth: int = 0
    compiling: int = 0
    started: float = 0.0


_TIMER = _OneTimeTimer()
event.register("numba:compile", _TIMER)


def _timed(method: Callable[..., Any]) -> Callable[..., Any]:
    """``method`` of numba's cache, its time counted with the compilations'."""
    if getattr(method, "_optik_timed", False):
        return method

    @functools.wraps(method)
    def timed(self: Any, *args: Any) -> Any:
        _TIMER.enter(True)
        try:
            return method(self, *args)
        finally:
            _TIMER.leave(True)

    timed._optik_timed = True  # type: ignore[attr-defined]
    return timed


# Loading a kernel from the cache and saving a fresh one happen outside numba's compile
# events (loading rebuilds the machine code of a kernel and its callees). Every cache of
# the process is timed, optik's or not, as the compile events are.
caching.Cache.load_overload = _timed(caching.Cache.load_overload)  # type: ignore[method-assign]
caching.Cache.save_overload = _timed(caching.Cache.save_overload)  # type: ignore[method-assign]


@contextmanager
def one_time_setup() -> Iterator[None]:
    """Work inside is one-time setup: :func:`budget_clock` stops while it runs."""
    _TIMER.enter(False)
    try:
        yield
    finally:
        _TIMER.leave(False)


def excluded_seconds() -> float:
    """Wall time (s) of the calling thread's one-time work: compilation, cache, setup.

    Work under way is not counted until it ends.
    """
    return _TIMER.seconds()


def compiling() -> bool:
    """Whether numba is compiling (or loading or saving a kernel) now, in any thread."""
    return _TIMER.compiling()


def budget_clock() -> float:
    """:func:`time.perf_counter` (s) minus :func:`excluded_seconds`: stops for one-time work."""
    return time.perf_counter() - _TIMER.seconds()
