"""The compiled (numba) machinery: cache entries, borrowed views, the LM stall rule."""

from __future__ import annotations

import importlib
import pkgutil

import numba as nb
import numpy as np
from numba.core.registry import CPUDispatcher

import optik
from optik._nrt import borrowed
from optik.problems import load_problem
from optik.solvers._lm_kernel import STALL_RATIO, STALL_WINDOW, lm_attempt, workspace


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


def test_borrowed_view_shares_data_without_an_owner() -> None:
    @nb.njit
    def double_through_view(x: np.ndarray) -> float:
        view = borrowed(x)
        total = 0.0
        for i in range(view.shape[0]):
            view[i] *= 2.0
            total += view[i]
        return total

    x = np.arange(5.0)
    assert double_through_view(x) == 20.0
    assert np.array_equal(x, 2.0 * np.arange(5.0))  # written through to the owner


def test_stall_rule_stops_an_attempt() -> None:
    panda = load_problem("panda").robot
    target = panda.fk(panda.lower + 0.8 * (panda.upper - panda.lower))
    args = (panda._K, panda._prismatic, panda._coupling, panda._identity_coupling)
    limits = (panda.lower, panda.upper)

    def attempt(window: int, ratio: float) -> tuple[int, bool]:
        q = panda.mid_limits.copy()
        scratch = workspace(panda._prismatic.shape[0], panda.dof)
        it, ok, _, _ = lm_attempt(
            *args, *limits, target, True, q, 1e-9, 100, 1e-3, window, ratio, scratch
        )
        return it, ok

    # A cut to 0 is impossible: the attempt stops as soon as the window has passed.
    assert attempt(2, 0.0) == (2, False)
    assert attempt(5, 0.0) == (5, False)
    # Any error counts as a cut when ratio is huge: only convergence or max_iter stops it.
    it, ok = attempt(STALL_WINDOW, 1e300)
    assert ok and it > 5
    assert attempt(STALL_WINDOW, STALL_RATIO)[1]
