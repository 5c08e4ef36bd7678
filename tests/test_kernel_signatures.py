"""Each compiled kernel is compiled once per real signature, not again for a literal or a flag.

numba types a constant argument written in a kernel (``f(x, 0)``) as ``Literal[int](0)``
and compiles the callee for it, apart from the ``int64`` signature that the same callee
gets from a caller passing a variable; a loop-carried counter that starts at a literal
(``n = 0`` then ``n = f(..., n)``) compiles the callee for both. A read-only array (the
robot's chain, ``Task.packed``) and a writable one of the same shape are two types too.
Each such copy costs its compile time at the warm-up (install) and its space in the
cache. This runs the warm-up's calls and finds the kernels holding two signatures that
differ only by literals, or only by read-only flags.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numba
import numpy as np
from numba.core import types
from numba.core.dispatcher import Dispatcher

#: Kernels called with the task both read-only (``Task.packed``, from Python and the
#: damped least squares) and writable (the ``qp:*`` programs' packed buffer, whose views
#: numba cannot make read-only): two small kernels, compiled in two warm-up workers.
READ_ONLY_COPIES_KEPT = {"optik.task.task_error", "optik.task.task_rows"}


def _plain(arg: types.Type) -> types.Type:
    """``arg`` without literal types or read-only flags (in tuples too)."""
    if isinstance(arg, types.Array):
        return arg.copy(readonly=False)
    if isinstance(arg, types.BaseTuple):
        return types.Tuple([_plain(item) for item in arg])
    return types.unliteral(arg)


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


def _copies(kernels: dict[str, Dispatcher], literal: bool) -> dict[str, list[str]]:
    """Kernels with two signatures equal once literals (or read-only flags) are dropped."""
    found = {}
    for name, kernel in kernels.items():
        seen: dict[str, list[str]] = {}
        for signature in kernel.signatures:
            if literal:
                key = str(tuple(types.unliteral(arg) for arg in signature))
            else:
                key = str(tuple(_plain(arg) for arg in signature))
            seen.setdefault(key, []).append(", ".join(str(arg) for arg in signature))
        copies = [sig for group in seen.values() if len(group) > 1 for sig in group]
        if copies:
            found[name] = copies
    return found


def test_the_checks_find_a_kernel_compiled_for_a_literal_and_for_a_read_only_array() -> None:
    """The checks themselves, on a toy callee called both ways."""

    @numba.njit
    def callee(x: np.ndarray, k: int) -> float:
        return x[0] + k

    @numba.njit
    def with_literal(x: np.ndarray) -> float:
        return callee(x, 0)

    @numba.njit
    def with_value(x: np.ndarray, k: int) -> float:
        return callee(x, k)

    array = np.array([1.0])
    with_literal(array)
    with_value(array, 2)
    found = _copies({"callee": callee}, literal=True)
    assert list(found) == ["callee"]
    assert any("Literal[int](0)" in sig for sig in found["callee"])
    assert _copies({"callee": callee}, literal=False) == found  # a literal is one too

    frozen = array.copy()
    frozen.flags.writeable = False
    with_value(frozen, 2)
    found = _copies({"callee": callee}, literal=False)
    assert any("readonly" in sig for sig in found["callee"])


# Run in a fresh process: other tests call kernels directly, with argument types of their
# own, and the dispatchers of this process would keep those signatures.
SCRIPT = """
import json, sys
sys.path.insert(0, sys.argv[1])
from test_kernel_signatures import _copies, _optik_kernels
from optik import solve_ik
from optik._warmup import run_groups
from optik.problems import load_problem

run_groups(["closed_forms", "closed_form_batches", "kinematics", "numeric", "batch", "programs"])
# The posture search (its own compiled kernel), beyond the warm-up's calls.
robot = load_problem("panda").robot
result = solve_ik(robot, robot.fk(robot.mid_limits + 0.2), posture=robot.mid_limits)
kernels = _optik_kernels()
print(json.dumps({
    "success": bool(result.success),
    "kernels": len(kernels),
    "literal": _copies(kernels, literal=True),
    "read_only": _copies(kernels, literal=False),
}))
"""


def test_the_warm_up_calls_compile_no_kernel_twice_for_a_literal_or_a_flag() -> None:
    done = subprocess.run(
        [sys.executable, "-c", SCRIPT, str(Path(__file__).parent)],
        capture_output=True,
        text=True,
        check=True,
    )
    found = json.loads(done.stdout.strip().splitlines()[-1])
    assert found["success"]
    assert found["kernels"] > 50  # the walk found the kernels (a module rename would hide them)
    assert found["literal"] == {}
    assert set(found["read_only"]) <= READ_ONLY_COPIES_KEPT
