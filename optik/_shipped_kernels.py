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
per folder and process, and lets numba read and write there as it would. Only fresh
kernels are copied, and they replace stale ones (:func:`_seed`): an index that numba
would read as empty (another numba release, other sources) is worth nothing.
"""

from __future__ import annotations

import functools
import os
import shutil
import tempfile
from pathlib import Path
from typing import Any

from numba.core import caching

from optik._kernel_cache import current_stamp, read_stamp

PACKAGE = Path(__file__).resolve().parent


@functools.cache
def _read_only_kernels(folder: str) -> bool:
    """Whether the ``__pycache__`` ``folder`` holds kernels and cannot be written."""
    path = Path(folder)
    return path.is_dir() and not os.access(path, os.W_OK) and any(path.glob("*.nbi"))


@functools.cache
def _seed(shipped: str, cache: str) -> int:
    """Copy the fresh kernels of ``shipped`` that ``cache`` lacks; the indexes copied.

    An index is fresh when numba would read it here (:func:`_fresh`): a stale shipped
    one (another numba release, edited sources) is not copied, and a stale one of the
    user's (an earlier release of optik) is replaced. Best effort, since it runs inside
    ``import optik``: an index that cannot be read (whatever the error) or copied is
    left to numba, which compiles its kernel.
    """
    copied = 0
    sources = Path(shipped).parent
    for index in sorted(Path(shipped).glob("*.nbi")):
        target = Path(cache) / index.name
        try:
            if not _fresh(index, sources) or (target.exists() and _fresh(target, sources)):
                continue  # nothing to give, or the user's own kernels of that function
            for data in sorted(index.parent.glob(f"{index.stem}.*.nbc")):
                _copy_whole(data, Path(cache) / data.name)
            _copy_whole(index, target)
        except Exception:  # best effort: this runs inside `import optik`
            continue
        copied += 1
    return copied


def _fresh(index: Path, sources: Path) -> bool:
    """Whether numba would read the index ``index`` of a kernel defined in ``sources``.

    The index's name starts with its module's (``_kernels.fk_into-101.py311.nbi``).
    """
    source = sources / f"{index.name.split('.', 1)[0]}.py"
    if not source.is_file():
        return False
    return read_stamp(index) == current_stamp(source)


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
        source = Path(py_file).resolve()  # as PACKAGE is: a symlinked install too
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
