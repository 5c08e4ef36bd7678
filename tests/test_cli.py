"""The ``optik`` command and the documented examples."""

from __future__ import annotations

import json
import math
import re
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from conftest import PROBLEM_NAMES, ROOT, load

from optik import cli, solve_ik
from optik.cli import main
from optik.compare import COLUMNS
from optik.errors import JointLimitError, OptikError
from optik.problems import load_problem


def _row(out: str, name: str) -> str:
    lines = [line for line in out.splitlines() if line.startswith(name + " ")]
    assert len(lines) == 1, (name, out)
    return lines[0]


def _position(row: str) -> tuple[float, ...]:
    match = re.search(r"\(([^)]*)\)", row)
    assert match, row
    return tuple(float(v) for v in match.group(1).split(","))


def test_problems_lists_every_builtin(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["problems"]) == 0
    captured = capsys.readouterr()
    assert captured.err == ""
    out = captured.out
    assert out.splitlines()[0].split()[:2] == ["problem", "dof"]
    for name in PROBLEM_NAMES:
        row = _row(out, name)
        robot = load(name).robot
        assert row.split()[1] == str(robot.dof)
    assert out.count("limits:") == len(PROBLEM_NAMES)


def test_python_dash_m_optik_is_the_command(tmp_path: Path) -> None:
    """Where the environment's scripts are not on PATH, ``python -m optik`` runs the CLI
    (there was no ``__main__``: "optik is a package and cannot be directly executed")."""
    import subprocess
    import sys

    done = subprocess.run(
        [sys.executable, "-m", "optik", "problems"], capture_output=True, text=True,
        timeout=120, cwd=tmp_path,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    assert all(name in done.stdout for name in PROBLEM_NAMES)
    bad = subprocess.run(
        [sys.executable, "-m", "optik", "solve", "nope"], capture_output=True, text=True,
        timeout=120, cwd=tmp_path,
    )  # fmt: skip
    assert bad.returncode == 2 and bad.stderr.startswith("optik: error:")


def test_problems_table_values(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["problems"]) == 0
    out = capsys.readouterr().out
    # planar 2R at mid-limits (0, 0): fully stretched along x, two unit links.
    assert _position(_row(out, "planar_2r")) == (2.0, 0.0, 0.0)
    # DOBOT at mid-limits J2 = J3 = 42.5 deg: the closed-form position, in metres.
    j = math.radians(42.5)
    r = 0.135 * math.sin(j) + 0.147 * math.cos(j)
    z = 0.138 + 0.135 * math.cos(j) - 0.147 * math.sin(j)
    assert _position(_row(out, "dobot_magician")) == pytest.approx((r, 0.0, z), abs=6e-5)
    assert "J2 0..85°" in out
    assert "boom_extension 2..6 m" in out
    assert "RRPRRR" in _row(out, "stanford_arm")


def test_problems_given_by_name_and_path(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["problems", "puma560", str(ROOT / "problems" / "ur5.toml")]) == 0
    out = capsys.readouterr().out
    assert _row(out, "puma560") and _row(out, "ur5")
    assert "panda" not in out


def test_missing_problem_file_exit_code_2(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    missing = tmp_path / "missing.toml"
    assert main(["problems", str(missing)]) == 2
    captured = capsys.readouterr()
    assert captured.out == ""
    assert captured.err.startswith("optik: error: ")
    assert str(missing) in captured.err
    assert "file not found" in captured.err


def test_bad_problem_file_exit_code_2(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bad = tmp_path / "bad.toml"
    bad.write_text('[robot]\nname = "b"\nsource = "s"\n[[robot.joints]]\nrole = "arm"\nd = "x"\n')
    assert main(["problems", str(bad)]) == 2
    err = capsys.readouterr().err
    assert str(bad) in err and "[robot.joints[0]]" in err and "'d'" in err


def test_usage_errors_exit_2(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as info:
        main([])
    assert info.value.code == 2
    with pytest.raises(SystemExit) as info:
        main(["frobnicate"])
    assert info.value.code == 2
    assert "invalid choice" in capsys.readouterr().err


# ---------------------------------------------------------------------- documented examples
def _python_blocks(path: Path) -> list[str]:
    return re.findall(r"```python\n(.*?)```", path.read_text(encoding="utf-8"), flags=re.S)


@pytest.mark.parametrize("doc", ["docs/index.md", "docs/problems.md", "README.md"])
def test_documented_examples_run(doc: str, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(ROOT)  # examples use paths relative to the repository
    blocks = _python_blocks(ROOT / doc)
    assert blocks, f"{doc} has no python example"
    for code in blocks:
        exec(compile(code, doc, "exec"), {"__name__": "__doc_example__"})


# ---------------------------------------------------------------------------- exit codes
def _strict_json(text: str) -> Any:
    """JSON as the standard defines it: ``Infinity`` and ``NaN`` are not JSON."""

    def refuse(name: str) -> None:
        raise ValueError(f"not JSON: {name}")

    return json.loads(text, parse_constant=refuse)


def test_no_solution_exits_1_with_valid_json(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["solve", "planar_2r", "--position", "5", "5", "0", "--json"]) == 1
    data = _strict_json(capsys.readouterr().out)
    assert data["status"] == "unreachable" and data["success"] is False
    # Two unit links reach 2 m: the target is at least 7.07 - 2 m from every tool position.
    assert data["position_error"] >= math.hypot(5, 5) - 2.0


def test_json_writes_non_finite_numbers_as_null(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    real = cli._solve.solve_ik

    def far(*args: Any, **kwargs: Any) -> Any:
        result = real(*args, **kwargs)
        return replace(result, position_error=math.inf, orientation_error=math.nan)

    monkeypatch.setattr(cli._solve, "solve_ik", far)
    assert main(["solve", "planar_2r", "--position", "1", "1", "0", "--json"]) == 0
    out = capsys.readouterr().out
    data = _strict_json(out)
    assert data["position_error"] is None and data["orientation_error"] is None
    assert data["success"] is True and len(data["q"]) == 2
    assert "Infinity" not in out and "NaN" not in out


@pytest.mark.parametrize(
    ("argv", "names"),
    [
        (["solve", "planar_2r", "--position", "1", "1", "0", "--seed", "-1"], "--seed"),
        (["solve", "planar_2r", "--position", "1", "1", "0", "--seed", "1.5"], "--seed"),
        (["solve", "planar_2r", "--position", "nan", "1", "0"], "--position"),
        (["solve", "planar_2r", "--position", "1", "1", "0", "--tol", "0"], "--tol"),
        (["solve", "planar_2r", "--position", "1", "1", "0", "--tol", "inf"], "--tol"),
        (["solve", "planar_2r", "--position", "1", "1", "0", "--timeout-ms", "-5"], "--timeout-ms"),
        (["solve", "planar_2r", "--position", "1", "1", "0", "--q0", "0", "x"], "--q0"),
        (["plan", "planar_2r", "--line", "1", "0", "0", "1", "1", "0", "--step", "0"], "--step"),
        (["plan", "planar_2r", "--problem-path", "p", "--limit-margin", "-1"], "--limit-margin"),
        (["report", "-n", "-3"], "-n"),
        (["report", "--timeout-ms", "nan"], "--timeout-ms"),
    ],
)
def test_bad_numbers_exit_2_naming_the_argument(
    argv: list[str], names: str, capsys: pytest.CaptureFixture[str]
) -> None:
    with pytest.raises(SystemExit) as info:
        main(argv)
    assert info.value.code == 2
    err = capsys.readouterr().err
    assert f"argument {names}" in err and "Traceback" not in err


def _one_error_line(err: str) -> str:
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("optik: error: "), err
    return lines[0]


@pytest.mark.parametrize("command", ["report", "plan"])
def test_out_on_a_file_exits_2(
    command: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    taken = tmp_path / "taken"
    taken.write_text("mine", encoding="utf-8")
    extra = ["planar_2r", "--line", "1", "0", "0", "1", "1", "0"] if command == "plan" else []
    assert main([command, *extra, "--out", str(taken)]) == 2
    line = _one_error_line(capsys.readouterr().err)
    assert f"cannot write {taken}" in line and "is a file, not a folder" in line
    assert taken.read_text(encoding="utf-8") == "mine"


@pytest.mark.skipif(not Path("/proc/self").is_dir(), reason="needs the Linux /proc file system")
@pytest.mark.parametrize("command", ["report", "plan"])
def test_out_in_a_place_that_cannot_be_written_exits_2(
    command: str, capsys: pytest.CaptureFixture[str]
) -> None:
    extra = ["planar_2r", "--line", "1", "0", "0", "1", "1", "0"] if command == "plan" else []
    assert main([command, *extra, "--out", "/proc/optik-out"]) == 2
    assert "cannot write /proc/optik-out" in _one_error_line(capsys.readouterr().err)


def test_resume_of_a_corrupted_table_exits_2(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    results = tmp_path / "results.csv"
    results.write_text(",".join(COLUMNS) + "\nik,planar_2r,oops\n", encoding="utf-8")
    argv = ["report", "--quick", "-n", "1", "--problems", "planar_2r", "--solvers", "dls"]
    assert main([*argv, "--out", str(tmp_path), "--resume"]) == 2
    line = _one_error_line(capsys.readouterr().err)
    assert f"{results}, line 2: corrupted row" in line


def test_an_internal_error_is_not_a_no_solution(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    def broken(*args: Any, **kwargs: Any) -> Any:
        raise RuntimeError("a bug")

    monkeypatch.setattr(cli._solve, "solve_ik", broken)
    code = main(["solve", "planar_2r", "--position", "1", "1", "0"])
    assert code == cli.EXIT_INTERNAL == 3
    err = capsys.readouterr().err
    assert "RuntimeError: a bug" in err and "internal error" in err


def test_a_multi_line_error_is_printed_on_one_line(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    def refuse(*args: Any, **kwargs: Any) -> Any:
        raise OptikError("first part\n  second part")

    monkeypatch.setattr(cli._solve, "solve_ik", refuse)
    assert main(["solve", "planar_2r", "--position", "1", "1", "0"]) == 2
    assert _one_error_line(capsys.readouterr().err) == "optik: error: first part second part"


@pytest.mark.parametrize(
    ("option", "values", "message"),
    [
        ("--q0", ["100", "0"], "--q0: joint 'shoulder': value 100.0 outside its limits"),
        ("--posture", ["0"], "--posture: expected 2 values, one per joint (shoulder, elbow)"),
    ],
)
def test_a_joint_option_out_of_range_is_named(
    capsys: pytest.CaptureFixture[str], option: str, values: list[str], message: str
) -> None:
    # The messages named the joint or "posture", never the option typed.
    code = main(["solve", "planar_2r", "--position", "1", "1", "0", option, *values])
    err = capsys.readouterr().err
    assert code == 2 and message in err, err


def test_the_api_names_the_argument_of_a_joint_out_of_limits() -> None:
    robot = load_problem("planar_2r").robot
    target = robot.fk(np.array([0.3, 0.4]))
    with pytest.raises(JointLimitError, match=r"^q0: joint 'shoulder'"):
        solve_ik(robot, target, q0=[100.0, 0.0])
    with pytest.raises(JointLimitError, match=r"^frozen: joint 'elbow'"):
        solve_ik(robot, target, frozen={"elbow": 100.0})
