"""Plain-text descriptions of a robot: a URDF's links and chains, joints, closed form.

``optik robot FILE`` prints these; they are plain functions so that a script can print
the same thing. Units: revolute values in rad (degrees shown next to them), prismatic
values in m.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

from optik.analytic import family_of, free_joint_reason
from optik.errors import URDFError
from optik.model import Robot
from optik.urdf import _parent_joints, _read_root

__all__ = ["UrdfChain", "UrdfTree", "joints_text", "read_urdf_tree", "robot_text"]


@dataclass(frozen=True)
class UrdfChain:
    """A root-to-leaf chain of a URDF: ``base`` link, ``tip`` link and its joints."""

    base: str
    tip: str
    joints: tuple[str, ...]
    moving: int

    def text(self) -> str:
        """``base -> tip  (N moving joints)``."""
        noun = "moving joint" if self.moving == 1 else "moving joints"
        return f"{self.base} -> {self.tip}  ({self.moving} {noun}, {len(self.joints)} in all)"


@dataclass(frozen=True)
class UrdfTree:
    """A URDF's name, its links (in file order) and its root-to-leaf chains."""

    name: str
    links: tuple[str, ...]
    chains: tuple[UrdfChain, ...]


def read_urdf_tree(source: str | Path) -> UrdfTree:
    """The links and every root-to-leaf chain of a URDF file.

    Args:
        source: path of the URDF file.

    Raises:
        URDFError: unreadable, non-UTF-8 or malformed file, a link with two parents, a
            self-loop or a cycle.
    """
    root = _read_root(Path(source))
    links = tuple(str(el.get("name")) for el in root.findall("link"))
    by_child = _parent_joints(root)
    parent_of = {child: str(j.find("parent").get("link")) for child, j in by_child.items()}  # type: ignore[union-attr]
    parents = set(parent_of.values())
    chains = []
    for leaf in links:
        if leaf in parents:
            continue
        joints: list[str] = []
        moving = 0
        seen = {leaf}
        link = leaf
        while link in by_child:
            joint = by_child[link]
            joints.append(str(joint.get("name")))
            moving += joint.get("type") != "fixed"
            link = str(joint.find("parent").get("link"))  # type: ignore[union-attr]
            if link in seen:
                raise URDFError(f"the joints {joints[::-1]} form a cycle through link {link!r}")
            seen.add(link)
        if joints:
            chains.append(UrdfChain(link, leaf, tuple(reversed(joints)), moving))
    return UrdfTree(str(root.get("name") or Path(source).stem), links, tuple(chains))


def _limit(value: float, kind: str) -> str:
    if kind == "prismatic":
        return f"{value:.6g} m"
    return f"{value:.6g} rad ({math.degrees(value):.4g} deg)"


def joints_text(robot: Robot) -> str:
    """One line per joint coordinate (``q`` order): name, type, limits with their units."""
    lines = []
    width = max((len(j.name) for j in robot.joints), default=4) + 2
    for i, joint in enumerate(robot.joints):
        if not math.isfinite(joint.lower) and not math.isfinite(joint.upper):
            limits = "continuous (no limits)"
        else:
            limits = f"{_limit(joint.lower, joint.kind)} .. {_limit(joint.upper, joint.kind)}"
        lines.append(f"  {i:>2} {joint.name:<{width}}{joint.kind:<11}{limits}")
    return "\n".join(lines)


def robot_text(robot: Robot) -> str:
    """The joints and the closed-form family of a robot (see :func:`joints_text`).

    A seven-joint arm without a family gets one more line: the joints around which, held
    (``frozen`` in :func:`optik.solve_ik`), the six others have a closed form.
    """
    family = family_of(robot)
    lines = [
        f"joints ({robot.dof}; q order; revolute in rad, prismatic in m):",
        joints_text(robot),
        f"closed-form family: {family.name if family else 'none (numeric solvers)'}",
    ]
    if family is None and robot.dof == 7:
        held = [name for name in robot.joint_names if not free_joint_reason(robot, name)]
        lines.append(f"closed form with one joint frozen: {', '.join(held) or 'none'}")
    return "\n".join(lines)
