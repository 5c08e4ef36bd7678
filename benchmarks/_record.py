"""Machine-readable figures: the ``--json`` file of ``bench_ik.py`` and ``bench_analytic.py``.

Both scripts write the same shape, which ``interleave.py`` reads to compare two source
trees::

    {"script": "bench_ik.py",
     "meta": {"optik_path": ..., "optik_commit": ..., "load_before": ..., ...},
     "metrics": [{"name": "panda: optik dls", "kind": "single" | "batch",
                  "seconds_per_query": ..., "runs_s": [...] | null, "n": ...,
                  "success_rate": ... | null, "mean_iterations": ... | null}, ...]}

``seconds_per_query`` is the figure compared: the median time of one query for single
calls, batch wall time / batch size for batches (its inverse is the throughput).
This module imports only the standard library and ``optik`` (whichever tree is first on
``sys.path``), so that the scripts of one tree can measure the package of another.
"""

from __future__ import annotations

import json
import math
import os
import subprocess
import tempfile
from pathlib import Path
from typing import Any

SCHEMA = 1


def git_commit(path: Path) -> str:
    """Short commit of a checkout (``+dirty`` when its ``optik/`` has changes), or ``?``."""
    try:
        rev = subprocess.run(
            ["git", "rev-parse", "--short", "HEAD"],
            cwd=path,
            capture_output=True,
            text=True,
            check=True,
        ).stdout.strip()
        dirty = subprocess.run(
            ["git", "status", "--porcelain", "--", "optik"],
            cwd=path,
            capture_output=True,
            text=True,
            check=True,
        ).stdout.strip()
        return rev + ("+dirty" if dirty else "")
    except (OSError, subprocess.CalledProcessError):
        return "?"


def optik_source() -> dict[str, str]:
    """Where the imported ``optik`` package lives, and that tree's git commit.

    The commit is the short hash of the checkout that holds the package, with ``+dirty``
    when it has local changes, or ``"?"`` outside git (an installed wheel).
    """
    import optik

    package = Path(optik.__file__).resolve().parent
    return {"optik_path": str(package), "optik_commit": git_commit(package.parent)}


def metric(
    name: str,
    kind: str,
    seconds_per_query: float,
    n: int,
    *,
    runs_s: list[float] | None = None,
    success_rate: float | None = None,
    mean_iterations: float | None = None,
) -> dict[str, Any]:
    """One figure of the ``metrics`` list (NaN becomes ``None``: JSON has no NaN)."""

    def clean(x: float | None) -> float | None:
        return None if x is None or not math.isfinite(x) else float(x)

    if kind not in ("single", "batch"):
        raise ValueError(f"kind must be 'single' or 'batch', got {kind!r}")
    return {
        "name": name,
        "kind": kind,
        "seconds_per_query": clean(seconds_per_query),
        "runs_s": None if runs_s is None else [clean(x) for x in runs_s],
        "n": int(n),
        "success_rate": clean(success_rate),
        "mean_iterations": clean(mean_iterations),
    }


def write_json(
    path: Path, script: str, meta: dict[str, Any], metrics: list[dict[str, Any]]
) -> None:
    """Write the figures whole or not at all (a temporary file, then an atomic rename)."""
    data = {"schema": SCHEMA, "script": script, "meta": meta, "metrics": metrics}
    text = json.dumps(data, indent=1, allow_nan=False) + "\n"
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", dir=path.parent)
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as f:
            f.write(text)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
