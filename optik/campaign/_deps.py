"""Guarded imports of the optional ``cluster`` extra (dask, distributed, zarr, xarray, pyarrow).

optik's core never imports these; a campaign imports them when it runs, and a missing
one is an :class:`~optik.errors.OptikError` that says how to install it.
"""

from __future__ import annotations

import importlib
from types import ModuleType

from optik.errors import OptikError

INSTALL_HINT = 'pip install "optik[cluster]"'


def require(module: str, what: str) -> ModuleType:
    """Import ``module`` for ``what``, or raise an error naming the extra to install.

    Raises:
        OptikError: the module is not installed.
    """
    try:
        return importlib.import_module(module)
    except ImportError as exc:
        raise OptikError(
            f"{what} needs the Python package {module.split('.')[0]!r}, which is not "
            f"installed ({exc}); install the cluster extra: {INSTALL_HINT}"
        ) from exc
