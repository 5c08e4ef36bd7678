"""Hostile-input faults in path files, path primitives and negative-number arguments.

Negative numbers with an exponent (``-3e-1``) are arguments, not options; an ``.npy``
renamed ``.npz``, an empty or single-pose NPZ, a single-waypoint TOML with ``rpy`` and a
degenerate arc or circle radius each give a clear ``OptikError`` or a one-waypoint path.
CLI cases run ``optik.cli.main`` in-process and check the exit code and the one error line.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from optik.cli import build_parser, main
from optik.errors import OptikError
from optik.paths import PathFileError, arc, circle, read_path

LINE = ["5e-1", "-3e-1", "2e-1", "5e-1", "3e-1", "2e-1"]


def _run(argv: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str]:
    """Exit code and standard error of ``optik ARGV`` (argparse's exits included)."""
    try:
        code = main(argv)
    except SystemExit as exc:
        code = exc.code if isinstance(exc.code, int) else 2
    return code, capsys.readouterr().err


def _one_error_line(err: str) -> str:
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("optik: error: "), err
    assert "Traceback" not in err
    return lines[0]


def _pose(x: float, y: float, z: float = 0.0) -> np.ndarray:
    T = np.eye(4)
    T[:3, 3] = [x, y, z]
    return T


# ---------------------------------------------------------------- negative exponents
def test_line_takes_negative_numbers_with_an_exponent() -> None:
    args = build_parser().parse_args(["plan", "puma560", "--line", *LINE, "--out", "p"])
    assert args.line == [0.5, -0.3, 0.2, 0.5, 0.3, 0.2]


def test_map_bounds_take_negative_numbers_with_an_exponent() -> None:
    argv = ["map", "puma560", "--bounds", "-1e-1", "1", "-1E+0", "1", "-.5e0", "1", "--out", "m"]
    args = build_parser().parse_args(argv)
    assert args.bounds == [-0.1, 1.0, -1.0, 1.0, -0.5, 1.0]


def test_plan_runs_with_a_negative_exponent_in_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    line = ["1.5", "-1e-1", "0", "1.5", "1e-1", "0"]
    argv = ["plan", "planar_2r", "--line", *line, "--out", str(tmp_path / "plan")]
    code, err = _run(argv, capsys)
    assert code == 0, err


def test_an_overflowing_negative_exponent_is_refused_as_a_number(
    capsys: pytest.CaptureFixture[str],
) -> None:
    # -1e400 now reaches the length type (float() gives -inf), which names it.
    argv = ["plan", "planar_2r", "--line", "1.5", "-1e400", "0", "1.5", "0.1", "0"]
    code, err = _run(argv, capsys)
    assert code == 2
    line = _one_error_line(err)
    assert "'-1e400'" in line and "length" in line


@pytest.mark.parametrize("bad", ["-inf", "inf", "nan", "-nan", "-Infinity", "-NaN"])
def test_non_finite_numbers_are_refused_by_name(
    bad: str, capsys: pytest.CaptureFixture[str]
) -> None:
    # Refused as numbers, naming the value: "-inf" taken for an option read "--line:
    # expected 6 arguments", which pointed at the count.
    argv = ["plan", "planar_2r", "--line", "1.5", bad, "0", "1.5", "0.1", "0"]
    code, err = _run(argv, capsys)
    assert code == 2
    line = _one_error_line(err)
    assert f"got {bad!r}" in line and "--line" in line, line
    code, err = _run(["solve", "planar_2r", "--position", bad, "1", "0"], capsys)
    assert code == 2
    line = _one_error_line(err)
    assert f"got {bad!r}" in line and "--position" in line, line


# ---------------------------------------------------------------- path files
def test_an_npy_named_npz_is_a_path_file_error(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    npy = tmp_path / "a.npy"
    np.save(npy, np.zeros((3, 3)))
    file = npy.rename(tmp_path / "path.npz")
    with pytest.raises(PathFileError, match=r"path\.npz: not an \.npz archive"):
        read_path(file)
    code, err = _run(["plan", "planar_2r", "--path", str(file), "--out", str(tmp_path)], capsys)
    assert code == 2
    assert "not an .npz archive" in _one_error_line(err)


def test_an_npz_of_one_pose_is_one_waypoint_like_a_csv(tmp_path: Path) -> None:
    np.savez(tmp_path / "one.npz", poses=_pose(0.1, 0.2, 0.3))
    (tmp_path / "one.csv").write_text("x,y,z\n0.1,0.2,0.3\n", encoding="utf-8")
    poses, mode = read_path(tmp_path / "one.npz")
    assert poses.shape == (1, 4, 4) and mode == "pose"
    assert np.array_equal(poses, read_path(tmp_path / "one.csv")[0])


@pytest.mark.parametrize(
    "name, array", [("poses", np.zeros((0, 4, 4))), ("positions", np.zeros((0, 3)))]
)
def test_an_empty_npz_is_refused_like_an_empty_csv(
    tmp_path: Path, name: str, array: np.ndarray
) -> None:
    np.savez(tmp_path / "empty.npz", **{name: array})
    with pytest.raises(PathFileError, match="at least one waypoint"):
        read_path(tmp_path / "empty.npz")


def test_a_toml_of_one_position_and_one_rpy_is_one_pose(tmp_path: Path) -> None:
    file = tmp_path / "one.toml"
    file.write_text("positions = [0.1, 0.2, 0.3]\nrpy = [0.0, 0.0, 0.5]\n", encoding="utf-8")
    poses, mode = read_path(file)
    assert poses.shape == (1, 4, 4) and mode == "pose"
    assert np.allclose(poses[0, :3, 3], [0.1, 0.2, 0.3])
    assert np.isclose(poses[0, 1, 0], np.sin(0.5))


# ---------------------------------------------------------------- primitives
def test_an_arc_of_a_vanishing_radius_names_the_radius() -> None:
    with pytest.raises(OptikError, match=r"arc: radius .*1e-160 m is below the minimum"):
        arc(_pose(1e-160, 0.0), _pose(0.0, 1e-160), np.zeros(3), 0.1)


def test_a_circle_whose_start_lies_on_its_axis_names_the_radius() -> None:
    with pytest.raises(OptikError, match=r"circle: radius .* 0 m is below the minimum"):
        circle(_pose(0.0, 0.0, 1.0), np.zeros(3), [0.0, 0.0, 1.0], 0.1)


def test_map_plots_into_a_file_is_refused_before_the_map_is_computed(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """``--plots`` naming a file: the map was computed and written, then the plots were
    skipped with a note and exit 0. Now the command stops first, exit 2, nothing written."""
    from optik.cli import main

    occupied = tmp_path / "plots"
    occupied.write_text("a file")
    out = tmp_path / "m.zarr"
    code = main(["map", "planar_2r", "--voxel", "0.5", "--out", str(out), "--plots", str(occupied)])
    assert code == 2
    assert "is a file, not a folder" in capsys.readouterr().err
    assert not out.exists()


@pytest.mark.parametrize(
    "args",
    [
        ["robot", "{folder}"],
        ["problems", "{folder}"],
        ["solve", "--dh", "{folder}", "--position", "1", "0", "0"],
        ["solve", "--urdf", "{folder}", "--base", "a", "--tip", "b", "--position", "1", "0", "0"],
        ["plan", "puma560", "--path", "{folder}"],
        ["batch", "puma560", "{folder}", "--out", "{out}"],
    ],
)
def test_a_folder_given_for_a_file_is_named_a_folder(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], args: list[str]
) -> None:
    # Each said "file not found" about a path that exists.
    folder = tmp_path / "given.toml"
    folder.mkdir()
    out = tmp_path / "out.parquet"
    code = main([a.format(folder=folder, out=out) for a in args])
    err = capsys.readouterr().err
    assert code == 2 and "a folder, not a file" in err and str(folder) in err, err
    assert "not found" not in err
