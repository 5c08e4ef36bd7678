"""Wheel build hook: compile optik's kernels while the wheel is built, and ship them.

numba compiles each kernel on its first call in an environment (about a minute of CPU for
a first ``solve_ik``, ``solve_ik_batch`` and ``optik report --quick``). A wheel built
from the sources (``pip install .``) runs ``optik._warmup`` here, on this machine, and
carries the compiled kernels in its ``__pycache__`` folders, where numba finds them: the
first calls after the install load them instead of compiling. They are valid for this
CPU, Python and numba release only, so such a wheel is tagged for this Python and
platform; elsewhere numba ignores them and compiles on first use, as without them.

Skipped for editable installs (the kernels are then compiled on first use and cached in
the source tree) and when ``OPTIK_WARMUP`` is ``0`` (or ``false``, ``no``, ``off``). A
warm-up that refuses its settings (``OPTIK_WARMUP_GROUPS`` naming no group) stops the
build with its message; one that fails otherwise leaves a working wheel without compiled
kernels, and says so in pip's verbose output (``pip install -v``).
"""

from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Any

from hatchling.builders.hooks.plugin.interface import BuildHookInterface


def _sources_digest(package: Path) -> str:
    """SHA-256 of the package's Python sources (paths and contents)."""
    digest = hashlib.sha256()
    for path in sorted(package.rglob("*.py")):
        digest.update(path.relative_to(package).as_posix().encode() + b"\0")
        digest.update(path.read_bytes())
    return digest.hexdigest()


_OFF = ("0", "false", "no", "off")
"""Values of ``OPTIK_WARMUP`` that build a wheel without compiled kernels."""


class WarmKernelsHook(BuildHookInterface):  # type: ignore[misc]
    """Fill numba's cache for the wheel (``optik._warmup``), then ship it."""

    PLUGIN_NAME = "custom"

    def initialize(self, version: str, build_data: dict[str, Any]) -> None:
        """Warm the kernels into a staging folder and add its files to the wheel."""
        if self.target_name != "wheel" or version == "editable":
            return
        if os.environ.get("OPTIK_WARMUP", "1").strip().lower() in _OFF:
            self.app.display_info("OPTIK_WARMUP is off: the wheel ships no compiled kernels")
            return
        self._staging = Path(tempfile.mkdtemp(prefix="optik-wheel-kernels-"))
        env = dict(os.environ)
        env["PYTHONPATH"] = os.pathsep.join(filter(None, [self.root, env.get("PYTHONPATH")]))
        command = [sys.executable, "-m", "optik._warmup", "--destination", str(self._staging)]
        self.app.display_info("compiling optik's kernels for this machine (optik._warmup)")
        sources = _sources_digest(Path(self.root) / "optik")
        done = subprocess.run(command, env=env, cwd=self.root, capture_output=True, text=True)
        if _sources_digest(Path(self.root) / "optik") != sources:
            # Kernels are stamped with their sources: these would never be loaded.
            self.app.display_warning(
                "optik's sources changed while its kernels compiled: "
                "the wheel ships none (they will compile on first use)"
            )
            return
        if done.returncode == 2:
            # A setting to correct ($OPTIK_WARMUP_GROUPS, an unwritable folder): the build
            # stops and says so (pip shows a hook's warnings only with -v).
            refusal = done.stderr.strip()
            raise RuntimeError(f"optik's kernel warm-up refused its settings: {refusal}")
        if done.returncode != 0:
            self.app.display_warning(
                "optik's kernels were not compiled into the wheel (they will compile on "
                f"first use):\n{(done.stdout + done.stderr)[-3000:]}"
            )
            return
        self.app.display_info(done.stdout.strip())
        for path in sorted(self._staging.rglob("*")):
            if path.is_file():
                build_data["force_include"][str(path)] = path.relative_to(self._staging).as_posix()
        # The kernels are machine code for this Python and platform.
        build_data["pure_python"] = False
        build_data["infer_tag"] = True

    def finalize(self, version: str, build_data: dict[str, Any], artifact_path: str) -> None:
        """Remove the staging folder."""
        staging = getattr(self, "_staging", None)
        if staging is not None:
            shutil.rmtree(staging, ignore_errors=True)
