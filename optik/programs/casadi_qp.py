"""The differential-IK step programs as CasADi conic (QP) problems: data, not solved here.

The same least-norm and least-squares programs as :mod:`optik.programs.diff_qp`, in the
standard form of ``casadi.conic``::

    min  1/2 x^T H x + g^T x   s.t.   lba <= A x <= uba,   lbx <= x <= ubx

Least norm: ``H = W``, ``g = 0``, ``A = J``, ``lba = uba = v``. Least squares:
``H = J^T Wt J + lambda^2 W``, ``g = -J^T Wt v`` and no rows in ``A``. Both are passed
equilibrated (:meth:`~optik.programs.diff_qp.DiffIKProgram.equilibrated`), so the
plugins' absolute tolerances act relative to the task size. The ``casadi:<plugin>`` step
backends (:mod:`optik.solvers.casadi_conic`) solve them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from optik._checks import FloatArray
from optik.errors import OptikError
from optik.programs.diff_qp import DiffIKProgram

__all__ = ["ConicProgram", "build_conic"]


@dataclass(frozen=True, eq=False)
class ConicProgram:
    """A step program as the inputs of a CasADi conic solver, inspectable before solving.

    Attributes:
        program: the step program it was built from.
        plugin: the conic plugin, e.g. ``"qrqp"``.
        args: the solver's inputs ``h, g, a, lba, uba, lbx, ubx`` (equilibrated, see the
            module).
        scale: the step is ``x / scale``.
    """

    program: DiffIKProgram
    plugin: str
    args: dict[str, FloatArray]
    scale: float

    @property
    def shape(self) -> tuple[int, int]:
        """``(variables, rows of A)``: with the plugin, what a conic solver is built for."""
        return self.program.dof, int(self.args["a"].shape[0])


def build_conic(program: DiffIKProgram, plugin: str) -> ConicProgram:
    """The step program as a CasADi conic problem for ``plugin``.

    Data only: the backend (``casadi:<plugin>`` step solvers,
    :mod:`optik.solvers.casadi_conic`) builds the ``casadi.conic`` function and solves it.

    Args:
        program: the step program.
        plugin: a conic plugin name (see
            :func:`optik.solvers.casadi_conic.casadi_conic_plugins`).

    Raises:
        OptikError: ``program`` is not a :class:`DiffIKProgram`, or ``plugin`` not a name.
    """
    if not isinstance(program, DiffIKProgram):
        raise OptikError(
            f"program must be a DiffIKProgram (build_program), got {type(program).__name__}"
        )
    if not isinstance(plugin, str) or not plugin:
        raise OptikError(f"plugin must be a CasADi conic plugin name, got {plugin!r}")
    eq = program.equilibrated()
    n = program.dof
    inf = np.full(n, np.inf)
    args: dict[str, FloatArray] = {
        "h": eq.P,
        "g": eq.c,
        "a": np.zeros((0, n)) if eq.A is None else eq.A,
        "lba": np.zeros(0) if eq.b is None else eq.b,
        "uba": np.zeros(0) if eq.b is None else eq.b,
        "lbx": -inf if eq.lb is None else eq.lb,
        "ubx": inf if eq.ub is None else eq.ub,
    }
    return ConicProgram(program, plugin, args, eq.scale)
