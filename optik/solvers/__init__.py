"""IK solvers behind one registry of names.

``pinv``, ``transpose``, ``dls`` (iterative, :mod:`optik.solvers.iterative`),
``qp:<backend>`` (bounded differential-IK steps through qpsolvers), ``casadi:ipopt`` and
``casadi:sqpmethod`` (the nonlinear program) provide whole IK (kind ``"ik"``);
``qp:<backend>`` and ``casadi:<conic plugin>`` provide the differential-IK step (kind
``"step"``). :func:`available_solvers` lists those whose backend imports here.
"""

from optik.solvers import casadi_conic, casadi_nlp, iterative, qp
from optik.solvers._base import (
    SOLVER_KINDS,
    IKQuery,
    IKSolver,
    RunOutput,
    SolverOutput,
    StepBackend,
    available_solvers,
    get_solver,
    register,
    register_solver,
    registered_solvers,
    unregister_solver,
)

__all__ = [
    "SOLVER_KINDS",
    "IKQuery",
    "IKSolver",
    "RunOutput",
    "SolverOutput",
    "StepBackend",
    "available_solvers",
    "casadi_conic",
    "casadi_nlp",
    "get_solver",
    "iterative",
    "qp",
    "register",
    "register_solver",
    "registered_solvers",
    "unregister_solver",
]
