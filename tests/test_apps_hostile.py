"""Faults of ``optik report`` and the comparison runs found with unusual inputs, each
checked against a computation of its own (csv, numpy, pandas), kept from coming back."""

from __future__ import annotations

import csv
import math
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pytest
from conftest import run_cli

from optik import OptikError
from optik.cli import build_parser, config_from_args, main
from optik.compare import ResultRow, RunConfig
from optik.problems import PROBLEMS_DIR
from optik.report import make_report, protocol_text, summarize_ik, summary_cells

BASE: dict[str, Any] = {
    "problems": ("planar_2r",),
    "solvers": ("dls",),
    "n": 2,
    "seeds": False,
    "closed_form_configs": 0,
}


def _ik_rows(path: Path) -> list[dict[str, str]]:
    """The ``ik`` records of a results file, read with the csv module alone."""
    with open(path, newline="", encoding="utf-8") as f:
        return [r for r in csv.DictReader(f) if r["kind"] == "ik"]


def _longer_planar_2r(folder: Path) -> Path:
    """A copy of ``planar_2r.toml`` whose first link is longer: another robot, same name."""
    folder.mkdir()
    text = (PROBLEMS_DIR / "planar_2r.toml").read_text(encoding="utf-8")
    assert text.count("a = 1.0") == 2
    copy = folder / "planar_2r.toml"
    copy.write_text(text.replace("a = 1.0", "a = 1.5", 1), encoding="utf-8")
    return copy


def test_two_robots_of_one_name_are_refused(tmp_path: Path) -> None:
    """Two robots named alike shared their rows' keys: the second ran nothing, silently
    (2 ik rows instead of 4, exit 0)."""
    other = _longer_planar_2r(tmp_path / "other")
    config = RunConfig(**{**BASE, "problems": ("planar_2r", str(other))})
    with pytest.raises(OptikError, match="two problems are named 'planar_2r'"):
        make_report(config, tmp_path / "api", progress=False)
    assert not (tmp_path / "api" / "results.csv").exists()
    argv = ["report", "--problems", "planar_2r", str(other), "--solvers", "dls", "-n", "2"]
    code, err = run_cli([*argv, "--out", str(tmp_path / "cli")])
    assert code == 2 and "two problems are named 'planar_2r'" in err and str(other) in err
    assert not (tmp_path / "cli" / "results.csv").exists()


def test_one_problem_given_twice_runs_once(tmp_path: Path) -> None:
    problems = ("planar_2r", str(PROBLEMS_DIR / "planar_2r.toml"), "planar_2r")
    config = RunConfig(**{**BASE, "problems": problems, "solvers": ("dls", "auto", "dls")})
    assert config.solvers == ("dls", "auto")
    report = make_report(config, tmp_path, progress=False)
    rows = _ik_rows(report.results)
    assert sorted((r["solver"], r["target"]) for r in rows) == [
        (s, t) for s in ("auto", "dls") for t in ("t0000", "t0001")
    ]
    assert [(s.problem, s.solver, s.n) for s in report.ik] == [
        ("planar_2r", "dls", 2),
        ("planar_2r", "auto", 2),
        ("all", "dls", 2),
        ("all", "auto", 2),
    ]


def _row(target: str, solver: str, iterations: int) -> ResultRow:
    return ResultRow(
        kind="ik",
        problem="p",
        robot="r",
        target=target,
        solver=solver,
        settings="{}",
        success=True,
        status="converged",
        position_error=0.0,
        orientation_error=0.0,
        limit_violation=0.0,
        iterations=iterations,
        restarts=0,
        time_s=1e-3,
    )


def test_unreported_iterations_take_no_part_in_the_percentiles() -> None:
    """A peer without an iteration count (-1 per row) showed "-1 / -1" as its median and
    95th percentile; a -1 among counts pulled them down."""
    counts = {"peer:eaik": [-1, -1, -1], "mixed": [3, -1, 5, 9]}
    rows = [_row(f"t{k}", s, i) for s, values in counts.items() for k, i in enumerate(values)]
    by_solver = {s.solver: s for s in summarize_ik(rows, 0.1, overall=False)}
    assert math.isnan(by_solver["peer:eaik"].iterations_median)
    assert math.isnan(by_solver["peer:eaik"].iterations_p95)
    assert summary_cells(by_solver["peer:eaik"])[10] == "– / –"
    reported = [3, 5, 9]
    assert by_solver["mixed"].iterations_median == pytest.approx(np.median(reported))
    assert by_solver["mixed"].iterations_p95 == pytest.approx(np.percentile(reported, 95))


