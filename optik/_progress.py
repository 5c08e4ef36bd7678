"""A tiny progress bar: drawn on a terminal only, silent otherwise, no dependency.

>>> with Progress(40, enabled=False) as bar:   # enabled=None: only when stderr is a TTY
...     for _ in range(40):
...         bar.advance(note="puma560 dls")
"""

from __future__ import annotations

import sys
import time
from typing import TextIO

from optik._closing import Closing


class Progress(Closing):
    """A one-line bar ``[#####.....]  12/40  note``, redrawn in place (carriage return).

    It draws only when ``enabled`` is true, or, by default, when ``stream`` is a TTY; so
    logs, pipes and tests stay clean. Redraws are limited to one per ``interval`` seconds
    (the last one always draws).

    Args:
        total: number of steps (a total of 0 draws nothing).
        stream: where to draw (default ``sys.stderr``).
        enabled: force on or off; ``None`` means "when ``stream`` is a TTY".
        width: number of cells of the bar.
        interval: smallest time between redraws, s.
    """

    def __init__(
        self,
        total: int,
        *,
        stream: TextIO | None = None,
        enabled: bool | None = None,
        width: int = 28,
        interval: float = 0.1,
    ) -> None:
        self.total = max(int(total), 0)
        self.stream = stream if stream is not None else sys.stderr
        if enabled is None:
            isatty = getattr(self.stream, "isatty", None)
            enabled = bool(isatty()) if callable(isatty) else False
        self.enabled = enabled and self.total > 0
        self.width = width
        self.interval = interval
        self.done = 0
        self._last_draw = -float("inf")
        self._last_length = 0
        self._start = time.perf_counter()

    def advance(self, steps: int = 1, note: str = "") -> None:
        """Count ``steps`` more steps done and redraw (at most every ``interval`` s)."""
        self.done = min(self.done + steps, self.total)
        if not self.enabled:
            return
        t = time.perf_counter()
        if self.done < self.total and t - self._last_draw < self.interval:
            return
        self._last_draw = t
        self._draw(note, t - self._start)

    def _draw(self, note: str, elapsed: float) -> None:
        filled = round(self.width * self.done / self.total) if self.total else self.width
        bar = "#" * filled + "." * (self.width - filled)
        digits = len(str(self.total))
        line = f"[{bar}] {self.done:>{digits}}/{self.total}  {elapsed:5.1f} s  {note}"
        line = line[:119]
        padding = " " * max(self._last_length - len(line), 0)
        self._last_length = len(line)
        self.stream.write("\r" + line + padding)
        self.stream.flush()

    def close(self) -> None:
        """End the line (if anything was drawn)."""
        if self.enabled and self._last_length:
            self.stream.write("\n")
            self.stream.flush()
            self._last_length = 0
