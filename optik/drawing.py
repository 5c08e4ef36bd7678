"""Pictures of the robot in 3-D (matplotlib, the ``report`` extra).

The arm is drawn from :meth:`optik.Robot.frames`: links as a polyline through the joint
origins in chain order, each joint's axis as a short arrow (a revolute joint turns about
it, a prismatic joint slides along it), the base and tool frames as RGB triads (x red,
y green, z blue), and, for a URDF robot whose visual meshes load offline, the meshes.
:func:`draw_robot` draws into a given 3-D axes; :func:`robot_figure` builds a figure;
:func:`show_robot` writes it as an image (``optik show``);
:func:`optik.reachability.reachability_figure` draws the arm over a reachability slice.
"""

from __future__ import annotations

import logging
import warnings
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from optik._checks import MAX_LENGTH_M, FloatArray
from optik._files import output_path, write_atomic_with
from optik._pyplot import pyplot
from optik.errors import OptikError
from optik.model import Robot
from optik.spatial import invert_transform

__all__ = [
    "ArmGeometry",
    "MeshWarning",
    "arm_geometry",
    "draw_robot",
    "extent_points",
    "joint_frames",
    "link_points",
    "robot_figure",
    "set_equal_3d",
    "show_robot",
    "visual_meshes",
]

_TRIAD_COLOURS = ("tab:red", "tab:green", "tab:blue")


@dataclass(frozen=True)
class ArmGeometry:
    """What a drawing of the arm at one configuration shows (world frame, m).

    Attributes:
        points: (K, 3) the link polyline: frame 0, each joint's origin and link frame (in
            chain order, repeats dropped), then the tool.
        axis_origins: (n, 3) a point on each chain joint's axis.
        axis_directions: (n, 3) unit direction of each chain joint's axis.
        prismatic: (n,) whether each chain joint slides.
        T_base: 4x4 frame 0.
        T_tool: 4x4 tool frame.
        scale: a length for arrows and triads: a tenth of the arm's extent (m).
    """

    points: FloatArray
    axis_origins: FloatArray
    axis_directions: FloatArray
    prismatic: np.ndarray
    T_base: FloatArray
    T_tool: FloatArray
    scale: float


def joint_frames(robot: Robot, frames: FloatArray) -> FloatArray:
    """(n, 4, 4) world frames of the chain joints, z along each joint's axis.

    Link frame ``i + 1`` is the frame after motion ``i`` times the constant link offset
    ``E[i]`` (:class:`optik.chain.Chain`); undoing ``E[i]`` gives the moved joint frame,
    whose z axis is the axis (a rotation about z or a translation along it keeps it).

    Args:
        robot: the robot.
        frames: ``robot.frames(q)``, every frame 0..n and the tool (world frame, m).
    """
    return frames[1:-1] @ invert_transform(robot.chain.E)


def link_points(frames: FloatArray, joints: FloatArray) -> FloatArray:
    """(K, 3) the link polyline: frame 0, each joint's origin and link frame, the tool (m).

    Args:
        frames: ``robot.frames(q)`` (n + 2, 4, 4).
        joints: :func:`joint_frames` of those frames (n, 4, 4).

    Consecutive repeats (a joint at its link frame's origin) are dropped.
    """
    ordered = [frames[0, :3, 3]]
    for i in range(len(joints)):
        ordered += [joints[i, :3, 3], frames[i + 1, :3, 3]]
    ordered.append(frames[-1, :3, 3])
    points = [ordered[0]]
    for p in ordered[1:]:
        if np.linalg.norm(p - points[-1]) > 1e-9:
            points.append(p)
    return np.array(points)


def arm_geometry(robot: Robot, q: Any) -> ArmGeometry:
    """The links, joint axes and frames of ``robot`` at ``q`` (dof,) rad or m.

    Args:
        robot: the robot.
        q: one configuration (dof,), rad or m.
    """
    F = robot.frames(q)
    motion = joint_frames(robot, F)
    P = link_points(F, motion)
    extent = float(np.max(np.ptp(P, axis=0))) if len(P) > 1 else 0.0
    return ArmGeometry(
        points=P,
        axis_origins=motion[:, :3, 3].copy(),
        axis_directions=motion[:, :3, 2].copy(),
        prismatic=np.asarray(robot.chain.prismatic).copy(),
        T_base=F[0].copy(),
        T_tool=F[-1].copy(),
        scale=max(0.1 * extent, 0.02),
    )


