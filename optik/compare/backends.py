"""Every solver name the comparison resolves, in one place.

Step-program backends (``qp:<name>``, ``casadi:<plugin>``) of the closed-form section
(:func:`step_backends`, :func:`solve_step`) and the iterative methods of the seed
reproductions (:func:`seed_solver`). The full-IK section passes its names to
:func:`optik.solve_ik`, which resolves them itself.
"""

from __future__ import annotations

from typing import Any, Final

from optik.errors import OptikError
from optik.solvers import IKSolver, available_solvers, get_solver

__all__ = ["SEED_SOLVERS", "seed_solver", "solve_step", "step_backends"]

#: The iterative methods of the seed reproductions (registry names).
SEED_SOLVERS: Final[tuple[str, ...]] = ("pinv", "transpose", "dls")


def seed_solver(name: str, **options: Any) -> IKSolver:
    """A fresh iterative solver of the seed reproductions (``pinv``, ``transpose``, ``dls``).

    The class is the one the registry holds under ``name``; a fresh instance takes the
    seed's options.

    Args:
        name: one of :data:`SEED_SOLVERS`.
        **options: passed to the solver's constructor (``step`` of ``pinv``...).

    Raises:
        OptikError: an unknown name.
    """
    if name not in SEED_SOLVERS:
        raise OptikError(f"unknown seed method {name!r}; expected one of {list(SEED_SOLVERS)}")
    solver: IKSolver = type(get_solver(name))(**options)
    return solver


def step_backends() -> tuple[str, ...]:
    """Backends that solve a step program here: ``qp:<name>`` then ``casadi:<plugin>``.

    The registry's ``"step"`` solvers (:func:`optik.solvers.available_solvers`): the
    ``qpsolvers`` backends that import and the conic plugins that pass their probe.
    """
    names = available_solvers(kind="step")
    return tuple(sorted(names, key=lambda name: (not name.startswith("qp:"), name)))


def solve_step(program: Any, backend: str) -> Any:
    """Solve a step program with a registered ``"step"`` backend, unchecked.

    Args:
        program: a :class:`optik.programs.diff_qp.DiffIKProgram`.
        backend: a name from :func:`step_backends`.

    Returns:
        The backend's :class:`optik.programs.diff_qp.QPSolution` (``x``, ``found``,
        ``status``, ``iterations``).

    Raises:
        UnknownSolverError: not a step backend here.
    """
    return get_solver(backend, kind="step").solve(program)
