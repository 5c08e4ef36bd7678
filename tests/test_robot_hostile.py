"""Hostile robot descriptions: each test is a fault a search found, kept from coming back.

Problem files, URDF axes, mimic strokes, the reach sphere, base and tool frames, the
``Robot`` constructor itself, the drawing of a file's meshes and the listing of a URDF's
chains.
"""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest
from conftest import run_cli
from scipy.spatial.transform import Rotation

import optik
from optik import Mimic, OptikError
from optik.chain import ChainLink
from optik.errors import ModelError, URDFError
from optik.robot_text import read_urdf_tree

TWO_LINK = """<robot name="r"><link name="a"/><link name="b"/><link name="c"/>
<joint name="j1" type="revolute"><parent link="a"/><child link="b"/><axis xyz="0 0 1"/>
 <limit lower="-2" upper="2" effort="1" velocity="1"/></joint>
<joint name="j2" type="revolute"><parent link="b"/><child link="c"/><origin xyz="0.3 0 0"/>
 <axis xyz="0 1 0"/><limit lower="-2" upper="2" effort="1" velocity="1"/></joint></robot>"""


def test_a_problem_files_overlong_urdf_name_is_not_found(tmp_path: Path) -> None:
    """The system refuses to look the name up (ENAMETOOLONG): 'not found', exit 2."""
    toml = tmp_path / "p.toml"
    toml.write_text(
        '[robot]\nname = "t"\nsource = "s"\nconvention = "urdf"\n'
        f'urdf = "{"x" * 300}.urdf"\nbase_link = "a"\ntip_link = "c"\n'
    )
    with pytest.raises(OptikError, match="file not found"):
        optik.load_problem(toml)
    code, err = run_cli(["robot", str(toml)])
    assert code == 2 and "file not found" in err


@pytest.mark.parametrize("tilt", [1e-6, 1e-9, 1e-12])
def test_a_urdf_axis_a_hair_off_z_turns_about_itself(tilt: float) -> None:
    """A tilt of 1e-6 rad was rounded to z (2e-6 m off at 1 m); scipy's rotation decides."""
    urdf = f"""<robot name="r"><link name="a"/><link name="b"/><link name="c"/>
    <joint name="j1" type="revolute"><parent link="a"/><child link="b"/>
      <axis xyz="{tilt} 0 1"/><limit lower="-3.1" upper="3.1"/></joint>
    <joint name="f" type="fixed"><parent link="b"/><child link="c"/><origin xyz="1 0 0"/></joint>
    </robot>"""
    robot = optik.Robot.from_urdf(urdf, "a", "c")
    axis = np.array([tilt, 0.0, 1.0])
    for q in (3.0, -1.2):
        R = Rotation.from_rotvec(axis / np.linalg.norm(axis) * q).as_matrix()
        T = robot.fk([q])
        assert np.max(np.abs(T[:3, 3] - R @ [1.0, 0.0, 0.0])) < 1e-14
        assert np.max(np.abs(T[:3, :3] - R)) < 1e-14


def test_a_prismatic_mimic_stroke_is_bounded_when_built() -> None:
    rows = [{"name": "x", "role": "arm"}, {"name": "y", "kind": "prismatic"}]
    for multiplier, reason in ((1e300, "stroke beyond"), (1e12, "stroke beyond")):
        rows[1]["mimic"] = Mimic("x", multiplier)
        with pytest.raises(ModelError, match=reason):
            optik.Robot.from_dh(rows)
    rows[0]["continuous"] = True
    rows[1]["mimic"] = Mimic("x", 1.0)
    with pytest.raises(ModelError, match="unbounded"):
        optik.Robot.from_dh(rows)
    rows[0]["continuous"] = False
    rows[1]["mimic"] = Mimic("x", 0.1)  # a stroke of 0.1 x its arm joint's range: fine
    robot = optik.Robot.from_dh(rows)
    T = robot.fk([0.7])
    assert optik.solve_ik(robot, T).success


def test_a_continuous_joint_beside_a_prismatic_one_keeps_the_sphere_finite() -> None:
    robot = optik.Robot.from_dh(
        [
            {"name": "r", "continuous": True, "a": 0.5},
            {"name": "p", "kind": "prismatic", "lower": 0.0, "upper": 1.0},
        ]
    )
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no 0 * inf
        _, radius = robot.reach_sphere
    assert radius == pytest.approx(1.5)
    assert optik.reachability(robot, [[100.0, 0.0, 0.0]]).proven_unreachable.tolist() == [True]


def test_base_and_tool_rotations_are_made_rigid() -> None:
    """Accepted within 1e-6 of a rotation, they are kept as the nearest rotation: the
    robot's own FK is a pose solve_ik takes."""
    S = np.diag([1 + 4.9e-7, 1 + 4.9e-7, 1 + 4.9e-7, 1.0])
    robot = optik.Robot.from_dh(
        [{"a": 1, "lower": -3, "upper": 3}, {"a": 1, "lower": -3, "upper": 3}], base=S, tool=S
    )
    for frame in (robot.T_world_base, robot.T_flange_tool):
        assert np.max(np.abs(frame[:3, :3].T @ frame[:3, :3] - np.eye(3))) < 1e-15
    assert optik.solve_ik(robot, robot.fk([0.3, 0.5]), mode="position").success