def _triad(ax: Any, T: FloatArray, length: float, alpha: float) -> None:
    for k, colour in enumerate(_TRIAD_COLOURS):
        d = T[:3, k] * length
        ax.quiver(
            *T[:3, 3], *d, color=colour, lw=1.8, alpha=alpha, arrow_length_ratio=0.25, zorder=5
        )


def draw_robot(
    ax: Any,
    robot: Robot,
    q: Any,
    *,
    colour: str = "tab:blue",
    alpha: float = 1.0,
    joint_axes: bool = True,
    frames: bool = True,
    meshes: Sequence[tuple[FloatArray, FloatArray]] = (),
    label: str | None = None,
    scale: float | None = None,
) -> ArmGeometry:
    """Draw the arm at ``q`` into a 3-D matplotlib axes.

    Args:
        ax: a ``projection="3d"`` axes.
        robot: the robot.
        q: (dof,) joint values, rad or m.
        colour: colour of the links.
        alpha: opacity of everything drawn.
        joint_axes: draw each joint's axis as an arrow (black: revolute; purple:
            prismatic, as in the viewer).
        frames: draw the base and tool frames as RGB triads.
        meshes: ``(vertices (V, 3), faces (F, 3))`` world-frame triangle meshes to draw
            under the links (see :func:`visual_meshes`).
        label: legend label of the links.
        scale: arrow and triad length (m); default a tenth of the arm's extent.

    Returns:
        The :class:`ArmGeometry` drawn.
    """
    g = arm_geometry(robot, q)
    length = g.scale if scale is None else scale
    if meshes:
        from mpl_toolkits.mplot3d.art3d import Poly3DCollection

        # Depth sorting of the meshes' polygons would hide the links inside them: draw the
        # meshes first and everything else above them.
        ax.computed_zorder = False

        for vertices, faces in meshes:
            triangles = vertices[faces]
            ax.add_collection3d(
                Poly3DCollection(
                    triangles, facecolors=_shaded(triangles, 0.45 * alpha), edgecolors="none"
                )
            )
    P = g.points
    ax.plot(
        P[:, 0], P[:, 1], P[:, 2], "-", color=colour, lw=3.2, alpha=alpha, label=label, zorder=3
    )
    ax.scatter(
        P[:, 0], P[:, 1], P[:, 2], color=colour, s=22, alpha=alpha, depthshade=False, zorder=4
    )
    if joint_axes:
        for origin, direction, slides in zip(
            g.axis_origins, g.axis_directions, g.prismatic, strict=True
        ):
            start = origin - 0.5 * length * direction
            ax.quiver(
                *start,
                *(length * direction),
                color="tab:purple" if slides else "black",
                lw=1.3,
                alpha=alpha,
                arrow_length_ratio=0.3,
                zorder=5,
            )
    if frames:
        _triad(ax, g.T_base, 1.3 * length, alpha)
        _triad(ax, g.T_tool, length, alpha)
    return g


def _shaded(triangles: FloatArray, alpha: float) -> FloatArray:
    """Grey face colours (F, 4) lit from above and in front (flat shading, no library)."""
    normals = np.cross(triangles[:, 1] - triangles[:, 0], triangles[:, 2] - triangles[:, 0])
    norms = np.linalg.norm(normals, axis=1, keepdims=True)
    normals = normals / np.where(norms > 0, norms, 1.0)
    light = np.array([0.4, -0.5, 0.77]) / np.linalg.norm([0.4, -0.5, 0.77])
    level = 0.45 + 0.4 * np.abs(normals @ light)
    colours = np.empty((len(triangles), 4))
    colours[:, :3] = level[:, None] * np.array([0.85, 0.87, 0.92])
    colours[:, 3] = alpha
    return colours


