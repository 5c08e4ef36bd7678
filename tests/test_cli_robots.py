"""The ``optik`` command with your own robot (--urdf, --dh, ``optik robot``), its pose and
unit options, the units rule of every option's help, and ``--version``."""

from __future__ import annotations

import argparse
import json
import math
import re
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from conftest import ROOT, load
from scipy.spatial.transform import Rotation

import optik
from optik import Robot, cli
from optik.cli import build_parser, main

PANDA_URDF = ROOT / "problems" / "panda.urdf"
PANDA_CHAIN = ["--urdf", str(PANDA_URDF), "--base", "panda_link0", "--tip", "panda_hand"]
PANDA_LINKS = [f"panda_link{i}" for i in range(8)] + ["panda_hand"]


def _panda() -> Robot:
    return Robot.from_urdf(PANDA_URDF, "panda_link0", "panda_hand")


def _one_error_line(err: str) -> str:
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("optik: error: "), err
    return lines[0]


def _exit_code(argv: list[str]) -> int:
    """``main(argv)``'s exit code, whether returned or raised by argparse."""
    try:
        return main(argv)
    except SystemExit as exc:
        return int(exc.code or 0)


def _solve_json(argv: list[str], capsys: pytest.CaptureFixture[str]) -> dict[str, Any]:
    code = main(["solve", *argv, "--json"])
    data: dict[str, Any] = json.loads(capsys.readouterr().out)
    assert code == (0 if data["success"] else 1)
    return data


# ---------------------------------------------------------------------------- --urdf
def test_solve_with_urdf_reaches_the_fk_of_an_in_limit_configuration(
    capsys: pytest.CaptureFixture[str],
) -> None:
    robot = _panda()
    q_true = robot.mid_limits + 0.2
    T = robot.fk(q_true)
    rpy = Rotation.from_matrix(T[:3, :3]).as_euler("xyz")  # extrinsic x, y, z: Rz Ry Rx
    position = [f"{v:.17g}" for v in T[:3, 3]]
    data = _solve_json([*PANDA_CHAIN, "--position", *position, "--rpy", *map(str, rpy)], capsys)
    assert data["success"] and data["problem"] == "panda"
    assert data["joint_names"] == [f"panda_joint{i}" for i in range(1, 8)]
    assert data["q_units"] == ["rad"] * 7
    T_found = robot.fk(np.array(data["q"]))
    np.testing.assert_allclose(T_found, T, atol=1e-5)


def test_solve_text_output_prints_si_values_with_units_and_the_solver_time(
    capsys: pytest.CaptureFixture[str],
) -> None:
    assert main(["solve", "planar_2r", "--position", "1", "1", "0"]) == 0
    out = capsys.readouterr().out
    first = out.splitlines()[0]
    assert re.fullmatch(r"planar_2r: \w+ \(\w+, solver time \d+\.\d{3} ms\)", first), first
    # Two unit links reach (1, 1) with the elbow at +-90 deg.
    elbow = next(line for line in out.splitlines() if line.strip().startswith("elbow"))
    match = re.search(r"([+-]\d+\.\d+) rad\s+\(([+-]\d+\.\d+)°\)", elbow)
    assert match, elbow
    assert abs(float(match.group(1))) == pytest.approx(math.pi / 2, abs=1e-6)
    assert abs(float(match.group(2))) == pytest.approx(90.0, abs=1e-4)


