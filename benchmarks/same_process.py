"""Old and new optik in one process, timed in alternation: a speed check that load spares.

Run (from the repository root, with any environment that has optik's dependencies)::

    python benchmarks/same_process.py --old 699937e --robots panda,puma560,ur5

The tree at ``--old`` (a git revision of this repository) is exported to a temporary
folder with its package renamed ``optik_old`` (every ``optik`` import rewritten), so that
both versions import side by side. Each round times, for each version in turn (the order
flips every round), on the same targets (the FK of seeded in-limit configurations):

- ``solve_ik_batch`` with one thread (µs per target);
- ``solve_ik(solver="dls")`` and ``solve_ik`` with the default solver (µs per query);
- ``analytic_ik`` and ``analytic_ik_batch`` for robots with a closed form (µs per pose).

Times are CPU time of the calling thread (``time.thread_time``), and each figure is the
best round: other processes on a shared machine only ever add time, and they add it to
both versions alike when the versions alternate within seconds. The ratio new / old > 1
means the new tree is slower. A separate-process harness (``interleave.py``) measures the
same figures with wall time; on a busy machine its rounds disagree by more than 10 %.
"""

from __future__ import annotations

import argparse
import re
import subprocess
import sys
import tarfile
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
_IMPORT = re.compile(r"\b(from|import) optik\b")
_NAME = re.compile(r"\boptik\.")


def export_renamed(revision: str, folder: Path) -> None:
    """Write ``revision``'s ``optik/`` and ``problems/`` into ``folder``, the package renamed."""
    archive = folder / "tree.tar"
    subprocess.run(
        ["git", "-C", str(ROOT), "archive", "-o", str(archive), revision, "optik", "problems"],
        check=True,
    )
    with tarfile.open(archive) as tar:
        tar.extractall(folder, filter="data")
    (folder / "optik").rename(folder / "optik_old")
    for path in (folder / "optik_old").rglob("*.py"):
        text = path.read_text(encoding="utf-8")
        text = _IMPORT.sub(r"\1 optik_old", text)
        text = _NAME.sub("optik_old.", text)
        path.write_text(text, encoding="utf-8")


def best_of(rounds: int, timers: dict[str, Callable[[], float]]) -> dict[str, float]:
    """The smallest time of each timer over ``rounds`` alternating rounds."""
    best = {key: float("inf") for key in timers}
    keys = list(timers)
    for r in range(rounds):
        for key in keys if r % 2 == 0 else reversed(keys):
            best[key] = min(best[key], timers[key]())
    return best


def per_call(fn: Callable[[int], Any], count: int) -> Callable[[], float]:
    """A timer of ``fn(k)`` for ``k < count``: CPU seconds per call."""

    def timer() -> float:
        t = time.thread_time()
        for k in range(count):
            fn(k)
        return (time.thread_time() - t) / count

    return timer


def once(fn: Callable[[], Any], count: int) -> Callable[[], float]:
    """A timer of one call of ``fn`` over ``count`` items: CPU seconds per item."""

    def timer() -> float:
        t = time.thread_time()
        fn()
        return (time.thread_time() - t) / count

    return timer


def compare(name: str, libs: dict[str, Any], targets: int, rounds: int) -> list[str]:
    """Rows ``figure, old µs, new µs, new/old`` for one robot."""
    robots = {key: lib.load_problem(name).robot for key, lib in libs.items()}
    new = robots["new"]
    rng = np.random.default_rng(1)
    Q = rng.uniform(new.lower, new.upper, size=(targets, new.dof))
    T = np.array([new.fk(q) for q in Q])
    singles = min(targets, 200)
    closed = libs["new"].analytic.family_of(new) is not None
    figures: dict[str, dict[str, Callable[[], float]]] = {}
    for key, lib in libs.items():
        robot = robots[key]
        lib.solve_ik_batch(robot, T[:50], threads=1)  # compile outside the timing
        lib.solve_ik(robot, T[0], solver="dls")
        lib.solve_ik(robot, T[0])

        def batch(lib: Any = lib, robot: Any = robot) -> Any:
            return lib.solve_ik_batch(robot, T, threads=1)

        figures.setdefault("solve_ik_batch, 1 thread", {})[key] = once(batch, targets)
        figures.setdefault('solve_ik(solver="dls")', {})[key] = per_call(
            lambda k, lib=lib, robot=robot: lib.solve_ik(robot, T[k], solver="dls"), singles
        )
        figures.setdefault("solve_ik (auto)", {})[key] = per_call(
            lambda k, lib=lib, robot=robot: lib.solve_ik(robot, T[k]), singles
        )
        if closed:
            lib.analytic_ik(robot, T[0])
            lib.analytic_ik_batch(robot, T[:10])
            figures.setdefault("analytic_ik", {})[key] = per_call(
                lambda k, lib=lib, robot=robot: lib.analytic_ik(robot, T[k]), singles
            )

            def analytic_batch(lib: Any = lib, robot: Any = robot) -> Any:
                return lib.analytic_ik_batch(robot, T)

            figures.setdefault("analytic_ik_batch", {})[key] = once(analytic_batch, targets)
    rows = []
    for figure, timers in figures.items():
        best = best_of(rounds, timers)
        old, now = best["old"] * 1e6, best["new"] * 1e6
        rows.append(f"| {name} | {figure} | {old:.2f} | {now:.2f} | {now / old:.3f} |")
    return rows


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--old", required=True, help="git revision of the old tree")
    parser.add_argument("--robots", default="panda,puma560,ur5", help="comma-separated")
    parser.add_argument("--targets", type=int, default=500, help="targets per robot")
    parser.add_argument("--rounds", type=int, default=21, help="alternating rounds")
    parser.add_argument(
        "--workdir",
        type=Path,
        default=None,
        help="keep the exported old tree here, with its numba cache, for the next run",
    )
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        folder = args.workdir or Path(tmp)
        if not (folder / "optik_old").is_dir():
            folder.mkdir(parents=True, exist_ok=True)
            export_renamed(args.old, folder)
        sys.path[:0] = [str(ROOT), str(folder)]
        import optik_old  # type: ignore[import-not-found]

        import optik

        for key, lib in (("new", optik), ("old", optik_old)):
            print(f"{key}: {Path(lib.__file__).parent}")
        print("\n| robot | figure | old µs | new µs | new/old |\n|---|---|---|---|---|")
        for name in args.robots.split(","):
            for row in compare(name, {"new": optik, "old": optik_old}, args.targets, args.rounds):
                print(row, flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