def set_equal_3d(ax: Any, points: FloatArray, margin: float = 0.08) -> None:
    """Equal scales on x, y, z around ``points`` (K, 3), so that the arm is not distorted."""
    lo, hi = points.min(axis=0), points.max(axis=0)
    centre = 0.5 * (lo + hi)
    half = 0.5 * float(np.max(hi - lo)) * (1.0 + 2.0 * margin) or 0.1
    ax.set_xlim(centre[0] - half, centre[0] + half)
    ax.set_ylim(centre[1] - half, centre[1] + half)
    ax.set_zlim(centre[2] - half, centre[2] + half)
    ax.set_box_aspect((1.0, 1.0, 1.0))
    from matplotlib.ticker import MaxNLocator

    for axis in (ax.xaxis, ax.yaxis, ax.zaxis):
        # Five ticks at most: a 3-D axis's labels run into each other beyond that.
        axis.set_major_locator(MaxNLocator(5))
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_zlabel("z (m)")


def extent_points(g: ArmGeometry) -> FloatArray:
    """Points (K, 3) that a drawing of ``g`` reaches: links, arrow tips, the base triad."""
    tips = g.axis_origins + 0.5 * g.scale * g.axis_directions
    return np.concatenate(
        [g.points, tips, g.T_base[None, :3, 3] + 1.3 * g.scale * g.T_base[:3, :3].T]
    )


def robot_figure(
    robot: Robot,
    q: Any = None,
    *,
    title: str | None = None,
    meshes: Sequence[tuple[FloatArray, FloatArray]] = (),
    view: tuple[float, float] = (22.0, -58.0),
    size: tuple[float, float] = (6.0, 6.0),
) -> tuple[Any, Any]:
    """A figure with the arm at ``q`` (default: mid-limits); returns ``(figure, axes)``.

    Args:
        robot: the robot.
        q: (dof,) joint values, rad or m.
        title: the figure's title (default: the robot's name and ``q``).
        meshes: world-frame triangle meshes to draw with it (:func:`visual_meshes`).
        view: elevation and azimuth of the camera, deg.
        size: figure size, inches.

    Raises:
        OptikError: a bad ``q``.
    """
    plt = pyplot()
    q = robot.mid_limits if q is None else robot.check_q(q, "q")
    if q.ndim != 1:
        raise OptikError(f"q: expected one configuration ({robot.dof},), got {q.shape}")
    fig = plt.figure(figsize=size)
    ax = fig.add_subplot(projection="3d")
    g = draw_robot(ax, robot, q, meshes=meshes)
    extent = [extent_points(g)] + [v for v, _ in meshes]
    set_equal_3d(ax, np.concatenate(extent))
    ax.view_init(elev=view[0], azim=view[1])
    values = ", ".join(f"{v:.3g}" for v in q)
    default = f"{robot.name} at q = ({values}) rad or m"
    ax.set_title(default if title is None else title, fontsize=10)
    fig.tight_layout()
    return fig, ax


def show_robot(
    robot: Robot,
    path: str | Path,
    q: Any = None,
    *,
    title: str | None = None,
    meshes: Sequence[tuple[FloatArray, FloatArray]] = (),
    view: tuple[float, float] = (22.0, -58.0),
    dpi: float = 110.0,
) -> Path:
    """Write a picture of the arm at ``q`` (default: mid-limits) to ``path`` (PNG, SVG, PDF).

    Written whole or not at all; drawn by :func:`robot_figure`.

    Args:
        robot: the robot.
        path: the image file to write; its suffix (``.png``, ``.svg``, ``.pdf``) picks the
            format.
        q: (dof,) joint values, rad or m (default: mid-limits).
        title: the figure's title (default: the robot's name and ``q``).
        meshes: world-frame triangle meshes to draw with it (:func:`visual_meshes`).
        view: elevation and azimuth of the camera, deg.
        dpi: resolution, dots per inch.
    """
    target = output_path(path)
    fig, _ = robot_figure(robot, q, title=title, meshes=meshes, view=view)
    return save_figure(fig, target, dpi)


