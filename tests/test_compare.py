"""Comparison runs (optik.compare): the long table, resume, targets, seeds, closed forms."""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import numpy as np
import pytest
from conftest import ROOT, Interrupt, one_qp_and_one_casadi, tiny_config, without_timing

from optik.compare import (
    AGREEMENT_TOL,
    CHAPTER_TABLE_2,
    COLUMNS,
    ResultRow,
    ResultsFile,
    RunConfig,
    closed_form_cases,
    dobot_chapter_rows,
    planar_2r_example,
    random_configurations,
    read_results,
    run,
    solve_step,
    step_backends,
    write_rows,
)
from optik.errors import OptikError, OutputFileError, ResultsFileError
from optik.problems import load_problem

#: The columns documented in docs/report.md, in order.
DOCUMENTED_COLUMNS = (
    "kind",
    "problem",
    "robot",
    "target",
    "solver",
    "settings",
    "success",
    "status",
    "position_error",
    "orientation_error",
    "limit_violation",
    "iterations",
    "restarts",
    "time_s",
    "backend_converged",
    "deviation",
    "method",
    "message",
)


@pytest.fixture(scope="module")
def reference(tmp_path_factory: pytest.TempPathFactory) -> list[ResultRow]:
    path = tmp_path_factory.mktemp("reference") / "results.csv"
    return run(tiny_config(), path, progress=False).rows


# ---------------------------------------------------------------------------- the table
def test_columns_are_documented() -> None:
    assert COLUMNS == DOCUMENTED_COLUMNS
    doc = (ROOT / "docs" / "report.md").read_text(encoding="utf-8")
    for column in COLUMNS:
        assert f"`{column}`" in doc, column


def test_one_row_per_target_and_solver(tmp_path: Path, reference: list[ResultRow]) -> None:
    config = tiny_config()
    path = tmp_path / "results.csv"
    rows = run(config, path, progress=False).rows
    with open(path, encoding="utf-8", newline="") as f:
        reader = csv.DictReader(f)
        assert tuple(reader.fieldnames or ()) == DOCUMENTED_COLUMNS
        records = list(reader)
    assert len(records) == len(rows)
    ik = [r for r in records if r["kind"] == "ik"]
    keys = [(r["problem"], r["target"], r["solver"]) for r in ik]
    assert len(keys) == len(set(keys)) == len(config.problems) * len(config.solvers) * config.n
    for record in ik:
        settings = json.loads(record["settings"])
        assert settings["tol"] == config.tol and settings["seed"] == config.seed
        assert settings["timeout_s"] == config.timeout_s and settings["mode"] == "pose"
        assert record["success"] in ("true", "false")
        assert float(record["time_s"]) > 0
    # Deterministic for a seed except the timings.
    assert without_timing(rows) == without_timing(reference)


def test_row_round_trip() -> None:
    row = ResultRow(
        kind="ik",
        problem="p",
        robot="r",
        target="t0001",
        solver="qp:x",
        settings='{"a":1,"b":"x,y"}',
        success=False,
        status="timeout",
        position_error=0.1 + 0.2,
        orientation_error=1e-300,
        iterations=7,
        time_s=1.5e-4,
        backend_converged=None,
        message='a "quoted", message\nover two lines',
    )
    record = dict(zip(COLUMNS, row.to_record(), strict=True))
    assert ResultRow.from_record(record) == row


def test_read_results_rejects_another_schema(tmp_path: Path) -> None:
    path = tmp_path / "other.csv"
    path.write_text("a,b\n1,2\n", encoding="utf-8")
    with pytest.raises(OptikError, match="not an optik results file"):
        read_results(path)
    with pytest.raises(OptikError, match="not an optik results file"):
        ResultsFile(path, resume=True)


# ---------------------------------------------------------------------------- resume
def test_resume_after_interruption(tmp_path: Path, reference: list[ResultRow]) -> None:
    path = tmp_path / "results.csv"
    written: list[ResultRow] = []

    def stop_after_k(row: ResultRow) -> None:
        written.append(row)
        if len(written) == 7:
            raise Interrupt

    with pytest.raises(Interrupt):
        run(tiny_config(), path, progress=False, on_row=stop_after_k)
    assert len(read_results(path)) == 7  # every row produced before the kill is kept
    stats = run(tiny_config(), path, resume=True, progress=False)
    assert stats.skipped == 7 and stats.written == len(reference) - 7
    assert without_timing(read_results(path)) == without_timing(reference)
    assert not list(tmp_path.glob(".*tmp*"))


