"""The ``optik`` command: its parser and entry point; one module per command beside it.

Exit codes: 0 success; 1 a well-formed query without an answer (``optik solve`` found no
solution); 2 bad input (a usage error, and every :class:`~optik.errors.OptikError` raised
by the input, printed as one ``optik: error: ...`` line); 3 an internal error (a bug: the
traceback is printed); 141 standard output closed early (``optik problems | head -1``),
silently.

Units: SI everywhere, in files, arrays and options (m, rad, s); an option in another
unit names it (``--rpy-deg``, ``--timeout-ms``), and the help of every option that takes
numbers states their unit or "no unit" (counts, seeds, quaternions). Output prints every
value with its unit (revolute joints in rad, with degrees alongside).
"""

from __future__ import annotations

import argparse
import os
import sys
import textwrap
import traceback
from collections.abc import Sequence
from typing import TextIO

from numba.core import event

from optik import __version__
from optik._interrupts import wrapped_interrupt
from optik.cli._batch import add_batch_command
from optik.cli._common import (
    EXIT_BAD_INPUT,
    EXIT_INTERNAL,
    EXIT_NO_SOLUTION,
    EXIT_OK,
    EXIT_OUTPUT_CLOSED,
    Parser,
)
from optik.cli._map import add_map_command
from optik.cli._plan import add_plan_command
from optik.cli._report import add_report_command, config_from_args
from optik.cli._robot import add_problems_command, add_robot_command
from optik.cli._show import add_show_command
from optik.cli._solve import add_solve_command
from optik.cli._view import add_view_command
from optik.cli._warmup import add_warmup_command
from optik.errors import OptikError

__all__ = [
    "EXIT_BAD_INPUT",
    "EXIT_INTERNAL",
    "EXIT_NO_SOLUTION",
    "EXIT_OK",
    "add_report_command",
    "build_parser",
    "config_from_args",
    "main",
]


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of the ``optik`` command."""
    parser = Parser(
        prog="optik",
        description=textwrap.fill(
            "Optimization-based inverse kinematics for robot arms. Units: SI (m, rad, s) in "
            "files, arrays and options; an option in another unit names it (--rpy-deg, "
            "--timeout-ms).",
            88,
        ),
        epilog="examples:\n  optik problems\n  optik robot problems/panda.urdf\n"
        "  optik solve planar_2r --position 1 1 0\n  optik report --quick\n",
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument(
        "--version",
        action="version",
        version=f"optik {__version__}",
        help="print the version and exit",
    )
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    add_problems_command(sub)
    add_robot_command(sub)
    add_show_command(sub)
    add_solve_command(sub)
    add_plan_command(sub)
    add_report_command(sub)
    add_view_command(sub)
    add_map_command(sub)
    add_batch_command(sub)
    add_warmup_command(sub)
    return parser


class _CompileNotice(event.Listener):
    """One line on ``stream`` when numba first compiles a kernel in this process."""

    def __init__(self, stream: TextIO) -> None:
        self.stream = stream
        self.said = False

    def on_start(self, event: object) -> None:
        if not self.said:
            self.said = True
            print(COMPILE_NOTICE, file=self.stream, flush=True)

    def on_end(self, event: object) -> None:
        pass


COMPILE_NOTICE = (
    "optik: compiling kernels on their first use in this environment (seconds to a "
    "minute, once: they are cached; `optik warmup` compiles them ahead)"
)
_NOTICES: dict[int, _CompileNotice] = {}


def say_when_compiling(stream: TextIO) -> None:
    """On a terminal, say so the first time numba compiles a kernel (once per stream)."""
    if stream.isatty() and id(stream) not in _NOTICES:
        notice = _NOTICES[id(stream)] = _CompileNotice(stream)
        event.register("numba:compile", notice)


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``optik`` console script.

    Args:
        argv: the command-line arguments after the program name (default: ``sys.argv[1:]``).
    """
    args = build_parser().parse_args(argv)  # a usage error exits with 2
    say_when_compiling(sys.stderr)
    try:
        code = int(args.func(args))
        sys.stdout.flush()  # a closed pipe shows here, not in the interpreter's exit
        return code
    except BrokenPipeError:  # the reader quit (| head): stop quietly, as SIGPIPE would
        _discard_stdout()
        return EXIT_OUTPUT_CLOSED
    except OptikError as exc:  # bad input: one line, no traceback
        message = " ".join(str(exc).split())
        print(f"optik: error: {message}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except KeyboardInterrupt:
        print("optik: interrupted", file=sys.stderr)
        return 130
    except Exception as exc:  # a bug, not the user's input: keep the traceback for the report
        if wrapped_interrupt(exc) is not None:  # Ctrl-C that a kernel handed back wrapped
            print("optik: interrupted", file=sys.stderr)
            return 130
        traceback.print_exc()
        print("optik: internal error (a bug; please report it)", file=sys.stderr)
        return EXIT_INTERNAL


def _discard_stdout() -> None:
    """Point standard output at the null device: the exit's flush must not fail again."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
    except (OSError, ValueError):  # not a file descriptor (a captured stream)
        pass


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
