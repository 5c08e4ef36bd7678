"""Kinematics-only URDF reading with the standard library.

optik needs only joints, their origins, axes and limits from a URDF, so it parses the
XML with :mod:`xml.etree.ElementTree` instead of depending on a full URDF stack (meshes,
collision geometry, trimesh). ``yourdfpy`` is an optional extra for users who want the
rest of the file; the tests compare both where it is installed.
"""

from __future__ import annotations

import difflib
import math
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

from optik._checks import MAX_LENGTH_M, FloatArray, not_a_file, read_number
from optik.chain import ChainLink
from optik.errors import URDFError
from optik.spatial import rpy_to_matrix, transform

_MOVING = {"revolute": "revolute", "continuous": "revolute", "prismatic": "prismatic"}
_REJECTED = {"floating", "planar"}


def _floats(text: str | None, count: int, what: str, default: tuple[float, ...]) -> FloatArray:
    if text is None:
        return np.array(default, dtype=float)
    try:
        # XML's (and urdfdom's) doubles have no digit grouping ("1_0").
        values = [read_number(v) for v in text.split()]
    except ValueError as exc:
        raise URDFError(f"{what}: cannot read numbers from {text!r}") from exc
    if len(values) != count or not all(math.isfinite(v) for v in values):
        numbers = "a finite number" if count == 1 else f"{count} finite numbers"
        raise URDFError(f"{what}: expected {numbers}, got {text!r}")
    return np.array(values)


def _origin(joint: ET.Element, jname: str) -> FloatArray:
    element = joint.find("origin")
    if element is None:
        return np.eye(4)
    xyz = _floats(element.get("xyz"), 3, f"joint {jname!r} origin xyz", (0.0, 0.0, 0.0))
    rpy = _floats(element.get("rpy"), 3, f"joint {jname!r} origin rpy", (0.0, 0.0, 0.0))
    if float(np.max(np.abs(xyz))) > MAX_LENGTH_M:
        raise URDFError(
            f"joint {jname!r} origin xyz: {element.get('xyz')!r} has a coordinate beyond "
            f"{MAX_LENGTH_M:g} m"
        )
    return transform(rpy_to_matrix(*rpy), xyz)


def _align_z(axis: FloatArray) -> FloatArray:
    """A 4x4 rotation taking the z axis onto the unit vector ``axis``."""
    z = np.array([0.0, 0.0, 1.0])
    c = float(z @ axis)
    v = np.cross(z, axis)
    s = float(np.linalg.norm(v))
    # Only an axis exactly along z is z: a tilt of 1e-6 rad moves a 1 m link by 1e-6 m,
    # the IK tolerance (a test on the cosine would round it away).
    if s == 0.0:
        return np.eye(4) if c > 0.0 else transform(np.diag([1.0, -1.0, -1.0]))
    k = v / s
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    one_minus_c = s * s / (1.0 + c) if c > 0.0 else 1.0 - c  # no cancellation near z
    R = np.eye(3) + s * K + one_minus_c * K @ K
    return transform(R)


def _is_file_path(source: object) -> bool:
    """Whether ``source`` names a URDF file (a string holding ``<`` is URDF text)."""
    return isinstance(source, Path) or (isinstance(source, str) and "<" not in source)


def _read_root(source: str | Path) -> ET.Element:
    text: str
    if isinstance(source, str) and not source.strip():
        raise URDFError("source: empty (expected a URDF path or XML text)")
    if _is_file_path(source):
        path = Path(source)
        try:
            found = path.is_file()
        except (OSError, ValueError) as exc:
            raise URDFError(f"{path}: cannot read the URDF file ({exc})") from exc
        if not found and not_a_file(path) == "file not found":
            raise URDFError(f"URDF file not found: {path}")
        if not found:
            raise URDFError(f"URDF path is a folder, not a file: {path}")
        try:
            text = path.read_text(encoding="utf-8")
        except UnicodeDecodeError as exc:
            raise URDFError(f"{path}: not a UTF-8 text file ({exc})") from exc
        except (OSError, ValueError) as exc:
            raise URDFError(f"{path}: cannot read the URDF file ({exc})") from exc
    elif isinstance(source, str):
        text = source
    else:
        raise URDFError(
            f"source: expected a URDF path or XML text, got {type(source).__name__} {source!r:.80}"
        )
    try:
        root = ET.fromstring(text)
    except ET.ParseError as exc:
        raise URDFError(f"URDF is not well-formed XML: {exc}") from exc
    if root.tag != "robot":
        raise URDFError(f"URDF root element is <{root.tag}>, expected <robot>")
    _check_names(root)
    return root