def test_resume_after_a_partial_last_line(tmp_path: Path, reference: list[ResultRow]) -> None:
    path = tmp_path / "results.csv"
    run(tiny_config(), path, progress=False)
    text = path.read_text(encoding="utf-8")
    lines = text.splitlines(keepends=True)
    cut = "".join(lines[:10]) + lines[10][: len(lines[10]) // 2]  # killed mid-write
    path.write_text(cut, encoding="utf-8")
    assert len(read_results(path)) == 9  # the partial line is ignored on reading
    run(tiny_config(), path, resume=True, progress=False)
    assert path.read_text(encoding="utf-8").endswith("\n")
    assert without_timing(read_results(path)) == without_timing(reference)


def test_resume_with_more_targets_keeps_the_first(
    tmp_path: Path, reference: list[ResultRow]
) -> None:
    path = tmp_path / "results.csv"
    run(tiny_config(n=2), path, progress=False)
    stats = run(tiny_config(n=3), path, resume=True, progress=False)
    assert stats.written == 2 * 3  # one new target per (problem, solver)
    assert sorted(without_timing(read_results(path))) == sorted(without_timing(reference))


def test_without_resume_the_file_starts_afresh(tmp_path: Path) -> None:
    path = tmp_path / "results.csv"
    run(tiny_config(n=1, step_backends=()), path, progress=False)
    first = read_results(path)
    run(tiny_config(n=1, step_backends=()), path, progress=False)
    assert len(read_results(path)) == len(first)


def _rows(n: int) -> list[ResultRow]:
    return [
        ResultRow(
            kind="ik",
            problem="planar_2r",
            robot="planar 2R",
            target=f"t{k:04d}",
            solver="dls",
            settings='{"a":1}',
            success=True,
            status="converged",
            position_error=1e-9,
            iterations=3,
            time_s=1e-4,
            message="multi\nline" if k == 1 else "",
        )
        for k in range(n)
    ]


@pytest.mark.parametrize(
    ("bad_cell", "reason"),
    [
        ("iterations", "'iterations'"),  # "three" is not a number
        ("success", "'success'"),  # "yes" is not true or false
        ("kind", "'kind'"),  # not one of the kinds
        ("cells", "cells instead of 18"),  # a cell lost
    ],
)
def test_resume_names_the_corrupted_line(tmp_path: Path, bad_cell: str, reason: str) -> None:
    path = write_rows(_rows(4), tmp_path / "results.csv")
    lines = path.read_text(encoding="utf-8").splitlines(keepends=True)
    # Line 1 is the header, row 1 spans lines 3-4 (a newline in its message): row 2 is line 5.
    assert lines[4].startswith("ik,planar_2r,planar 2R,t0002,")
    cells = next(csv.reader([lines[4]]))
    if bad_cell == "cells":
        cells = cells[:-1]
    else:
        cells[COLUMNS.index(bad_cell)] = {"iterations": "three", "success": "yes"}.get(
            bad_cell, "bogus"
        )
    with open(path, "w", encoding="utf-8", newline="") as f:
        f.writelines(lines[:4])
        csv.writer(f, lineterminator="\n").writerow(cells)
        f.writelines(lines[5:])
    for read in (read_results, lambda p: ResultsFile(p, resume=True)):
        with pytest.raises(ResultsFileError, match=reason) as info:
            read(path)
        assert info.value.line == 5 and info.value.path == str(path)
        assert f"{path}, line 5: corrupted row" in str(info.value)


def test_resume_names_both_lines_of_a_duplicate(tmp_path: Path) -> None:
    rows = _rows(3)
    path = write_rows([*rows, rows[1]], tmp_path / "results.csv")  # row 1 twice (lines 3-4 and 6-7)
    for read in (read_results, lambda p: ResultsFile(p, resume=True)):
        with pytest.raises(ResultsFileError, match="line 6: duplicate of the row at line 3"):
            read(path)
    # Deleting one of the two lines, as the message says, makes the file resumable.
    lines = path.read_text(encoding="utf-8").splitlines(keepends=True)
    path.write_text("".join(lines[:5]), encoding="utf-8")
    with ResultsFile(path, resume=True) as results:
        assert [r.target for r in results.rows] == ["t0000", "t0001", "t0002"]


def test_results_file_in_place_of_a_folder_or_on_a_file(tmp_path: Path) -> None:
    with pytest.raises(OutputFileError, match="is a folder"):
        ResultsFile(tmp_path)
    (tmp_path / "plain").write_text("x", encoding="utf-8")
    with pytest.raises(OutputFileError, match="plain is a file, not a folder"):
        ResultsFile(tmp_path / "plain" / "results.csv")


def test_resume_rejects_a_file_that_is_not_utf8(tmp_path: Path) -> None:
    path = write_rows(_rows(2), tmp_path / "results.csv")
    path.write_bytes(path.read_bytes() + b"ik,\xff\xfe\n")
    with pytest.raises(ResultsFileError, match="line 5: not UTF-8"):
        ResultsFile(path, resume=True)


# ---------------------------------------------------------------------------- targets
def test_targets_are_seeded_inside_the_limits() -> None:
    robot = load_problem("puma560").robot
    Q = random_configurations(robot, "puma560", 6, seed=3)
    assert Q.shape == (6, robot.dof)
    assert np.all(robot.lower <= Q)
    assert np.all(robot.upper >= Q)
    np.testing.assert_array_equal(Q, random_configurations(robot, "puma560", 6, seed=3))
    np.testing.assert_array_equal(Q[:4], random_configurations(robot, "puma560", 4, seed=3))
    assert not np.allclose(Q, random_configurations(robot, "puma560", 6, seed=4))
    assert not np.allclose(Q, random_configurations(robot, "other", 6, seed=3))


def test_config_rejects_unknown_solvers_and_bad_values() -> None:
    with pytest.raises(OptikError, match="available"):
        RunConfig(problems=("planar_2r",), solvers=("no-such-solver",))
    with pytest.raises(OptikError, match="timeout"):
        RunConfig(problems=("planar_2r",), solvers=("dls",), timeout_s=0.0)
    assert RunConfig(("planar_2r",), ("dls",), n=5, caps={"dls": 2}).targets_for("dls") == 2


# ---------------------------------------------------------------------------- seeds
def test_seed001_chapter_comparison() -> None:
    rows = dobot_chapter_rows()
    assert [r.target for r in rows if r.solver == "pinv"] == list(CHAPTER_TABLE_2)
    for row in rows:
        assert row.success and row.backend_converged
        assert row.position_error is not None and row.position_error <= 0.2e-3
        assert row.limit_violation == 0.0
    iterations = {(r.target, r.solver): int(r.iterations or 0) for r in rows}
    for part in CHAPTER_TABLE_2:  # the chapter's finding: pinv needs fewer iterations
        assert iterations[part, "pinv"] < iterations[part, "transpose"]
    assert json.loads(rows[0].settings)["start_rad"] == [0.0, 0.0, 0.0, 0.0]


def test_seed003_trajectory() -> None:
    rows, trajectory = planar_2r_example()
    slow, full = rows
    assert json.loads(slow.settings)["step"] == 0.001 and json.loads(full.settings)["step"] == 1
    assert slow.success and full.success
    assert slow.iterations is not None and full.iterations is not None
    assert trajectory.shape == (slow.iterations + 1, 2)
    np.testing.assert_array_equal(trajectory[0], [0.5, 0.5])
    robot = load_problem("planar_2r").robot
    tip = robot.fk(trajectory[-1])[:2, 3]
    assert (
        np.linalg.norm(tip - [1.2, 1.3])
        < 0.01
        <= np.linalg.norm(robot.fk(trajectory[-2])[:2, 3] - [1.2, 1.3])
    )
    # alpha = 0.001 shrinks the error by (1 - alpha) per step: log(e0 / 0.01) / alpha steps.
    e0 = np.linalg.norm(robot.fk(trajectory[0])[:2, 3] - [1.2, 1.3])
    assert abs(slow.iterations - math.log(e0 / 0.01) / 0.001) < 0.01 * slow.iterations
    assert full.iterations < 10


# ---------------------------------------------------------------------------- closed forms
def test_closed_form_cases_follow_the_shapes() -> None:
    planar = load_problem("planar_2r").robot  # 2 joints: least squares only
    cases = closed_form_cases(planar, "planar_2r", 1, seed=0)
    assert {c.objective for c in cases} == {"least_squares"}
    assert {c.damping > 0 for c in cases} == {True, False}
    panda = load_problem("panda").robot  # 7 joints: least norm for both tasks
    cases = closed_form_cases(panda, "panda", 2, seed=0)
    kinds = {(c.task, c.objective, c.damping > 0) for c in cases}
    assert kinds == {
        ("position", "least_norm", False),
        ("pose", "least_norm", False),
        ("position", "least_squares", True),
        ("pose", "least_squares", True),
    }
    assert len({c.target for c in cases}) == len(cases)
    for case in cases:
        assert np.max(np.abs(case.reference)) <= 0.05 + 1e-15
        program = case.program(panda)
        # The limits are in the program, with room to spare: inactive at the answer.
        assert np.all(case.reference <= 0.5 * program.upper + 1e-15)
        assert np.all(case.reference >= 0.5 * program.lower - 1e-15)


def test_step_backends_agree_with_the_closed_forms() -> None:
    backends = step_backends()
    assert backends, "osqp and proxsuite are core dependencies: backends must be found"
    assert all(b.startswith(("qp:", "casadi:")) for b in backends)
    robot = load_problem("dobot_magician").robot
    for case in closed_form_cases(robot, "dobot_magician", 1, seed=1):
        program = case.program(robot)
        for backend in backends:
            solution = solve_step(program, backend)
            assert solution.x is not None, (backend, solution.status)
            deviation = np.max(np.abs(solution.x - case.reference))
            assert deviation <= AGREEMENT_TOL, (backend, case.target, deviation)


def test_solve_step_rejects_other_names() -> None:
    robot = load_problem("planar_2r").robot
    case = closed_form_cases(robot, "planar_2r", 1, seed=0)[0]
    with pytest.raises(OptikError, match="qp:"):
        solve_step(case.program(robot), "dls")


def test_closed_form_rows(reference: list[ResultRow]) -> None:
    rows = [r for r in reference if r.kind == "closed_form"]
    assert one_qp_and_one_casadi(), "osqp / proxsuite and casadi are core dependencies"
    assert rows
    for row in rows:
        assert row.method in ("min_norm", "least_squares")
        assert row.deviation is not None and row.deviation <= AGREEMENT_TOL
        assert row.success and row.status == "agrees" and row.backend_converged
        assert row.position_error is None and row.limit_violation == 0.0
        assert json.loads(row.settings)["limits"] == "inactive"