@pytest.mark.parametrize(
    ("links", "message"),
    [
        ("abc", "sequence of ChainLink"),
        (5, "sequence of ChainLink"),
        ([optik.DHJoint(role="arm")], "expected a ChainLink"),
        ([ChainLink("j", "ball", np.eye(4), np.eye(4), 0.0)], "unknown joint type"),  # type: ignore[arg-type]
        ([ChainLink("j", "revolute", np.full((4, 4), np.nan), np.eye(4), 0.0)], "before"),
        ([ChainLink("j", "revolute", np.eye(3), np.eye(4), 0.0)], "before"),
        ([ChainLink("j", "revolute", np.eye(4), np.eye(4), "x")], "offset"),  # type: ignore[arg-type]
        ([ChainLink("", "revolute", np.eye(4), np.eye(4), 0.0)], "name"),
        ([ChainLink("j", "revolute", np.eye(4), np.eye(4), 0.0, velocity=-1.0)], "velocity"),
    ],
)
def test_the_robot_constructor_checks_its_links(links: object, message: str) -> None:
    with pytest.raises(ModelError, match=message):
        optik.Robot(links)  # type: ignore[arg-type]


def test_the_robot_constructor_checks_its_name() -> None:
    link = ChainLink("j", "revolute", np.eye(4), np.eye(4), 0.0)
    with pytest.raises(ModelError, match="robot name"):
        optik.Robot([link], name=None)  # type: ignore[arg-type]


def _write(tmp_path: Path, text: str) -> str:
    path = tmp_path / "r.urdf"
    path.write_text(text)
    return str(path)


def test_show_of_a_file_yourdfpy_cannot_place_exits_2(tmp_path: Path) -> None:
    """An off-chain joint of an unknown type: optik reads the chain, yourdfpy fails."""
    urdf = TWO_LINK.replace(
        "</robot>",
        '<link name="d"/><joint name="m" type="weird"><parent link="b"/>'
        '<child link="d"/></joint></robot>',
    ).replace(
        '<link name="b"/>',
        '<link name="b"><visual><geometry><box size="0.1 0.1 0.1"/></geometry></visual></link>',
    )
    path = _write(tmp_path, urdf)
    optik.Robot.from_urdf(path, "a", "c")
    out = tmp_path / "x.png"
    code, err = run_cli(["show", "--urdf", path, "--base", "a", "--tip", "c", "--out", str(out)])
    assert code in (0, 2), err
    assert "Traceback" not in err


@pytest.mark.parametrize("size", ["nan 1 1", "inf 1 1"])
def test_show_skips_a_visual_of_non_finite_size(tmp_path: Path, size: str) -> None:
    urdf = TWO_LINK.replace(
        '<link name="b"/>',
        f'<link name="b"><visual><geometry><box size="{size}"/></geometry></visual></link>',
    )
    path = _write(tmp_path, urdf)
    out = tmp_path / "x.png"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # trimesh's own warnings about the box
        code, err = run_cli(
            ["show", "--urdf", path, "--base", "a", "--tip", "c", "--out", str(out)]
        )
    assert code in (0, 2), err
    assert "Traceback" not in err
    if code == 0:
        assert out.stat().st_size > 0


def _comb(n: int) -> str:
    """A chain of ``n`` fixed joints with a leaf link hanging off each link."""
    parts = ['<robot name="r">']
    for i in range(n + 1):
        parts.append(f'<link name="l{i}"/><link name="leaf{i}"/>')
    for i in range(n):
        parts.append(
            f'<joint name="j{i}" type="fixed"><parent link="l{i}"/><child link="l{i + 1}"/></joint>'
            f'<joint name="k{i}" type="fixed"><parent link="l{i}"/><child link="leaf{i}"/></joint>'
        )
    parts.append("</robot>")
    return "".join(parts)


def test_listing_the_chains_of_a_comb_is_linear(tmp_path: Path) -> None:
    """Each leaf was walked to the root (n^2: 9 s for 6,000 joints); now each link once."""
    small, large = tmp_path / "small.urdf", tmp_path / "large.urdf"
    small.write_text(_comb(300))
    large.write_text(_comb(4800))
    tree = read_urdf_tree(small)
    by_tip = {chain.tip: chain for chain in tree.chains}
    assert len(by_tip) == 301  # leaf0 .. leaf299 and the chain's own end l300
    assert by_tip["leaf0"].joints == 1 and by_tip["leaf7"].joints == 8
    assert by_tip["l300"].joints == 300 and by_tip["l300"].moving == 0
    assert all(chain.base == "l0" for chain in tree.chains)
    # 4,800 joints: 23 million joint visits before, 9,600 now (no timing asserted).
    large_tree = read_urdf_tree(large)
    assert len(large_tree.chains) == 4801
    assert max(chain.joints for chain in large_tree.chains) == 4800


def test_the_tree_reader_names_the_file_of_a_bad_tree(tmp_path: Path) -> None:
    """`optik robot FILE` read the tree without the file in its errors (loading a chain of
    the same file named it)."""
    joint = (
        "<joint name='{0}' type='revolute'><parent link='{1}'/><child link='{2}'/>"
        "<axis xyz='0 0 1'/><limit lower='-2' upper='2'/></joint>"
    )
    two_parents = tmp_path / "two_parents.urdf"
    two_parents.write_text(
        "<robot name='r'><link name='base'/><link name='l1'/><link name='l2'/>"
        + joint.format("a", "base", "l1")
        + joint.format("b", "l1", "l2")
        + joint.format("c", "base", "l2")
        + "</robot>",
        encoding="utf-8",
    )
    with pytest.raises(URDFError, match=rf"^{two_parents}: link 'l2' has two parent joints"):
        read_urdf_tree(two_parents)
    code, err = run_cli(["robot", str(two_parents)])
    assert code == 2 and err.startswith(f"optik: error: {two_parents}: link 'l2'")
