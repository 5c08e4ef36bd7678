"""Plain-text descriptions of a robot: a URDF's links and chains, joints, closed form.

``optik robot FILE`` prints these; they are plain functions so that a script can print
the same thing. Units: revolute values in rad (degrees shown next to them), prismatic
values in m.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

from optik.analytic import family_of, free_joint_reason, match_families
from optik.errors import URDFError
from optik.model import Robot
from optik.urdf import _parent_joints, _read_root

__all__ = ["UrdfChain", "UrdfTree", "joints_text", "read_urdf_tree", "robot_text"]


@dataclass(frozen=True)
class UrdfChain:
    """A root-to-leaf chain of a URDF.

    ``base`` and ``tip`` links, its number of joints (``joints``) and of moving (not
    fixed) ones.
    """

    base: str
    tip: str
    joints: int
    moving: int

    def text(self) -> str:
        """``base -> tip  (N moving joints)``."""
        noun = "moving joint" if self.moving == 1 else "moving joints"
        return f"{self.base} -> {self.tip}  ({self.moving} {noun}, {self.joints} in all)"


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
            self-loop or a cycle; the message names the file.
    """
    try:
        return _tree(Path(source))
    except URDFError as exc:
        if str(source) in str(exc):  # the read errors name it already
            raise
        raise URDFError(f"{source}: {exc}") from None


def _tree(source: Path) -> UrdfTree:
    """:func:`read_urdf_tree` of a file, its errors not yet naming it."""
    root = _read_root(source)
    links = tuple(str(el.get("name")) for el in root.findall("link"))
    by_child = _parent_joints(root)
    parent_of = {child: str(j.find("parent").get("link")) for child, j in by_child.items()}  # type: ignore[union-attr]
    parents = set(parent_of.values())
    # (root, joints, moving joints) above each link, each link walked once: a leaf's
    # walk stops at the first link already known (a comb of n leaves is linear, not n^2).
    above: dict[str, tuple[str, int, int]] = {}
    chains = []
    for leaf in links:
        if leaf in parents:
            continue
        path: list[str] = []
        on_path = {leaf}
        link = leaf
        while link in by_child and link not in above:
            path.append(link)
            link = parent_of[link]
            if link in on_path:
                names = [str(by_child[k].get("name")) for k in path]
                raise URDFError(f"the joints {names[::-1]} form a cycle through link {link!r}")
            on_path.add(link)
        root_link, count, moving = above.get(link, (link, 0, 0))
        for child in reversed(path):
            count += 1
            moving += by_child[child].get("type") != "fixed"
            above[child] = (root_link, count, moving)
        if count:
            chains.append(UrdfChain(root_link, leaf, count, moving))
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

    An arm of at most six joints without a family gets one line per registered family:
    why it does not fit (:func:`optik.analytic.match_families`). A seven-joint arm
    without a family gets one more line: the joints around which, held (``frozen`` in
    :func:`optik.solve_ik`), the six others have a closed form.
    """
    family = family_of(robot)
    lines = [
        f"joints ({robot.dof}; q order; revolute in rad, prismatic in m):",
        joints_text(robot),
        f"closed-form family: {family.name if family else 'none (numeric solvers)'}",
    ]
    if family is None and robot.dof <= 6:
        # Why each family declines (for seven joints and more: they take at most six).
        lines += [f"  {m.family}: {m.reason}" for m in match_families(robot)]
    if family is None and robot.dof == 7:
        held = [name for name in robot.joint_names if not free_joint_reason(robot, name)]
        lines.append(f"closed form with one joint frozen: {', '.join(held) or 'none'}")
    return "\n".join(lines)
