"""Pictures of the robot: drawn pixels cover the arm's projected frames, for DH and URDF robots.

Each picture is compared with the same axes emptied of what was drawn (the background:
panes, grid, ticks): the pixels at the joint origins, projected here with the axes' own
transform, must differ from it, and pixels far from the arm must not.
"""

from __future__ import annotations

import importlib.metadata
import itertools
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.image as mpimg
import numpy as np
import pytest
from mpl_toolkits.mplot3d import proj3d

from optik.drawing import (
    MeshWarning,
    arm_geometry,
    robot_figure,
    save_figure,
    visual_meshes,
)
from optik.errors import OptikError
from optik.model import Robot
from optik.paths import line
from optik.planning import PathPlan, plan_path
from optik.plots import plan_figure
from optik.problems import load_problem
from optik.reachability import reachability_figure

ROOT = Path(__file__).resolve().parent.parent
DPI = 100.0


def _ur5_urdf() -> Path:
    dist = importlib.metadata.distribution("example-robot-data")  # the test extra
    path = Path(str(dist.locate_file("cmeel.prefix/share/example-robot-data/robots")))
    return path / "ur_description" / "urdf" / "ur5_robot.urdf"


def _pixels(fig, ax, points: np.ndarray, dpi: float = DPI) -> np.ndarray:  # type: ignore[no-untyped-def]
    """Image (row, column) of world points (K, 3), from the axes' projection."""
    fig.set_dpi(dpi)
    fig.canvas.draw()
    x, y, _ = proj3d.proj_transform(points[:, 0], points[:, 1], points[:, 2], ax.get_proj())
    display = ax.transData.transform(np.column_stack([x, y]))
    height = fig.canvas.get_width_height()[1]
    return np.column_stack([height - display[:, 1], display[:, 0]])


def _render_pair(fig, ax, tmp_path: Path, name: str) -> tuple[np.ndarray, np.ndarray]:  # type: ignore[no-untyped-def]
    """The saved picture and the same axes with every drawn artist removed."""
    drawn = save_figure(fig, tmp_path / f"{name}.png", DPI)
    image = mpimg.imread(drawn)[..., :3]
    for artist in [*ax.lines, *ax.collections]:
        artist.remove()
    ax.get_legend() and ax.get_legend().remove()
    empty = mpimg.imread(save_figure(fig, tmp_path / f"{name}-empty.png", DPI))[..., :3]
    assert image.shape == empty.shape
    return image, empty


def _differs_near(
    image: np.ndarray, empty: np.ndarray, rc: np.ndarray, radius: int = 2
) -> np.ndarray:
    out = []
    for r, c in np.rint(rc).astype(int):
        window = (
            slice(max(r - radius, 0), r + radius + 1),
            slice(max(c - radius, 0), c + radius + 1),
        )
        out.append(np.abs(image[window] - empty[window]).max() > 0.15)
    return np.array(out)


def _far_pixels(
    shape: tuple[int, ...], drawn: np.ndarray, distance: float, rng: np.random.Generator
) -> np.ndarray:
    candidates = np.column_stack([rng.integers(0, shape[0], 4000), rng.integers(0, shape[1], 4000)])
    d = np.min(np.linalg.norm(candidates[:, None, :] - drawn[None], axis=2), axis=1)
    return candidates[d > distance]


def _check_picture(fig, ax, points: np.ndarray, tmp_path: Path, name: str) -> None:  # type: ignore[no-untyped-def]
    rc = _pixels(fig, ax, points)
    image, empty = _render_pair(fig, ax, tmp_path, name)
    h, w = image.shape[:2]
    assert np.all((rc[:, 0] >= 0) & (rc[:, 0] < h) & (rc[:, 1] >= 0) & (rc[:, 1] < w))
    covered = _differs_near(image, empty, rc)
    assert covered.all(), f"frames {np.flatnonzero(~covered)} not drawn at their projection"
    # The check can fail: the drawing does not cover the image. Far from the projected
    # points (and the segments between them) the picture equals its background.
    segment = np.concatenate([np.linspace(a, b, 40) for a, b in itertools.pairwise(rc)])
    far = _far_pixels(image.shape, segment, 0.12 * min(h, w), np.random.default_rng(3))
    assert len(far) > 200
    same = np.abs(image[far[:, 0], far[:, 1]] - empty[far[:, 0], far[:, 1]]).max(axis=1) < 0.02
    assert same.mean() > 0.97


def _frame_origins(robot: Robot, q: np.ndarray) -> np.ndarray:
    """Every frame's origin, from robot.frames directly (not from the drawing code)."""
    return robot.frames(q)[:, :3, 3]


