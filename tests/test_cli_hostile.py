"""Hostile arguments for every ``optik`` command: exit 2, one error line, no traceback.

Each case runs ``optik.cli.main`` in-process under a time limit (SIGALRM) and asserts
exit code 2, a standard error of exactly one ``optik: error: ...`` line, no traceback
and nothing on standard output. The numbers go into every numeric option of every
command; the files are missing, directories, empty, not UTF-8, not TOML or not XML, or a
URDF with a cycle.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest
from conftest import ROOT, time_limit

from optik.cli import main

TIME_LIMIT_S = 30.0  # generous: a loaded two-core machine; the cases take milliseconds
PANDA = str(ROOT / "problems" / "panda.urdf")
CHAIN = ["--base", "panda_link0", "--tip", "panda_hand"]

BAD_NUMBERS = ["nan", "inf", "-inf", "1e400", "", "abc", "1..2", "0x10", "\udcff"]
BAD_INTS = ["-1", "1.5", "nan", "", "x", str(2**32), "1" * 5000, "1e3"]

SOLVE = ["solve", "planar_2r", "--position", "1", "1", "0"]
PLAN = ["plan", "planar_2r", "--line", "1.5", "0", "0", "1.5", "0.1", "0"]
REPORT = ["report", "--quick", "--problems", "planar_2r", "--solvers", "dls"]


def _number_cases() -> list[list[str]]:
    cases: list[list[str]] = []
    for bad in BAD_NUMBERS:
        cases += [
            ["solve", "planar_2r", "--position", bad, "1", "0"],
            [*SOLVE, "--rpy", "0", bad, "0"],
            [*SOLVE, "--rpy-deg", bad, "0", "0"],
            [*SOLVE, "--quat-wxyz", "1", "0", "0", bad],
            [*SOLVE, "--quat-xyzw", bad, "0", "0", "1"],
            [*SOLVE, "--tol", bad],
            [*SOLVE, "--timeout-ms", bad],
            [*SOLVE, "--q0", "0", bad],
            ["plan", "planar_2r", "--line", "1.5", "0", "0", bad, "0.1", "0"],
            [*PLAN, "--step", bad],
            [*PLAN, "--max-joint-step", bad],
            [*PLAN, "--limit-margin", bad],
            [*PLAN, "--q0", bad, "0"],
            [*PLAN, "--rpy", bad, "0", "0"],
            [*REPORT, "--timeout-ms", bad],
            [*REPORT, "--tol", bad],
        ]
    for bad in BAD_INTS:
        cases += [[*SOLVE, "--seed", bad], [*PLAN, "--seed", bad], [*REPORT, "-n", bad]]
        cases += [[*REPORT, "--seed", bad]]
    return cases


def _value_cases() -> list[list[str]]:
    """Well-formed numbers that the library refuses (ranges, lengths, norms)."""
    return [
        ["solve", "planar_2r", "--position", "1e300", "0", "0"],
        ["solve", "planar_2r", "--position", "-1e10", "0", "0"],
        [*SOLVE, "--q0", "0", "0", "0"],
        [*SOLVE, "--q0", "100", "0"],
        [*SOLVE, "--quat-wxyz", "0", "0", "0", "0"],
        [*SOLVE, "--quat-xyzw", "1", "1", "1", "1"],
        [*SOLVE, "--target", "nosuch"],
        [*SOLVE, "--mode", "position", "--rpy", "0", "0", "0"],
        ["solve", "planar_2r", "--target", "x", "--position", "1", "1", "0"],
        ["solve", "planar_2r"],
        [*SOLVE, "--solver", "nosuch"],
        [*SOLVE, "--frobnicate"],
        ["plan", "planar_2r", "--line", "0", "0", "0", "1e300", "0", "0"],
        [*PLAN, "--step", "1e-300"],
        [*PLAN, "--q0", "0"],
        [*PLAN, "--limit-margin", "1e300"],
        ["plan", "planar_2r", "--problem-path", "nosuch"],
        ["plan", "planar_2r"],
        [*REPORT, "--cap", "dls"],
        [*REPORT, "--cap", "dls=²"],
        [*REPORT, "--cap", "=3"],
        [*REPORT, "--solvers", "nosuch"],
        ["report", "--problems", "nosuch"],
        ["report", "--problems"],
        ["robot"],
        ["robot", "puma560", "--base", "a"],
        ["robot", PANDA, "--base", "panda_link0"],
        ["robot", PANDA, "--base", "nosuch", "--tip", "panda_hand"],
        ["solve", "--urdf", PANDA, "--base", "panda_hand", "--tip", "panda_link0", *SOLVE[2:]],
        ["solve", "--urdf", PANDA, "--base", "", "--tip", "", *SOLVE[2:]],
        ["problems", "nosuch"],
        ["problems", "x" * 252],  # a name whose built-in file name would be too long
        ["solve", "x" * 252, *SOLVE[2:]],
        ["frobnicate"],
        [],
    ]


@pytest.fixture(scope="module")
def files(tmp_path_factory: pytest.TempPathFactory) -> dict[str, str]:
    folder = tmp_path_factory.mktemp("hostile")
    made: dict[str, str] = {"missing": str(folder / "missing"), "dir": str(folder)}
    contents: dict[str, bytes] = {
        "latin1.toml": "[robot]\nname = 'caf\xe9'\n".encode("latin-1"),
        "latin1.urdf": '<robot name="caf\xe9"/>'.encode("latin-1"),
        "latin1.csv": "x,y,z\n1,0,\xe9\n".encode("latin-1"),
        "empty.toml": b"",
        "empty.urdf": b"",
        "empty.csv": b"",
        "garbage.toml": b"[robot\nname = ",
        "garbage.urdf": b"<robot><link name='a'>",
        "notrobot.urdf": b"<model/>",
        "binary.npz": bytes(range(256)),
        "cycle.urdf": (
            b'<robot name="c"><link name="a"/><link name="b"/>'
            b'<joint name="ab" type="fixed"><parent link="a"/><child link="b"/></joint>'
            b'<joint name="ba" type="fixed"><parent link="b"/><child link="a"/></joint></robot>'
        ),
    }
    for name, data in contents.items():
        (folder / name).write_bytes(data)
        made[name] = str(folder / name)
    made["file"] = made["empty.csv"]
    return made


FILE_CASES: list[list[str]] = [
    ["solve", "{missing}", *SOLVE[2:]],
    ["solve", "{dir}", *SOLVE[2:]],
    ["solve", "{latin1.toml}", *SOLVE[2:]],
    ["solve", "{empty.toml}", *SOLVE[2:]],
    ["solve", "{garbage.toml}", *SOLVE[2:]],
    ["solve", "--urdf", "{missing}", *CHAIN, *SOLVE[2:]],
    ["solve", "--urdf", "{dir}", *CHAIN, *SOLVE[2:]],
    ["solve", "--urdf", "{latin1.urdf}", *CHAIN, *SOLVE[2:]],
    ["solve", "--urdf", "{empty.urdf}", *CHAIN, *SOLVE[2:]],
    ["solve", "--urdf", "{garbage.urdf}", *CHAIN, *SOLVE[2:]],
    ["solve", "--urdf", "{notrobot.urdf}", *CHAIN, *SOLVE[2:]],
    ["solve", "--urdf", "{cycle.urdf}", "--base", "a", "--tip", "b", *SOLVE[2:]],
    ["solve", "--urdf", "{cycle.urdf}", *SOLVE[2:]],
    ["solve", "--dh", "{missing}", *SOLVE[2:]],
    ["solve", "--dh", "{dir}", *SOLVE[2:]],
    ["solve", "--dh", "{latin1.toml}", *SOLVE[2:]],
    ["solve", "--dh", "{garbage.toml}", *SOLVE[2:]],
    ["plan", "planar_2r", "--path", "{missing}"],
    ["plan", "planar_2r", "--path", "{dir}"],
    ["plan", "planar_2r", "--path", "{latin1.csv}"],
    ["plan", "planar_2r", "--path", "{empty.csv}"],
    ["plan", "planar_2r", "--path", "{binary.npz}"],
    ["plan", "planar_2r", "--path", "{garbage.toml}"],
    ["plan", "--urdf", "{latin1.urdf}", *CHAIN, *PLAN[2:]],
    ["plan", "--dh", "{empty.toml}", *PLAN[2:]],
    [*PLAN, "--out", "{file}"],
    ["robot", "{missing}"],
    ["robot", "{dir}"],
    ["robot", "{latin1.urdf}"],
    ["robot", "{latin1.toml}"],
    ["robot", "{empty.urdf}"],
    ["robot", "{garbage.urdf}"],
    ["robot", "{cycle.urdf}"],
    ["report", "--problems", "{latin1.toml}"],
    ["report", "--problems", "{dir}"],
    ["report", "--urdf", "{dir}", *CHAIN],
    ["report", "--urdf", "{cycle.urdf}"],
    ["report", "--dh", "{missing}"],
    [*REPORT, "--out", "{file}"],
    ["problems", "{dir}"],
    ["problems", "{latin1.toml}"],
]


def _run(argv: list[str]) -> int:
    with time_limit(TIME_LIMIT_S):
        try:
            return main(argv)
        except SystemExit as exc:  # argparse's usage errors
            return int(exc.code) if isinstance(exc.code, int) else 2


def _check(argv: list[str], capsys: pytest.CaptureFixture[str]) -> None:
    code = _run(argv)
    captured = capsys.readouterr()
    assert "Traceback" not in captured.err, (argv, captured.err)
    assert code == 2, (argv, code, captured.err)
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("optik: error: "), (argv, captured.err)
    assert captured.out == "", (argv, captured.out)


def _path_cases() -> list[list[str]]:
    """Paths the system cannot look up: a NUL byte, a name too long, an empty string."""
    cases: list[list[str]] = []
    for bad in ["a\0b.toml", "x" * 5000, "x" * 300 + ".urdf", ""]:
        cases += [
            ["solve", bad, *SOLVE[2:]],
            ["solve", "--urdf", bad, *CHAIN, *SOLVE[2:]],
            ["solve", "--dh", bad, *SOLVE[2:]],
            ["plan", "planar_2r", "--path", bad],
            [*PLAN, "--out", bad],
            ["robot", bad],
            ["report", "--problems", bad],
            ["report", "--urdf", bad, *CHAIN],
            [*REPORT, "--out", bad],
            ["problems", bad],
        ]
    return cases


CASES = _number_cases() + _value_cases() + _path_cases()


def test_there_are_about_a_hundred_cases_or_more() -> None:
    assert len(CASES) + len(FILE_CASES) >= 100


@pytest.mark.parametrize("argv", CASES, ids=[" ".join(c)[:80] for c in CASES])
def test_hostile_arguments_exit_2_with_one_error_line(
    argv: list[str], capsys: pytest.CaptureFixture[str]
) -> None:
    _check(argv, capsys)


@pytest.mark.parametrize("template", FILE_CASES, ids=[" ".join(c)[:80] for c in FILE_CASES])
def test_hostile_files_exit_2_with_one_error_line(
    template: list[str], files: dict[str, str], capsys: pytest.CaptureFixture[str]
) -> None:
    argv = [files[a[1:-1]] if a.startswith("{") and a.endswith("}") else a for a in template]
    _check(argv, capsys)
    if "--out" in argv:  # the file in the way is left as it was
        assert Path(argv[argv.index("--out") + 1]).read_bytes() == b""


ENTRY_POINT = "import sys; from optik.cli import main; sys.exit(main())"


@pytest.mark.parametrize(
    "argv",
    [["problems"], ["robot", "puma560"], ["solve", "puma560", "--position", "0.5", "0.1", "0.4"]],
)
def test_a_closed_output_pipe_ends_quietly(argv: list[str]) -> None:
    # `optik problems | head -1`: the reader quits first. This was a BrokenPipeError
    # traceback and "internal error (a bug)", exit 3, in 6 of 10 runs.
    read_end, write_end = os.pipe()
    os.close(read_end)  # the reader is gone before the first line is written
    try:
        done = subprocess.run(
            [sys.executable, "-c", ENTRY_POINT, *argv],
            stdout=write_end, stderr=subprocess.PIPE, text=True, timeout=300, check=False,
        )  # fmt: skip
    finally:
        os.close(write_end)
    assert done.returncode == 141, done.stderr
    assert "Traceback" not in done.stderr and "internal error" not in done.stderr


@pytest.mark.parametrize(
    ("argv", "says", "not_said"),
    [
        # One value per joint, counted and named (it read "expected shape (6,) or (N, 6)").
        (
            ["show", "puma560", "--q", "0", "0.5"],
            "--q: expected 6 values, one per joint (j1,",
            "(N, 6)",
        ),
        (
            ["solve", "puma560", "--position", "0.5", "0.1", "0.4", "--q0", "0", "0", "0"],
            "--q0: expected 6 values",
            "shape",
        ),
        # `optik problems` takes no --urdf: its hint does not offer one.
        (["problems", "nosuch"], "built-in problems: ", "--urdf"),
        # The frozen value's limits with their unit.
        (
            ["solve", "puma560", "--position", "0.5", "0.1", "0.4", "--freeze", "j1=10"],
            "(rad) by 7.",
            "rad or m",
        ),
    ],
)
def test_messages_say_what_the_user_typed(
    argv: list[str], says: str, not_said: str, capsys: pytest.CaptureFixture[str]
) -> None:
    _check(argv, capsys)
    code = _run(argv)
    err = capsys.readouterr().err
    assert code == 2 and says in err and not_said not in err, err
