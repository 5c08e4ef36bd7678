"""How optik compiles its kernels with numba: the options, written once.

:data:`jit` compiles a kernel; :data:`inline` compiles a small helper of a hot loop that
numba inlines into each caller (numba IR), so that the scratch arrays it takes are not
reference-counted at a call. Both:

- cache the machine code on disk next to the source (``cache=True``;
  :mod:`optik._kernel_cache` keeps the entries fresh when any kernel source changes; it
  fingerprints the modules whose text names numba, which the import of this module
  does);
- release the GIL (``nogil=True``), so that batch worker threads run side by side;
- use numpy's error model (``error_model="numpy"``): a division by zero gives an
  infinity or a NaN, which the kernels test, instead of raising (and the divisions are
  not guarded by a branch each).
"""

from __future__ import annotations

import numba as nb

jit = nb.njit(cache=True, nogil=True, error_model="numpy")
"""Decorator of a compiled kernel (see the module)."""

inline = nb.njit(cache=True, nogil=True, error_model="numpy", inline="always")
"""Decorator of a compiled helper inlined into its callers (see the module)."""
