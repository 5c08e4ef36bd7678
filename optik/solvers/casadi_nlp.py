"""The ``casadi:<nlpsol>`` family (``casadi:ipopt``, ``casadi:sqpmethod``): IK as one NLP.

The program is :func:`optik.programs.nlp.build_nlp`, built once per robot and mode and
reused for every target. Each solve is warm-started from the current ``q``; when a solve
stops short of ``query.tol`` (a claimed success at a point optik measures as not yet
converged, or a proximal sub-problem, below) the solver restarts from where it stopped,
as long as the error keeps decreasing, up to ``max_iter`` iterations in total.

Ipopt on a redundant task (more joints than task rows, e.g. a 7-joint arm and a pose, or
any 6-joint arm and a position) converges slowly: its barrier term moves the iterate
along the self-motion manifold, where the objective has no curvature. There it solves
proximal sub-problems instead, ``mu ||q - q_k||^2`` with ``q_k`` the previous answer and
``mu`` = :attr:`CasadiNLPSolver.proximal_weight`: each fixes the null-space motion and
the sequence converges to a zero-residual point (the proximal-point method; measured in
``docs/programs.md``). ``sqpmethod`` does not need it.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import casadi
import numpy as np

from optik import _kernels
from optik._checks import FloatArray
from optik.model import Robot
from optik.programs.nlp import NLPProgram, build_nlp
from optik.solvers._base import IKQuery, IKSolver, SolverOutput, budget_now, register_solver

__all__ = ["CasadiNLPSolver"]


class CasadiNLPSolver(IKSolver):
    """IK as one nonlinear program solved by a ``casadi.nlpsol`` plugin.

    The program (see :mod:`optik.programs.nlp`), with ``p*, R*`` the target::

        min  ||p(q) - p*||^2 + (3 - trace(R*^T R(q))) + mu ||q - q_ref||^2
        s.t. lower <= q <= upper

    (no orientation term in position mode; ``mu = 0`` except for ipopt's proximal
    sub-problems on redundant tasks, where ``q_ref`` is the previous answer). Stops when
    the position error is at most ``tol`` (m) and the orientation error at most ``tol``
    (rad), when a restart makes no progress, at ``max_iter`` solver iterations in total,
    or at the deadline (checked between solves: a running solve is not interrupted, it is
    bounded by ``max_iter``). ``converged`` is the last solve's own claim
    (``stats()["success"]``).
    """

    plain_tasks_only = True

    kind = "nlp"
    default_max_iter = 200
    #: Weight ``mu`` of the proximal term (m^2 per rad^2) on redundant tasks (ipopt only).
    proximal_weight: float = 1e-6

    def __init__(self, plugin: str) -> None:
        self.plugin = plugin
        self.name = f"casadi:{plugin}"

    def _program(self, query: IKQuery, max_iter: int) -> NLPProgram:
        return build_nlp(query.robot, query.mode, plugin=self.plugin, max_iter=max_iter)  # type: ignore[arg-type]

    def solve(self, query: IKQuery, q0: FloatArray, max_iter: int, deadline: float) -> SolverOutput:
        """Refine ``q0`` towards ``query.target`` (see the class docstring)."""
        robot = query.robot
        q = np.clip(np.asarray(q0, dtype=np.float64), robot.lower, robot.upper)
        try:
            program = self._program(query, max(1, int(max_iter)))
        except Exception as exc:  # report, never raise from a backend run
            return SolverOutput(q, 0, False, f"{type(exc).__name__}: {exc}", True)
        task_rows = 3 if query.mode == "position" else 6
        mu = self.proximal_weight if self.plugin == "ipopt" and robot.dof > task_rows else 0.0
        fk = _pose_of(robot)
        e = query.error_vector(fk(q))
        # The parameters [p*, vec(R*), w_rot, mu, q_ref] (NLPProgram.parameter_vector) of
        # the query's target, validated by the query already; each solve only moves q_ref.
        target = query.target
        rotation = np.eye(3) if query.mode == "position" else target[:3, :3]
        params = np.concatenate([target[:3, 3], rotation.ravel(order="F"), [1.0, mu], q])
        q_ref = params[-robot.dof :]
        iterations = 0
        claim, status = False, "not started"
        while True:
            if _converged(e, query.tol):
                return SolverOutput(q, iterations, claim if iterations else True, status)
            if iterations >= max_iter:
                return SolverOutput(q, iterations, claim, f"max_iter ({status})")
            if budget_now() > deadline:
                return SolverOutput(q, iterations, claim, f"timeout ({status})")
            q_ref[:] = q
            try:
                result = program.solve_parameters(params, q)
            except Exception as exc:  # report, never raise from a backend run
                return SolverOutput(q, iterations, False, f"{type(exc).__name__}: {exc}", True)
            iterations += max(result.iterations, 1)
            claim, status = result.success, result.status
            if not np.all(np.isfinite(result.q)):
                return SolverOutput(q, iterations, False, f"non-finite answer ({status})", True)
            q_new = np.clip(result.q, robot.lower, robot.upper)
            e_new = query.error_vector(fk(q_new))
            if float(e_new @ e_new) >= float(e @ e):
                return SolverOutput(q, iterations, claim, f"no progress ({status})")
            q, e = q_new, e_new


def _pose_of(robot: Robot) -> Callable[[FloatArray], FloatArray]:
    """``q -> T`` for a ``q`` already inside the limits: the compiled FK, unvalidated."""
    chain = robot.chain
    K, prismatic, C = chain.K, chain.prismatic, chain.C
    identity = chain.identity

    def pose(q: FloatArray) -> FloatArray:
        T = np.empty((4, 4))
        _kernels.fk_into(K, prismatic, q if identity else np.ascontiguousarray(C @ q), T)
        return T

    return pose


def _converged(e: FloatArray, tol: float) -> bool:
    """Position (m) and orientation (rad) errors both within ``tol``."""
    values = e.tolist()
    if math.sqrt(sum(x * x for x in values[:3])) > tol:
        return False
    return len(values) == 3 or math.sqrt(sum(x * x for x in values[3:])) <= tol


def _has_nlpsol(plugin: str) -> bool:
    try:
        return bool(casadi.has_nlpsol(plugin))
    except Exception:  # a plugin that cannot load is not available
        return False


def _register_all() -> None:
    """Register ``casadi:ipopt`` and ``casadi:sqpmethod``."""
    for plugin in ("ipopt", "sqpmethod"):

        def factory(plugin: str = plugin) -> IKSolver:
            return CasadiNLPSolver(plugin)

        def available(plugin: str = plugin) -> bool:
            return _has_nlpsol(plugin)

        register_solver(
            f"casadi:{plugin}",
            factory,
            available,
            f"CasADi was built without the {plugin!r} nlpsol plugin; install the casadi "
            "wheel from PyPI (`pip install casadi`), which ships it.",
        )


_register_all()