def test_solver_time_is_the_results_time_not_the_process_time(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    from dataclasses import replace

    real = cli._solve.solve_ik
    monkeypatch.setattr(
        cli._solve, "solve_ik", lambda *a, **k: replace(real(*a, **k), time_s=0.1234567)
    )
    assert main(["solve", "planar_2r", "--position", "1", "1", "0"]) == 0
    assert "solver time 123.457 ms" in capsys.readouterr().out


def test_an_unsolved_target_prints_no_joint_values(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["solve", "planar_2r", "--position", "5", "5", "0"]) == 1
    out = capsys.readouterr().out
    assert out.startswith("planar_2r: no solution: unreachable")
    assert "rad" not in out.split("\n", 1)[1].split("orientation error")[0]
    assert "shoulder" not in out and "elbow" not in out and "°" not in out
    assert main(["solve", "planar_2r", "--position", "5", "5", "0", "--json"]) == 1
    assert json.loads(capsys.readouterr().out)["q"] is None


def test_plan_with_urdf_writes_a_plan_of_every_waypoint(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    argv = ["plan", *PANDA_CHAIN, "--line", "0.4", "-0.05", "0.5", "0.4", "0.05", "0.5"]
    assert (
        main([*argv, "--step", "0.05", "--rpy-deg", "180", "0", "0", "--out", str(tmp_path)]) == 0
    )
    out = capsys.readouterr().out
    assert out.startswith("panda: ") and "/3 waypoints solved" in out
    data = np.load(tmp_path / "plan.npz")
    assert data["q"].shape == (3, 7)
    robot = _panda()
    solved = np.array([s == "ok" or s == "near_singular" for s in data["status"]])
    for q, T in zip(data["q"][solved], data["poses"][solved], strict=True):
        np.testing.assert_allclose(robot.fk(q), T, atol=1e-5)


def test_report_with_urdf_runs_on_that_robot(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    argv = ["report", "--quick", "-n", "1", "--solvers", "dls", *PANDA_CHAIN]
    assert main([*argv, "--out", str(tmp_path)]) == 0
    capsys.readouterr()
    summary = json.loads((tmp_path / "summary.json").read_text(encoding="utf-8"))
    assert summary["config"]["problems"] == [str(PANDA_URDF)]
    rows = (tmp_path / "results.csv").read_text(encoding="utf-8").splitlines()
    ik_rows = [r for r in rows if r.startswith("ik,")]
    assert len(ik_rows) == 1 and ik_rows[0].startswith("ik,panda,")


def _two_link(folder: Path) -> Path:
    """A DH table without a ``source``: two links of 0.5 and 0.25 m, limits +-170 deg."""
    table = folder / "two_link.toml"
    table.write_text(
        '[robot]\nname = "two_link"\nangle_unit = "deg"\n'
        "[[robot.joints]]\na = 0.5\nlower = -170\nupper = 170\n"
        "[[robot.joints]]\na = 0.25\nlower = -170\nupper = 170\n",
        encoding="utf-8",
    )
    return table


def test_dh_table_file_for_solve(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    table = _two_link(tmp_path)
    q = np.radians([30.0, 45.0])
    x = 0.5 * math.cos(q[0]) + 0.25 * math.cos(q.sum())
    y = 0.5 * math.sin(q[0]) + 0.25 * math.sin(q.sum())
    data = _solve_json(["--dh", str(table), "--position", repr(x), repr(y), "0"], capsys)
    assert data["success"] and data["problem"] == "two_link"
    q_found = np.array(data["q"])
    p = [
        0.5 * math.cos(q_found[0]) + 0.25 * math.cos(q_found.sum()),
        0.5 * math.sin(q_found[0]) + 0.25 * math.sin(q_found.sum()),
    ]
    np.testing.assert_allclose(p, [x, y], atol=1e-6)


def test_robot_of_a_dh_table(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    table = _two_link(tmp_path)
    assert main(["robot", str(table)]) == 0
    out = capsys.readouterr().out
    assert f"source: robot file {table}" in out
    assert "chain: base -> tool  (2 joints)" in out
    limit = f"{math.radians(170):.6g} rad (170 deg)"
    assert out.count(limit) == 2
    assert out.rstrip().endswith("closed-form family: planar_2r")


def test_report_with_dh_runs_on_that_robot(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    table = _two_link(tmp_path)
    out = tmp_path / "out"
    argv = ["report", "--quick", "-n", "2", "--solvers", "dls", "--dh", str(table)]
    assert main([*argv, "--out", str(out)]) == 0
    capsys.readouterr()
    rows = (out / "results.csv").read_text(encoding="utf-8").splitlines()
    ik_rows = [r for r in rows if r.startswith("ik,")]
    assert len(ik_rows) == 2 and all(r.startswith("ik,two_link,") for r in ik_rows)


def test_dh_refuses_a_urdf_convention_file(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    file = tmp_path / "u.toml"
    file.write_text(
        f'[robot]\nname = "u"\nconvention = "urdf"\nurdf = "{PANDA_URDF}"\n'
        'base_link = "panda_link0"\ntip_link = "panda_hand"\n',
        encoding="utf-8",
    )
    assert main(["solve", "--dh", str(file), "--position", "0.4", "0", "0.5"]) == 2
    assert "is not a DH table" in _one_error_line(capsys.readouterr().err)


@pytest.mark.parametrize(
    ("argv", "words"),
    [
        (["solve", "--position", "1", "1", "0"], "give a robot"),
        (["solve", "planar_2r", "--dh", "x.toml", "--position", "1", "1", "0"], "not PROBLEM and"),
        (["solve", "planar_2r", "--base", "a", "--position", "1", "1", "0"], "give --urdf"),
        (["solve", "--urdf", str(PANDA_URDF), "--position", "1", "1", "0"], "panda_link0 ->"),
        (["plan", "--urdf", "a.urdf", "--dh", "b.toml", "--line", *"000111"], "--urdf and --dh"),
        (["report", "--problems", "ur5", "--urdf", str(PANDA_URDF)], "--problems and --urdf"),
        (["report", "--problems", "nosuch"], "built-in problems: dobot_magician"),
    ],
)
def test_robot_choice_errors_exit_2(
    argv: list[str], words: str, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(argv) == 2
    assert words in _one_error_line(capsys.readouterr().err)


@pytest.mark.parametrize("command", ["solve", "plan", "problems", "robot"])
def test_an_unknown_problem_name_lists_the_builtins(
    command: str, capsys: pytest.CaptureFixture[str]
) -> None:
    extra = {"solve": ["--position", "1", "1", "0"], "plan": ["--line", *"000111"]}
    assert main([command, "no_such_robot", *extra.get(command, [])]) == 2
    line = _one_error_line(capsys.readouterr().err)
    assert "'no_such_robot'" in line
    for path in optik.problems.builtin_problems():
        assert path.stem in line


# ---------------------------------------------------------------------------- optik robot
def test_robot_of_a_urdf_lists_links_chains_joints_and_family(
    capsys: pytest.CaptureFixture[str],
) -> None:
    assert main(["robot", str(PANDA_URDF)]) == 0
    out = capsys.readouterr().out
    links_line = next(line for line in out.splitlines() if line.startswith("links"))
    assert links_line == f"links ({len(PANDA_LINKS)}): " + ", ".join(PANDA_LINKS)
    assert "panda_link0 -> panda_hand  (7 moving joints, 8 in all)" in out
    robot = _panda()
    for joint in robot.joints:  # every limit in rad, with degrees alongside
        row = next(line for line in out.splitlines() if f" {joint.name} " in line)
        assert f"{joint.lower:.6g} rad ({math.degrees(joint.lower):.4g} deg)" in row
        assert f"{joint.upper:.6g} rad ({math.degrees(joint.upper):.4g} deg)" in row
    assert "closed-form family: none (numeric solvers)\n" in out
    # The joint whose holding leaves six with a closed form (solve_ik with it frozen).
    assert out.rstrip().endswith("closed form with one joint frozen: panda_joint7")


def test_robot_of_a_branching_urdf_lists_the_chains_to_pick(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    def joint(name: str, parent: str, child: str, kind: str = "revolute") -> str:
        limit = '<limit lower="-1" upper="1"/>' if kind == "revolute" else ""
        return (
            f'<joint name="{name}" type="{kind}"><parent link="{parent}"/>'
            f'<child link="{child}"/><axis xyz="0 0 1"/>{limit}</joint>'
        )

    links = "".join(f'<link name="{n}"/>' for n in ("root", "arm", "left", "right", "cam"))
    joints = (
        joint("j1", "root", "arm")
        + joint("jl", "arm", "left")
        + joint("jr", "arm", "right")
        + joint("jc", "root", "cam", "fixed")
    )
    urdf = tmp_path / "tree.urdf"
    urdf.write_text(f'<robot name="tree">{links}{joints}</robot>', encoding="utf-8")
    assert main(["robot", str(urdf)]) == 0
    out = capsys.readouterr().out
    assert "root -> left  (2 moving joints, 2 in all)" in out
    assert "root -> right  (2 moving joints, 2 in all)" in out
    assert "root -> cam  (0 moving joints, 1 in all)" in out
    assert "pick a chain with --base LINK --tip LINK" in out
    assert main(["robot", str(urdf), "--base", "root", "--tip", "right"]) == 0
    out = capsys.readouterr().out
    assert "chain root -> right: 2 moving joints" in out and " jr " in out and " jl " not in out


def test_robot_of_a_problem_file_prints_joints_and_family(
    capsys: pytest.CaptureFixture[str],
) -> None:
    assert main(["robot", "puma560"]) == 0
    out = capsys.readouterr().out
    robot = load("puma560").robot
    assert f"chain: base -> tool  ({robot.dof} joints)" in out
    assert out.rstrip().endswith("closed-form family: spherical_wrist")
    assert main(["robot", str(ROOT / "problems" / "stanford_arm.toml")]) == 0
    out = capsys.readouterr().out
    assert "prismatic" in out and re.search(r"\d m \.\. \d+(\.\d+)? m", out)


def test_robot_with_base_and_tip_of_a_toml_exits_2(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["robot", "puma560", "--base", "a", "--tip", "b"]) == 2
    assert "name links of a URDF" in _one_error_line(capsys.readouterr().err)


# ---------------------------------------------------------------------------- poses
def _puma_target() -> tuple[Robot, np.ndarray]:
    robot = load("puma560").robot
    return robot, robot.fk(np.array([0.3, 0.4, -0.9, 0.2, 0.6, -0.4]))


def _orientation_args(option: str, R: np.ndarray) -> list[str]:
    rotation = Rotation.from_matrix(R)
    values = {
        "--rpy": rotation.as_euler("xyz"),
        "--rpy-deg": rotation.as_euler("xyz", degrees=True),
        "--quat-xyzw": rotation.as_quat(),  # scipy: scalar last
        "--quat-wxyz": np.roll(rotation.as_quat(), 1),
    }[option]
    return [option, *(f"{v:.17g}" for v in values)]


ORIENTATIONS = ["--rpy", "--rpy-deg", "--quat-wxyz", "--quat-xyzw"]


@pytest.mark.parametrize("option", ORIENTATIONS)
def test_solve_orientation_options_match_scipy(
    option: str, capsys: pytest.CaptureFixture[str]
) -> None:
    robot, T = _puma_target()
    position = [f"{v:.17g}" for v in T[:3, 3]]
    data = _solve_json(
        ["puma560", "--position", *position, *_orientation_args(option, T[:3, :3])], capsys
    )
    assert data["success"]
    np.testing.assert_allclose(robot.fk(np.array(data["q"])), T, atol=1e-6)


@pytest.mark.parametrize("option", ORIENTATIONS)
def test_plan_line_orientation_options_match_scipy(
    option: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    R = Rotation.from_euler("z", 30, degrees=True).as_matrix()  # planar 2R: about z only
    argv = ["plan", "planar_2r", "--line", "1.5", "0", "0", "1.5", "0.1", "0", "--step", "0.05"]
    code = main([*argv, *_orientation_args(option, R), "--out", str(tmp_path)])
    capsys.readouterr()
    status = json.loads((tmp_path / "plan.json").read_text())["status"]
    unsolved = {"unreachable", "outside_limits", "not_found"}
    assert code == (1 if unsolved & set(status) else 0)  # the files are written either way
    poses = np.load(tmp_path / "plan.npz")["poses"]
    assert poses.shape == (3, 4, 4)
    np.testing.assert_allclose(poses[:, :3, :3], np.broadcast_to(R, (3, 3, 3)), atol=1e-12)
    np.testing.assert_allclose(poses[:, 1, 3], [0.0, 0.05, 0.1], atol=1e-12)


@pytest.mark.parametrize("option", ORIENTATIONS)
def test_an_orientation_with_path_is_an_error(
    option: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = tmp_path / "p.csv"
    path.write_text("x,y,z\n1.5,0,0\n1.5,0.1,0\n", encoding="utf-8")
    args = _orientation_args(option, np.eye(3))
    assert main(["plan", "planar_2r", "--path", str(path), *args, "--out", str(tmp_path)]) == 2
    assert "orientation of --line only" in _one_error_line(capsys.readouterr().err)


def test_two_orientation_forms_are_a_usage_error(capsys: pytest.CaptureFixture[str]) -> None:
    argv = ["solve", "puma560", "--position", "0.4", "0", "0.3", "--rpy", "0", "0", "0"]
    assert _exit_code([*argv, "--quat-wxyz", "1", "0", "0", "0"]) == 2
    assert "not allowed with argument" in _one_error_line(capsys.readouterr().err)


def test_a_quaternion_far_from_unit_norm_exits_2(capsys: pytest.CaptureFixture[str]) -> None:
    argv = ["solve", "puma560", "--position", "0.4", "0", "0.3", "--quat-xyzw", "0", "0", "0", "2"]
    assert main(argv) == 2
    assert "quat_xyzw" in _one_error_line(capsys.readouterr().err)


def test_q0_is_in_radians(capsys: pytest.CaptureFixture[str]) -> None:
    # From q0 = (0, pi/2) the planar 2R's nearest solution of (1, 1) is that q0 itself.
    argv = ["planar_2r", "--position", "1", "1", "0", "--solver", "dls", "--q0", "0", "1.5707963"]
    data = _solve_json(argv, capsys)
    np.testing.assert_allclose(data["q"], [0.0, math.pi / 2], atol=1e-6)


# ---------------------------------------------------------------------------- units rule
UNIT_WORD = re.compile(r"(?<![\w-])(m|rad|deg|s|ms)(?![\w-])|no unit")


def _subparsers(parser: argparse.ArgumentParser) -> dict[str, argparse.ArgumentParser]:
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            return dict(action.choices)
    raise AssertionError("no subcommands")


def _options() -> list[tuple[str, argparse.Action]]:
    parser = build_parser()
    found = [("optik", a) for a in parser._actions]
    for name, sub in _subparsers(parser).items():
        found += [(name, a) for a in sub._actions]
    # A hidden option (a deprecated alias, help=SUPPRESS) is in no help text to check.
    return [
        (name, a)
        for name, a in found
        if not isinstance(a, argparse._HelpAction | argparse._SubParsersAction)
        and a.help != argparse.SUPPRESS
    ]


TEXT_TYPES = ("str", "path_text", "peer_list")
"""The CLI's argument types whose values are text (names, paths, lists of names)."""


def _takes_numbers(action: argparse.Action) -> bool:
    """Whether an option's values are numbers: not a flag, a choice, a name or a path."""
    text = action.type is None or getattr(action.type, "__name__", "") in TEXT_TYPES
    return action.nargs != 0 and not action.choices and not text


@pytest.mark.parametrize(
    ("command", "action"),
    _options(),
    ids=[f"{c} {(a.option_strings or [a.dest])[0]}" for c, a in _options()],
)
def test_every_option_states_its_unit(command: str, action: argparse.Action) -> None:
    assert action.help, f"optik {command} {action.option_strings or action.dest}: no help"
    if not _takes_numbers(action):
        # A flag or a choice has no unit to state (a file may state its contents' units).
        if action.nargs == 0 or action.choices:
            assert "no unit" not in action.help, f"optik {command} {action.option_strings}"
        return
    assert UNIT_WORD.search(action.help), (
        f"optik {command} {action.option_strings or action.dest}: help names no unit "
        f"(m, rad, deg, s, ms or 'no unit'): {action.help!r}"
    )


def test_the_units_rule_catches_an_option_without_a_unit() -> None:
    assert not UNIT_WORD.search("initial guess")
    assert not UNIT_WORD.search("the mode of the solver")  # 'm' only as a word
    assert UNIT_WORD.search("target position, m")
    assert UNIT_WORD.search("no unit")


@pytest.mark.parametrize("name", sorted(_subparsers(build_parser())))
def test_every_command_has_a_description_and_an_example(name: str) -> None:
    sub = _subparsers(build_parser())[name]
    assert sub.description and len(sub.description) > 40
    assert sub.epilog and f"optik {name}" in sub.epilog


def test_version(capsys: pytest.CaptureFixture[str]) -> None:
    assert _exit_code(["--version"]) == 0
    assert capsys.readouterr().out.strip() == f"optik {optik.__version__}"


# ---------------------------------------------------------------------------- progress
def test_plan_draws_progress_for_every_waypoint(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    class Drawn(cli._plan.Progress):
        def __init__(self, total: int, **kwargs: Any) -> None:
            super().__init__(total, enabled=True, interval=0.0)

    monkeypatch.setattr(cli._plan, "Progress", Drawn)
    argv = ["plan", "planar_2r", "--line", "1.5", "0", "0", "1.5", "0.1", "0", "--step", "0.01"]
    assert main([*argv, "--out", str(tmp_path)]) == 0
    err = capsys.readouterr().err
    assert "11/11" in err and err.count("\r") == 11


def test_robot_lists_the_links_of_a_urdf_whose_one_chain_cannot_be_loaded(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # The mimic joint's error stopped the command before the links it exists to show.
    urdf = tmp_path / "mimic.urdf"
    urdf.write_text(
        "<robot name='r'><link name='a'/><link name='b'/><link name='c'/>"
        "<joint name='j1' type='revolute'><parent link='a'/><child link='b'/>"
        "<limit lower='-1' upper='1'/></joint>"
        "<joint name='j2' type='revolute'><parent link='b'/><child link='c'/>"
        "<limit lower='-1' upper='1'/><mimic joint='j1'/></joint></robot>"
    )
    assert main(["robot", str(urdf)]) == 0
    out = capsys.readouterr().out
    assert "links (3): a, b, c" in out
    assert "chain a -> c: cannot be loaded (joint 'j2': mimic joints are not supported" in out
    # Asked for by name, the chain is an error, as before.
    assert main(["robot", str(urdf), "--base", "a", "--tip", "c"]) == 2
