"""A clock that stops while numba compiles: for deadlines that never count compilation.

optik's kernels compile on their first call in an environment and are loaded from
numba's on-disk cache afterwards. A kernel also compiles when the cache cannot serve it
(``NUMBA_CACHE_DIR`` set, another CPU or numba release, an edited source). Such a
compilation takes seconds, and a ``timeout_s`` measured on :func:`time.perf_counter` would
charge it to the caller. :func:`budget_clock` is :func:`time.perf_counter` minus the time
spent in numba compilations in this process (from numba's ``"numba:compile"`` events,
which fire on compilations only, not on loads from the cache), so a deadline set and
checked on it measures the caller's work alone.
"""

from __future__ import annotations

import threading
import time
from typing import Any

from numba.core import event


class _CompileTimer(event.Listener):
    """Sums the wall time of outermost compilations (nested ones are inside them)."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._depth = 0
        self._started = 0.0
        self.total = 0.0

    def on_start(self, event: Any) -> None:
        with self._lock:
            if self._depth == 0:
                self._started = time.perf_counter()
            self._depth += 1

    def on_end(self, event: Any) -> None:
        with self._lock:
            self._depth -= 1
            if self._depth == 0:
                self.total += time.perf_counter() - self._started

    def busy(self) -> bool:
        """Whether a compilation is under way."""
        with self._lock:
            return self._depth > 0

    def seconds(self) -> float:
        """Compilation time so far (s), including a compilation under way."""
        with self._lock:
            running = time.perf_counter() - self._started if self._depth > 0 else 0.0
            return self.total + running


_TIMER = _CompileTimer()
event.register("numba:compile", _TIMER)


def compile_seconds() -> float:
    """Wall time (s) this process has spent in numba compilations since optik's import."""
    return _TIMER.seconds()


def compiling() -> bool:
    """Whether numba is compiling in this process now (any thread)."""
    return _TIMER.busy()


def budget_clock() -> float:
    """:func:`time.perf_counter` (s) minus :func:`compile_seconds`: stops while compiling."""
    return time.perf_counter() - _TIMER.seconds()
