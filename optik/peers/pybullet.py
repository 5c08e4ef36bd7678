"""pybullet: ``calculateInverseKinematics`` on a URDF loaded into a headless physics server.

The URDF is written from optik's chain (:func:`optik.peers._chain.urdf_text`) and loaded
with a fixed base into a ``DIRECT`` (no GUI) server of its own. A query sets the joints
to the start, calls ``calculateInverseKinematics`` for the tool link (position and
orientation, ``maxNumIterations`` iterations, with optik's limits, ranges and the start as
the rest pose for pybullet's null-space variant when ``null_space``), sets the joints to
the answer and calls again, up to ``rounds`` calls, until pybullet's own FK meets the
protocol's tolerance; then seeded random restarts, up to ``restarts`` or ``timeout_s``.

pybullet computes in single precision: its link states carry float32 rounding (about
1e-7 m on an arm of a metre), so its FK cannot equal optik's to
:data:`~optik.peers._base.FK_MATCH_TOL`. Its model check uses :data:`FLOAT32_FK_TOL`
instead (:attr:`PyBulletPeer.fk_tol`) and records the difference found; the answers
are verified by optik's FK like every other peer's, so the looser check can cost pybullet
successes, never grant any.
"""

from __future__ import annotations

import math
import tempfile
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, ClassVar, Final

import numpy as np

from optik._checks import FloatArray
from optik.model import Robot
from optik.peers._base import Peer, PeerAnswer, PeerUnavailable, random_start
from optik.peers._chain import TOOL_LINK, write_urdf
from optik.spatial import pose_error

__all__ = ["FLOAT32_FK_TOL", "PyBulletPeer"]

#: Model check of a single-precision peer, m (or entry of a rotation matrix).
FLOAT32_FK_TOL: Final[float] = 1e-6


def _quaternion_xyzw(R: FloatArray) -> list[float]:
    """Unit quaternion (x, y, z, w) of a rotation matrix (Shepperd's stable branch)."""
    trace = float(np.trace(R))
    if trace > 0.0:
        s = 2.0 * math.sqrt(trace + 1.0)
        w, x = 0.25 * s, (R[2, 1] - R[1, 2]) / s
        y, z = (R[0, 2] - R[2, 0]) / s, (R[1, 0] - R[0, 1]) / s
    elif R[0, 0] > R[1, 1] and R[0, 0] > R[2, 2]:
        s = 2.0 * math.sqrt(1.0 + R[0, 0] - R[1, 1] - R[2, 2])
        w, x = (R[2, 1] - R[1, 2]) / s, 0.25 * s
        y, z = (R[0, 1] + R[1, 0]) / s, (R[0, 2] + R[2, 0]) / s
    elif R[1, 1] > R[2, 2]:
        s = 2.0 * math.sqrt(1.0 + R[1, 1] - R[0, 0] - R[2, 2])
        w, x = (R[0, 2] - R[2, 0]) / s, (R[0, 1] + R[1, 0]) / s
        y, z = 0.25 * s, (R[1, 2] + R[2, 1]) / s
    else:
        s = 2.0 * math.sqrt(1.0 + R[2, 2] - R[0, 0] - R[1, 1])
        w, x = (R[1, 0] - R[0, 1]) / s, (R[0, 2] + R[2, 0]) / s
        y, z = (R[1, 2] + R[2, 1]) / s, 0.25 * s
    return [float(x), float(y), float(z), float(w)]


