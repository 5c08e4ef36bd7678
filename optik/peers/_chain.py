"""optik's kinematic chain in the forms peers read: constant transforms and a URDF.

Every optik robot, DH or URDF, is the product ``fk(q) = K_0 M_1(q_1) K_1 ... M_n(q_n) K_n``
of constant transforms ``K_i`` (world frame first, tool last) and joint motions ``M_i``
(a rotation about z, or a translation along z). :func:`chain_of` reads that product from
:attr:`optik.Robot.chain`; :func:`urdf_text` writes it as a kinematics-only URDF (links
``base``, ``link1`` .. ``linkN``, ``tool``), so peers that read URDF model exactly
optik's robot, whatever it was built from.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from optik._checks import FloatArray
from optik.model import Robot
from optik.peers._base import PeerUnavailable

__all__ = ["ChainSpec", "chain_of", "urdf_text", "write_urdf"]

#: Link names of the written URDF: root and tool.
ROOT_LINK = "base"
TOOL_LINK = "tool"


@dataclass(frozen=True)
class ChainSpec:
    """optik's chain as constant transforms and z-axis joints.

    Attributes:
        origins: (n + 1, 4, 4) the constant transforms ``K_0 .. K_n`` (m).
        prismatic: (n,) whether each joint translates along z (else rotates about z).
        names: the joint names.
        lower: (n,) lower limits, rad or m (``-inf`` for a continuous joint).
        upper: (n,) upper limits.
    """

    origins: FloatArray
    prismatic: np.ndarray
    names: tuple[str, ...]
    lower: FloatArray
    upper: FloatArray

    @property
    def dof(self) -> int:
        """Number of joints."""
        return int(self.prismatic.shape[0])

    def fk(self, q: FloatArray) -> FloatArray:
        """``K_0 M_1(q_1) K_1 ... M_n(q_n) K_n``, (4, 4) (an independent product)."""
        T = self.origins[0].copy()
        for i, value in enumerate(q):
            M = np.eye(4)
            if self.prismatic[i]:
                M[2, 3] = value
            else:
                c, s = math.cos(value), math.sin(value)
                M[:2, :2] = ((c, -s), (s, c))
            T = T @ M @ self.origins[i + 1]
        return T


def chain_of(robot: Robot, peer: str) -> ChainSpec:
    """The chain of ``robot`` as :class:`ChainSpec`.

    Args:
        robot: the robot.
        peer: the asking peer's name (for the error).

    Raises:
        PeerUnavailable: the robot has mimic (coupled) joints, which the peers' models
            lack.
    """
    chain = robot.chain
    if not chain.identity:
        raise PeerUnavailable(
            peer, f"{robot.name} has mimic (coupled) joints; the adapter models none"
        )
    return ChainSpec(
        origins=np.array(chain.K),
        prismatic=np.array(chain.prismatic, dtype=bool),
        names=robot.joint_names,
        lower=np.array(robot.lower),
        upper=np.array(robot.upper),
    )


def _rpy(R: FloatArray) -> tuple[float, float, float]:
    """URDF roll, pitch, yaw of ``R = Rz(yaw) Ry(pitch) Rx(roll)``, robust at gimbal lock."""
    cos_pitch = math.hypot(R[0, 0], R[1, 0])
    pitch = math.atan2(-R[2, 0], cos_pitch)
    if cos_pitch < 1e-12:  # pitch = ±90°: roll and yaw share one axis
        return math.atan2(-R[1, 2], R[1, 1]), pitch, 0.0
    return math.atan2(R[2, 1], R[2, 2]), pitch, math.atan2(R[1, 0], R[0, 0])


def _origin(T: FloatArray) -> str:
    r, p, y = _rpy(T[:3, :3])
    xyz = " ".join(repr(float(v)) for v in T[:3, 3])
    return f'<origin xyz="{xyz}" rpy="{r!r} {p!r} {y!r}"/>'


def _link(name: str) -> list[str]:
    # A small inertia at the link frame: simulators (pybullet) then put the link's centre
    # of mass on its frame, and nothing else in the file depends on it.
    return [
        f'  <link name="{name}">',
        "    <inertial>",
        '      <origin xyz="0 0 0" rpy="0 0 0"/>',
        '      <mass value="1.0"/>',
        '      <inertia ixx="0.001" ixy="0" ixz="0" iyy="0.001" iyz="0" izz="0.001"/>',
        "    </inertial>",
        "  </link>",
    ]


def urdf_text(robot: Robot, peer: str) -> str:
    """A kinematics-only URDF of ``robot``'s chain (root ``base``, tool link ``tool``).

    The root link is the world frame; joint ``i`` sits at ``K_{i-1}`` after the previous
    joint's motion, with axis z; the fixed joint ``tool_joint`` places ``tool`` at ``K_n``.
    A joint without limits is ``continuous``; joint ``i`` is named ``joint<i>`` (optik's
    names may hold characters that XML names cannot).

    Raises:
        PeerUnavailable: mimic joints (see :func:`chain_of`).
    """
    spec = chain_of(robot, peer)
    links = [ROOT_LINK, *(f"link{i + 1}" for i in range(spec.dof)), TOOL_LINK]
    lines = ['<?xml version="1.0"?>', f'<robot name="{_xml_name(robot.name)}">']
    for name in links:
        lines += _link(name)
    for i in range(spec.dof):
        lo, hi = float(spec.lower[i]), float(spec.upper[i])
        kind = "prismatic" if spec.prismatic[i] else "revolute"
        if not (math.isfinite(lo) and math.isfinite(hi)):
            kind = "continuous"
        lines += [
            f'  <joint name="joint{i + 1}" type="{kind}">',
            f'    <parent link="{links[i]}"/>',
            f'    <child link="{links[i + 1]}"/>',
            f"    {_origin(spec.origins[i])}",
            '    <axis xyz="0 0 1"/>',
        ]
        if kind != "continuous":
            lines.append(f'    <limit lower="{lo!r}" upper="{hi!r}" effort="100" velocity="100"/>')
        lines.append("  </joint>")
    lines += [
        '  <joint name="tool_joint" type="fixed">',
        f'    <parent link="{links[-2]}"/>',
        f'    <child link="{TOOL_LINK}"/>',
        f"    {_origin(spec.origins[-1])}",
        "  </joint>",
        "</robot>",
    ]
    return "\n".join(lines) + "\n"


def _xml_name(name: str) -> str:
    """A name safe inside an XML attribute (the robot's names come from user files)."""
    return "".join(c if c.isalnum() or c in "_-." else "_" for c in name) or "unnamed"


def write_urdf(robot: Robot, folder: Path, peer: str) -> Path:
    """Write :func:`urdf_text` to ``folder/<name>.urdf``; returns the path."""
    path = folder / f"{_xml_name(robot.name)}.urdf"
    path.write_text(urdf_text(robot, peer), encoding="utf-8")
    return path
