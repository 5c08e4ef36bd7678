"""``optik warmup``: compile the kernels now, so that no first call waits for numba."""

from __future__ import annotations

import argparse
import sys
from typing import Any

from optik.cli._common import EXIT_OK, command


def _cmd_warmup(args: argparse.Namespace) -> int:
    from optik._warmup import warm

    processes = args.processes
    if processes < 1:
        from optik.errors import OptikError

        raise OptikError(f"--processes must be at least 1, got {processes}")
    report = warm(processes=processes, log=lambda line: print(line, file=sys.stderr))
    print(
        f"{report.compiled} kernels compiled in {report.seconds:.1f} s, "
        f"{report.kernels} of them new to the cache"
    )
    return EXIT_OK


def add_warmup_command(sub: Any) -> None:
    p = command(
        sub,
        "warmup",
        "compile optik's kernels ahead of their first call",
        "numba compiles each kernel on its first call in an environment (about a minute "
        "of CPU before a first solve_ik, solve_ik_batch or report) and caches it. This "
        "compiles the kernels of the common calls now, in worker processes side by side, "
        "into the installed package's cache (or NUMBA_CACHE_DIR when set). A wheel built "
        "with pip from the sources already carries them; run this after an install from "
        "a wheel built elsewhere, or in an editable checkout.",
        "  optik warmup\n  optik warmup --processes 1\n",
    )
    p.add_argument(
        "--processes",
        type=int,
        default=2,
        metavar="N",
        help="worker processes compiling side by side (no unit; default 2)",
    )
    p.set_defaults(func=_cmd_warmup)
