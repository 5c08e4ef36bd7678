"""Hostile inputs to the comparison runs, the report and the batch: each a fault found by
a search, kept from coming back."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from conftest import run_cli

from optik import OptikError, load_problem
from optik.campaign import solve_batch
from optik.cli import main
from optik.compare import RunConfig, read_results
from optik.compare.results import COLUMNS, ResultsFile
from optik.errors import OutputFileError, ResultsFileError

BASE: dict[str, Any] = {
    "problems": ("planar_2r",),
    "solvers": ("dls",),
    "n": 1,
    "seeds": False,
    "closed_form_configs": 0,
}


SMALL_REPORT = ["report", "--quick", "-n", "1", "--problems", "planar_2r", "--solvers", "dls"]


def test_a_foreign_results_file_is_not_overwritten(tmp_path: Path) -> None:
    """A results.csv that is not an optik table was truncated by a run without --resume."""
    (tmp_path / "results.csv").write_text("precious user data\n")
    with pytest.raises(OutputFileError, match="not an optik results table"):
        ResultsFile(tmp_path / "results.csv")
    assert (tmp_path / "results.csv").read_text() == "precious user data\n"
    code, err = run_cli([*SMALL_REPORT, "--out", str(tmp_path)])
    assert code == 2 and "not an optik results table" in err
    assert (tmp_path / "results.csv").read_text() == "precious user data\n"


def test_an_earlier_runs_table_is_started_over(tmp_path: Path) -> None:
    path = tmp_path / "results.csv"
    ResultsFile(path).close()
    path.write_text(path.read_text() + "a row of an earlier run\n")  # its header: optik's
    table = ResultsFile(path)
    table.close()
    assert read_results(path) == []
    assert path.read_text().splitlines() == [",".join(COLUMNS)]


def test_missing_or_unreadable_results_files_are_named(tmp_path: Path) -> None:
    with pytest.raises(ResultsFileError, match=r"missing\.csv"):
        read_results(tmp_path / "missing.csv")
    with pytest.raises(ResultsFileError, match="cannot read"):
        read_results(tmp_path)
    if os.geteuid() != 0:  # root reads anything: the permission case needs a user
        locked = tmp_path / "locked.csv"
        locked.write_text(",".join(COLUMNS) + "\n")
        locked.chmod(0)
        with pytest.raises(ResultsFileError, match=r"locked\.csv"):
            read_results(locked)


@pytest.mark.parametrize(
    ("override", "field"),
    [
        ({"seed": -1}, "seed"),
        ({"seed": 0.5}, "seed"),
        ({"seed": "x"}, "seed"),
        ({"n": 1.5}, "n"),
        ({"n": True}, "n"),
        ({"n": 10**12}, "n"),
        ({"n": "3"}, "n"),
        ({"caps": {"dls": -1}}, "caps"),
        ({"caps": {"dls": 0.5}}, "caps"),
        ({"caps": None}, "caps"),
        ({"closed_form_configs": 1.5}, "closed_form_configs"),
        ({"seeds": "no"}, "seeds"),
        ({"step_backends": ("qp:nosuch",)}, "step backend"),
        ({"tol": "1e-6"}, "tol"),
        ({"timeout_s": None}, "timeout_s"),
        ({"timeout_s": 1e300}, "timeout_s"),
    ],
)
def test_a_run_configuration_checks_every_field(override: dict[str, Any], field: str) -> None:
    with pytest.raises(OptikError, match=field):
        RunConfig(**{**BASE, **override})


def test_report_refuses_a_timeout_beyond_a_day(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """--timeout-ms 1e300 ran the whole comparison, then the figures overflowed."""
    with pytest.raises(SystemExit) as exit_:  # a usage error, from argparse
        main([*SMALL_REPORT, "--timeout-ms", "1e300", "--out", str(tmp_path / "r")])
    assert exit_.value.code == 2 and "--timeout-ms" in capsys.readouterr().err
    assert not (tmp_path / "r" / "results.csv").exists()


def test_a_cap_on_no_solver_of_the_run_is_an_error(tmp_path: Path) -> None:
    code, err = run_cli([*SMALL_REPORT, "--cap", "casadi_ipopt=1", "--out", str(tmp_path / "r")])
    assert code == 2 and "casadi_ipopt" in err


def test_a_bad_quaternion_in_a_targets_file_names_the_file(tmp_path: Path) -> None:
    import pyarrow as pa  # the test extra installs the cluster extra
    import pyarrow.parquet as parquet

    targets = tmp_path / "zero_quaternion.parquet"
    columns = {"x": [0.3], "y": [0.1], "z": [0.4], "qw": [0.0], "qx": [0.0], "qy": [0.0]}
    parquet.write_table(pa.table({**columns, "qz": [0.0]}), targets)
    code, err = run_cli(["batch", "ur5", str(targets), "--out", str(tmp_path / "out")])
    assert code == 2 and "zero_quaternion.parquet" in err and "quaternion" in err


def test_a_stray_part_file_in_a_batch_folder_is_an_error(tmp_path: Path) -> None:
    """A part file copied in from another run was counted on --resume (7 rows for 6
    targets, exit 0); one of another schema raised pyarrow's error."""
    robot = load_problem("planar_2r").robot
    targets = robot.fk(np.random.default_rng(3).uniform(-1.0, 1.0, (6, 2)))[:, :3, 3]
    options: dict[str, Any] = {"mode": "position", "restarts": 1}
    solve_batch(robot, targets, out=tmp_path / "a", **options)
    solve_batch(robot, targets, out=tmp_path / "b", chunk=1, **options)
    stray = (tmp_path / "b" / "part-000003.parquet").read_bytes()
    (tmp_path / "a" / "part-000007.parquet").write_bytes(stray)
    with pytest.raises(OptikError, match=r"part-000007\.parquet: a part file of another run"):
        solve_batch(robot, targets, out=tmp_path / "a", resume=True, **options)
    # A part of this very run under another name: its rows are counted twice.
    own = (tmp_path / "a" / "part-000000.parquet").read_bytes()
    (tmp_path / "a" / "part-000007.parquet").write_bytes(own)
    with pytest.raises(OptikError, match=r"part-000007\.parquet: holds rows 0 to 5, but the run"):
        solve_batch(robot, targets, out=tmp_path / "a", resume=True, **options)
    # Copied over another chunk's part: the counts agree, the file is named all the same.
    (tmp_path / "a" / "part-000007.parquet").unlink()
    (tmp_path / "b" / "part-000000.parquet").write_bytes(stray)
    with pytest.raises(
        OptikError, match=r"part-000000\.parquet: holds rows 3 to 3, not chunk 0's targets 0 to 0"
    ):
        solve_batch(robot, targets, out=tmp_path / "b", chunk=1, resume=True, **options)
