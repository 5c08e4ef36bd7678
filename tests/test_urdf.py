"""URDF input: the Panda against its modified-DH model, general axes, and rejected input.

References: the Panda's MDH model in problems/panda.toml (the URDF was written from it),
and transforms composed with ``scipy.spatial.transform.Rotation`` for joints with
arbitrary origins and axes.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from conftest import PROBLEMS_DIR, assert_close, fd_jacobian, random_q, robot_of
from scipy.spatial.transform import Rotation

from optik.errors import ModelError, URDFError
from optik.model import Robot

PANDA_URDF = PROBLEMS_DIR / "panda.urdf"


@pytest.fixture(scope="module")
def panda_urdf() -> Robot:
    return Robot.from_urdf(PANDA_URDF, "panda_link0", "panda_hand")


# ---------------------------------------------------------------------- Panda
def test_panda_urdf_matches_mdh(panda_urdf: Robot, rng: np.random.Generator) -> None:
    mdh = robot_of("panda")
    assert panda_urdf.dof == mdh.dof == 7
    assert panda_urdf.joint_names == mdh.joint_names
    assert panda_urdf.convention == "urdf"
    assert panda_urdf.dh is None
    for q in random_q(mdh, rng, 32):
        assert_close(panda_urdf.fk(q), mdh.fk(q), atol=1e-12)
        assert_close(panda_urdf.jacobian(q), mdh.jacobian(q), atol=1e-12)


def test_panda_urdf_link_frames_match_mdh(panda_urdf: Robot, rng: np.random.Generator) -> None:
    mdh = robot_of("panda")
    for q in random_q(mdh, rng, 5):
        assert_close(panda_urdf.frames(q), mdh.frames(q), atol=1e-12)


def test_panda_urdf_limits_match_mdh(panda_urdf: Robot) -> None:
    mdh = robot_of("panda")
    assert_close(panda_urdf.lower, mdh.lower, atol=1e-12)
    assert_close(panda_urdf.upper, mdh.upper, atol=1e-12)
    assert_close(np.degrees(panda_urdf.upper[[0, 3, 5]]), [166.0, -4.0, 215.0], atol=1e-9)


def test_panda_urdf_batched(panda_urdf: Robot, rng: np.random.Generator) -> None:
    Q = random_q(panda_urdf, rng, 20)
    T, J = panda_urdf.fk_jacobian(Q)
    mdh = robot_of("panda")
    assert_close(T, mdh.fk(Q), atol=1e-12)
    assert_close(J, mdh.jacobian(Q), atol=1e-12)


def test_urdf_from_string_equals_from_file(panda_urdf: Robot, rng: np.random.Generator) -> None:
    robot = Robot.from_urdf(PANDA_URDF.read_text(), "panda_link0", "panda_hand", name="p2")
    assert robot.name == "p2"
    assert panda_urdf.name == "panda"
    q = random_q(robot, rng)
    assert_close(robot.fk(q), panda_urdf.fk(q), atol=0.0)


def test_urdf_sub_chain_and_tool(panda_urdf: Robot, rng: np.random.Generator) -> None:
    """A chain between inner links, and a tool appended after the tip link."""
    sub = Robot.from_urdf(PANDA_URDF, "panda_link2", "panda_link5")
    assert sub.joint_names == ("panda_joint3", "panda_joint4", "panda_joint5")
    q = random_q(panda_urdf, rng)
    frames = panda_urdf.frames(q)  # frames[i] = link i in link0
    expected = np.linalg.inv(frames[2]) @ frames[5]
    assert_close(sub.fk(q[2:5]), expected, atol=1e-12)

    tool = np.eye(4)
    tool[:3, :3] = Rotation.from_euler("xyz", [0.1, -0.2, 0.3]).as_matrix()
    tool[:3, 3] = [0.01, 0.02, 0.03]
    tooled = Robot.from_urdf(PANDA_URDF, "panda_link0", "panda_hand", tool=tool)
    assert_close(tooled.fk(q), panda_urdf.fk(q) @ tool, atol=1e-12)


def test_panda_urdf_matches_yourdfpy(panda_urdf: Robot, rng: np.random.Generator) -> None:
    """The full URDF stack (``optik[urdf]``, also in the test extra) as a peer reference."""
    import yourdfpy

    model = yourdfpy.URDF.load(
        str(PANDA_URDF), build_scene_graph=True, load_meshes=False, load_collision_meshes=False
    )
    for q in random_q(panda_urdf, rng, 10):
        model.update_cfg(dict(zip(panda_urdf.joint_names, q, strict=True)))
        expected = model.get_transform("panda_hand", "panda_link0")
        assert_close(panda_urdf.fk(q), expected, atol=1e-12)


# ---------------------------------------------------------------------- general joints
def _pose(xyz: tuple[float, float, float], rpy: tuple[float, float, float]) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = Rotation.from_euler("xyz", rpy).as_matrix()  # extrinsic x-y-z = URDF rpy
    T[:3, 3] = xyz
    return T


def _rot_about(axis: np.ndarray, angle: float) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = Rotation.from_rotvec(axis / np.linalg.norm(axis) * angle).as_matrix()
    return T


def _slide_along(axis: np.ndarray, distance: float) -> np.ndarray:
    T = np.eye(4)
    T[:3, 3] = axis / np.linalg.norm(axis) * distance
    return T


GENERAL_URDF = """<?xml version="1.0"?>
<robot name="general">
  <link name="world"/><link name="base"/><link name="l1"/><link name="l2"/>
  <link name="l2b"/><link name="l3"/><link name="l4"/><link name="tip"/>
  <link name="elsewhere"/>
  <joint name="mount" type="fixed">
    <parent link="world"/><child link="base"/>
    <origin xyz="0.1 -0.2 0.3" rpy="0.3 -0.1 0.7"/>
  </joint>
  <joint name="j1" type="revolute">
    <parent link="base"/><child link="l1"/>
    <origin xyz="0 0 0.4" rpy="0 0 0.25"/>
    <axis xyz="0 1 0"/>
    <limit lower="-1.5" upper="1.5" effort="1" velocity="1"/>
  </joint>
  <joint name="j2" type="prismatic">
    <parent link="l1"/><child link="l2"/>
    <origin xyz="0.2 0.1 0" rpy="0.5 0.2 -0.4"/>
    <axis xyz="1 1 0"/>
    <limit lower="0" upper="0.3" effort="1" velocity="1"/>
  </joint>
  <joint name="spacer" type="fixed">
    <parent link="l2"/><child link="l2b"/>
    <origin xyz="0 0.05 0.05" rpy="1.0 0 0"/>
  </joint>
  <joint name="j3" type="continuous">
    <parent link="l2b"/><child link="l3"/>
    <origin xyz="0.3 0 0" rpy="0 -0.6 0"/>
    <axis xyz="0 0 -1"/>
  </joint>
  <joint name="j4" type="revolute">
    <parent link="l3"/><child link="l4"/>
    <origin xyz="0 0 0.1"/>
    <limit lower="-2" upper="2" effort="1" velocity="1"/>
  </joint>
  <joint name="flange" type="fixed">
    <parent link="l4"/><child link="tip"/>
    <origin xyz="0 0 0.12" rpy="0 0 1.2"/>
  </joint>
  <joint name="side" type="fixed">
    <parent link="base"/><child link="elsewhere"/>
  </joint>
