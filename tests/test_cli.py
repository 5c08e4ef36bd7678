"""The ``optik`` command and the documented examples."""

from __future__ import annotations

import math
import re
from pathlib import Path

import pytest
from conftest import PROBLEM_NAMES, ROOT, load

from optik.cli import main


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