def save_figure(fig: Any, path: str | Path, dpi: float = 110.0) -> Path:
    """Save ``fig`` to ``path`` whole or not at all (format from the suffix) and close it.

    Raises:
        OptikError: a suffix matplotlib cannot write (the message lists those it can).
        OutputFileError: the file cannot be written.
    """
    try:
        path = output_path(path)
        suffix = path.suffix.lower().lstrip(".")
        formats = fig.canvas.get_supported_filetypes()
        if suffix not in formats:
            raise OptikError(
                f"{path}: cannot write {suffix!r} images (formats: {', '.join(formats)})"
            )
        fig.set_dpi(dpi)
        return write_atomic_with(
            path, lambda handle: fig.savefig(handle, format=suffix, dpi=dpi), binary=True
        )
    finally:
        pyplot().close(fig)


# ------------------------------------------------------------------------ meshes
MESH_FACES = 1500
"""A visual mesh with more triangles is drawn as its convex hull (matplotlib draws every
triangle as one polygon, so a detailed mesh would take minutes)."""


def _package_handler(urdf: Path) -> Any:
    """Resolve ``package://NAME/rest`` against the folders above the URDF (offline)."""

    def handler(fname: str) -> str:
        name = fname
        if not name.startswith("package://"):
            return name if Path(name).is_absolute() else str(urdf.parent / name)
        package, _, rest = name[len("package://") :].partition("/")
        for parent in urdf.resolve().parents:
            if parent.name == package:
                return str(parent / rest)
            if (parent / package).is_dir():
                return str(parent / package / rest)
        return name

    return handler


def visual_meshes(
    urdf: str | Path, robot: Robot, q: Any, base_link: str
) -> list[tuple[FloatArray, FloatArray]]:
    """The URDF's visual meshes at ``q``, in the robot's world frame (``base_link``).

    Loaded with yourdfpy and trimesh (the ``urdf`` extra), offline: ``package://`` names
    resolve against the folders above the file. Every link below ``base_link`` is drawn,
    its joints off the chain at 0; a mesh of more than :data:`MESH_FACES` triangles as its
    convex hull. The link poses yourdfpy computes are checked against optik's FK.

    Args:
        urdf: the URDF file the robot was read from.
        robot: the robot.
        q: one configuration (dof,), rad or m, of the robot's joints.
        base_link: the URDF link that is the robot's world frame.

    Returns:
        ``(vertices (V, 3), faces (F, 3))`` per mesh.

    Raises:
        OptikError: yourdfpy or trimesh missing, the file or a mesh not loadable, no
            visual mesh (with the meshes not found), or link poses that disagree with the
            robot (another chain).

    Warns:
        MeshWarning: a mesh the file names was not found (the others are returned).
    """
    try:
        import trimesh  # noqa: F401  (checked here, with yourdfpy; used when placing)
        import yourdfpy
    except ImportError as exc:  # pragma: no cover - both are in the test extra
        raise OptikError("meshes need yourdfpy and trimesh: pip install 'optik[urdf]'") from exc
    path = Path(urdf)
    q = robot.check_q(q, "q")
    with _LoaderNotes() as notes:
        try:
            model = yourdfpy.URDF.load(
                str(path),
                filename_handler=_package_handler(path),
                load_meshes=True,
                build_scene_graph=True,
                load_collision_meshes=False,
            )
            meshes = _placed_meshes(model, robot, q, base_link, path)
        except OptikError as exc:
            raise OptikError(f"{exc}{notes.missing_text()}") from exc
        except Exception as exc:  # yourdfpy and trimesh raise many kinds: a bad file
            raise OptikError(f"{path}: the URDF's meshes do not load ({exc})") from exc
    for missing in notes.missing:
        warnings.warn(f"{path}: mesh not drawn: {missing}", MeshWarning, stacklevel=2)
    return meshes


class MeshWarning(UserWarning):
    """A URDF's visual mesh that :func:`visual_meshes` could not find (the rest are drawn)."""


