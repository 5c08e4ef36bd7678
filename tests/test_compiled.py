"""The compiled (numba) kernels: each on-disk cache entry belongs to one function."""

from __future__ import annotations

import importlib
import pkgutil

from numba.core.registry import CPUDispatcher

import optik


def _dispatchers() -> dict[int, tuple[str, CPUDispatcher]]:
    found: dict[int, tuple[str, CPUDispatcher]] = {}
    for info in pkgutil.walk_packages(optik.__path__, "optik."):
        module = importlib.import_module(info.name)
        for name, value in vars(module).items():
            if isinstance(value, CPUDispatcher):
                found.setdefault(id(value), (f"{info.name}.{name}", value))
    return found


def test_no_two_kernels_share_a_cache_entry() -> None:
    # numba's disk cache is keyed by the Python function's file, name and first line, not
    # by options such as `parallel`: one function jitted twice would share one entry, and
    # a parallel kernel could silently load its serial twin (or the reverse).
    owners: dict[tuple[str, int, str], str] = {}
    dispatchers = _dispatchers()
    assert len(dispatchers) > 20  # the walk found optik's kernels
    for name, dispatcher in dispatchers.values():
        code = dispatcher.py_func.__code__
        key = (code.co_filename, code.co_firstlineno, dispatcher.py_func.__qualname__)
        assert key not in owners, f"{name} and {owners[key]} compile the same function"
        owners[key] = name
