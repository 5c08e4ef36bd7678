"""Ctrl-C handed back as another exception by a compiled kernel or a backend.

A ``KeyboardInterrupt`` that arrives while a numba kernel boxes its result (numba runs a
little Python there) comes out of the call as ``SystemError: ... returned a result with
an exception set``, the interrupt as its cause; CasADi's Ipopt callback reports one the
same way. A caller's ``except KeyboardInterrupt`` would miss it, and optik's own
handlers that turn a backend's failure into a status would swallow it. The public entry
points raise the interrupt itself (:func:`surfaces_interrupts`), and those handlers let it
through (:func:`reraise_interrupt`).
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from typing import ParamSpec, TypeVar

_P = ParamSpec("_P")
_R = TypeVar("_R")


def wrapped_interrupt(exc: BaseException) -> KeyboardInterrupt | None:
    """The ``KeyboardInterrupt`` among ``exc``'s causes and contexts, or ``None``."""
    seen: set[int] = set()
    current: BaseException | None = exc
    while current is not None and id(current) not in seen:
        if isinstance(current, KeyboardInterrupt):
            return current
        seen.add(id(current))
        current = current.__cause__ or current.__context__
    return None


def reraise_interrupt(exc: BaseException) -> None:
    """Raise ``KeyboardInterrupt`` when ``exc`` wraps one; otherwise return."""
    if wrapped_interrupt(exc) is not None:
        raise KeyboardInterrupt from exc


def surfaces_interrupts(function: Callable[_P, _R]) -> Callable[_P, _R]:
    """``function``, raising the ``KeyboardInterrupt`` a kernel wrapped in a ``SystemError``."""

    @functools.wraps(function)
    def surfacing(*args: _P.args, **kwargs: _P.kwargs) -> _R:
        try:
            return function(*args, **kwargs)
        except SystemError as exc:
            reraise_interrupt(exc)
            raise

    return surfacing
