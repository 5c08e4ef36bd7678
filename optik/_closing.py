"""A base for objects that hold a resource and free it in ``close()``.

``with Thing(...) as thing:`` closes ``thing`` on leaving the block, however it is left;
``close()`` may also be called directly (and, in every subclass, more than once).
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from typing import TypeVar

C = TypeVar("C", bound="Closing")


class Closing(ABC):
    """A context manager whose exit calls :meth:`close` (an exception still propagates)."""

    @abstractmethod
    def close(self) -> None:
        """Free what the object holds."""

    def __enter__(self: C) -> C:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