</robot>
"""


def _general_reference(q: np.ndarray) -> np.ndarray:
    return (
        _pose((0.1, -0.2, 0.3), (0.3, -0.1, 0.7))
        @ _pose((0.0, 0.0, 0.4), (0.0, 0.0, 0.25))
        @ _rot_about(np.array([0.0, 1.0, 0.0]), q[0])
        @ _pose((0.2, 0.1, 0.0), (0.5, 0.2, -0.4))
        @ _slide_along(np.array([1.0, 1.0, 0.0]), q[1])
        @ _pose((0.0, 0.05, 0.05), (1.0, 0.0, 0.0))
        @ _pose((0.3, 0.0, 0.0), (0.0, -0.6, 0.0))
        @ _rot_about(np.array([0.0, 0.0, -1.0]), q[2])
        @ _pose((0.0, 0.0, 0.1), (0.0, 0.0, 0.0))
        @ _rot_about(np.array([1.0, 0.0, 0.0]), q[3])  # URDF default axis (1, 0, 0)
        @ _pose((0.0, 0.0, 0.12), (0.0, 0.0, 1.2))
    )


def test_general_axes_origins_and_fixed_joints(rng: np.random.Generator) -> None:
    robot = Robot.from_urdf(GENERAL_URDF, "world", "tip")
    assert robot.name == "general"
    assert robot.joint_names == ("j1", "j2", "j3", "j4")
    assert [j.kind for j in robot.joints] == ["revolute", "prismatic", "revolute", "revolute"]
    for q in random_q(robot, rng, 24):
        assert_close(robot.fk(q), _general_reference(q), atol=1e-12)
        assert_close(robot.jacobian(q), fd_jacobian(robot, q), atol=1e-8)


def test_continuous_joint_has_infinite_limits() -> None:
    robot = Robot.from_urdf(GENERAL_URDF, "world", "tip")
    assert robot.lower[2] == -math.inf
    assert robot.upper[2] == math.inf
    assert_close(robot.lower[[0, 1, 3]], [-1.5, 0.0, -2.0], atol=0.0)
    assert_close(robot.upper[[0, 1, 3]], [1.5, 0.3, 2.0], atol=0.0)
    assert robot.mid_limits[2] == 0.0
    assert robot.within_limits([0.0, 0.1, 1e6, 0.0])


# ---------------------------------------------------------------------- rejected input
def _urdf(
    joint_type: str,
    extra: str = "",
    limit: str | None = 'lower="-1" upper="1"',
    axis: str = "0 0 1",
) -> str:
    """Two joints a-b-c; the second has the given type, limit attributes and axis."""
    lim = f"<limit {limit} effort='1' velocity='1'/>" if limit is not None else ""
    return f"""<robot name="bad"><link name="a"/><link name="b"/><link name="c"/>
      <joint name="first" type="revolute"><parent link="a"/><child link="b"/>
        <axis xyz="0 0 1"/><limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
      <joint name="second" type="{joint_type}"><parent link="b"/><child link="c"/>
        <axis xyz="{axis}"/>{lim}{extra}</joint></robot>"""


def test_mimic_joint_rejected() -> None:
    source = _urdf("revolute", '<mimic joint="first" multiplier="2"/>')
    with pytest.raises(URDFError, match=r"'second'.*mimic"):
        Robot.from_urdf(source, "a", "c")


def test_an_undeclared_link_in_the_chain_is_refused() -> None:
    """urdfdom refuses a joint whose link has no <link> element; such a link was taken
    in the middle of a chain (and refused as base or tip only)."""
    source = _urdf("revolute").replace('<link name="b"/>', "")
    with pytest.raises(URDFError, match=r"joint 'first': child link 'b' is not declared"):
        Robot.from_urdf(source, "a", "c")
    assert Robot.from_urdf(_urdf("revolute"), "a", "c").dof == 2


def test_floating_joint_rejected() -> None:
    with pytest.raises(URDFError, match=r"'second'.*floating"):
        Robot.from_urdf(_urdf("floating", limit=None), "a", "c")


def test_planar_joint_rejected() -> None:
    with pytest.raises(URDFError, match=r"'second'.*planar"):
        Robot.from_urdf(_urdf("planar", limit=None), "a", "c")


def test_unknown_joint_type_rejected() -> None:
    with pytest.raises(URDFError, match=r"'second'.*unknown joint type 'helical'"):
        Robot.from_urdf(_urdf("helical"), "a", "c")


def test_rejected_joint_off_the_path_is_ignored() -> None:
    robot = Robot.from_urdf(_urdf("floating", limit=None), "a", "b")
    assert robot.joint_names == ("first",)


def test_no_path_between_links() -> None:
    with pytest.raises(URDFError, match=r"no kinematic path from 'c' to 'a'"):
        Robot.from_urdf(_urdf("revolute"), "c", "a")
    with pytest.raises(URDFError, match=r"no kinematic path from 'l1' to 'elsewhere'"):
        Robot.from_urdf(GENERAL_URDF, "l1", "elsewhere")


def test_unknown_link() -> None:
    with pytest.raises(URDFError, match=r"link 'hand' not in the URDF"):
        Robot.from_urdf(_urdf("revolute"), "a", "hand")
    with pytest.raises(URDFError, match=r"link 'origin' not in the URDF"):
        Robot.from_urdf(_urdf("revolute"), "origin", "c")


def test_missing_limit_on_revolute_joint() -> None:
    with pytest.raises(URDFError, match=r"'second'.*revolute joint needs <limit"):
        Robot.from_urdf(_urdf("revolute", limit=None), "a", "c")


def test_missing_limit_on_prismatic_joint() -> None:
    with pytest.raises(URDFError, match=r"'second'.*prismatic joint needs <limit"):
        Robot.from_urdf(_urdf("prismatic", limit=None), "a", "c")


def test_continuous_joint_needs_no_limit() -> None:
    robot = Robot.from_urdf(_urdf("continuous", limit=None), "a", "c")
    assert robot.lower[1] == -math.inf and robot.upper[1] == math.inf


def test_zero_axis_rejected() -> None:
    source = _urdf("revolute", axis="0 0 0")
    with pytest.raises(URDFError, match=r"'second'.*axis is zero"):
        Robot.from_urdf(source, "a", "c")


def test_bad_numbers_rejected() -> None:
    source = _urdf("revolute", limit='lower="nan" upper="1"')
    with pytest.raises(URDFError, match=r"'second' lower"):
        Robot.from_urdf(source, "a", "c")


def test_lower_above_upper_in_urdf(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """Checked by the robot, the error named neither the file nor <limit>, suggested
    infinite limits (a URDF's reader refuses them), and `optik robot FILE` failed
    instead of listing the chain with the reason."""
    source = _urdf("revolute", limit='lower="1" upper="-1"')
    with pytest.raises(
        URDFError,
        match=r"'second': <limit lower=1 upper=-1>: lower is above upper "
        r"\(a joint without limits is type=\"continuous\"\)",
    ):
        Robot.from_urdf(source, "a", "c")
    path = tmp_path / "arm.urdf"
    path.write_text(_urdf("prismatic", limit='lower="1" upper="-1"'), encoding="utf-8")
    with pytest.raises(
        URDFError,
        match=rf"^{path}: joint 'second': <limit lower=1 upper=-1>: lower is above upper$",
    ):
        Robot.from_urdf(path, "a", "c")
    path.write_text(_urdf("revolute", limit='lower="-1e16" upper="1e16"'), encoding="utf-8")
    with pytest.raises(
        URDFError, match=rf"^{path}: .*a revolute range must lie within \+-1e\+09 rad"
    ):
        Robot.from_urdf(path, "a", "c")
    from optik.cli import main

    assert main(["robot", str(path)]) == 0
    assert "cannot be loaded" in capsys.readouterr().out


def test_not_xml_and_wrong_root(tmp_path: Path) -> None:
    with pytest.raises(URDFError, match="not well-formed XML"):
        Robot.from_urdf("<robot name='x'><link></robot>", "a", "b")
    with pytest.raises(URDFError, match=r"root element is <sdf>"):
        Robot.from_urdf("<sdf><link name='a'/></sdf>", "a", "b")
    missing = tmp_path / "missing.urdf"
    with pytest.raises(URDFError, match=r"URDF file not found: .*missing\.urdf"):
        Robot.from_urdf(missing, "a", "b")


def test_no_moving_joint() -> None:
    with pytest.raises(URDFError, match=r"no moving joint between 'world' and 'base'"):
        Robot.from_urdf(GENERAL_URDF, "world", "base")


def test_urdf_error_is_model_error() -> None:
    assert issubclass(URDFError, ModelError)


_JOINT = (
    '<joint {name} type="revolute"><parent link="{parent}"/><child link="{child}"/>'
    '<origin xyz="0 0 0.1"/><axis xyz="0 0 1"/><limit lower="-1" upper="1"/></joint>'
)


def test_unnamed_and_twice_named_elements_rejected() -> None:
    links = '<link name="l0"/><link name="l1"/><link name="l2"/>'
    unnamed = (
        f'<robot name="r">{links}'
        + _JOINT.format(name='name="j0"', parent="l0", child="l1")
        + _JOINT.format(name="", parent="l1", child="l2")
        + "</robot>"
    )
    with pytest.raises(URDFError, match=r"<joint> number 2 has no name"):
        Robot.from_urdf(unnamed, "l0", "l2")
    twice = (
        '<robot name="r"><link name="l0"/><link name="l0"/><link name="l1"/>'
        + _JOINT.format(name='name="j0"', parent="l0", child="l1")
        + "</robot>"
    )
    with pytest.raises(URDFError, match=r"two <link> elements are named 'l0'"):
        Robot.from_urdf(twice, "l0", "l1")


def test_empty_source_and_missing_file_named_once(tmp_path: Path) -> None:
    with pytest.raises(URDFError, match=r"^source: empty"):
        Robot.from_urdf("", "a", "b")
    missing = tmp_path / "none.urdf"
    with pytest.raises(URDFError, match=r"^URDF file not found: .*none\.urdf$"):
        Robot.from_urdf(missing, "a", "b")


def test_errors_about_a_urdf_file_name_it(tmp_path: Path) -> None:
    # Only the read errors named the file: "link 'tip' not in the URDF" left the user to
    # guess which of the files given was meant.
    panda = PROBLEMS_DIR / "panda.urdf"
    with pytest.raises(URDFError, match=rf"^{panda}: link 'nowhere' not in the URDF"):
        Robot.from_urdf(panda, "panda_link0", "nowhere")
    broken = tmp_path / "broken.urdf"
    broken.write_text("<robot name='r'><link name='a'></robot>")
    with pytest.raises(URDFError, match=rf"^{broken}: URDF is not well-formed XML"):
        Robot.from_urdf(str(broken), "a", "b")
    # URDF text has no file to name.
    with pytest.raises(URDFError, match=r"^link 'b' not in the URDF"):
        Robot.from_urdf("<robot name='r'><link name='a'/></robot>", "a", "b")


def test_a_number_with_an_underscore_is_refused() -> None:
    # float() reads "1_0" as 10: a file urdfdom refuses loaded with a meaning of its own.
    text = (
        "<robot name='r'><link name='a'/><link name='b'/>"
        "<joint name='j' type='revolute'><parent link='a'/><child link='b'/>"
        "<origin xyz='1_0 0 0'/><axis xyz='0 0 1'/><limit lower='-1' upper='1'/></joint>"
        "</robot>"
    )
    with pytest.raises(
        URDFError, match=r"joint 'j' origin xyz: cannot read numbers from '1_0 0 0'"
    ):
        Robot.from_urdf(text, "a", "b")


def test_fixed_joints_that_add_up_beyond_the_length_bound_are_refused() -> None:
    # Each origin was checked, not their sum: ten 9e8 m offsets gave a 9e9 m tool.
    links = "".join(f"<link name='l{i}'/>" for i in range(12))
    fixed = "".join(
        f"<joint name='f{i}' type='fixed'><parent link='l{i}'/><child link='l{i + 1}'/>"
        "<origin xyz='9e8 0 0'/></joint>"
        for i in range(10)
    )
    moving = (
        "<joint name='j' type='revolute'><parent link='l10'/><child link='l11'/>"
        "<axis xyz='0 0 1'/><limit lower='-1' upper='1'/></joint>"
    )
    with pytest.raises(
        URDFError, match=r"joint 'f1': the fixed joints up to it .* beyond 1e\+09 m"
    ):
        Robot.from_urdf(f"<robot name='r'>{links}{fixed}{moving}</robot>", "l0", "l11")


def test_a_misspelt_or_swapped_link_gets_a_hint() -> None:
    panda = PROBLEMS_DIR / "panda.urdf"
    with pytest.raises(
        URDFError, match=r"link 'panda_lnk7' not in the URDF; did you mean 'panda_link7'\?"
    ):
        Robot.from_urdf(panda, "panda_link0", "panda_lnk7")
    with pytest.raises(URDFError, match=r"'panda_link0' is the base side; swap them"):
        Robot.from_urdf(panda, "panda_link7", "panda_link0")
    # Two links on different branches: no path either way, and no swap offered.
    text = (
        "<robot name='r'><link name='a'/><link name='b'/><link name='c'/>"
        "<joint name='j1' type='revolute'><parent link='a'/><child link='b'/>"
        "<limit lower='-1' upper='1'/></joint>"
        "<joint name='j2' type='revolute'><parent link='a'/><child link='c'/>"
        "<limit lower='-1' upper='1'/></joint></robot>"
    )
    with pytest.raises(URDFError, match=r"^no kinematic path from 'b' to 'c'$"):
        Robot.from_urdf(text, "b", "c")