# ----------------------------------------------------------------------- robot pictures
def test_dh_robot_picture_covers_its_projected_frames(tmp_path: Path) -> None:
    robot = load_problem("puma560").robot
    q = np.array([0.4, 0.6, -0.9, 0.5, 0.8, 0.2])
    fig, ax = robot_figure(robot, q)
    _check_picture(fig, ax, _frame_origins(robot, q), tmp_path, "puma")


def test_urdf_robot_picture_covers_its_projected_frames(tmp_path: Path) -> None:
    robot = Robot.from_urdf(ROOT / "problems" / "panda.urdf", "panda_link0", "panda_hand")
    q = robot.mid_limits + 0.3
    fig, ax = robot_figure(robot, q, view=(30.0, -120.0))
    _check_picture(fig, ax, _frame_origins(robot, q), tmp_path, "panda")


def test_a_wrong_projection_is_caught(tmp_path: Path) -> None:
    # The same check with the points mirrored through the arm's centre fails: the test
    # locates the arm, it does not merely find ink somewhere.
    robot = load_problem("puma560").robot
    q = np.array([0.4, 0.6, -0.9, 0.5, 0.8, 0.2])
    fig, ax = robot_figure(robot, q)
    points = _frame_origins(robot, q)
    centre = points.mean(axis=0)
    mirrored = 2 * centre - points
    mirrored[:, 2] = points[:, 2]
    rc = _pixels(fig, ax, mirrored)
    image, empty = _render_pair(fig, ax, tmp_path, "mirror")
    assert not _differs_near(image, empty, rc).all()


def test_joint_axes_point_along_each_motion(tmp_path: Path) -> None:
    robot = load_problem("puma560").robot
    q = np.array([0.4, 0.6, -0.9, 0.5, 0.8, 0.2])
    g = arm_geometry(robot, q)
    # Independent: a revolute joint's axis is the direction about which a small change of
    # that joint turns the tool; the Jacobian's angular rows give it.
    J = robot.jacobian(q)
    np.testing.assert_allclose(g.axis_directions, J[3:].T, atol=1e-12)
    # And each axis passes through the tool's instantaneous rotation: v = w x (p - o).
    p = robot.fk(q)[:3, 3]
    for k in range(robot.dof):
        np.testing.assert_allclose(np.cross(J[3:, k], p - g.axis_origins[k]), J[:3, k], atol=1e-12)


def test_urdf_meshes_load_offline_and_sit_on_the_links(tmp_path: Path) -> None:
    urdf = _ur5_urdf()
    robot = Robot.from_urdf(urdf, "base_link", "tool0")
    q = np.array([0.3, -1.2, 1.5, -1.0, -1.4, 0.2])
    meshes = visual_meshes(urdf, robot, q, "base_link")
    assert len(meshes) >= 6
    # Every joint origin lies inside (or on) the bounding box of the meshes near it.
    vertices = np.concatenate([v for v, _ in meshes])
    for origin in arm_geometry(robot, q).axis_origins:
        assert np.min(np.linalg.norm(vertices - origin, axis=1)) < 0.1
    fig, ax = robot_figure(robot, q, meshes=meshes)
    rc = _pixels(fig, ax, _frame_origins(robot, q))
    image, empty = _render_pair(fig, ax, tmp_path, "ur5")
    assert _differs_near(image, empty, rc).all()
    with pytest.raises(OptikError, match="no visual mesh"):
        panda = Robot.from_urdf(ROOT / "problems" / "panda.urdf", "panda_link0", "panda_hand")
        visual_meshes(ROOT / "problems" / "panda.urdf", panda, panda.mid_limits, "panda_link0")
    other = load_problem("puma560").robot
    with pytest.raises(OptikError, match="not in the file"):
        visual_meshes(urdf, other, other.mid_limits, "base_link")


