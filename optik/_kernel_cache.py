"""numba's on-disk cache of optik's kernels, kept fresh across every kernel source.

numba stamps a cached kernel with the content hash of the file that defines it, and
nothing else: a kernel whose callee (defined in another module) changed loads its stale
compiled code. That happens after an upgrade (pip leaves the ``__pycache__`` cache files
behind) or a ``git pull`` in a checkout. Here every optik kernel's stamp also carries a
fingerprint of all of optik's kernel sources (the modules that use numba and every
module they import, whose constants numba freezes into the kernels), so a change in any
of them makes every cached kernel stale, and numba compiles afresh.

:func:`install` must run before the first kernel is defined: ``optik/__init__.py``
imports this module first.
"""

from __future__ import annotations

import hashlib
import pickle
import re
import sys
from functools import cache
from pathlib import Path
from typing import Any

import numba
from numba.core import caching

PACKAGE = Path(__file__).resolve().parent


_OPTIK_IMPORT = re.compile(
    rb"^[ \t]*(?:from[ \t]+optik((?:\.\w+)*)[ \t]+import[ \t]+(\([^)]*\)|[^\n]*)"
    rb"|import[ \t]+optik((?:\.\w+)*))",
    re.MULTILINE,
)
"""An ``import optik...`` or ``from optik... import ...`` line (indented ones too)."""


_DEFINES_KERNELS = re.compile(
    rb"^[ \t]*@(?:_?jit|_?inline|njit|intrinsic|numba\.\w+)\b", re.MULTILINE
)
"""A decorator line of a compiled function (a kernel, an inlined helper, an intrinsic)."""


def _module_file(package: Path, dotted: str) -> Path | None:
    """The file of ``optik<dotted>`` (``dotted`` like ``".analytic._base"``), if any."""
    base = package.joinpath(*[part for part in dotted.split(".") if part])
    for path in (base.with_suffix(".py"), base / "__init__.py"):
        if path.is_file():
            return path
    return None


def _imported_files(package: Path, source: bytes) -> set[Path]:
    """The files of ``package`` whose names ``source`` imports.

    ``from optik.x import a, b``: the submodules ``a``, ``b`` where they exist, else the
    module ``optik.x`` itself (``optik/x.py`` or ``optik/x/__init__.py``).
    """
    found: set[Path] = set()
    for match in _OPTIK_IMPORT.finditer(source):
        dotted = (match[1] if match[1] is not None else match[3]).decode()
        names = (match[2] or b"").strip(b"()").replace(b"\\", b" ")
        from_module = match[3] is None
        for name in names.split(b","):
            words = name.split()
            if not words:
                continue
            submodule = _module_file(package, f"{dotted}.{words[0].decode()}")
            if submodule is None:
                break  # a name defined in (or re-exported by) the module itself
            found.add(submodule)
        else:
            if from_module:
                continue  # only submodules
        module = _module_file(package, dotted)
        if module is not None:
            found.add(module)
    return found


def kernel_sources(package: Path) -> list[Path]:
    """The modules of ``package`` a kernel's compiled code can depend on, sorted.

    Those that use numba, and every module they import names from, transitively (a
    package's ``__init__`` counts, but its own imports are not followed: it re-exports
    the public API): numba freezes a global's value (a tolerance in a module without
    kernels) into the code of each kernel that reads it.
    """
    sources = {path: path.read_bytes() for path in package.rglob("*.py")}
    pending = [path for path, data in sources.items() if _DEFINES_KERNELS.search(data)]
    seen = set(pending)
    while pending:
        path = pending.pop()
        if path.name == "__init__.py" and not _DEFINES_KERNELS.search(sources[path]):
            continue
        for imported in _imported_files(package, sources[path]):
            if imported in sources and imported not in seen:
                seen.add(imported)
                pending.append(imported)
    return sorted(seen)


def fingerprint(package: Path) -> str:
    """SHA-256 (hex) of :func:`kernel_sources` of ``package``: paths and contents."""
    digest = hashlib.sha256()
    for path in kernel_sources(package):
        digest.update(path.relative_to(package).as_posix().encode())
        digest.update(b"\0")
        digest.update(path.read_bytes())
    return digest.hexdigest()


@cache
def sources_fingerprint() -> str:
    """:func:`fingerprint` of the installed optik package (computed once per process)."""
    return fingerprint(PACKAGE)


def _load_index(path: Path, unpickler: type[pickle.Unpickler]) -> tuple[str, Any, Any]:
    """Read numba's cache index: its release, then ``(stamp, overloads)`` by ``unpickler``."""
    with open(path, "rb") as f:
        version = pickle.load(f)
        stamp, overloads = unpickler(f).load()
    return version, stamp, overloads


def read_index(path: Path) -> tuple[str, Any, dict[Any, str]]:
    """Read numba's cache index: (numba release, source stamp, {key: data file name})."""
    version, stamp, overloads = _load_index(path, pickle.Unpickler)
    return version, stamp, dict(overloads)


class _Placeholder:
    """Whatever an index's signatures name, when only its stamp is read."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        pass

    def __setstate__(self, state: Any) -> None:
        pass


class _StampReader(pickle.Unpickler):
    """Unpickles an index without importing anything.

    A class of a module not imported yet (or not defined in it yet, during optik's own
    import) is a placeholder.
    """

    def find_class(self, module: str, name: str) -> Any:
        loaded = sys.modules.get(module)
        found = getattr(loaded, name, None) if loaded is not None else None
        return found if found is not None else _Placeholder


def read_stamp(path: Path) -> tuple[str, Any]:
    """``(numba release, source stamp)`` of numba's cache index ``path``.

    Safe while optik is being imported: :func:`read_index` would import the modules
    that the signatures name.
    """
    version, stamp, _ = _load_index(path, _StampReader)
    return version, stamp


class _SourceStamp(caching._SourceFileBackedLocatorMixin):
    """numba's stamp of a source file, as its cache locators compute it."""

    def __init__(self, source: Path) -> None:
        self._py_file = str(source)


def current_stamp(source: Path) -> tuple[str, Any]:
    """``(numba release, stamp)`` of a fresh index of the kernels of ``source``.

    The stamp is numba's (the source's content hash) with :func:`sources_fingerprint`
    (:func:`install`); an index whose release or stamp differs is stale, and numba
    reads it as empty.
    """
    return numba.__version__, (_SourceStamp(source).get_source_stamp(), sources_fingerprint())


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