@dataclass(eq=False, kw_only=True)
class PyBulletPeer(Peer):
    """pybullet ``calculateInverseKinematics``, repeated from its answer, with restarts.

    Args:
        tol: the protocol's tolerance, m and rad: rounds stop within it (pybullet's FK).
        seed: seed of the random restarts.
        timeout_s: no restart starts after this time, s.
        max_iterations: ``maxNumIterations`` of one call.
        residual: ``residualThreshold`` of one call.
        rounds: calls per attempt, each from the previous answer.
        restarts: random restarts after the attempt from ``q0``.
        null_space: pass optik's limits, ranges and the start (rest pose) to pybullet's
            null-space variant; without it pybullet ignores the limits.
    """

    name: ClassVar[str] = "pybullet"
    module: ClassVar[str] = "pybullet"
    distribution: ClassVar[str] = "pybullet"
    title: ClassVar[str] = "pybullet calculateInverseKinematics (Bullet, single precision)"
    reports_iterations: ClassVar[bool] = False
    fk_tol: ClassVar[float] = FLOAT32_FK_TOL

    max_iterations: int = 100
    residual: float = 1e-12
    rounds: int = 20
    restarts: int = 10
    null_space: bool = False
    _client: int | None = field(default=None, init=False, repr=False)
    _body: int = field(default=-1, init=False, repr=False)
    _joints: Sequence[int] = field(default=(), init=False, repr=False)
    _tool: int = field(default=-1, init=False, repr=False)

    def settings(self) -> dict[str, Any]:
        """Iterations, residual, rounds, restarts, null space, tolerance."""
        return {
            "max_iterations": self.max_iterations,
            "null_space": self.null_space,
            "residual": self.residual,
            "restarts": self.restarts,
            "rounds": self.rounds,
            "tol": self.tol,
        }

    def _connect(self) -> int:
        import pybullet

        if self._client is None:
            self._client = int(pybullet.connect(pybullet.DIRECT))
        else:
            pybullet.resetSimulation(physicsClientId=self._client)
        if self._client < 0:
            raise PeerUnavailable(self.name, "pybullet.connect(DIRECT) failed")
        return self._client

    def _prepare(self, robot: Robot) -> list[str]:
        import pybullet

        client = self._connect()
        with tempfile.TemporaryDirectory(prefix="optik-pybullet-") as tmp:
            path = write_urdf(robot, Path(tmp), self.name)
            body = pybullet.loadURDF(str(path), useFixedBase=True, physicsClientId=client)
        infos = [
            pybullet.getJointInfo(body, i, physicsClientId=client)
            for i in range(pybullet.getNumJoints(body, physicsClientId=client))
        ]
        joints = [i for i, info in enumerate(infos) if info[2] != pybullet.JOINT_FIXED]
        tools = [i for i, info in enumerate(infos) if info[12].decode() == TOOL_LINK]
        if len(joints) != robot.dof or len(tools) != 1:
            raise PeerUnavailable(
                self.name, f"pybullet body has {len(joints)} movable joints, optik {robot.dof}"
            )
        self._body, self._joints, self._tool = body, joints, tools[0]
        note = self.check_fk(
            self._fk, robot, "pybullet body from a URDF written from optik's chain (float32)"
        )
        self.reseed(self.seed)
        return [note]

    def _set(self, q: FloatArray) -> None:
        import pybullet

        for joint, value in zip(self._joints, q, strict=True):
            pybullet.resetJointState(self._body, joint, float(value), physicsClientId=self._client)

    def _fk(self, q: FloatArray) -> FloatArray:
        import pybullet

        self._set(q)
        state = pybullet.getLinkState(
            self._body, self._tool, computeForwardKinematics=True, physicsClientId=self._client
        )
        T = np.eye(4)
        T[:3, :3] = np.reshape(pybullet.getMatrixFromQuaternion(state[5]), (3, 3))
        T[:3, 3] = state[4]
        return T

    def solve(self, T_target: FloatArray, q0: FloatArray) -> PeerAnswer:
        """Rounds of ``calculateInverseKinematics`` from ``q0``, then random restarts."""
        import pybullet

        robot = self.robot
        start_time = time.perf_counter()
        position = [float(v) for v in T_target[:3, 3]]
        orientation = _quaternion_xyzw(np.asarray(T_target[:3, :3]))
        extra: dict[str, Any] = {}
        start = np.asarray(q0, dtype=float)
        best, best_err = None, math.inf
        for attempt in range(self.restarts + 1):
            if attempt and self.out_of_time(start_time):
                break
            if self.null_space:
                lower = np.where(np.isfinite(robot.lower), robot.lower, -math.pi)
                upper = np.where(np.isfinite(robot.upper), robot.upper, math.pi)
                extra = {
                    "lowerLimits": lower.tolist(),
                    "upperLimits": upper.tolist(),
                    "jointRanges": (upper - lower).tolist(),
                    "restPoses": start.tolist(),
                }
            q = start
            for _ in range(self.rounds):
                self._set(q)
                q = np.asarray(
                    pybullet.calculateInverseKinematics(
                        self._body,
                        self._tool,
                        position,
                        orientation,
                        maxNumIterations=self.max_iterations,
                        residualThreshold=self.residual,
                        physicsClientId=self._client,
                        **extra,
                    ),
                    dtype=float,
                )
                err = max(pose_error(self._fk(q), T_target))
                if err < best_err:
                    best, best_err = q, err
                if err <= self.tol:
                    return PeerAnswer(best)
            start = random_start(robot, self._rng)
        return PeerAnswer(best)

    def __del__(self) -> None:
        if self._client is not None:
            try:
                import pybullet

                pybullet.disconnect(physicsClientId=self._client)
            except Exception:  # the interpreter may be shutting down
                pass
