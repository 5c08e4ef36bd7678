"""Hostile inputs to the output places, ``report --resume``, path CSVs, the reachability
figure and ``optik show``'s camera option: each a fault found by a search (session s36b),
kept from coming back."""

from __future__ import annotations

import argparse
import re
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from conftest import run_cli

from optik.cli import build_parser, main
from optik.compare import read_results
from optik.compare.results import COLUMNS, ResultsFile
from optik.errors import ArgumentError, OutputFileError, ResultsFileError
from optik.paths import PathFileError, read_path

# /proc/self refuses new entries even to root, whose os.access otherwise says yes to
# any folder (a chmod-ed temporary folder cannot stand in for an unwritable place here).
UNWRITABLE = "/proc/self/optik-out"
needs_proc = pytest.mark.skipif(
    not Path("/proc/self").is_dir(), reason="needs the Linux /proc file system"
)


def _fail_if_called(*_args: Any, **_kwargs: Any) -> Any:
    raise AssertionError("the work started before the output place was checked")


# ------------------------------------------------------------- F3: unwritable --out
@needs_proc
def test_check_folder_refuses_a_place_that_cannot_be_written_and_creates_nothing(
    tmp_path: Path,
) -> None:
    from optik._files import check_folder

    with pytest.raises(OutputFileError, match=r"/proc/self is not a writable folder"):
        check_folder(f"{UNWRITABLE}/deeper")
    new = tmp_path / "new" / "deeper"
    assert check_folder(new) == new
    assert list(tmp_path.iterdir()) == []  # a check creates nothing


@needs_proc
def test_plan_refuses_an_unwritable_out_before_planning(
    capsys: pytest.CaptureFixture[str],
) -> None:
    """The plan was computed and its summary printed, then the write failed."""
    argv = ["plan", "planar_2r", "--line", "1", "1", "0", "1.2", "1", "0", "--step", "0.1"]
    assert main([*argv, "--out", UNWRITABLE]) == 2
    out, err = capsys.readouterr()
    assert out == ""  # nothing planned
    assert "is not a writable folder" in err


