"""EAIK: closed-form IK by subproblem decomposition, for the 1-6R chains it decomposes.

The model is EAIK's ``HomogeneousRobot`` built from optik's chain at ``q = 0``: the frame
of each joint (``K_0 K_1 ... K_{i-1}``, its z axis the joint axis) and the tool frame, so
DH and URDF robots alike run when EAIK knows a decomposition of the chain (spherical
wrist, three parallel axes...). EAIK ignores joint limits: each exact branch (not
EAIK's least-squares fallbacks) is moved by whole turns into optik's limits, nearest
``q0``; the branch nearest ``q0`` is the answer, none when no branch fits the limits.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np

from optik._checks import FloatArray
from optik.model import Robot
from optik.peers._base import Peer, PeerAnswer, PeerUnavailable, wrap_into_limits
from optik.peers._chain import chain_of

__all__ = ["EAIKPeer"]

#: The most joints EAIK solves (it rejects larger chains).
MAX_JOINTS = 6


@dataclass(eq=False)
class EAIKPeer(Peer):
    """EAIK closed form on optik's chain; branches filtered by optik's limits.

    Args:
        tol: unused by the closed form (recorded in the settings).
        seed: unused (no randomness).
        timeout_s: unused (one closed-form call per query).
    """

    name: ClassVar[str] = "eaik"
    module: ClassVar[str] = "eaik.IK_Homogeneous"
    distribution: ClassVar[str] = "eaik"
    title: ClassVar[str] = "EAIK closed form (subproblem decomposition)"
    reports_iterations: ClassVar[bool] = False

    _bot: Any = field(default=None, init=False, repr=False)

    def settings(self) -> dict[str, Any]:
        """The branch rule (no numeric options)."""
        return {"branches": "exact, wrapped into the limits, nearest q0"}

    def _prepare(self, robot: Robot) -> list[str]:
        from eaik.IK_Homogeneous import HomogeneousRobot

        spec = chain_of(robot, self.name)
        if spec.prismatic.any():
            raise PeerUnavailable(
                self.name, f"EAIK solves revolute chains; {robot.name} has a prismatic joint"
            )
        if spec.dof > MAX_JOINTS:
            raise PeerUnavailable(
                self.name,
                f"EAIK solves chains of 1-{MAX_JOINTS} revolute joints; {robot.name} has "
                f"{spec.dof} (a joint would have to be locked)",
            )
        frames, T = [], np.eye(4)
        for K in spec.origins:  # joint frames at q = 0, then the tool
            T = T @ K
            frames.append(T.copy())
        bot = HomogeneousRobot(np.array(frames))
        if not bot.hasKnownDecomposition():
            raise PeerUnavailable(
                self.name, f"EAIK knows no decomposition of {robot.name}'s {spec.dof}R chain"
            )
        note = self.check_fk(bot.fwdKin, robot, f"EAIK {bot.getKinematicFamily()}")
        self._bot = bot
        return [note]

    def solve(self, T_target: FloatArray, q0: FloatArray) -> PeerAnswer:
        """Every exact branch, wrapped into the limits; the one nearest ``q0``."""
        robot = self.robot
        sol = self._bot.IK(T_target)
        best, best_dist = None, math.inf
        for q, least_squares in zip(sol.Q, sol.is_LS, strict=True):
            if least_squares:
                continue
            wrapped = wrap_into_limits(np.asarray(q, dtype=float), robot.lower, robot.upper, q0)
            if wrapped is None:
                continue
            dist = float(np.linalg.norm(wrapped - q0))
            if dist < best_dist:
                best, best_dist = wrapped, dist
        note = "" if best is not None else "no exact branch inside the limits"
        return PeerAnswer(best, None, None, note)
