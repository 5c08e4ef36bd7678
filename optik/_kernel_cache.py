"""numba's on-disk cache of optik's kernels, kept fresh across every kernel source.

numba stamps a cached kernel with the content hash of the file that defines it, and
nothing else: a kernel whose callee (defined in another module) changed loads its stale
compiled code. That happens after an upgrade (pip leaves the ``__pycache__`` cache files
behind) or a ``git pull`` in a checkout. Here every optik kernel's stamp also carries a
fingerprint of all of optik's kernel sources (the modules that use numba), so a change
in any of them makes every cached kernel stale, and numba compiles afresh.

:func:`install` must run before the first kernel is defined: ``optik/__init__.py``
imports this module first.
"""

from __future__ import annotations

import hashlib
from functools import cache
from pathlib import Path
from typing import Any

from numba.core import caching

PACKAGE = Path(__file__).resolve().parent


def fingerprint(package: Path) -> str:
    """SHA-256 (hex) of every module under ``package`` that uses numba: paths and contents."""
    digest = hashlib.sha256()
    for path in sorted(package.rglob("*.py")):
        data = path.read_bytes()
        if b"numba" in data:
            digest.update(path.relative_to(package).as_posix().encode())
            digest.update(b"\0")
            digest.update(data)
    return digest.hexdigest()


@cache
def sources_fingerprint() -> str:
    """:func:`fingerprint` of the installed optik package (computed once per process)."""
    return fingerprint(PACKAGE)


def _is_optik(py_func: Any) -> bool:
    module = getattr(py_func, "__module__", None) or ""
    return module == "optik" or module.startswith("optik.")


def install() -> bool:
    """Stamp the cache of every optik kernel defined from now on (idempotent).

    Returns whether numba's cache has the attributes this relies on (numba 0.59 to 0.68
    have them; ``tests/test_kernel_cache.py`` fails if a numba release drops them).
    """
    original = caching.Cache.__init__
    if getattr(original, "_optik_stamped", False):
        return True

    def __init__(self: Any, py_func: Any) -> None:
        original(self, py_func)
        cache_file: Any = getattr(self, "_cache_file", None)
        if _is_optik(py_func) and hasattr(cache_file, "_source_stamp"):
            cache_file._source_stamp = (cache_file._source_stamp, sources_fingerprint())

    __init__._optik_stamped = True  # type: ignore[attr-defined]
    caching.Cache.__init__ = __init__  # type: ignore[method-assign]
    return True


install()
