"""``optik warmup``: compile the kernels now, so that no first call waits for numba."""

from __future__ import annotations

import argparse
import sys
from typing import Any

from optik.cli._common import EXIT_OK, command


def _cmd_warmup(args: argparse.Namespace) -> int:
    from optik._warmup import parse_groups, warm

    processes = args.processes
    if processes < 1:
        from optik.errors import OptikError

        raise OptikError(f"--processes must be at least 1, got {processes}")
    groups = parse_groups(args.groups, "--groups") if args.groups is not None else None
    report = warm(processes=processes, groups=groups, log=lambda line: print(line, file=sys.stderr))
    if report.cached:
        print(
            f"every kernel of the groups is cached already: none compiled ({report.seconds:.1f} s)"
        )
        return EXIT_OK
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
        "a wheel built elsewhere, or in an editable checkout; when every kernel of the groups "
        "is cached already (a second run), a probe of about 5 s says so and none compiles. "
        "--groups names the groups "
        "(default: the install's); held_joint (seven-joint arms with a joint held, about "
        "11 s of CPU) and axes_arms (the seven arm kinds of the spherical_axes and "
        "three_parallel families: 11-20 s for the first, 5-15 s for each other, about "
        "70 s in all) are compiled only when named.",
        "  optik warmup\n  optik warmup --processes 1\n"
        "  optik warmup --groups held_joint,axes_arms\n",
    )
    p.add_argument(
        "--processes",
        type=int,
        default=2,
        metavar="N",
        help="worker processes compiling side by side (no unit; default 2)",
    )
    p.add_argument(
        "--groups",
        metavar="NAMES",
        help="comma-separated warm-up groups to compile (default: the install's "
        "groups, or $OPTIK_WARMUP_GROUPS)",
    )
    p.set_defaults(func=_cmd_warmup)
