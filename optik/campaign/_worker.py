"""The preload of the workers of the local clusters optik starts: Ctrl-C is the client's.

A terminal sends Ctrl-C (SIGINT) to every process of its foreground process group, the
worker processes of ``workers=N`` included. Each would die of a ``KeyboardInterrupt`` and
print its traceback (about 30 lines a worker) before the client's ``optik: interrupted``;
the client, which stops the run, closes the cluster anyway, and the chunks already written
stay for a resume. Dask runs :func:`dask_setup` in every worker it starts, a replacement
too.
"""

from __future__ import annotations

import logging
import signal
import threading
from typing import Any


def dask_setup(worker: Any) -> None:
    """Ignore SIGINT in this worker process (signals are set on the main thread only)."""
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, signal.SIG_IGN)


def quiet_logs() -> None:
    """Drop this worker's Dask log records below CRITICAL: its cluster is shutting down.

    Run on the workers of a local cluster just before it closes (``Client.run``): a worker
    still solving a chunk when the scheduler stops (after Ctrl-C) would otherwise log a
    "Failed to communicate with scheduler" traceback; a worker of a local cluster has no
    news for the user that the client does not give.
    """
    names = [n for n in logging.root.manager.loggerDict if n.partition(".")[0] == "distributed"]
    for name in ["distributed", *names]:
        logging.getLogger(name).setLevel(logging.CRITICAL)