class _LoaderNotes(logging.Handler):
    """yourdfpy's log records while a URDF's meshes load, kept instead of printed.

    yourdfpy logs through the ``logging`` module; with no handler configured, Python
    prints its warnings to stderr ("Using different parsing approach.", "Can't find
    http:/...") beside optik's own messages. The meshes it could not find are kept
    (:attr:`missing`) for optik's message; the rest (how it parsed) are dropped.
    """

    _LOGGER = "yourdfpy"

    def __init__(self) -> None:
        super().__init__(logging.DEBUG)
        self.missing: list[str] = []
        self._propagate = True

    def emit(self, record: logging.LogRecord) -> None:
        text = record.getMessage()
        if text.startswith("Can't find "):
            self.missing.append(text[len("Can't find ") :])

    def missing_text(self) -> str:
        """`` (not found: a, b)`` naming the meshes yourdfpy could not find, or ``""``."""
        return f" (not found: {', '.join(self.missing)})" if self.missing else ""

    def __enter__(self) -> _LoaderNotes:
        logger = logging.getLogger(self._LOGGER)
        self._propagate = logger.propagate
        logger.addHandler(self)
        logger.propagate = False
        return self

    def __exit__(self, *exc: object) -> None:
        logger = logging.getLogger(self._LOGGER)
        logger.removeHandler(self)
        logger.propagate = self._propagate


def _placed_meshes(
    model: Any, robot: Robot, q: FloatArray, base_link: str, path: Path
) -> list[tuple[FloatArray, np.ndarray]]:
    """The visual meshes of a loaded yourdfpy ``model`` at ``q``, in the base frame."""
    import trimesh

    actuated = list(model.actuated_joint_names)
    missing = [n for n in robot.joint_names if n not in actuated]
    if missing:
        raise OptikError(f"{path}: joints {missing} of {robot.name!r} are not in the file")
    cfg = np.zeros(len(actuated))
    for name, value in zip(robot.joint_names, q, strict=True):
        cfg[actuated.index(name)] = value
    model.update_cfg(cfg)
    T_root_base = model.get_transform(base_link)
    to_base = np.linalg.inv(T_root_base)
    # A check that the file and the robot describe the same chain at this q.
    frames = robot.frames(q)
    for k, joint_name in enumerate(robot.joint_names):
        child = model.joint_map[joint_name].child
        T = to_base @ model.get_transform(child)
        if not np.allclose(T[:3, 3], frames[k + 1, :3, 3], atol=1e-6):
            raise OptikError(f"{path}: link {child!r} is not where {robot.name!r} puts it")
    below = _links_below(model, base_link)
    out = []
    scene = model.scene
    for node in scene.graph.nodes_geometry:
        transform, geometry_name = scene.graph[node]
        link = _link_of(model, node)
        if link not in below:
            continue
        mesh = scene.geometry[geometry_name]
        if not isinstance(mesh, trimesh.Trimesh) or len(mesh.faces) == 0:
            continue
        if len(mesh.faces) > MESH_FACES:
            mesh = mesh.convex_hull
        vertices = np.asarray(mesh.vertices, dtype=float)
        T = to_base @ np.asarray(transform, dtype=float)
        placed = vertices @ T[:3, :3].T + T[:3, 3]
        if not np.all(np.isfinite(placed)) or float(np.max(np.abs(placed))) > MAX_LENGTH_M:
            continue  # a NaN or absurd size or scale in the file: that mesh is not drawn
        out.append((placed, np.asarray(mesh.faces)))
    if not out:
        raise OptikError(f"{path}: no visual mesh below {base_link!r}")
    return out


def _links_below(model: Any, base_link: str) -> set[str]:
    children: dict[str, list[str]] = {}
    for joint in model.robot.joints:
        children.setdefault(joint.parent, []).append(joint.child)
    found, todo = set(), [base_link]
    while todo:
        link = todo.pop()
        found.add(link)
        todo += children.get(link, [])
    return found


def _link_of(model: Any, node: str) -> str:
    """The link a scene-graph geometry node hangs from."""
    parent = model.scene.graph.transforms.parents.get(node, node)
    return str(parent)
