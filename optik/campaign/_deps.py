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


ZARR_MAJOR = 3
"""Maps are stored in Zarr format 3 through the zarr >= 3 API (which needs Python >= 3.11)."""


def require_zarr(what: str) -> ModuleType:
    """:func:`require` ``zarr``, at least version :data:`ZARR_MAJOR`.

    Raises:
        OptikError: zarr is not installed, or is older (zarr 2 writes another format and
            has another API; optik does not write it).
    """
    zarr = require("zarr", what)
    version = str(getattr(zarr, "__version__", "0"))
    major = version.split(".")[0]
    if not major.isdigit() or int(major) < ZARR_MAJOR:
        raise OptikError(
            f"{what} needs zarr >= {ZARR_MAJOR} (Python >= 3.11), found zarr {version}; "
            f"upgrade it: pip install 'zarr>={ZARR_MAJOR}'"
        )
    return zarr