def test_a_peers_cap_is_stated_in_the_protocol() -> None:
    """docs/report.md: the report lists the caps; a ``peer:NAME`` cap was left out."""
    config = RunConfig(**{**BASE, "n": 5, "peers": ("ikpy",), "caps": {"peer:ikpy": 2, "dls": 3}})
    assert "Capped solvers (targets per robot): peer:ikpy: 2, dls: 3." in protocol_text(config)


def test_summary_csv_reads_without_targets(tmp_path: Path) -> None:
    """``-n 0`` wrote an empty summary.csv, which no CSV reader takes (no header)."""
    with_targets = make_report(RunConfig(**{**BASE, "n": 1}), tmp_path / "one", progress=False)
    expected = list(pd.read_csv(with_targets.summary_csv).columns)
    empty = make_report(RunConfig(**{**BASE, "n": 0}), tmp_path / "none", progress=False)
    table = pd.read_csv(empty.summary_csv)
    assert list(table.columns) == expected and len(table) == 0


@pytest.mark.parametrize("value", ["1e300", "86400001"])
def test_a_timeout_beyond_a_day_names_the_option_in_ms(
    tmp_path: Path, value: str, capsys: pytest.CaptureFixture[str]
) -> None:
    """The error named ``timeout_s`` and a value in s (``got 1e+297``), not the option."""
    argv = ["report", "--problems", "planar_2r", "--solvers", "dls", "--timeout-ms", value]
    with pytest.raises(SystemExit) as exit_:  # a usage error, from argparse
        main([*argv, "--out", str(tmp_path / "r")])
    err = capsys.readouterr().err
    assert exit_.value.code == 2 and "argument --timeout-ms" in err and "86400000 ms" in err
    assert not (tmp_path / "r").exists()
    assert config_from_args(build_parser().parse_args([*argv[:-1], "86400000"])).timeout_s == 86400


@pytest.mark.parametrize(
    ("column", "cell"),
    [
        ("iterations", "1_000"),
        ("iterations", " 7"),
        ("position_error", " 1e-3 "),
        ("position_error", "1_0.5"),
        ("time_s", "nan"),
        ("time_s", "-5.0"),
        ("time_s", "inf"),
    ],
)
def test_a_hand_edited_number_is_a_corrupted_row(tmp_path: Path, column: str, cell: str) -> None:
    """int() and float() take these cells, which the writer never writes: --resume read
    them (a negative or NaN time turned the summaries into NaN, exit 0)."""
    config = RunConfig(**BASE)
    make_report(config, tmp_path, progress=False)
    path = tmp_path / "results.csv"
    with open(path, newline="", encoding="utf-8") as f:
        records = list(csv.reader(f))
    line = next(i for i, r in enumerate(records) if r[0] == "ik") + 1  # from 1, header first
    records[line - 1][records[0].index(column)] = cell
    with open(path, "w", newline="", encoding="utf-8") as f:
        csv.writer(f, lineterminator="\n").writerows(records)
    before = path.read_bytes()
    with pytest.raises(OptikError, match=rf"line {line}: corrupted row: column '{column}'"):
        make_report(config, tmp_path, resume=True, progress=False)
    assert path.read_bytes() == before


@pytest.mark.parametrize(
    ("argv", "seeds"),
    [
        (["report", "--quick"], True),
        (["report"], True),
        (["report", "--quick", "--problems", "puma560"], False),
        (
            [
                "report",
                "--quick",
                "--urdf",
                "problems/panda.urdf",
                "--base",
                "panda_link0",
                "--tip",
                "panda_hand",
            ],
            False,
        ),
        (["report", "--problems", "ur5"], False),
    ],
)
def test_the_textbook_sections_belong_to_the_built_ins_report(
    argv: list[str], seeds: bool, monkeypatch: pytest.MonkeyPatch
) -> None:
    # A report on the user's own robot ran the seeds' DOBOT and two-link sections too,
    # and wrote their rows into its results.csv.
    monkeypatch.chdir(Path(__file__).resolve().parent.parent)
    assert config_from_args(build_parser().parse_args(argv)).seeds is seeds