def test_a_mesh_not_found_is_a_warning_and_the_loader_prints_nothing(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # The UR5's file with its base mesh renamed to one that does not exist; the package
    # folder is reached through a link beside the copy, as package:// names resolve.
    urdf = _ur5_urdf()
    package = next(p for p in urdf.parents if p.name == "example-robot-data")
    (tmp_path / "example-robot-data").symlink_to(package)
    text = urdf.read_text()
    assert text.count("ur5/visual/base.dae") == 1
    copy = tmp_path / "ur5_missing_base.urdf"
    copy.write_text(text.replace("ur5/visual/base.dae", "ur5/visual/nothing.dae"))
    robot = Robot.from_urdf(copy, "base_link", "tool0")
    with pytest.warns(MeshWarning, match=r"mesh not drawn: .*nothing\.dae") as caught:
        meshes = visual_meshes(copy, robot, robot.mid_limits, "base_link")
    assert len(caught) == 1
    every = visual_meshes(urdf, robot, robot.mid_limits, "base_link")
    assert 0 < len(meshes) < len(every)  # the base's meshes (one file, two parts) left out
    assert capsys.readouterr().err == ""  # yourdfpy's "Can't find ..." is not printed
    from optik.cli import main

    assert main(["show", "--urdf", str(copy), "--base", "base_link", "--tip", "tool0",
                 "--out", str(tmp_path / "ur5.png")]) == 0  # fmt: skip
    out, err = capsys.readouterr()
    assert "mesh not drawn" in out and "nothing.dae" in out and err == ""


def test_no_mesh_found_names_the_missing_files(tmp_path: Path) -> None:
    text = (
        '<robot name="r"><link name="a"><visual><geometry><mesh filename="missing.stl"/>'
        '</geometry></visual></link><link name="b"/><joint name="j1" type="revolute">'
        '<parent link="a"/><child link="b"/><axis xyz="0 0 1"/><limit lower="-1" upper="1"/>'
        "</joint></robot>"
    )
    urdf = tmp_path / "r.urdf"
    urdf.write_text(text)
    robot = Robot.from_urdf(urdf, "a", "b")
    with pytest.raises(OptikError, match=r"no visual mesh below 'a' \(not found: .*missing\.stl\)"):
        visual_meshes(urdf, robot, robot.mid_limits, "a")


# ----------------------------------------------------------------------- plans
def test_plan_figure_draws_the_path_its_flags_and_the_arm(tmp_path: Path) -> None:
    robot = load_problem("puma560").robot
    q = np.array([0.2, 0.5, -0.8, 0.1, 0.6, 0.3])
    start = robot.fk(q)
    far = start.copy()
    far[:3, 3] += [1.2, 0.0, 0.3]
    plan = plan_path(robot, np.concatenate([line(start, far, 0.05), line(far, start, 0.05)]))
    assert "unreachable" in plan.status and plan.solved.any()
    parts = plan_figure(plan, robot)
    fig, ax = parts.figure, parts.path_axes
    assert parts.arm_waypoints and all(plan.solved[k] for k in parts.arm_waypoints)
    arm_points = np.concatenate([_frame_origins(robot, plan.q[k]) for k in parts.arm_waypoints])
    path_points = plan.poses[:, :3, 3]
    rc_arm = _pixels(fig, ax, arm_points)
    rc_path = _pixels(fig, ax, path_points)
    unreachable = np.array([s == "unreachable" for s in plan.status])
    image, empty = _render_pair(fig, ax, tmp_path, "plan")
    assert _differs_near(image, empty, rc_arm).all()
    assert _differs_near(image, empty, rc_path).all()
    # Unreachable waypoints are black markers: the darkest pixel near each is near black.
    for r, c in np.rint(rc_path[unreachable]).astype(int):
        assert image[r - 2 : r + 3, c - 2 : c + 3].sum(axis=2).min() < 0.3


def test_plan_plot_writes_a_png_with_and_without_a_robot(tmp_path: Path) -> None:
    robot = load_problem("planar_2r").robot
    poses = line(robot.fk(np.array([0.3, 0.9])), robot.fk(np.array([0.9, 0.5])), 0.05)
    plan = plan_path(robot, poses[:, :3, 3])  # positions: a planar arm keeps no orientation
    assert plan.solved.all()
    with_robot = plan.plot(tmp_path / "with.png", robot)
    without = plan.plot(tmp_path / "without.png")
    wide, narrow = mpimg.imread(with_robot), mpimg.imread(without)
    assert wide.shape[1] > narrow.shape[1]  # the 3-D panel is there


def _plan(robot: Robot, q: np.ndarray, status: list[str]) -> PathPlan:
    """A plan of these configurations and statuses (NaN rows unsolved), poses from FK."""
    n = len(q)
    poses = np.array([robot.fk(np.nan_to_num(row, nan=0.0)) for row in q])
    return PathPlan(
        poses=poses, mode="pose", q=q, status=status, limit_margin=np.zeros_like(q),
        manipulability=np.zeros(n), step=np.zeros(n), candidates=np.zeros(n, dtype=int),
        max_joint_step=0.1, joint_names=robot.joint_names,
    )  # fmt: skip


def test_unsolved_waypoints_are_marked_inside_their_own_panel() -> None:
    """The shared x axis spanned the solved waypoints only, so the marks of unsolved ones
    (drawn unclipped along the panel's foot) landed on the neighbouring panels."""
    robot = load_problem("ur5").robot
    n = 21
    q = np.full((n, robot.dof), np.nan)
    q[9:18] = robot.mid_limits + np.linspace(0.0, 0.5, 9)[:, None]
    status = ["unreachable"] * 9 + ["ok"] * 9 + ["unreachable"] * 3
    parts = plan_figure(_plan(robot, q, status), robot)
    parts.figure.canvas.draw()
    for ax in parts.joint_axes:
        assert ax.get_xlim() == (-0.5, n - 0.5)
        box = ax.get_window_extent()
        marks = [c for c in ax.collections if len(c.get_offsets()) == 12]  # the unsolved
        assert len(marks) == 1
        x = marks[0].get_offset_transform().transform(marks[0].get_offsets())[:, 0]
        assert np.all((x > box.x0) & (x < box.x1))


def test_without_a_robot_joint_values_are_plotted_as_they_are() -> None:
    """Without the robot a joint's kind is unknown: a prismatic stroke was labelled and
    scaled as degrees (0.5 m shown as 28.6 deg)."""
    robot = load_problem("stanford_arm").robot
    q = np.tile(robot.mid_limits, (3, 1))
    q[:, 2] = [0.5, 0.7, 0.9]
    plan = _plan(robot, q, ["ok"] * 3)
    bare = plan_figure(plan).joint_axes
    assert bare[2].get_ylabel().endswith("(rad or m)")
    assert np.allclose(bare[2].lines[0].get_ydata(), [0.5, 0.7, 0.9])
    known = plan_figure(plan, robot).joint_axes
    assert known[2].get_ylabel().endswith("(m)") and known[0].get_ylabel().endswith("(deg)")
    assert np.allclose(known[0].lines[0].get_ydata(), np.degrees(q[:, 0]))


# ----------------------------------------------------------------------- reachability
def test_reachability_slice_figure(tmp_path: Path) -> None:
    planar = load_problem("planar_2r").robot
    # Elbow within +-90 deg: with unit links the tool reaches the annulus
    # 2 cos(45 deg) <= r <= 2 (the shoulder turns all the way round).
    robot = planar.with_limits([-np.pi, -np.pi / 2], [np.pi, np.pi / 2])
    fig, ax = reachability_figure(robot, axis="z", value=0.0, resolution=31)
    result = ax.reachability
    r = np.linalg.norm(result.points[:, :2], axis=1)
    inner = np.sqrt(2.0)
    assert not result.reachable[r < inner - 0.03].any()
    assert result.reachable[(r > inner + 0.03) & (r < 1.97)].all()
    assert (r < inner - 0.03).sum() > 20 and result.reachable.sum() > 20
    rc = _pixels(fig, ax, result.points[::7])
    image, empty = _render_pair(fig, ax, tmp_path, "slice")
    assert _differs_near(image, empty, rc).mean() > 0.9  # the slice's points are drawn
    with pytest.raises(OptikError, match="axis"):
        reachability_figure(robot, axis="w")


# ----------------------------------------------------------------------- command line
def test_optik_show_writes_the_picture(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from optik.cli import main

    out = tmp_path / "robot.png"
    q = np.array([0.0, 0.5, -0.5, 0.0, 0.8, 0.0])
    assert main(["show", "puma560", "--q", *map(str, q), "--out", str(out)]) == 0
    # The command's picture covers the frames, projected through the same figure rebuilt
    # here (show_robot's defaults: 110 dpi) and compared with its empty axes.
    robot = load_problem("puma560").robot
    fig, ax = robot_figure(robot, q)
    rc = _pixels(fig, ax, _frame_origins(robot, q), dpi=110.0)
    for artist in [*ax.lines, *ax.collections]:
        artist.remove()
    empty = mpimg.imread(save_figure(fig, tmp_path / "empty.png", 110.0))[..., :3]
    image = mpimg.imread(out)[..., :3]
    assert image.shape == empty.shape
    assert _differs_near(image, empty, rc).all()
    urdf = str(ROOT / "problems" / "panda.urdf")
    args = ["show", "--urdf", urdf, "--base", "panda_link0", "--tip", "panda_hand"]
    assert main([*args, "--out", str(tmp_path / "panda.svg")]) == 0
    assert "no meshes drawn" in capsys.readouterr().out  # this URDF has none
    assert (tmp_path / "panda.svg").read_text().lstrip().startswith("<?xml")
    ur5 = ["show", "--urdf", str(_ur5_urdf()), "--base", "base_link", "--tip", "tool0"]
    assert main([*ur5, "--view-deg", "30", "-120", "--out", str(tmp_path / "ur5.png")]) == 0
    assert "visual meshes" in capsys.readouterr().out
    assert main(["show", "puma560", "--q", "1", "2", "--out", str(out)]) == 2
    assert main(["show", "puma560", "--out", str(tmp_path / "robot.txt")]) == 2
    from optik.drawing import show_robot

    with pytest.raises(OptikError, match="cannot write 'xyz'"):
        show_robot(load_problem("puma560").robot, tmp_path / "robot.xyz")
    assert not (tmp_path / "robot.xyz").exists()
