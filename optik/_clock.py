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
from typing import Any

from numba.core import caching, event


class _OneTimeTimer(event.Listener):
    """Sums the wall time of outermost one-time work (nested work is inside it)."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._depth = 0
        self._compiling = 0
        self._started = 0.0
        self.total = 0.0

    def enter(self, compiling: bool) -> None:
        with self._lock:
            if self._depth == 0:
                self._started = time.perf_counter()
            self._depth += 1
            self._compiling += compiling

    def leave(self, compiling: bool) -> None:
        with self._lock:
            self._depth -= 1
            self._compiling -= compiling
            if self._depth == 0:
                self.total += time.perf_counter() - self._started

    def on_start(self, event: Any) -> None:
        self.enter(True)

    def on_end(self, event: Any) -> None:
        self.leave(True)

    def compiling(self) -> bool:
        """Whether numba is compiling or using its cache."""
        with self._lock:
            return self._compiling > 0

    def seconds(self) -> float:
        """One-time work so far (s), including work under way."""
        with self._lock:
            running = time.perf_counter() - self._started if self._depth > 0 else 0.0
            return self.total + running


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
    """Wall time (s) of one-time work since optik's import: compilation, cache, setup."""
    return _TIMER.seconds()


def compiling() -> bool:
    """Whether numba is compiling (or loading or saving a kernel) now, in any thread."""
    return _TIMER.compiling()


def budget_clock() -> float:
    """:func:`time.perf_counter` (s) minus :func:`excluded_seconds`: stops for one-time work."""
    return time.perf_counter() - _TIMER.seconds()
