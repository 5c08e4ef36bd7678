"""Adapters for the peer IK libraries that ``bench_ik.py`` runs in optik's process.

Every adapter turns one query (a 4x4 target pose, a start ``q0`` inside the limits) into a
joint vector in optik's joint order and units. It never judges its own answer: the
benchmark verifies every ``q`` from optik's forward kinematics and the joint limits.
Each peer first checks that its model of the robot is optik's (forward kinematics equal at
random configurations, to 1e-9 m); a peer that cannot import, or cannot model a robot,
raises :class:`PeerUnavailable` with the reason, and the benchmark reports it.

Peers (install: ``pip install roboticstoolbox-python ikpy pin-pink eaik daqp``):

- ``rtb ik_LM``: Robotics Toolbox for Python, the C++ Levenberg-Marquardt solver
  (``ETS.ik_LM``, Chan damping), on RTB's own DH models ``rtb.models.DH.*`` with optik's
  joint limits copied in, ``joint_limits=True`` (an answer outside the limits is rejected
  and a new random search starts, up to ``slimit`` searches). RTB stops when
  ``E = ½‖e‖² < tol`` with ``e`` = (position error, rotation vector): ``tol = ½·tol_optik²``
  asks for the same accuracy as optik; RTB's default ``tol=1e-6`` only guarantees
  ``‖e‖ < 1.4e-3`` and is run as a second row for reference.
- ``ikpy``: a chain read from a URDF, ``scipy.optimize.least_squares`` with the joint
  limits as bounds, full orientation (``orientation_mode="all"``); seeded random restarts.
- ``pink``: Pinocchio model from the same URDF, one ``FrameTask`` (position and orientation
  cost 1, gain 1), ``ConfigurationLimit``, differential IK with ``dt = 1`` iterated until the
  pose error (Pinocchio's forward kinematics) is below ``tol``; seeded random restarts.
- ``eaik``: EAIK's closed form for standard-DH arms with a known decomposition (Puma 560,
  UR5). It ignores joint limits: each branch is wrapped by whole turns into the limits
  (nearest ``q0``), least-squares branches and branches outside the limits are dropped,
  and the one nearest ``q0`` is returned.

The URDF for ikpy and pink is ``problems/<robot>.urdf`` when the project ships one, else it
is written here from optik's DH table (:func:`write_urdf`) into a temporary folder.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import importlib
import importlib.metadata
import itertools
import math
import xml.etree.ElementTree as ET
from abc import ABC, abstractmethod
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

import optik
from optik.problems import PROBLEMS_DIR

Array = NDArray[np.float64]

FK_MATCH_TOL = 1e-9
"""Largest allowed difference (m, or entry of a rotation matrix) between a peer's forward
kinematics and optik's at random configurations before the peer's model is rejected."""


class PeerUnavailable(Exception):
    """A peer cannot run (import failed, or the robot is outside what it models)."""


@dataclass
class PeerAnswer:
    """A peer's answer to one query, before verification.

    Attributes:
        q: joint vector (dof,) in optik's order and units, or ``None`` for no answer.
        iterations: the peer's own iteration count, ``None`` when it does not report one.
        note: a short remark (a backend's exception text, ``"no branch"``).
    """

    q: Array | None
    iterations: int | None = None
    note: str = ""


# ---------------------------------------------------------------- homogeneous transforms
def _rz(t: float) -> Array:
    c, s = math.cos(t), math.sin(t)
    return np.array([[c, -s, 0, 0], [s, c, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1.0]])


def _rx(t: float) -> Array:
    c, s = math.cos(t), math.sin(t)
    return np.array([[1, 0, 0, 0], [0, c, -s, 0], [0, s, c, 0], [0, 0, 0, 1.0]])


def _trans(x: float, y: float, z: float) -> Array:
    T = np.eye(4)
    T[:3, 3] = (x, y, z)
    return T


def _rpy(R: Array) -> tuple[float, float, float]:
    """URDF roll, pitch, yaw of ``R = Rz(yaw) Ry(pitch) Rx(roll)``, robust at gimbal lock."""
    pitch = math.atan2(-R[2, 0], math.hypot(R[0, 0], R[1, 0]))
    if math.hypot(R[0, 0], R[1, 0]) < 1e-12:  # pitch = ±90°: roll and yaw share one axis
        return math.atan2(-R[1, 2], R[1, 1]), pitch, 0.0
    return math.atan2(R[2, 1], R[2, 2]), pitch, math.atan2(R[1, 0], R[0, 0])


def pose_error(T: Array, T_target: Array) -> tuple[float, float]:
    """Position error (m) and rotation angle of ``R*^T R`` (rad), robust near zero."""
    position = float(np.linalg.norm(T[:3, 3] - T_target[:3, 3]))
    R = T_target[:3, :3].T @ T[:3, :3]
    skew = np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])
    angle = math.atan2(float(np.linalg.norm(skew)) / 2.0, (float(np.trace(R)) - 1.0) / 2.0)
    return position, angle


def fk_mismatch(fk: Any, robot: optik.Robot, count: int = 20, seed: int = 12345) -> float:
    """Largest entry of ``|fk(q) - robot.fk(q)|`` over random ``q`` inside the limits."""
    rng = np.random.default_rng(seed)
    lower = np.where(np.isfinite(robot.lower), robot.lower, -math.pi)
    upper = np.where(np.isfinite(robot.upper), robot.upper, math.pi)
    worst = 0.0
    for _ in range(count):
        q = rng.uniform(lower, upper)
        worst = max(worst, float(np.abs(np.asarray(fk(q)) - robot.fk(q)).max()))
    return worst


# ---------------------------------------------------------------- URDF from a DH table
def dh_origins(robot: optik.Robot) -> list[Array]:
    """Constant transforms ``C_0 .. C_n`` with ``fk(q) = C_0 Rz(q_1) C_1 ... Rz(q_n) C_n``.

    Built from the public DH rows (standard ``A = Rz(θ+q) Tz(d) Tx(a) Rx(α)`` or modified
    ``A = Rx(α) Tx(a) Rz(θ+q) Tz(d)``), the base and the tool; revolute joints only.

    Raises:
        PeerUnavailable: no DH table, a prismatic or mimic joint.
    """
    rows = robot.dh
    if rows is None:
        raise PeerUnavailable(f"{robot.name}: no DH table to write a URDF from")
    if len(rows) != robot.dof or any(r.kind != "revolute" or r.mimic for r in rows):
        raise PeerUnavailable(f"{robot.name}: URDF writer handles revolute, unmimicked rows")
    base, tool = robot.T_world_base, robot.T_flange_tool
    if robot.convention == "dh":
        origins = [base @ _rz(rows[0].theta)]
        for prev, row in itertools.pairwise(rows):
            origins.append(_trans(0, 0, prev.d) @ _trans(prev.a, 0, 0) @ _rx(prev.alpha))
            origins[-1] = origins[-1] @ _rz(row.theta)
        last = rows[-1]
        origins.append(_trans(0, 0, last.d) @ _trans(last.a, 0, 0) @ _rx(last.alpha) @ tool)
    else:
        first = rows[0]
        origins = [base @ _rx(first.alpha) @ _trans(first.a, 0, 0) @ _rz(first.theta)]
        for prev, row in itertools.pairwise(rows):
            origins.append(
                _trans(0, 0, prev.d) @ _rx(row.alpha) @ _trans(row.a, 0, 0) @ _rz(row.theta)
            )
        origins.append(_trans(0, 0, rows[-1].d) @ tool)
    return origins


def write_urdf(robot: optik.Robot, path: Path) -> tuple[Path, str, str]:
    """Write a kinematics-only URDF of ``robot``; returns (path, root link, tool link)."""
    origins = dh_origins(robot)

    def chain_fk(q: Array) -> Array:
        T = origins[0]
        for qi, C in zip(q, origins[1:], strict=True):
            T = T @ _rz(qi) @ C
        return T

    mismatch = fk_mismatch(chain_fk, robot)
    if mismatch > FK_MATCH_TOL:  # pragma: no cover - a transcription bug here
        raise PeerUnavailable(f"{robot.name}: URDF transcription differs by {mismatch:.1e}")

    def origin(T: Array) -> str:
        r, p, y = _rpy(T[:3, :3])
        x = " ".join(repr(float(v)) for v in T[:3, 3])
        return f'<origin xyz="{x}" rpy="{r!r} {p!r} {y!r}"/>'

    links = ["base", *(f"link{i + 1}" for i in range(robot.dof)), "tool"]
    lines = ['<?xml version="1.0"?>', f'<robot name="{robot.name}">']
    lines += [f'  <link name="{name}"/>' for name in links]
    for i, joint in enumerate(robot.joints):
        lines += [
            f'  <joint name="{joint.name}" type="revolute">',
            f'    <parent link="{links[i]}"/>',
            f'    <child link="{links[i + 1]}"/>',
            f"    {origin(origins[i])}",
            '    <axis xyz="0 0 1"/>',
            f'    <limit lower="{joint.lower!r}" upper="{joint.upper!r}" effort="100"'
            ' velocity="100"/>',
            "  </joint>",
        ]
    lines += [
        '  <joint name="tool_joint" type="fixed">',
        f'    <parent link="{links[-2]}"/>',
        '    <child link="tool"/>',
        f"    {origin(origins[-1])}",
        "  </joint>",
        "</robot>",
    ]
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path, "base", "tool"


def urdf_for(key: str, robot: optik.Robot, workdir: Path) -> tuple[Path, str, str, str]:
    """The URDF used for ``key``: (path, root link, tool link, where it came from)."""
    shipped = PROBLEMS_DIR / f"{key}.urdf"
    if shipped.is_file():
        root = ET.parse(shipped).getroot()
        parents = {j.find("parent").get("link") for j in root.iter("joint")}  # type: ignore[union-attr]
        children = {j.find("child").get("link") for j in root.iter("joint")}  # type: ignore[union-attr]
        (base,) = parents - children
        (tool,) = children - parents
        return shipped, base, tool, f"problems/{shipped.name}"
    path, base, tool = write_urdf(robot, workdir / f"{key}.urdf")
    return path, base, tool, "written from the DH table"


def wrap_into_limits(q: Array, lower: Array, upper: Array, q_ref: Array) -> Array | None:
    """Move each angle by whole turns into ``[lower, upper]``, nearest ``q_ref``; None if none."""
    out = np.empty_like(q)
    for i, (a, lo, hi, ref) in enumerate(zip(q, lower, upper, q_ref, strict=True)):
        k_lo, k_hi = math.ceil((lo - a) / (2 * math.pi)), math.floor((hi - a) / (2 * math.pi))
        if k_lo > k_hi:
            return None
        k = min(max(round((ref - a) / (2 * math.pi)), k_lo), k_hi)
        out[i] = a + 2 * math.pi * k
    return out


# ---------------------------------------------------------------- the peers
@dataclass
class Peer(ABC):
    """One peer method: import, model check per robot, then queries."""

    name: str
    module: str
    distribution: str
    slow: bool = False
    settings: str = ""
    version: str = ""
    notes: list[str] = field(default_factory=list)

    def load(self) -> None:
        """Import the peer (raises :class:`PeerUnavailable` with the reason)."""
        try:
            importlib.import_module(self.module)
        except Exception as exc:  # any import-time failure means "not installed"
            raise PeerUnavailable(f"import {self.module}: {type(exc).__name__}: {exc}") from exc
        try:
            self.version = importlib.metadata.version(self.distribution)
        except importlib.metadata.PackageNotFoundError:
            self.version = "?"

    @abstractmethod
    def prepare(self, key: str, robot: optik.Robot, workdir: Path, seed: int) -> list[str]:
        """Build and check the peer's model of ``robot``; returns notes on the model."""

    @abstractmethod
    def solve(self, T_target: Array, q0: Array) -> PeerAnswer:
        """One query (timed by the caller)."""


_RTB_MODELS = {"puma560": "Puma560", "ur5": "UR5", "panda": "Panda"}


@dataclass
class RTBLM(Peer):
    """Robotics Toolbox for Python, ``ETS.ik_LM`` (C++), joint limits enforced."""

    tol: float = 5e-13
    ilimit: int = 30
    slimit: int = 100

    def prepare(self, key: str, robot: optik.Robot, workdir: Path, seed: int) -> list[str]:
        """Load ``rtb.models.DH.<Robot>``, compare with optik, copy optik's limits in."""
        import roboticstoolbox as rtb

        if key not in _RTB_MODELS:
            raise PeerUnavailable(f"no RTB DH model mapped for {key!r}")
        model = getattr(rtb.models.DH, _RTB_MODELS[key])()
        notes = []
        qlim = np.asarray(model.qlim, dtype=float)
        ours = np.vstack([robot.lower, robot.upper])
        diff = np.abs(qlim - ours).max() if qlim.shape == ours.shape else math.inf
        if diff > 1e-9:
            notes.append(
                f"RTB {_RTB_MODELS[key]} qlim differs from optik's by up to "
                f"{math.degrees(diff):.3g} deg: optik's limits are used"
            )
        model.qlim = ours
        # ETS.ik_LM is the compiled solver; DHRobot.ik_LM rebuilds the ETS on every call
        # (about 10x the solve time) and, for the Panda, applies the tool twice.
        self._ets = model.ets()
        mismatch = fk_mismatch(lambda q: self._ets.fkine(q).A, robot)
        if mismatch > FK_MATCH_TOL:
            raise PeerUnavailable(f"RTB {_RTB_MODELS[key]} FK differs by {mismatch:.2e}")
        notes.append(f"RTB {_RTB_MODELS[key]} ETS FK = optik FK (max diff {mismatch:.1e})")
        # Eigen's Random() draws the restarts from C rand(): seed it for repeatable runs.
        libc = ctypes.CDLL(ctypes.util.find_library("c"))
        libc.srand(ctypes.c_uint(seed))
        return notes

    def solve(self, T_target: Array, q0: Array) -> PeerAnswer:
        """``ets.ik_LM(T, q0, tol, joint_limits=True)``."""
        sol = self._ets.ik_LM(
            T_target,
            q0=q0,
            ilimit=self.ilimit,
            slimit=self.slimit,
            tol=self.tol,
            joint_limits=True,
        )
        return PeerAnswer(np.asarray(sol.q, dtype=float), int(sol.iterations))


def _random_q(robot: optik.Robot, rng: np.random.Generator) -> Array:
    lower = np.where(np.isfinite(robot.lower), robot.lower, -math.pi)
    upper = np.where(np.isfinite(robot.upper), robot.upper, math.pi)
    return rng.uniform(lower, upper)


@dataclass
class IKPy(Peer):
    """ikpy: ``chain.inverse_kinematics_frame`` (scipy least squares, bounds = limits)."""

    restarts: int = 10
    tol: float = 1e-12

    def prepare(self, key: str, robot: optik.Robot, workdir: Path, seed: int) -> list[str]:
        """Read the URDF into an ikpy chain and check its FK."""
        from ikpy.chain import Chain

        path, base, _, origin = urdf_for(key, robot, workdir)
        mask = [False] + [True] * robot.dof + [False]
        self._chain = Chain.from_urdf_file(
            str(path), base_elements=[base], active_links_mask=mask, name=key
        )
        if len(self._chain.links) != robot.dof + 2:
            raise PeerUnavailable(f"ikpy chain has {len(self._chain.links)} links")
        mismatch = fk_mismatch(lambda q: self._chain.forward_kinematics(self._full(q)), robot)
        if mismatch > FK_MATCH_TOL:
            raise PeerUnavailable(f"ikpy FK differs from optik by {mismatch:.2e}")
        self._robot = robot
        self._rng = np.random.default_rng(seed)
        return [f"ikpy chain from {origin}: FK = optik FK (max diff {mismatch:.1e})"]

    @staticmethod
    def _full(q: Array) -> Array:
        return np.concatenate([[0.0], q, [0.0]])

    def solve(self, T_target: Array, q0: Array) -> PeerAnswer:
        """From ``q0``, then seeded random restarts until ikpy's FK meets the tolerance."""
        start, best, best_err = q0, None, math.inf
        for _ in range(self.restarts + 1):
            full = self._chain.inverse_kinematics_frame(
                T_target, initial_position=self._full(start), orientation_mode="all", tol=self.tol
            )
            q = np.asarray(full[1:-1], dtype=float)
            err = sum(pose_error(self._chain.forward_kinematics(full), T_target))
            if err < best_err:
                best, best_err = q, err
            if err < 1e-6:
                break
            start = _random_q(self._robot, self._rng)
        return PeerAnswer(best, None)


@dataclass
class Pink(Peer):
    """pink: differential IK (one QP per step, ``dt = 1``) iterated to convergence."""

    qp_solver: str = "daqp"
    max_iter: int = 100
    restarts: int = 10
    tol: float = 1e-6
    limit_gain: float = 0.5

    def prepare(self, key: str, robot: optik.Robot, workdir: Path, seed: int) -> list[str]:
        """Build the Pinocchio model from the URDF and check its FK."""
        import pinocchio as pin
        import qpsolvers
        from pink.limits import ConfigurationLimit
        from pink.tasks import FrameTask

        if self.qp_solver not in qpsolvers.available_solvers:
            raise PeerUnavailable(
                f"QP solver {self.qp_solver!r} not installed (have {qpsolvers.available_solvers})"
            )
        path, _, tool, origin = urdf_for(key, robot, workdir)
        model = pin.buildModelFromUrdf(str(path))
        if model.nq != robot.dof:
            raise PeerUnavailable(f"Pinocchio model has nq={model.nq}, optik dof={robot.dof}")
        data = model.createData()
        frame_id = model.getFrameId(tool)

        def fk(q: Array) -> Array:
            pin.framesForwardKinematics(model, data, q)
            return data.oMf[frame_id].homogeneous

        mismatch = fk_mismatch(fk, robot)
        if mismatch > FK_MATCH_TOL:
            raise PeerUnavailable(f"Pinocchio FK differs from optik by {mismatch:.2e}")
        self._model, self._data, self._tool = model, data, tool
        self._limits = [ConfigurationLimit(model, config_limit_gain=self.limit_gain)]
        self._task = FrameTask(tool, position_cost=1.0, orientation_cost=1.0, gain=1.0)
        self._robot = robot
        self._rng = np.random.default_rng(seed)
        return [f"Pinocchio model from {origin}: FK = optik FK (max diff {mismatch:.1e})"]

    def solve(self, T_target: Array, q0: Array) -> PeerAnswer:
        """Iterate ``q += solve_ik(...)`` from ``q0``, then from seeded random restarts."""
        import pink
        import pinocchio as pin

        self._task.set_target(pin.SE3(T_target[:3, :3].copy(), T_target[:3, 3].copy()))
        start, best, best_err, iterations, note = q0, None, math.inf, 0, ""
        for _ in range(self.restarts + 1):
            config = pink.Configuration(self._model, self._data, start.copy())
            for _ in range(self.max_iter):
                T = config.get_transform_frame_to_world(self._tool).homogeneous
                position, angle = pose_error(T, T_target)
                if position < self.tol and angle < self.tol:
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
                except Exception as exc:  # a failed QP ends this attempt
                    note = f"{type(exc).__name__}: {exc}"[:80]
                    break
                config.integrate_inplace(v, 1.0)
                iterations += 1
            T = config.get_transform_frame_to_world(self._tool).homogeneous
            position, angle = pose_error(T, T_target)
            if position + angle < best_err:
                best, best_err = np.array(config.q, dtype=float), position + angle
            if position < self.tol and angle < self.tol:
                break
            start = _random_q(self._robot, self._rng)
        return PeerAnswer(best, iterations, note)


@dataclass
class EAIK(Peer):
    """EAIK closed form (standard DH); branches filtered by optik's limits."""

    def prepare(self, key: str, robot: optik.Robot, workdir: Path, seed: int) -> list[str]:
        """Build ``DhRobot(alpha, a, d)``; only zero θ offsets, no base or tool."""
        from eaik.IK_DH import DhRobot

        rows = robot.dh
        if rows is None or robot.convention != "dh":
            raise PeerUnavailable("EAIK's DH robots are standard DH; this robot is not")
        if any(r.kind != "revolute" or r.theta != 0.0 or r.mimic for r in rows) or not (
            np.allclose(robot.T_world_base, np.eye(4))
            and np.allclose(robot.T_flange_tool, np.eye(4))
        ):
            raise PeerUnavailable("EAIK adapter: theta offsets, base or tool not supported")
        bot = DhRobot(
            np.array([r.alpha for r in rows]),
            np.array([r.a for r in rows]),
            np.array([r.d for r in rows]),
        )
        if not bot.hasKnownDecomposition():
            raise PeerUnavailable(f"EAIK: no known decomposition for {robot.name}")
        mismatch = fk_mismatch(bot.fwdKin, robot)
        if mismatch > FK_MATCH_TOL:
            raise PeerUnavailable(f"EAIK FK differs from optik by {mismatch:.2e}")
        self._bot, self._robot = bot, robot
        return [f"EAIK {bot.getKinematicFamily()}: FK = optik FK (max diff {mismatch:.1e})"]

    def solve(self, T_target: Array, q0: Array) -> PeerAnswer:
        """All branches, wrapped into the limits; the one nearest ``q0``."""
        sol = self._bot.IK(T_target)
        best, best_dist = None, math.inf
        for q, least_squares in zip(sol.Q, sol.is_LS, strict=True):
            if least_squares:
                continue
            wrapped = wrap_into_limits(np.asarray(q), self._robot.lower, self._robot.upper, q0)
            if wrapped is None:
                continue
            dist = float(np.linalg.norm(wrapped - q0))
            if dist < best_dist:
                best, best_dist = wrapped, dist
        return PeerAnswer(best, None, "" if best is not None else "no exact branch in limits")


def make_peers(tol: float, restarts: int, pink_solver: str) -> list[Peer]:
    """The peers in report order, configured for the benchmark tolerance ``tol``."""
    rtb_tol = 0.5 * tol * tol
    return [
        RTBLM(
            "rtb ik_LM",
            "roboticstoolbox",
            "roboticstoolbox-python",
            settings=f"ETS.ik_LM C++, tol={rtb_tol:.0e} (=½·tol²), slimit=100, joint_limits",
            tol=rtb_tol,
        ),
        RTBLM(
            "rtb ik_LM tol=1e-6",
            "roboticstoolbox",
            "roboticstoolbox-python",
            settings="ETS.ik_LM C++, RTB default tol=1e-6 on ½‖e‖² (looser than 1e-6)",
            tol=1e-6,
        ),
        IKPy(
            "ikpy",
            "ikpy.chain",
            "ikpy",
            slow=True,
            settings=f"least_squares, bounds, tol=1e-12, {restarts} restarts",
            restarts=restarts,
        ),
        Pink(
            "pink",
            "pink",
            "pin-pink",
            slow=True,
            settings=f"{pink_solver}, dt=1, ConfigurationLimit(0.5), 100 it, {restarts} restarts",
            qp_solver=pink_solver,
            restarts=restarts,
            tol=tol,
        ),
        EAIK("eaik", "eaik.IK_DH", "eaik", settings="closed form, branches wrapped into limits"),
    ]
