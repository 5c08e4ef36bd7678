"""IK solvers behind one registry of names.

``pinv``, ``transpose``, ``dls`` (iterative, :mod:`optik.solvers.iterative`),
``qp:<backend>`` (bounded differential-IK steps through qpsolvers), ``casadi:ipopt`` and
``casadi:sqpmethod`` (the nonlinear program). :func:`available_solvers` lists those whose
backend imports here.
"""

from optik.solvers import casadi_nlp, iterative, qp
from optik.solvers._base import (
    IKQuery,
    IKSolver,
    SolverOutput,
    available_solvers,
    get_solver,
    register,
    register_solver,
    registered_solvers,
)

__all__ = [
    "IKQuery",
    "IKSolver",
    "SolverOutput",
    "available_solvers",
    "casadi_nlp",
    "get_solver",
    "iterative",
    "qp",
    "register",
    "register_solver",
    "registered_solvers",
]
