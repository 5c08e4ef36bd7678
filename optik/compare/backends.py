"""Every solver name the comparison resolves, in one place.

Step-program backends (``qp:<name>``, ``casadi:<plugin>``) of the closed-form section
(:func:`step_backends`, :func:`solve_step`) and the iterative methods of the seed
reproductions (:func:`seed_solver`). The full-IK section passes its names to
:func:`optik.solve_ik`, which resolves them itself.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, Final

from optik.errors import OptikError
from optik.solvers import IKSolver
from optik.solvers.iterative import DLSSolver, PinvSolver, TransposeSolver

__all__ = ["SEED_SOLVERS", "seed_solver", "solve_step", "step_backends"]

#: The iterative methods of the seed reproductions, by name.
SEED_SOLVERS: Final[dict[str, Callable[..., IKSolver]]] = {
    "pinv": PinvSolver,
    "transpose": TransposeSolver,
    "dls": DLSSolver,
}


def seed_solver(name: str, **options: Any) -> IKSolver:
    """A fresh iterative solver of the seed reproductions (``pinv``, ``transpose``, ``dls``).

    Args:
        name: a key of :data:`SEED_SOLVERS`.
        **options: passed to the solver's constructor (``step`` of ``pinv``...).

    Raises:
        OptikError: an unknown name.
    """
    try:
        factory = SEED_SOLVERS[name]
    except KeyError:
        raise OptikError(
            f"unknown seed method {name!r}; expected one of {sorted(SEED_SOLVERS)}"
        ) from None
    return factory(**options)


def step_backends() -> tuple[str, ...]:
    """Backends that solve a step program here: ``qp:<name>`` then ``casadi:<plugin>``.

    Found by guarded imports of :mod:`optik.solvers.qp` (the ``qpsolvers`` backends that
    import) and :mod:`optik.programs.casadi_qp` (the conic plugins that pass its probe);
    a missing module contributes nothing, so the section is empty rather than broken.
    """
    names: list[str] = []
    try:
        from optik.solvers.qp import installed_backends
    except ImportError:
        pass
    else:
        names += [f"qp:{b}" for b in installed_backends()]
    try:
        from optik.programs.casadi_qp import casadi_conic_plugins
    except ImportError:
        pass
    else:
        names += [f"casadi:{p}" for p in casadi_conic_plugins()]
    return tuple(names)


def solve_step(program: Any, backend: str) -> Any:
    """Solve a step program with ``qp:<name>`` or ``casadi:<plugin>``, unchecked.

    Args:
        program: a :class:`optik.programs.diff_qp.DiffIKProgram`.
        backend: a name from :func:`step_backends`.

    Returns:
        The backend's :class:`optik.programs.diff_qp.QPSolution` (``x``, ``found``,
        ``status``, ``iterations``).

    Raises:
        OptikError: a name without the ``qp:`` or ``casadi:`` prefix.
    """
    family, _, name = backend.partition(":")
    if family == "qp":
        from optik.solvers.qp import solve_program

        return solve_program(program, name)
    if family == "casadi":
        from optik.programs.casadi_qp import solve_conic

        return solve_conic(program, name)
    raise OptikError(f"not a step-program backend: {backend!r} (expected qp:* or casadi:*)")
