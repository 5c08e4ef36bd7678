"""Borrowed array views for compiled inner loops: no reference counting.

numba counts references to every array with atomic increments and decrements, at each
call that passes an array and each view it makes. In a solver iteration that passes a
dozen scratch arrays through a few helper calls, those atomic operations cost as much
as the arithmetic, and with several threads the shared inputs' counters bounce between
cores. A *borrowed* view shares the data, shape and strides of an array but has no
owner record (``meminfo``), so numba skips its counting.

The rule that keeps this safe: borrow only from arrays that outlive every use of the
view (a function's own arguments, whose owners are held by the caller for the whole
call), and never return a borrowed view or store it where it can outlive its owner.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, TypeVar

from numba.core import types
from numba.extending import intrinsic

ArrayT = TypeVar("ArrayT")


def _borrowed_typing(typingctx: Any, array: Any) -> Any:
    """A view of ``array`` without an owner record (see the module's rule)."""
    if not isinstance(array, types.Array):
        return None

    def codegen(context: Any, builder: Any, signature: Any, args: Any) -> Any:
        source = context.make_array(signature.args[0])(context, builder, value=args[0])
        view = context.make_array(signature.return_type)(context, builder)
        context.populate_array(
            view,
            data=source.data,
            shape=source.shape,
            strides=source.strides,
            itemsize=source.itemsize,
            meminfo=None,
            parent=None,
        )
        return view._getvalue()

    return array(array), codegen


if TYPE_CHECKING:

    def borrowed(array: ArrayT) -> ArrayT:
        """A view of ``array`` without an owner record (see the module's rule)."""
        ...

else:
    borrowed = intrinsic(_borrowed_typing)
