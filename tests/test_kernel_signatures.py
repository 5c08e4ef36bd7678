"""Each compiled kernel is compiled once per real signature, not once more for a literal.

numba types a constant argument written in a kernel (``f(x, 0)``) as ``Literal[int](0)``
and compiles the callee for it, apart from the ``int64`` signature that the same callee
gets from a caller passing a variable; a loop-carried counter that starts at a literal
(``n = 0`` then ``n = f(..., n)``) compiles the callee for both. Each such copy costs its
compile time at the warm-up (install) and its space in the cache. This runs the
warm-up's calls and finds any kernel holding two signatures that differ only by literals.
"""

from __future__ import annotations

import sys

from numba.core import types
from numba.core.dispatcher import Dispatcher

from optik import solve_ik
from optik._warmup import run_groups
from optik.problems import load_problem


def _without_literals(signature: tuple[types.Type, ...]) -> str:
    """``signature`` as text, each literal type (in tuples too) replaced by its type."""
    return str(tuple(types.unliteral(arg) for arg in signature))


def _optik_kernels() -> dict[str, Dispatcher]:
    """Every compiled kernel of the optik modules imported, by qualified name."""
    kernels = {}
    for name, module in list(sys.modules.items()):
        if name != "optik" and not name.startswith("optik."):
            continue
        for attribute, value in vars(module).items():
            if isinstance(value, Dispatcher) and value.__module__ == name:
                kernels[f"{name}.{attribute}"] = value
    return kernels


def _literal_copies(kernels: dict[str, Dispatcher]) -> dict[str, list[str]]:
    """Kernels with signatures equal once literals are dropped, with those signatures."""
    found = {}
    for name, kernel in kernels.items():
        seen: dict[str, list[str]] = {}
        for signature in kernel.signatures:
            seen.setdefault(_without_literals(signature), []).append(str(signature))
        copies = [sig for group in seen.values() if len(group) > 1 for sig in group]
        if copies:
            found[name] = copies
    return found


def test_the_literal_check_finds_a_kernel_compiled_for_a_literal() -> None:
    """The check itself: a toy callee called with ``0`` and with a variable is flagged."""
    import numba

    @numba.njit
    def callee(x: float, k: int) -> float:
        return x + k

    @numba.njit
    def with_literal(x: float) -> float:
        return callee(x, 0)

    @numba.njit
    def with_value(x: float, k: int) -> float:
        return callee(x, k)

    with_literal(1.0)
    with_value(1.0, 2)
    found = _literal_copies({"callee": callee})
    assert list(found) == ["callee"]
    assert any("Literal[int](0)" in sig for sig in found["callee"])


def test_the_warm_up_calls_compile_no_kernel_twice_for_a_literal() -> None:
    run_groups(["closed_forms", "closed_form_batches", "kinematics", "numeric", "batch"])
    # The posture search (its own compiled kernel), beyond the warm-up's calls.
    robot = load_problem("panda").robot
    target = robot.fk(robot.mid_limits + 0.2)
    result = solve_ik(robot, target, posture=robot.mid_limits)
    assert result.success
    kernels = _optik_kernels()
    assert len(kernels) > 50  # the walk found the kernels (a module rename would hide them)
    assert _literal_copies(kernels) == {}
