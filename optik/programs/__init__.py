"""Solver-agnostic formulations of IK, built before they are solved.

* :mod:`optik.programs.diff_qp`: one differential-IK step as a ``qpsolvers.Problem``
  (least norm or damped least squares, with joint and velocity limits as bounds).
* :mod:`optik.programs.casadi_qp`: the same step programs as CasADi conic problems.
* :mod:`optik.programs.nlp`: the full nonlinear IK program as a CasADi ``nlpsol``,
  built once per robot with the target as a parameter.
"""

from optik.programs.diff_qp import (
    DEFAULT_DAMPING,
    DiffIKProgram,
    KKTReport,
    QPSolution,
    build_program,
    build_qp,
    step_bounds,
)

__all__ = [
    "DEFAULT_DAMPING",
    "DiffIKProgram",
    "KKTReport",
    "QPSolution",
    "build_program",
    "build_qp",
    "step_bounds",
]
