"""First calls on arms found from their axes: the compile time of each arm kind's pipeline.

Run: ``python benchmarks/bench_kind_first_call.py [--kinds NAMES]``

``spherical_axes`` and ``three_parallel`` compile a pipeline per arm kind
(:func:`optik.analytic.spherical_axes.kind_pipeline`), outside the install's warm-up. This
copies the checkout's ``optik`` package into a temporary folder, compiles the install's
warm-up groups there once (``optik warmup``: what a user's environment holds after the
README's install), keeps that state, and then for each of the five arm kinds with a
spherical wrist restores it and times, in a fresh process, the first ``analytic_ik`` and
the first ``analytic_ik_batch`` on an arm of that kind (process CPU time: the
compilation), the same calls again (warm), and how many of the kind's two pipelines the
process compiled (2: neither came from the cache); then the first calls again in a copy
of that state where the next kind's first calls ran before ("after other": the kernels
the kinds share, such as their post-processing, come from the cache). No assertions:
times are reported, never tested.
"""

from __future__ import annotations

import argparse
import os
import platform
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent

WRIST = [(0.0, -90.0, 0.45, 0.0), (0.0, 90.0, 0.0, 0.3), (0.0, 0.0, 0.1, 0.0)]
"""A spherical wrist: DH rows (a m, alpha deg, d m, theta rad) of joints 4 to 6."""
ARMS = {
    "PARALLEL_23": [(0.1, 60.0, 0.4, 0.2), (0.5, 0.0, 0.1, 0.1), (0.05, 75.0, 0.0, -0.3)],
    "PARALLEL_12": [(0.4, 0.0, 0.3, 0.2), (0.3, 70.0, 0.1, 0.0), (0.05, 80.0, 0.0, 0.4)],
    "INTERSECTING": [(0.0, 70.0, 0.3, 0.1), (0.4, 50.0, 0.05, 0.2), (0.05, 80.0, 0.0, 0.0)],
    "SECOND_PAIR": [(0.1, 60.0, 0.4, 0.2), (0.0, 40.0, 0.1, 0.1), (0.05, 75.0, 0.0, -0.3)],
    "GENERAL": [(0.1, 60.0, 0.4, 0.2), (0.5, 40.0, 0.1, 0.1), (0.05, 75.0, 0.0, -0.3)],
}
"""Arms with a spherical wrist, one per arm kind (the kinds' names in ``spherical_axes``)."""

CALLS = """
import math, sys, time
import numpy as np
import optik
from optik.analytic import family_of
from optik.analytic import spherical_axes

rows = [
    {"a": a, "alpha": math.radians(al), "d": d, "theta": th, "lower": -3.0, "upper": 3.0}
    for a, al, d, th in ROWS
]
robot = optik.Robot.from_dh(rows)
family = family_of(robot)
kind = robot.cached(family.plan).kind
assert kind == getattr(spherical_axes, KIND), (kind, KIND)
T = robot.fk(np.full(6, 0.3))
figures = []
for _ in range(2):
    start = time.process_time()
    optik.analytic_ik(robot, T)
    single = time.process_time() - start
    start = time.process_time()
    optik.analytic_ik_batch(robot, np.stack([T, T]))
    figures += [single, time.process_time() - start]
kernels = spherical_axes.kind_pipeline(kind)
compiled = sum(sum(f.stats.cache_misses.values()) for f in (kernels.solve, kernels.solve_batch))
print(" ".join(f"{x:.2f}" for x in figures), compiled)
"""


def _calls(kind: str) -> str:
    """The timed calls (:data:`CALLS`) on the arm of ``kind``."""
    return CALLS.replace("ROWS", repr(ARMS[kind] + WRIST)).replace("KIND", repr(kind))


def _python(folder: Path, code: str) -> str:
    """Run ``code`` in a fresh interpreter importing ``optik`` from ``folder``."""
    env = {**os.environ, "PYTHONPATH": str(folder)}
    env.pop("NUMBA_CACHE_DIR", None)
    # Run from the folder: ``-c`` puts the working directory first on sys.path, and the
    # checkout's own package there would shadow the copy.
    check = f"import optik; assert optik.__file__.startswith({str(folder)!r}), optik.__file__\n"
    done = subprocess.run(
        [sys.executable, "-c", check + code],
        env=env,
        cwd=folder,
        capture_output=True,
        text=True,
        check=True,
    )
    return done.stdout.strip()


def _row(cells: tuple[str, ...]) -> str:
    """One table row: the kind, then right-aligned figures."""
    return f"{cells[0]:14s}" + "".join(f" {cell:>11s}" for cell in cells[1:])


def main() -> None:
    """Print each arm kind's first-call and warm CPU times."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--kinds", default=",".join(ARMS), help=f"comma-separated kinds (default: {','.join(ARMS)})"
    )
    args = parser.parse_args()
    kinds = [k for k in args.kinds.split(",") if k]
    unknown = sorted(set(kinds) - set(ARMS))
    if unknown:
        parser.error(f"unknown kinds {unknown}; known: {sorted(ARMS)}")
    import numba

    print(f"python {platform.python_version()}, numba {numba.__version__}, "
          f"{platform.machine()}, {os.cpu_count()} cores, load {os.getloadavg()[0]:.2f}; "
          f"checkout {ROOT}")  # fmt: skip
    with tempfile.TemporaryDirectory() as tmp:
        warm = Path(tmp) / "warm"
        fresh = shutil.ignore_patterns("__pycache__")
        for folder in ("optik", "problems"):  # the package finds its problems beside it
            shutil.copytree(ROOT / folder, warm / folder, ignore=fresh)
        print("compiling the install's warm-up groups (optik warmup) ...", flush=True)
        _python(warm, "from optik._warmup import warm; warm()")
        header = ("arm kind", "first call", "first batch", "warm call", "warm batch", "compiled")
        print(_row((*header, "after other", "then batch"))
              + "  (process CPU s; kernels the kind compiled)")  # fmt: skip
        names = list(ARMS)
        for kind in kinds:
            trial = Path(tmp) / kind
            shutil.copytree(warm, trial)
            figures = _python(trial, _calls(kind)).split()
            shutil.rmtree(trial)
            # Again where another kind's first calls ran before (the shared kernels cached).
            other = names[(names.index(kind) + 1) % len(names)]
            shutil.copytree(warm, trial)
            _python(trial, _calls(other))
            after = _python(trial, _calls(kind)).split()[:2]
            shutil.rmtree(trial)
            print(_row((kind, *figures, *after)), flush=True)


if __name__ == "__main__":
    main()
