"""Reports (optik.report): summaries from the raw rows, files written whole, HTML, CLI."""

from __future__ import annotations

import base64
import csv
import io
import json
import math
from html.parser import HTMLParser
from pathlib import Path

import numpy as np
import pytest
from conftest import Interrupt, tiny_config, without_timing

from optik._progress import Progress
from optik.cli import build_parser
from optik.compare import ResultRow, read_results
from optik.report import (
    ACCURACY_LEVELS,
    SGM_SHIFT_S,
    Report,
    make_report,
    shifted_geometric_mean,
)

SECTIONS = ("closed-form", "full-ik", "seed001", "seed003", "environment")
FIGURES = ("performance_profile", "error_distributions", "iteration_histograms")
OUTPUTS = ("results.csv", "summary.csv", "summary.json", "summary.md", "index.html")


@pytest.fixture(scope="module")
def report(tmp_path_factory: pytest.TempPathFactory) -> Report:
    out = tmp_path_factory.mktemp("report")
    return make_report(tiny_config(seeds=True), out, progress=False, command="optik report")


def _temporary_files(folder: Path) -> list[Path]:
    return [p for p in folder.rglob("*") if ".tmp" in p.name]


# ---------------------------------------------------------------------------- files
def test_every_output_is_written(report: Report) -> None:
    for name in OUTPUTS:
        assert (report.out_dir / name).stat().st_size > 0, name
    for name in (*FIGURES, "planar_2r_trajectory"):
        assert (report.out_dir / "figures" / f"{name}.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert not _temporary_files(report.out_dir)


# ---------------------------------------------------------------------------- summaries
def _raw_ik_records(path: Path) -> list[dict[str, str]]:
    """The raw table read with the csv module only (independent of optik.compare)."""
    with open(path, encoding="utf-8", newline="") as f:
        return [r for r in csv.DictReader(f) if r["kind"] == "ik"]


def test_summaries_match_the_raw_rows(report: Report) -> None:
    config = tiny_config()
    records = _raw_ik_records(report.results)
    with open(report.summary_csv, encoding="utf-8", newline="") as f:
        summary = {(r["problem"], r["solver"]): r for r in csv.DictReader(f)}
    groups: dict[tuple[str, str], list[dict[str, str]]] = {}
    for record in records:
        groups.setdefault((record["problem"], record["solver"]), []).append(record)
        groups.setdefault(("all", record["solver"]), []).append(record)
    assert set(groups) == set(summary)
    sgm: dict[tuple[str, str], float] = {}
    for key, group in groups.items():
        ok = np.array([r["success"] == "true" for r in group])
        t = np.array([float(r["time_s"]) for r in group])
        charged = np.where(ok, t, config.timeout_s)
        sgm[key] = math.exp(np.mean(np.log(charged + 0.010))) - 0.010
        position = np.array([float(r["position_error"]) for r in group])
        orientation = np.array([float(r["orientation_error"]) for r in group])
        claims = [r for r in group if r["backend_converged"] != ""]
        s = summary[key]
        assert int(s["n"]) == len(group)
        assert float(s["success_rate"]) == pytest.approx(ok.mean(), abs=1e-15)
        assert float(s["time_median_s"]) == pytest.approx(np.median(t), rel=1e-12)
        assert float(s["time_p95_s"]) == pytest.approx(np.percentile(t, 95), rel=1e-12)
        assert float(s["sgm_s"]) == pytest.approx(sgm[key], rel=1e-12)
        assert float(s["position_error_max"]) == pytest.approx(position.max(), rel=1e-12)
        assert float(s["orientation_error_p50"]) == pytest.approx(
            np.median(orientation), rel=1e-12, abs=1e-300
        )
        assert int(s["claims"]) == len(claims)
        assert int(s["claims_disagree"]) == sum(
            r["backend_converged"] != r["success"] for r in claims
        )
        for level in ACCURACY_LEVELS:
            within = np.mean(
                (np.maximum(position, orientation) <= level)
                & (np.array([float(r["limit_violation"]) for r in group]) <= 1e-12)
            )
            assert float(s[f"accuracy_{level:.0e}"]) == pytest.approx(within, abs=1e-15)
    for (problem, solver), value in sgm.items():
        best = min(v for (p, _), v in sgm.items() if p == problem)
        assert float(summary[problem, solver]["sgm_normalised"]) == pytest.approx(value / best)
    assert min(s.sgm_normalised for s in report.ik if s.problem == "all") == 1.0


def test_shifted_geometric_mean() -> None:
    assert SGM_SHIFT_S == 0.010
    assert shifted_geometric_mean([0.01, 0.07]) == pytest.approx(math.sqrt(0.02 * 0.08) - 0.01)
    assert math.isnan(shifted_geometric_mean([]))


def test_summary_json_and_markdown(report: Report) -> None:
    data = json.loads(report.summary_json.read_text(encoding="utf-8"))
    assert data["config"]["n"] == 3 and data["config"]["seed"] == 5
    env = data["environment"]
    for key in ("python", "os", "cpu_model", "cpu_count", "packages", "optik"):
        assert env[key], key
    for package in ("numpy", "scipy", "numba", "casadi", "qpsolvers"):
        assert package in env["packages"]
    assert data["seed001"]["finding_holds"] is True
    assert len(data["ik"]) == len(report.ik)
    markdown = report.markdown.read_text(encoding="utf-8")
    for title in ("Closed-form agreement", "Full IK per robot", "Seed 001", "Seed 003"):
        assert title in markdown
    assert "| problem | solver |" in markdown


# ---------------------------------------------------------------------------- HTML
class _Collector(HTMLParser):
    def __init__(self) -> None:
        super().__init__()
        self.ids: list[str] = []
        self.images: list[str] = []
        self.tables = 0
        self.open: list[str] = []

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        attributes = dict(attrs)
        if attributes.get("id"):
            self.ids.append(str(attributes["id"]))
        if tag == "img":
            self.images.append(str(attributes.get("src")))
        if tag == "table":
            self.tables += 1
        if tag not in ("meta", "img", "br"):
            self.open.append(tag)

    def handle_endtag(self, tag: str) -> None:
        assert self.open and self.open[-1] == tag, (tag, self.open[-5:])
        self.open.pop()


def test_html_parses_with_every_section_and_image(report: Report) -> None:
    parser = _Collector()
    parser.feed(report.index.read_text(encoding="utf-8"))
    parser.close()
    assert parser.open == []  # every element closed, properly nested
    for section in SECTIONS:
        assert section in parser.ids, section
    for figure in (*FIGURES, "planar_2r_trajectory"):
        assert f"fig-{figure}" in parser.ids
    assert len(parser.images) == 4
    for src in parser.images:
        assert src.startswith("data:image/png;base64,")
        assert base64.b64decode(src.split(",", 1)[1])[:4] == b"\x89PNG"
    # Closed form, all + 2 problems, seed 001, seed 003, environment.
    assert parser.tables == 1 + 3 + 1 + 1 + 1


def test_protocol_stands_above_every_ik_table(report: Report) -> None:
    page = report.index.read_text(encoding="utf-8")
    section = page[page.index('id="full-ik"') : page.index('id="seed001"')]
    pieces = section.split("<table>")
    assert len(pieces) - 1 == 3  # all problems, planar_2r, dobot_magician
    for piece in pieces[:-1]:
        before = piece.rsplit("</table>", 1)[-1]  # between the previous table and this one
        assert 'class="protocol"' in before and "timeout 500 ms" in before


# ---------------------------------------------------------------------------- interruption
def test_interrupted_report_leaves_no_partial_file_and_resumes(
    tmp_path: Path, report: Report
) -> None:
    written: list[ResultRow] = []

    def stop(row: ResultRow) -> None:
        written.append(row)
        if len(written) == 5:
            raise Interrupt

    config = tiny_config(seeds=True)
    with pytest.raises(Interrupt):
        make_report(config, tmp_path, progress=False, on_row=stop)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["results.csv"]
    resumed = make_report(config, tmp_path, resume=True, progress=False)
    assert resumed.stats.skipped == 5
    assert without_timing(read_results(resumed.results)) == without_timing(
        read_results(report.results)
    )
    assert not _temporary_files(tmp_path)
    assert [s.problem for s in resumed.ik] == [s.problem for s in report.ik]


# ---------------------------------------------------------------------------- CLI
def test_report_command(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    parser = build_parser()
    out = tmp_path / "out"
    args = parser.parse_args(
        ["report", "--quick", "-n", "1", "--problems", "planar_2r", "--solvers", "auto", "dls",
         "--cap", "dls=1", "--out", str(out)]
    )  # fmt: skip
    assert args.func(args) == 0
    printed = capsys.readouterr()
    assert printed.err == ""  # no progress bar when stderr is not a terminal
    # (qpOASES may print its banner first when sys.stdout is captured: skip to the table.)
    lines = printed.out.splitlines()
    lines = lines[[line.startswith("problem ") for line in lines].index(True) :]
    assert lines[0].split()[:4] == ["problem", "solver", "n", "success"]
    assert any(line.split()[:3] == ["planar_2r", "dls", "1"] for line in lines)
    assert str((out / "index.html").resolve()) in printed.out
    data = json.loads((out / "summary.json").read_text(encoding="utf-8"))
    assert data["config"]["timeout_s"] == 0.1 and data["config"]["problems"] == ["planar_2r"]


def test_report_command_rejects_unknown_solvers() -> None:
    parser = build_parser()
    with pytest.raises(SystemExit):
        parser.parse_args(["report", "--solvers", "no-such-solver"])


# ---------------------------------------------------------------------------- progress
class _Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_progress_bar_draws_on_a_terminal_only() -> None:
    quiet = io.StringIO()
    with Progress(3, stream=quiet) as bar:
        for _ in range(3):
            bar.advance(note="x")
    assert quiet.getvalue() == ""
    terminal = _Terminal()
    with Progress(4, stream=terminal, interval=0.0) as bar:
        for _ in range(4):
            bar.advance(note="puma560 dls")
    text = terminal.getvalue()
    assert text.count("\r") == 4 and text.endswith("\n")
    assert "4/4" in text and "puma560 dls" in text and "[" + "#" * 28 + "]" in text


def test_every_argument_parser_is_in_the_cli() -> None:
    import optik.report

    folder = Path(optik.report.__file__).parent
    sources = sorted(folder.glob("*.py"))
    assert len(sources) > 1
    for path in sources:
        assert "argparse" not in path.read_text(encoding="utf-8"), path.name
