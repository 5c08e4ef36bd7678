"""Kernels shipped beside optik's sources, for a user who cannot write there.

numba reads the cache in a package's ``__pycache__`` folders only when it can write
them too (:class:`numba.core.caching.InTreeCacheLocator` probes with a temporary file).
Otherwise it keeps the kernels in ``NUMBA_CACHE_DIR`` or the user's cache folder
(``~/.cache/numba``) and compiles every one anew: a wheel's kernels (``hatch_build.py``)
served only the user who installed it, not the one who runs a container image built as
root, nor the users of a ``sudo pip install`` (measured: 55 compilations and 7.5 s before
a first forward kinematics, about 75 s before a first ``solve_ik``).

:func:`install` puts a locator before numba's own for optik's sources. Where a source's
``__pycache__`` holds kernels and cannot be written, it takes the place numba would take
next (``NUMBA_CACHE_DIR``, else the user's cache folder), copies there the kernels it
lacks (each index after its data files, each file whole through a temporary name), once
per folder and process, and lets numba read and write there as it would. numba checks
each entry's source stamp as usual: kernels of other sources are never loaded.
"""

from __future__ import annotations

import functools
import os
import shutil
import tempfile
from pathlib import Path
from typing import Any

from numba.core import caching

PACKAGE = Path(__file__).resolve().parent


@functools.cache
def _read_only_kernels(folder: str) -> bool:
    """Whether the ``__pycache__`` ``folder`` holds kernels and cannot be written."""
    path = Path(folder)
    return path.is_dir() and not os.access(path, os.W_OK) and any(path.glob("*.nbi"))


@functools.cache
def _seed(shipped: str, cache: str) -> int:
    """Copy the kernels of ``shipped`` that ``cache`` lacks; the number of indexes copied.

    Best effort: a file that cannot be copied is left to numba, which compiles its kernel.
    """
    copied = 0
    for index in sorted(Path(shipped).glob("*.nbi")):
        target = Path(cache) / index.name
        if target.exists():
            continue  # this user's own kernels of that function: numba keeps adding to them
        try:
            for data in sorted(index.parent.glob(f"{index.stem}.*.nbc")):
                _copy_whole(data, Path(cache) / data.name)
            _copy_whole(index, target)
        except OSError:
            continue
        copied += 1
    return copied


def _copy_whole(source: Path, target: Path) -> None:
    """Copy ``source`` to ``target`` through a temporary file renamed into place."""
    fd, temporary = tempfile.mkstemp(prefix=f".{target.name}.", dir=target.parent)
    os.close(fd)
    try:
        shutil.copyfile(source, temporary)
        os.chmod(temporary, 0o644)
        os.replace(temporary, target)
    except BaseException:
        Path(temporary).unlink(missing_ok=True)
        raise


class ShippedKernelsLocator:
    """numba's next cache locator for an optik source beside read-only kernels, seeded.

    Only :meth:`from_function` is used: it returns numba's own locator (user-provided or
    user-wide), or None to let numba's locators choose as they do.
    """

    @classmethod
    def from_function(cls, py_func: Any, py_file: str) -> Any:
        """The locator of ``py_func`` (defined in ``py_file``) with the kernels copied."""
        source = Path(py_file)
        if PACKAGE not in source.parents:
            return None
        shipped = str(source.parent / "__pycache__")
        if not _read_only_kernels(shipped):
            return None
        for base in (caching.UserProvidedCacheLocator, caching.UserWideCacheLocator):
            locator = base.from_function(py_func, py_file)
            if locator is not None:
                _seed(shipped, str(locator.get_cache_path()))
                return locator
        return None


def install() -> None:
    """Put :class:`ShippedKernelsLocator` first among numba's locators (idempotent)."""
    locators: list[Any] = caching.CacheImpl._locator_classes
    if ShippedKernelsLocator not in locators:
        locators.insert(0, ShippedKernelsLocator)


install()
