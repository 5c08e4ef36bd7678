"""How optik compiles its kernels with numba: the options, written once.

:data:`jit` compiles a kernel; :data:`inline` compiles a small helper of a hot loop that
numba inlines into each caller (numba IR), so that the scratch arrays it takes are not
reference-counted at a call. Both:

- cache the machine code on disk next to the source (``cache=True``;
  :mod:`optik._kernel_cache` keeps the entries fresh when any kernel source changes; it
  fingerprints the modules whose text names numba, which the import of this module
  does). numba refuses ``cache=True`` when it has no place to write: the package's
  ``__pycache__``, ``NUMBA_CACHE_DIR`` and the user's cache folder all unwritable (a
  service account without a home folder running a read-only install). The kernels are
  then compiled in memory, in each process, with a
  :class:`~optik.errors.KernelCacheWarning`;
- release the GIL (``nogil=True``), so that batch worker threads run side by side;
- use numpy's error model (``error_model="numpy"``): a division by zero gives an
  infinity or a NaN, which the kernels test, instead of raising (and the divisions are
  not guarded by a branch each).
"""

from __future__ import annotations

import warnings
from typing import Any

import numba as nb
from numba.core import caching

from optik.errors import KernelCacheWarning


def _can_cache() -> bool:
    """Whether numba has a writable place for the kernels of optik's sources."""
    locators: list[Any] = list(caching.CacheImpl._locator_classes)
    for locator in locators:
        if locator.from_function(_can_cache, __file__) is not None:
            return True
    warnings.warn(
        "optik: numba has nowhere to keep compiled kernels (optik's __pycache__ folders, "
        "NUMBA_CACHE_DIR and the user's cache folder cannot be written): each process "
        "compiles them on first use. Set NUMBA_CACHE_DIR to a folder this user can write.",
        KernelCacheWarning,
        stacklevel=2,
    )
    return False


CACHE = _can_cache()
"""Whether the kernels are cached on disk (see the module)."""

jit = nb.njit(cache=CACHE, nogil=True, error_model="numpy")
"""Decorator of a compiled kernel (see the module)."""

inline = nb.njit(cache=CACHE, nogil=True, error_model="numpy", inline="always")
"""Decorator of a compiled helper inlined into its callers (see the module)."""