def _check_names(root: ET.Element) -> None:
    """Every ``<link>`` and ``<joint>`` named, and no name used twice by one kind."""
    for kind in ("link", "joint"):
        seen: set[str] = set()
        for index, element in enumerate(root.findall(kind)):
            name = element.get("name")
            if name is None or not name.strip():
                raise URDFError(f"<{kind}> number {index + 1} has no name")
            if name in seen:
                raise URDFError(f"two <{kind}> elements are named {name!r}")
            seen.add(name)


def _parent_joints(root: ET.Element) -> dict[str, ET.Element]:
    """The joint whose child each link is.

    A link with two parents, a self-loop or a cycle anywhere in the file is an error
    (a URDF describes a tree), whichever chain is asked for.
    """
    by_child: dict[str, ET.Element] = {}
    for joint in root.findall("joint"):
        jname = joint.get("name")
        child = joint.find("child")
        parent = joint.find("parent")
        if child is None or child.get("link") is None:
            raise URDFError(f"joint {jname!r} has no <child link=...>")
        if parent is None or parent.get("link") is None:
            raise URDFError(f"joint {jname!r} has no <parent link=...>")
        link = str(child.get("link"))
        if link == parent.get("link"):
            raise URDFError(f"joint {jname!r} connects link {link!r} to itself")
        if link in by_child:
            first = by_child[link].get("name")
            raise URDFError(
                f"link {link!r} has two parent joints, {first!r} and {jname!r}: "
                "a URDF describes a tree"
            )
        by_child[link] = joint
    parent_of = {child: str(j.find("parent").get("link")) for child, j in by_child.items()}  # type: ignore[union-attr]
    _check_acyclic(parent_of, by_child)
    return by_child


def _check_acyclic(parent_of: dict[str, str], by_child: dict[str, ET.Element]) -> None:
    """Raise on a cycle of parent links (each link visited once: linear in the links)."""
    done: set[str] = set()
    for start in parent_of:
        path: list[str] = []
        on_path: set[str] = set()
        link: str | None = start
        while link is not None and link not in done:
            if link in on_path:
                names = [str(by_child[x].get("name")) for x in path[path.index(link) :]]
                raise URDFError(f"the joints {names} form a cycle through link {link!r}")
            path.append(link)
            on_path.add(link)
            link = parent_of.get(link)
        done.update(path)


def _path_to(by_child: dict[str, ET.Element], base_link: str, tip_link: str) -> list[ET.Element]:
    """The joints from ``base_link`` to ``tip_link``, found by walking up from the tip.

    Every link has at most one parent joint and the tree has no cycle
    (:func:`_parent_joints`), so the walk is unique and ends.
    """
    path: list[ET.Element] = []
    link = tip_link
    while link != base_link:
        joint = by_child.get(link)
        if joint is None:
            raise URDFError(f"no kinematic path from {base_link!r} to {tip_link!r}")
        path.append(joint)
        link = str(joint.find("parent").get("link"))  # type: ignore[union-attr]
    path.reverse()
    return path


def _velocity(text: str | None, jname: str) -> float | None:
    """A joint's ``<limit velocity=...>`` (rad/s or m/s); ``None`` when absent or zero.

    The URDF schema defaults an omitted velocity to 0, which no joint could move with:
    it reads as "unknown", not as a limit.
    """
    if text is None:
        return None
    value = float(_floats(text, 1, f"joint {jname!r} velocity limit", (0.0,))[0])
    if value < 0:
        raise URDFError(f"joint {jname!r}: velocity limit {text!r} is negative")
    return value if value > 0 else None


def parse_urdf_chain(
    source: str | Path, base_link: str, tip_link: str
) -> tuple[str, list[ChainLink], FloatArray]:
    """Read the serial chain from ``base_link`` to ``tip_link``.

    Returns:
        The robot's name, the chain joints (fixed joints folded into the constant
        transform before the next moving joint; each with its ``<limit velocity>`` when
        stated), and the fixed 4x4 transform from the last moving joint's child link to
        ``tip_link``. Each moving joint's axis is aligned with z by a constant rotation
        before it and its inverse after it.

    Raises:
        URDFError: unreadable or non-UTF-8 file, unknown links, no path between the
            links, a link with two parent joints, a joint whose parent is its child, a
            cycle, a mimic, floating or planar joint on the path, a zero axis, missing
            limits, a negative velocity limit, or a length beyond
            :data:`~optik._checks.MAX_LENGTH_M`.
    """
    for what, value in (("base_link", base_link), ("tip_link", tip_link)):
        if not isinstance(value, str):
            raise URDFError(f"{what}: expected a link name, got {value!r}")
    try:
        return _chain(_read_root(source), base_link, tip_link)
    except URDFError as exc:
        # A file's errors name it (the read errors do already).
        if not _is_file_path(source) or str(source) in str(exc):
            raise
        raise URDFError(f"{source}: {exc}") from None