@needs_proc
def test_show_refuses_an_unwritable_out_before_drawing(
    capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    import optik.drawing

    monkeypatch.setattr(optik.drawing, "show_robot", _fail_if_called)
    assert main(["show", "planar_2r", "--out", f"{UNWRITABLE}/robot.png"]) == 2
    out, err = capsys.readouterr()
    assert out == "" and "is not a writable folder" in err


def test_show_refuses_a_folder_named_like_an_image_before_drawing(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    import optik.drawing

    monkeypatch.setattr(optik.drawing, "show_robot", _fail_if_called)
    (tmp_path / "d.png").mkdir()
    assert main(["show", "planar_2r", "--out", str(tmp_path / "d.png")]) == 2
    out, err = capsys.readouterr()
    assert out == "" and "a folder, not an image file" in err


@needs_proc
def test_batch_and_map_refuse_an_unwritable_out_before_their_engine_starts(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    import optik.campaign.batch
    import optik.campaign.capability

    monkeypatch.setattr(optik.campaign.batch, "open_engine", _fail_if_called)
    monkeypatch.setattr(optik.campaign.capability, "open_engine", _fail_if_called)
    code, err = run_cli(["map", "planar_2r", "--voxel", "0.5", "--out", f"{UNWRITABLE}/m.zarr"])
    assert code == 2 and "is not a writable folder" in err
    targets = "/proc/self/cmdline"  # never read: the output place is checked first
    code, err = run_cli(["batch", "planar_2r", targets, "--out", f"{UNWRITABLE}/b.parquet"])
    assert code == 2 and "is not a writable folder" in err, err


@needs_proc
def test_report_refuses_an_unwritable_out() -> None:
    argv = ["report", "--quick", "-n", "1", "--problems", "planar_2r", "--solvers", "dls"]
    code, err = run_cli([*argv, "--out", UNWRITABLE])
    assert code == 2 and "is not a writable folder" in err


# ------------------------------------------------- F4: report --resume on a bad file
@pytest.mark.parametrize(
    "content",
    [b"name,value\nalpha,1\nbeta,2", b"\x00\xff", b"name,value", b"not,a,table\n"],
    ids=["foreign-table", "binary-junk", "foreign-header-only", "foreign-line"],
)
def test_resume_refuses_a_foreign_file_and_leaves_it_byte_identical(
    tmp_path: Path, content: bytes
) -> None:
    """The unterminated last line was cut off before the file was checked; junk without
    a newline was silently replaced by a new table."""
    path = tmp_path / "results.csv"
    path.write_bytes(content)
    with pytest.raises(ResultsFileError, match=r"results\.csv, line 1: "):
        ResultsFile(path, resume=True)
    assert path.read_bytes() == content
    argv = ["report", "--problems", "planar_2r", "--solvers", "dls", "-n", "1", "--resume"]
    code, err = run_cli([*argv, "--out", str(tmp_path)])
    assert code == 2 and "results.csv, line 1" in err
    assert path.read_bytes() == content


def test_resume_keeps_the_partial_line_of_a_table_with_a_corrupted_row(tmp_path: Path) -> None:
    path = tmp_path / "results.csv"
    content = (",".join(COLUMNS) + "\ngarbage\npartial,ro").encode()
    path.write_bytes(content)
    with pytest.raises(ResultsFileError, match=r"line 2: corrupted row"):
        ResultsFile(path, resume=True)
    assert path.read_bytes() == content


def test_resume_still_cuts_the_partial_line_of_a_killed_run(tmp_path: Path) -> None:
    header = ",".join(COLUMNS) + "\n"
    path = tmp_path / "results.csv"
    path.write_text(header + "partial,ro", encoding="utf-8")
    ResultsFile(path, resume=True).close()
    assert path.read_text(encoding="utf-8") == header
    # Killed while writing the header: the file starts over.
    path.write_text(header[:10], encoding="utf-8")
    ResultsFile(path, resume=True).close()
    assert path.read_text(encoding="utf-8") == header
    assert read_results(path) == []


# ------------------------------------------------------ F5: path CSV line numbers
def test_a_path_csv_error_names_the_files_own_line(tmp_path: Path) -> None:
    """Blank and comment lines were dropped before the lines were numbered."""
    csv = tmp_path / "lines.csv"
    csv.write_text("x,y,z\n0.5,0.1,0.3\n\n# a comment\n0.5,0.1\n", encoding="utf-8")
    with pytest.raises(PathFileError, match=r"line 5: expected 3 values, got 2"):
        read_path(csv)
    csv.write_text("# made by hand\n\nx,y,z\n\n0.5,0.1,0.3\n0.5,oops,0.3\n", encoding="utf-8")
    with pytest.raises(PathFileError, match=r"line 6: could not convert"):
        read_path(csv)
    csv.write_text("# made by hand\n1,2,3\n4,5,6\n", encoding="utf-8")
    with pytest.raises(PathFileError, match=r"line 2 must be the header"):
        read_path(csv)
    csv.write_text('x,y,z\n# c\n"0.5\n",0.1,0.3\n0.5,0.1,nan\n', encoding="utf-8")
    with pytest.raises(PathFileError, match=r"line 5: NaN or infinite value"):
        read_path(csv)  # a quoted cell spans lines 3-4: the next row is line 5
    code, err = run_cli(["plan", "planar_2r", "--path", str(csv), "--out", str(tmp_path / "p")])
    assert code == 2 and "line 5: NaN or infinite value" in err
    csv.write_text(f'x,y,z\n\n"{"1" * 200_000}",1,1\n', encoding="utf-8")
    with pytest.raises(PathFileError, match=r"line 3: field larger than field limit"):
        read_path(csv)  # was a bare csv.Error: an internal error of the CLI


def test_a_path_csv_coordinate_beyond_the_bound_names_its_line(tmp_path: Path) -> None:
    far = tmp_path / "far.csv"
    far.write_text("x,y,z\n# a comment\n0.5,0.1,0.3\n2e9,0.1,0.3\n", encoding="utf-8")
    with pytest.raises(PathFileError, match=r"line 4: a coordinate beyond 1e\+09 m"):
        read_path(far)  # named positions[1, 0] before


def test_a_path_csv_with_a_byte_order_mark_reads(tmp_path: Path) -> None:
    """A spreadsheet's UTF-8 export begins with a BOM: its header had been refused."""
    plain, marked = tmp_path / "plain.csv", tmp_path / "marked.csv"
    text = "x,y,z,roll,pitch,yaw\n0.5,0.1,0.3,0,0,0.2\n0.5,0.2,0.3,0,0,0.3\n"
    plain.write_text(text, encoding="utf-8")
    marked.write_text(text, encoding="utf-8-sig")
    assert marked.read_bytes().startswith(b"\xef\xbb\xbf")
    (poses, mode), (again, again_mode) = read_path(plain), read_path(marked)
    assert mode == again_mode == "pose"
    np.testing.assert_array_equal(poses, again)


# ------------------------------------------------ F7: reachability_figure(value=...)
@pytest.mark.parametrize(
    ("value", "expected"),
    [
        ("abc", "a real number"),
        (True, "a real number"),
        (float("nan"), "a number, not NaN"),
        (float("inf"), "a finite number"),
        (1e300, "a length of magnitude"),
    ],
)
def test_reachability_figure_checks_value_like_other_reals(value: Any, expected: str) -> None:
    """A string raised a bare ValueError from float(), True was taken for 1.0 and NaN
    was said to miss the reach sphere."""
    from optik import load_problem
    from optik.reachability import reachability_figure

    robot = load_problem("planar_2r").robot
    with pytest.raises(ArgumentError, match=rf"^value: expected {expected}"):
        reachability_figure(robot, value=value)


# ----------------------------------------------------------- F8: show --view-deg
def _show_view(argv: list[str], monkeypatch: pytest.MonkeyPatch) -> tuple[int, str, Any]:
    """Exit code, stderr and the camera view ``optik show ARGV`` draws with."""
    import optik.drawing

    seen: dict[str, Any] = {}

    def fake_show(robot: Any, out: Any, q: Any, **kwargs: Any) -> Any:
        seen.update(kwargs)
        return out

    monkeypatch.setattr(optik.drawing, "show_robot", fake_show)
    code, err = run_cli(["show", "planar_2r", *argv, "--out", "robot.png"])
    return code, err, seen.get("view")


def test_show_takes_the_view_in_degrees_by_a_name_that_says_so(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    code, err, view = _show_view(["--view-deg", "30", "-120"], monkeypatch)
    assert code == 0 and view == (30.0, -120.0) and "deprecated" not in err
    assert _show_view([], monkeypatch)[::2] == (0, (22.0, -58.0))
    code, err, view = _show_view(["--view", "30", "-120"], monkeypatch)  # old scripts run
    assert code == 0 and view == (30.0, -120.0)
    assert "--view is deprecated" in err and "--view-deg" in err
    code, err, view = _show_view(["--view", "1", "2", "--view-deg", "3", "4"], monkeypatch)
    assert code == 2 and "--view-deg" in err and view is None


def test_options_in_degrees_or_ms_name_their_unit() -> None:
    """docs/cli.md: an option in a non-SI unit says so in its name (--rpy-deg)."""
    parser = build_parser()
    subs = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    unnamed = []
    for name, sub in subs.choices.items():
        for action in sub._actions:
            unit = re.search(r"(?<![\w-])(deg|ms)(?![\w-])", action.help or "")
            # A flag (no value) may mention a unit in passing: "100 ms per call".
            if unit and action.nargs != 0 and action.help != argparse.SUPPRESS:
                suffix = f"-{unit.group(1)}"
                if not all(o.endswith(suffix) for o in action.option_strings):
                    unnamed.append(f"optik {name} {action.option_strings}")
    assert unnamed == []
    help_text = subs.choices["show"].format_help()
    assert "--view-deg ELEV AZIM" in help_text and "--view " not in help_text


def test_an_argument_error_shows_an_array_on_one_line() -> None:
    """An array's repr spans lines, and the API's messages carried them (the CLI flattens
    its own): the value is shown on one line, cut, with its type."""
    from optik import load_problem
    from optik.campaign import solve_batch

    robot = load_problem("puma560").robot
    with pytest.raises(ArgumentError) as caught:
        solve_batch(robot, np.full((2, 3), "a"), mode="position", progress=False)
    message = str(caught.value)
    assert "\n" not in message
    assert message.startswith("targets: expected a numeric array, got array([['a', 'a', 'a'], [")
    assert message.endswith("(ndarray)")
    spaced = ArgumentError("name", "two  spaces", "a number")  # a string's spaces are kept
    assert str(spaced) == "name: expected a number, got 'two  spaces' (str)"


def test_digit_grouping_is_no_number_in_files_or_options(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Python reads "1_0" as 10: a typo in a path file was a waypoint ten times farther,
    and in an option ten times the value meant."""
    csv = tmp_path / "path.csv"
    csv.write_text("x,y,z\n0.5,0.1,0.3\n1_0,0.1,0.5\n", encoding="utf-8")
    with pytest.raises(PathFileError, match=r"line 3: an underscore in the number '1_0'"):
        read_path(csv)
    code, err = run_cli(["plan", "puma560", "--path", str(csv), "--out", str(tmp_path / "p")])
    assert code == 2 and "an underscore" in err
    csv.write_text("x,y,z\n0.5,0.1,0.3\n\uff10.2,0.1,0.5\n", encoding="utf-8")
    with pytest.raises(PathFileError, match=r"line 3: not a plain decimal number"):
        read_path(csv)  # a full-width digit: float() reads it
    for argv, expected in [
        (["map", "puma560", "--voxel", "0_3"], "--voxel: expected a finite number > 0, got '0_3'"),
        (["batch", "ur5", "t.npy", "--chunk", "1_0"], "--chunk: expected an integer >= 1"),
        (["batch", "ur5", "t.npy", "--workers", "-1"], "--workers: expected an integer >= 1"),
    ]:  # fmt: skip
        with pytest.raises(SystemExit) as exited:
            main([*argv, "--out", str(tmp_path / "out")])
        assert exited.value.code == 2
        assert expected in capsys.readouterr().err
