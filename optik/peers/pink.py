"""pink: differential IK (one QP per step) on a Pinocchio model, iterated to convergence.

The Pinocchio model is read from a URDF written from optik's chain
(:func:`optik.peers._chain.urdf_text`). One ``FrameTask`` on the tool link (position
and orientation cost 1, gain 1), a ``ConfigurationLimit`` (gain ``limit_gain``); each
step solves pink's QP with ``dt = 1`` and integrates the velocity, until the pose error
(from Pinocchio's FK) is within the protocol's tolerance or ``max_iter`` steps; then
seeded random restarts, up to ``restarts`` or ``timeout_s``.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np

from optik._checks import FloatArray
from optik._interrupts import reraise_interrupt
from optik.model import Robot
from optik.peers._base import Peer, PeerAnswer, PeerUnavailable, random_start
from optik.peers._chain import TOOL_LINK, urdf_text
from optik.spatial import pose_error

__all__ = ["PinkPeer"]


@dataclass(eq=False, kw_only=True)
class PinkPeer(Peer):
    """pink ``solve_ik`` iterated with ``dt = 1`` from ``q0``, then random restarts.

    Args:
        tol: the protocol's tolerance, m and rad: the iteration stops within it.
        seed: seed of the random restarts.
        timeout_s: no restart starts after this time, s.
        qp_solver: the qpsolvers backend of pink's QP.
        max_iter: steps per attempt.
        restarts: random restarts after the attempt from ``q0``.
        limit_gain: ``ConfigurationLimit``'s gain (fraction of the distance to a limit one
            step may cover).
    """

    name: ClassVar[str] = "pink"
    module: ClassVar[str] = "pink"
    distribution: ClassVar[str] = "pin-pink"
    title: ClassVar[str] = "pink differential IK (Pinocchio), iterated"

    qp_solver: str = "daqp"
    max_iter: int = 100
    restarts: int = 10
    limit_gain: float = 0.5
    _model: Any = field(default=None, init=False, repr=False)
    _data: Any = field(default=None, init=False, repr=False)
    _task: Any = field(default=None, init=False, repr=False)
    _limits: Any = field(default=None, init=False, repr=False)

    def settings(self) -> dict[str, Any]:
        """QP backend, steps, restarts, limit gain, tolerance."""
        return {
            "dt": 1.0,
            "limit_gain": self.limit_gain,
            "max_iter": self.max_iter,
            "qp_solver": self.qp_solver,
            "restarts": self.restarts,
            "tol": self.tol,
        }

    def _prepare(self, robot: Robot) -> list[str]:
        import pinocchio as pin
        import qpsolvers
        from pink.limits import ConfigurationLimit
        from pink.tasks import FrameTask

        if self.qp_solver not in qpsolvers.available_solvers:
            raise PeerUnavailable(
                self.name,
                f"QP solver {self.qp_solver!r} not installed (qpsolvers has "
                f"{sorted(qpsolvers.available_solvers)}); pip install {self.qp_solver}",
            )
        if not (np.all(np.isfinite(robot.lower)) and np.all(np.isfinite(robot.upper))):
            raise PeerUnavailable(
                self.name,
                "a joint without limits is continuous in Pinocchio (two coordinates, cos "
                "and sin): the adapter maps only bounded joints",
            )
        model = pin.buildModelFromXML(urdf_text(robot, self.name))
        if model.nq != robot.dof:
            raise PeerUnavailable(
                self.name, f"Pinocchio model has nq={model.nq}, optik dof={robot.dof}"
            )
        data = model.createData()
        frame_id = model.getFrameId(TOOL_LINK)

        def fk(q: FloatArray) -> FloatArray:
            pin.framesForwardKinematics(model, data, q)
            return np.asarray(data.oMf[frame_id].homogeneous)

        note = self.check_fk(fk, robot, "Pinocchio model from a URDF written from optik's chain")
        self._model, self._data = model, data
        self._limits = [ConfigurationLimit(model, config_limit_gain=self.limit_gain)]
        self._task = FrameTask(TOOL_LINK, position_cost=1.0, orientation_cost=1.0, gain=1.0)
        self.reseed(self.seed)
        return [note]

    def solve(self, T_target: FloatArray, q0: FloatArray) -> PeerAnswer:
        """Iterate ``q += solve_ik(...)`` from ``q0``, then from seeded random restarts."""
        import pink
        import pinocchio as pin

        start_time = time.perf_counter()
        self._task.set_target(pin.SE3(T_target[:3, :3].copy(), T_target[:3, 3].copy()))
        start = np.asarray(q0, dtype=float)
        best, best_err, iterations, note = None, math.inf, 0, ""
        for attempt in range(self.restarts + 1):
            if attempt and self.out_of_time(start_time):
                break
            config = pink.Configuration(self._model, self._data, start.copy())
            for _ in range(self.max_iter):
                T = config.get_transform_frame_to_world(TOOL_LINK).homogeneous
                position, angle = pose_error(T, T_target)
                if position <= self.tol and angle <= self.tol:
                    break
                try:
                    v = pink.solve_ik(
                        config,
                        [self._task],
                        dt=1.0,
                        solver=self.qp_solver,
                        limits=self._limits,
                        safety_break=False,
                    )
                except Exception as exc:  # a failed QP ends this attempt, its text kept
                    reraise_interrupt(exc)  # Ctrl-C is the caller's, not a failure
                    note = f"{type(exc).__name__}: {exc}"[:120]
                    break
                config.integrate_inplace(v, 1.0)
                iterations += 1
            T = config.get_transform_frame_to_world(TOOL_LINK).homogeneous
            position, angle = pose_error(T, T_target)
            if max(position, angle) < best_err:
                best, best_err = np.array(config.q, dtype=float), max(position, angle)
            if position <= self.tol and angle <= self.tol:
                break
            start = random_start(self.robot, self._rng)
        return PeerAnswer(best, iterations, None, note)
