"""Where a run happened: Python, package versions, CPU, OS, load (recorded in the report)."""

from __future__ import annotations

import datetime as _dt
import importlib.metadata
import os
import platform
import subprocess
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any, Final

from optik.solvers import available_solvers

__all__ = ["environment"]

#: Distribution names of the ``qpsolvers`` backends whose module name differs.
_BACKEND_PACKAGES: Final[dict[str, str]] = {
    "gurobi": "gurobipy",
    "highs": "highspy",
    "hpipm": "hpipm_python",
    "jaxopt_osqp": "jaxopt",
    "proxqp": "proxsuite",
    "qpswift": "qpSWIFT",
    "sip": "sip_python",
}


def _version(distribution: str) -> str | None:
    try:
        return importlib.metadata.version(distribution)
    except importlib.metadata.PackageNotFoundError:
        return None


def _cpu_model() -> str:
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as f:
            for line in f:
                if line.lower().startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    if sys.platform == "darwin":
        try:
            out = subprocess.run(
                ["sysctl", "-n", "machdep.cpu.brand_string"],
                capture_output=True,
                text=True,
                timeout=2,
                check=False,
            )
            if out.stdout.strip():
                return out.stdout.strip()
        except (OSError, subprocess.SubprocessError):
            pass
    return platform.processor() or platform.machine() or "unknown"


def _git(root: Path, *args: str) -> str:
    """The output of ``git -C root ARGS`` (raises on a failure or after 5 s)."""
    command = ["git", "-C", str(root), *args]
    out = subprocess.run(command, capture_output=True, text=True, timeout=5, check=True)
    return out.stdout.strip()


def _git_revision() -> str | None:
    """The short revision of the checkout optik runs from, ``+dirty`` with local changes."""
    root = Path(__file__).resolve().parents[2]
    if not (root / ".git").exists():
        return None
    try:
        head = _git(root, "rev-parse", "--short", "HEAD")
        dirty = _git(root, "status", "--porcelain", "--untracked-files=no")
    except (OSError, subprocess.SubprocessError):
        return None
    return head + ("+dirty" if dirty else "")


def _load_average() -> list[float] | None:
    """The 1, 5 and 15 minute load averages (None where the OS has none)."""
    try:
        return [round(x, 2) for x in os.getloadavg()]
    except (AttributeError, OSError):
        return None


def environment(step_backends: Sequence[str] = ()) -> dict[str, Any]:
    """Where the run happened: Python, package versions, CPU, OS, load (for the report).

    Args:
        step_backends: the closed-form section's backends, recorded as they were used.

    Returns:
        A JSON-able mapping: ``python``, ``os``, ``cpu_model``, ``cpu_count`` (logical CPUs),
        ``cpu_affinity`` (CPUs this process may use), ``load_average`` (1, 5, 15 min),
        ``packages`` (name -> version, ``None`` when absent), ``qpsolvers_backends``,
        ``step_backends``, ``ik_solvers``, ``optik`` (version and git revision), ``date``.
    """
    from optik import __version__

    packages: dict[str, str | None] = {
        name: _version(name)
        for name in ("numpy", "scipy", "numba", "casadi", "qpsolvers", "matplotlib")
    }
    try:
        import qpsolvers

        backends = sorted(qpsolvers.available_solvers)
    except ImportError:
        backends = []
    for backend in backends:
        package = _BACKEND_PACKAGES.get(backend, backend)
        packages[package] = _version(package)
    sched_getaffinity = getattr(os, "sched_getaffinity", None)  # Linux only
    affinity = len(sched_getaffinity(0)) if sched_getaffinity is not None else None
    load = _load_average()
    return {
        "python": f"{platform.python_implementation()} {platform.python_version()}",
        "os": platform.platform(),
        "cpu_model": _cpu_model(),
        "cpu_count": os.cpu_count(),
        "cpu_affinity": affinity,
        "load_average": load,
        "packages": packages,
        "qpsolvers_backends": backends,
        "step_backends": list(step_backends),
        "ik_solvers": available_solvers(),
        "optik": {"version": __version__, "git": _git_revision()},
        "date": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
    }