def _chain(
    root: ET.Element, base_link: str, tip_link: str
) -> tuple[str, list[ChainLink], FloatArray]:
    """:func:`parse_urdf_chain` of a parsed document."""
    links = {el.get("name") for el in root.findall("link")}
    for link in (base_link, tip_link):
        if link not in links:
            names = sorted(map(str, links))
            near = difflib.get_close_matches(link, names, n=1)
            hint = f"; did you mean {near[0]!r}?" if near else ""
            raise URDFError(f"link {link!r} not in the URDF{hint} (links: {names})")
    by_child = _parent_joints(root)
    try:
        path = _path_to(by_child, base_link, tip_link)
    except URDFError as no_path:
        try:
            _path_to(by_child, tip_link, base_link)
        except URDFError:
            raise no_path from None
        raise URDFError(
            f"no kinematic path from {base_link!r} to {tip_link!r}: {tip_link!r} is the "
            f"base side; swap them (base_link={tip_link!r}, tip_link={base_link!r})"
        ) from None

    chain: list[ChainLink] = []
    pending = np.eye(4)  # fixed transforms since the last moving joint
    for joint in path:
        jname = str(joint.get("name"))
        jtype = str(joint.get("type"))
        for end in ("parent", "child"):
            # As urdfdom: a joint's links are declared (the base and tip are, above).
            named = joint.find(end).get("link")  # type: ignore[union-attr]
            if named not in links:
                raise URDFError(f"joint {jname!r}: {end} link {named!r} is not declared")
        if jtype in _REJECTED:
            raise URDFError(f"joint {jname!r}: {jtype} joints are not supported in a chain")
        if joint.find("mimic") is not None:
            raise URDFError(f"joint {jname!r}: mimic joints are not supported in URDF input")
        origin = _origin(joint, jname)
        if jtype == "fixed":
            pending = pending @ origin
            if float(np.max(np.abs(pending[:3, 3]))) > MAX_LENGTH_M:  # ten 9e8 m offsets
                raise URDFError(
                    f"joint {jname!r}: the fixed joints up to it place the next frame "
                    f"beyond {MAX_LENGTH_M:g} m"
                )
            continue
        if jtype not in _MOVING:
            raise URDFError(f"joint {jname!r}: unknown joint type {jtype!r}")
        axis_el = joint.find("axis")
        axis = _floats(
            axis_el.get("xyz") if axis_el is not None else None,
            3,
            f"joint {jname!r} axis",
            (1.0, 0.0, 0.0),
        )
        # Scale by the largest entry first: the norm of (1e300, 1e300, 0) would overflow.
        largest = float(np.max(np.abs(axis)))
        if largest == 0.0:
            raise URDFError(f"joint {jname!r}: axis is zero")
        axis = axis / largest
        align = _align_z(axis / float(np.linalg.norm(axis)))
        lower = upper = None
        continuous = jtype == "continuous"
        if not continuous:
            limit = joint.find("limit")
            if limit is None or limit.get("lower") is None or limit.get("upper") is None:
                raise URDFError(f"joint {jname!r}: a {jtype} joint needs <limit lower upper>")
            lower = float(_floats(limit.get("lower"), 1, f"joint {jname!r} lower", (0.0,))[0])
            upper = float(_floats(limit.get("upper"), 1, f"joint {jname!r} upper", (0.0,))[0])
            if jtype == "prismatic" and max(abs(lower), abs(upper)) > MAX_LENGTH_M:
                raise URDFError(
                    f"joint {jname!r}: prismatic range [{lower:g}, {upper:g}] m goes beyond "
                    f"{MAX_LENGTH_M:g} m"
                )
            # Checked here rather than by the robot, so that the message names the file
            # and the element, and says what a URDF can do about it.
            if lower > upper:
                free = ' (a joint without limits is type="continuous")'
                hint = free if jtype == "revolute" else ""
                raise URDFError(
                    f"joint {jname!r}: <limit lower={lower:g} upper={upper:g}>: lower is above "
                    f"upper{hint}"
                )
            if jtype == "revolute" and max(abs(lower), abs(upper)) > MAX_LENGTH_M:
                raise URDFError(
                    f"joint {jname!r}: <limit lower={lower:g} upper={upper:g}>: a revolute "
                    f'range must lie within +-{MAX_LENGTH_M:g} rad (type="continuous" for '
                    "a joint without limits)"
                )
        before = pending @ origin @ align
        limit = joint.find("limit")
        velocity = None if limit is None else _velocity(limit.get("velocity"), jname)
        chain.append(
            ChainLink(
                name=jname,
                kind=_MOVING[jtype],  # type: ignore[arg-type]
                before=before,
                after=align.T.copy(),
                offset=0.0,
                lower=lower,
                upper=upper,
                continuous=continuous,
                velocity=velocity,
            )
        )
        pending = np.eye(4)
    if not chain:
        raise URDFError(f"no moving joint between {base_link!r} and {tip_link!r}")
    return str(root.get("name") or "robot"), chain, pending
