"""Robotics Toolbox for Python: the C++ Levenberg-Marquardt solver ``ETS.ik_LM``.

The model is an ``ETS`` built from optik's chain (:mod:`optik.peers._chain`): ``SE3(K_0)
Rz(q_1) SE3(K_1) ... SE3(K_n)`` (``tz`` for a prismatic joint), so any robot optik models
without mimic joints runs, DH or URDF. optik's limits are copied into ``qlim`` (a joint
without limits gets [-pi, pi]: any angle wraps into it) and ``joint_limits=True``: an
answer outside the limits is rejected by RTB and a new random search starts, up to
``slimit`` searches. RTB stops when ``E = ½‖e‖² < tol_rtb`` with ``e`` = (position error,
rotation vector): ``tol_rtb = ½·tol²`` asks for the protocol's accuracy (RTB's own default
``1e-6`` only bounds ``‖e‖`` by 1.4e-3).

``ETS.ik_LM`` is the compiled solver; ``DHRobot.ik_LM`` rebuilds the ETS on every call
(about 10x the solve time). Its random restarts come from C ``rand()``, seeded with
``srand(seed)`` in :meth:`RTBPeer.prepare` for repeatable runs.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import math
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np

from optik._checks import FloatArray
from optik.model import Robot
from optik.peers._base import Peer, PeerAnswer
from optik.peers._chain import chain_of

__all__ = ["RTBPeer"]


@dataclass(eq=False, kw_only=True)
class RTBPeer(Peer):
    """Robotics Toolbox for Python, ``ETS.ik_LM`` (C++), joint limits enforced.

    Args:
        tol: the protocol's tolerance, m and rad (RTB's ``tol`` is ``½·tol²``, unless
            ``rtb_tol`` is given).
        seed: seed of C ``rand()``, which drives RTB's restarts.
        timeout_s: unused: RTB bounds its own work by ``ilimit * slimit`` iterations.
        ilimit: iterations per search.
        slimit: searches (the first from ``q0``, then random).
        rtb_tol: RTB's ``tol`` on ``½‖e‖²`` directly (for example its default 1e-6).
    """

    name: ClassVar[str] = "rtb"
    module: ClassVar[str] = "roboticstoolbox"
    distribution: ClassVar[str] = "roboticstoolbox-python"
    title: ClassVar[str] = "Robotics Toolbox for Python, ETS.ik_LM (C++)"

    ilimit: int = 30
    slimit: int = 100
    rtb_tol: float | None = None
    _ets: Any = field(default=None, init=False, repr=False)

    def __post_init__(self) -> None:
        super().__post_init__()
        self.rtb_tol = 0.5 * self.tol * self.tol if self.rtb_tol is None else float(self.rtb_tol)

    def settings(self) -> dict[str, Any]:
        """RTB's tolerance, iteration and search limits."""
        return {
            "ilimit": self.ilimit,
            "joint_limits": True,
            "rtb_tol": self.rtb_tol,
            "slimit": self.slimit,
        }

    def _prepare(self, robot: Robot) -> list[str]:
        from roboticstoolbox import ET
        from roboticstoolbox.ets.ETS import ETS

        spec = chain_of(robot, self.name)
        elements = [ET.SE3(spec.origins[0])]
        for i in range(spec.dof):
            elements.append(ET.tz() if spec.prismatic[i] else ET.Rz())
            elements.append(ET.SE3(spec.origins[i + 1]))
        ets = ETS(elements)
        lower = np.where(np.isfinite(spec.lower), spec.lower, -math.pi)
        upper = np.where(np.isfinite(spec.upper), spec.upper, math.pi)
        ets.qlim = np.vstack([lower, upper])
        note = self.check_fk(lambda q: ets.fkine(q).A, robot, "ETS from optik's chain")
        self._ets = ets
        self.reseed(self.seed)
        return [note, "optik's joint limits copied into qlim"]

    def reseed(self, seed: int) -> None:
        """Seed C ``rand()``, which draws RTB's restarts (process-wide)."""
        super().reseed(seed)
        libc_name = ctypes.util.find_library("c")
        if libc_name is not None:
            ctypes.CDLL(libc_name).srand(ctypes.c_uint(self.seed % 2**32))

    def solve(self, T_target: FloatArray, q0: FloatArray) -> PeerAnswer:
        """``ets.ik_LM(T, q0, ilimit, slimit, tol, joint_limits=True)``."""
        sol = self._ets.ik_LM(
            T_target,
            q0=q0,
            ilimit=self.ilimit,
            slimit=self.slimit,
            tol=self.rtb_tol,
            joint_limits=True,
        )
        return PeerAnswer(
            np.asarray(sol.q, dtype=float), int(sol.iterations), bool(sol.success), sol.reason
        )
