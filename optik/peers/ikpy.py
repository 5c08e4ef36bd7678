"""ikpy: a chain read from a URDF, ``scipy.optimize.least_squares`` with the limits as bounds.

The URDF is written from optik's chain (:func:`optik.peers._chain.urdf_text`); the chain
has ikpy's origin link, one active link per joint and the fixed tool link. Each query
asks for the full orientation (``orientation_mode="all"``) from ``q0``, then from seeded
random restarts until ikpy's own FK meets the protocol's tolerance, ``restarts`` are
spent, or ``timeout_s`` has passed; the answer is the attempt with the smallest error.
"""

from __future__ import annotations

import math
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from optik._checks import FloatArray
from optik.model import Robot
from optik.peers._base import Peer, PeerAnswer, PeerUnavailable, random_start
from optik.peers._chain import ROOT_LINK, write_urdf
from optik.spatial import pose_error

__all__ = ["IKPyPeer"]


@dataclass(eq=False, kw_only=True)
class IKPyPeer(Peer):
    """ikpy ``Chain.inverse_kinematics_frame`` (scipy least squares, bounds = limits).

    Args:
        tol: the protocol's tolerance, m and rad: a restart starts while ikpy's FK misses
            it.
        seed: seed of the random restarts.
        timeout_s: no restart starts after this time, s.
        restarts: random restarts after the attempt from ``q0``.
        ikpy_tol: ``tol`` passed to ikpy's optimizer.
    """

    name: ClassVar[str] = "ikpy"
    module: ClassVar[str] = "ikpy.chain"
    distribution: ClassVar[str] = "ikpy"
    title: ClassVar[str] = "ikpy, scipy least_squares with bounds"
    reports_iterations: ClassVar[bool] = False

    restarts: int = 10
    ikpy_tol: float = 1e-12
    _chain: Any = field(default=None, init=False, repr=False)

    def settings(self) -> dict[str, Any]:
        """Restarts, ikpy's tolerance, the orientation mode."""
        return {
            "ikpy_tol": self.ikpy_tol,
            "orientation_mode": "all",
            "restarts": self.restarts,
            "tol": self.tol,
        }

    def _prepare(self, robot: Robot) -> list[str]:
        from ikpy.chain import Chain

        with tempfile.TemporaryDirectory(prefix="optik-ikpy-") as tmp:
            path = write_urdf(robot, Path(tmp), self.name)
            mask = [False] + [True] * robot.dof + [False]
            chain = Chain.from_urdf_file(
                str(path), base_elements=[ROOT_LINK], active_links_mask=mask, name=robot.name
            )
        if len(chain.links) != robot.dof + 2:
            raise PeerUnavailable(
                self.name, f"ikpy chain has {len(chain.links)} links, expected {robot.dof + 2}"
            )
        note = self.check_fk(
            lambda q: chain.forward_kinematics(self._full(q)),
            robot,
            "ikpy chain from a URDF written from optik's chain",
        )
        self._chain = chain
        self.reseed(self.seed)
        return [note]

    @staticmethod
    def _full(q: FloatArray) -> FloatArray:
        return np.concatenate([[0.0], q, [0.0]])

    def solve(self, T_target: FloatArray, q0: FloatArray) -> PeerAnswer:
        """From ``q0``, then seeded random restarts, until ikpy's FK meets ``tol``."""
        start_time = time.perf_counter()
        start, best, best_err = np.asarray(q0, dtype=float), None, math.inf
        for attempt in range(self.restarts + 1):
            if attempt and self.out_of_time(start_time):
                break
            full = self._chain.inverse_kinematics_frame(
                T_target,
                initial_position=self._full(start),
                orientation_mode="all",
                tol=self.ikpy_tol,
            )
            q = np.asarray(full[1:-1], dtype=float)
            position, angle = pose_error(self._chain.forward_kinematics(full), T_target)
            if max(position, angle) < best_err:
                best, best_err = q, max(position, angle)
            if position <= self.tol and angle <= self.tol:
                break
            start = random_start(self.robot, self._rng)
        return PeerAnswer(best)
