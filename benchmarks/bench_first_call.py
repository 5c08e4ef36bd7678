"""First-call times in a fresh environment: the install, then each first call, cold and warm.

Run: ``python3 benchmarks/bench_first_call.py [--venv DIR] [--no-install]``

1. Builds a fresh virtual environment in ``--venv`` (default: a temporary folder) with the
   README's non-editable install, ``pip install -q "<checkout>[report]"``, and times it.
   ``--no-install`` reuses an environment built before (its install time is not shown).
2. Keeps a copy of the installed ``optik`` package as pip left it (with whatever compiled
   kernels the wheel carries), so that every "cold" run starts from the state just after
   the install.
3. For each of the four measurements, restores that copy and runs the measurement in a
   fresh process (cold), then again in a second fresh process (warm, after numba's cache
   has whatever the first process wrote):

   - ``puma``: the first ``optik.solve_ik`` on the Puma 560 (closed form);
   - ``panda``: the first ``optik.solve_ik`` on the Panda (numeric: damped least squares);
   - ``batch``: the first ``optik.solve_ik_batch`` of 64 Panda targets (parallel kernel);
   - ``report``: ``optik report --quick`` (the README's main job), as a whole process.

For the three calls the table gives the call's own time (``time.perf_counter`` around
it), the process's wall time (interpreter start, ``import optik``, loading the problem, its
forward kinematics and the call) and the number of numba signatures compiled in the
process (cache misses: 0 means every kernel came from the cache). No assertions: times
are reported, never tested.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

CHECKOUT = Path(__file__).resolve().parent.parent

# Counts numba's cache misses over optik's compiled functions (each is one compilation).
_MISSES = """
def _misses():
    import sys
    from numba.core.registry import CPUDispatcher
    seen, total = set(), 0
    for name, module in list(sys.modules.items()):
        if name.split(".")[0] != "optik":
            continue
        for value in vars(module).values():
            if isinstance(value, CPUDispatcher) and id(value) not in seen:
                seen.add(id(value))
                total += sum(value.stats.cache_misses.values())
    return total
"""

_CALL = """
import json, time
t0 = time.perf_counter()
import numpy as np
import optik
t_import = time.perf_counter() - t0
{setup}
t1 = time.perf_counter()
{call}
t_call = time.perf_counter() - t1
print(json.dumps({{"import_s": t_import, "call_s": t_call, "ok": bool({ok}),
                   "misses": _misses()}}))
"""

PROBES = {
    "puma": (
        'robot = optik.load_problem("puma560").robot\n'
        "T = robot.fk(np.radians([20.0, 60.0, -120.0, 30.0, 40.0, 10.0]))",
        "r = optik.solve_ik(robot, T)",
        'r.success and r.solver == "analytic"',
    ),
    "panda": (
        'robot = optik.load_problem("panda").robot\n'
        "T = robot.fk(np.array([0.3, -0.4, 0.2, -2.0, 0.1, 1.6, 0.5]))",
        "r = optik.solve_ik(robot, T)",
        'r.success and r.solver != "analytic"',
    ),
    "report": (
        "from optik.cli import main\nimport contextlib, io",
        "with contextlib.redirect_stdout(io.StringIO()):\n"
        '    code = main(["report", "--quick", "--out", "optik-report"])',
        "code == 0",
    ),
    "batch": (
        'robot = optik.load_problem("panda").robot\n'
        "rng = np.random.default_rng(0)\n"
        "Q = rng.uniform(robot.lower, robot.upper, size=(64, robot.dof))\n"
        "Ts = robot.fk(Q)",
        "r = optik.solve_ik_batch(robot, Ts)",
        "r.success.mean() > 0.9",
    ),
}


def children_cpu_s() -> float:
    """CPU time (user + system, s) of the finished child processes so far."""
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def site_package(python: Path) -> Path:
    """The folder of the ``optik`` package installed for ``python``."""
    code = "import importlib.util as u; print(u.find_spec('optik').submodule_search_locations[0])"
    return Path(subprocess.check_output([str(python), "-c", code], cwd="/", text=True).strip())


def install(venv: Path) -> tuple[float, float]:
    """Create ``venv`` and install the checkout as the README does; wall and CPU seconds."""
    start, cpu = time.perf_counter(), children_cpu_s()
    subprocess.run([sys.executable, "-m", "venv", str(venv)], check=True)
    pip = venv / "bin" / "pip"
    subprocess.run([str(pip), "install", "-q", f"{CHECKOUT}[report]"], check=True)
    return time.perf_counter() - start, children_cpu_s() - cpu


def run_probe(venv: Path, name: str, workdir: Path) -> dict[str, float]:
    """Run one measurement in a fresh process; its times and compile count."""
    start, cpu = time.perf_counter(), children_cpu_s()
    setup, call, ok = PROBES[name]
    code = _MISSES + _CALL.format(setup=setup, call=call, ok=ok)
    text = subprocess.check_output([str(venv / "bin" / "python"), "-c", code], cwd=workdir)
    result: dict[str, float] = json.loads(text.decode().strip().splitlines()[-1])
    result["wall_s"] = time.perf_counter() - start
    result["cpu_s"] = children_cpu_s() - cpu
    return result


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--venv", type=Path, help="environment folder (default: temporary)")
    parser.add_argument("--no-install", action="store_true", help="reuse --venv as it is")
    parser.add_argument("--only", nargs="*", default=["puma", "panda", "batch", "report"])
    args = parser.parse_args(argv)
    scratch = Path(tempfile.mkdtemp(prefix="optik-first-call-"))
    venv = args.venv or scratch / "venv"
    installed = None if args.no_install else install(venv)
    package = site_package(venv / "bin" / "python")
    pristine = scratch / "pristine"
    shutil.copytree(package, pristine, symlinks=True)
    rows = []
    for name in args.only:
        shutil.rmtree(package)
        shutil.copytree(pristine, package, symlinks=True)
        cold = run_probe(venv, name, scratch)
        warm = run_probe(venv, name, scratch)
        rows.append((name, cold, warm))
    print(f"command: python3 benchmarks/bench_first_call.py {' '.join(argv or sys.argv[1:])}")
    print(f"python {platform.python_version()}, {platform.machine()}, {os.cpu_count()} cores, "
          f"load {os.getloadavg()[0]:.2f}; checkout {CHECKOUT}")  # fmt: skip
    shipped = sorted(pristine.rglob("*.nbi"))
    took = "-" if installed is None else f"{installed[0]:.1f} s wall, {installed[1]:.1f} s CPU"
    print(f"install: {took}; "
          f"{len(shipped)} numba index files installed by pip")  # fmt: skip
    print()
    head = [
        f"{s} {c}"
        for s in ("cold", "warm")
        for c in ("call (s)", "process (s)", "CPU (s)", "compiles")
    ]
    print(f"| measurement | {' | '.join(head)} | answers |")
    print("| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: | --- |")
    for name, cold, warm in rows:

        def cell(r: dict[str, float], key: str) -> str:
            value = r.get(key)
            return "-" if value is None else (f"{value:.2f}" if key != "misses" else f"{value:d}")

        ok = "-" if "ok" not in cold else ("correct" if cold["ok"] and warm["ok"] else "WRONG")
        cells = [
            cell(r, key) for r in (cold, warm) for key in ("call_s", "wall_s", "cpu_s", "misses")
        ]
        print(f"| {name} | {' | '.join(cells)} | {ok} |")
    shutil.rmtree(scratch, ignore_errors=True)


if __name__ == "__main__":
    main()
