"""Cached kernels go stale when any kernel source changes, not only their own file."""

from __future__ import annotations

import importlib
import os
import pkgutil
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import numba
from numba.core.registry import CPUDispatcher

import optik
from optik import _kernel_cache
from optik.solvers import _lm_kernel

CALLER = """
import numba
from {package}._probe_callee import callee

@numba.njit(cache=True)
def caller():
    return callee() + 1
"""
CALLEE = """
import numba

@numba.njit(cache=True)
def callee():
    return {value}
"""


def test_every_loaded_optik_kernel_is_stamped_with_the_fingerprint() -> None:
    stamped = 0
    for name, module in list(sys.modules.items()):
        if not (name == "optik" or name.startswith("optik.")):
            continue
        for value in vars(module).values():
            cache = getattr(value, "_cache", None)
            if isinstance(value, numba.core.registry.CPUDispatcher) and hasattr(
                cache, "_cache_file"
            ):
                stamp = cache._cache_file._source_stamp
                assert isinstance(stamp, tuple), f"{name}.{value.__name__} is not stamped"
                assert stamp[1] == _kernel_cache.sources_fingerprint()
                stamped += 1
    assert stamped >= 20  # the solvers, the closed forms, the task, FK
    assert isinstance(_lm_kernel.lm_attempt._cache._cache_file._source_stamp, tuple)


def test_fingerprint_follows_kernel_sources_only(tmp_path: Path) -> None:
    (tmp_path / "a.py").write_text("import numba\n\n@numba.njit\ndef f():\n    return 1\n")
    (tmp_path / "b.py").write_text("import numba\nY = 1\n")
    first = _kernel_cache.fingerprint(tmp_path)
    (tmp_path / "b.py").write_text("import numba\nY = 2\n")  # defines no kernel
    assert _kernel_cache.fingerprint(tmp_path) == first
    (tmp_path / "a.py").write_text("import numba\n\n@numba.njit\ndef f():\n    return 2\n")
    assert _kernel_cache.fingerprint(tmp_path) != first


def test_fingerprint_follows_what_kernels_import(tmp_path: Path) -> None:
    # numba freezes a global's value into the kernel that reads it: a tolerance defined
    # in a module without kernels must make the kernels that import it stale.
    (tmp_path / "sub").mkdir()
    (tmp_path / "sub" / "__init__.py").write_text("from optik.unrelated import Z\n")
    (tmp_path / "unrelated.py").write_text("Z = 1\n")
    (tmp_path / "tols.py").write_text("from optik.deeper import W\nTOL = 1e-6\n")
    (tmp_path / "deeper.py").write_text("W = 1\n")
    (tmp_path / "sub" / "more.py").write_text("M = 1\n")
    (tmp_path / "kernel.py").write_text(
        "from optik._numba import jit\n"
        "from optik.tols import (\n    TOL,\n)\n"
        "from optik.sub import more\n\n"
        "@jit\ndef f():\n    return TOL + more.M\n"
    )
    sources = {p.relative_to(tmp_path).as_posix() for p in _kernel_cache.kernel_sources(tmp_path)}
    # the package's __init__ is not followed (it re-exports), nor a module nothing imports
    assert sources == {"kernel.py", "tols.py", "deeper.py", "sub/more.py"}
    first = _kernel_cache.fingerprint(tmp_path)
    for name in ("tols.py", "deeper.py", "sub/more.py"):
        path = tmp_path / name
        text = path.read_text()
        path.write_text(text + "# changed\n")
        assert _kernel_cache.fingerprint(tmp_path) != first, name
        path.write_text(text)
    (tmp_path / "unrelated.py").write_text("Z = 2\n")
    assert _kernel_cache.fingerprint(tmp_path) == first


def test_the_library_tolerances_read_by_kernels_are_fingerprinted() -> None:
    sources = {
        p.relative_to(_kernel_cache.PACKAGE).as_posix()
        for p in _kernel_cache.kernel_sources(_kernel_cache.PACKAGE)
    }
    # ELBOW_REACH_TOL and the limit tolerance live in modules without kernels.
    assert {"analytic/_base.py", "limits.py", "analytic/ur.py", "_math.py"} <= sources
    assert "report/rendering.py" not in sources


def test_every_module_with_kernels_is_in_the_fingerprint(tmp_path: Path) -> None:
    # A module whose kernels the fingerprint did not read would, once changed, leave its
    # callers in other modules on stale compiled code: each module that defines an optik
    # kernel must change the fingerprint when it changes.
    copy = tmp_path / "optik"
    shutil.copytree(Path(optik.__file__).parent, copy, ignore=shutil.ignore_patterns("__pycache__"))
    first = _kernel_cache.fingerprint(copy)
    checked = []
    for info in pkgutil.walk_packages(optik.__path__, "optik."):
        module = importlib.import_module(info.name)
        if not any(
            isinstance(value, CPUDispatcher) and value.py_func.__module__ == info.name
            for value in vars(module).values()
        ):
            continue
        source = copy / Path(str(module.__file__)).relative_to(Path(optik.__file__).parent)
        text = source.read_text(encoding="utf-8")
        source.write_text(text + "\n# changed\n", encoding="utf-8")
        assert _kernel_cache.fingerprint(copy) != first, f"{info.name} is not fingerprinted"
        source.write_text(text, encoding="utf-8")
        checked.append(info.name)
    assert {"optik._math", "optik._kernels", "optik.solvers._lm_kernel"} <= set(checked)
    assert len(checked) >= 15


def _run(root: Path, package: str, cache_dir: Path) -> int:
    env = {**os.environ, "PYTHONPATH": str(root), "NUMBA_CACHE_DIR": str(cache_dir)}
    code = f"import {package}._probe_caller as m; print(m.caller())"
    out = subprocess.run(
        [sys.executable, "-c", code],
        env=env,
        cwd=root,
        capture_output=True,
        text=True,
        check=True,
    )
    return int(out.stdout.strip())


def _two_runs(root: Path, package: str, cache_dir: Path) -> tuple[int, int]:
    """The caller's answer, before and after the callee's file changes (cache kept)."""
    pkg = root / package
    (pkg / "_probe_caller.py").write_text(textwrap.dedent(CALLER.format(package=package)))
    (pkg / "_probe_callee.py").write_text(CALLEE.format(value=1))
    before = _run(root, package, cache_dir)
    (pkg / "_probe_callee.py").write_text(CALLEE.format(value=5))
    return before, _run(root, package, cache_dir)


def test_a_changed_callee_is_recompiled_in_optik_and_not_by_numba_alone(
    tmp_path: Path,
) -> None:
    # numba alone: the caller's cache entry survives its callee's change (stale answer).
    plain = tmp_path / "plain"
    (plain / "probepkg").mkdir(parents=True)
    (plain / "probepkg" / "__init__.py").write_text("")
    assert _two_runs(plain, "probepkg", tmp_path / "cache-plain") == (2, 2)
    # A copy of optik: the stamp carries every kernel source, so the caller recompiles.
    copy = tmp_path / "copy"
    shutil.copytree(
        Path(optik.__file__).parent, copy / "optik", ignore=shutil.ignore_patterns("__pycache__")
    )
    assert _two_runs(copy, "optik", tmp_path / "cache-optik") == (2, 6)
