"""The report's documents: ``summary.csv``, ``summary.json``, ``summary.md``, ``index.html``.

Each function returns the whole text; :func:`optik.report.make_report` writes it with
the atomic write.
"""

from __future__ import annotations

import base64
import csv
import html
import io
import json
import math
from collections.abc import Sequence
from dataclasses import asdict, fields
from typing import Any, Final

from optik.compare import AGREEMENT_TOL
from optik.report.outputs import Report, _Context
from optik.report.peers import PEER_HEADER, peer_cells, peers_intro
from optik.report.summaries import ACCURACY_LEVELS, SolverSummary, _level_name
from optik.report.tables import (
    CLOSED_FORM_HEADER,
    SUMMARY_HEADER,
    _closed_form_intro,
    _environment_rows,
    _finding,
    _no_backends_text,
    _per_problem,
    _seed001_intro,
    _seed003_table,
    _short_protocol,
    closed_form_cells,
    markdown_table,
    protocol_text,
    seed001_table,
    summary_cells,
)

__all__: list[str] = []


def _summary_csv_columns() -> list[str]:
    """The columns of ``summary.csv``, in :meth:`SolverSummary.flat`'s order."""
    names = [f.name for f in fields(SolverSummary) if f.name != "accuracy"]
    return names + [f"accuracy_{_level_name(level)}" for level in ACCURACY_LEVELS]


def _summary_csv(summaries: Sequence[SolverSummary]) -> str:
    """``summary.csv``: its header even without a row (a run of no targets), so it reads."""
    buffer = io.StringIO()
    records = [s.flat() for s in summaries]
    writer = csv.DictWriter(buffer, fieldnames=_summary_csv_columns(), lineterminator="\n")
    writer.writeheader()
    for record in records:
        writer.writerow({k: repr(v) if isinstance(v, float) else v for k, v in record.items()})
    return buffer.getvalue()


def _json_safe(value: Any) -> Any:
    if isinstance(value, float) and not math.isfinite(value):
        return None if math.isnan(value) else ("inf" if value > 0 else "-inf")
    if isinstance(value, dict):
        return {k: _json_safe(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_json_safe(v) for v in value]
    return value


def _json(report: Report, context: _Context) -> str:
    data = {
        "config": context.config.to_dict(),
        "command": context.command,
        "environment": context.environment,
        "rows": {"written": report.stats.written, "skipped": report.stats.skipped},
        "ik": [s.flat() for s in report.ik],
        "closed_form": [asdict(s) for s in report.closed_form],
        "agreement_tol": AGREEMENT_TOL,
        "seed001": None if report.seed001 is None else asdict(report.seed001),
        "seed003": [
            {
                "settings": json.loads(r.settings),
                "iterations": r.iterations,
                "position_error": r.position_error,
                "success": r.success,
            }
            for r in report.seed003
        ],
        "peers": [asdict(p) for p in report.peers],
        "elapsed_s": report.elapsed_s,
    }
    return json.dumps(_json_safe(data), indent=2) + "\n"


def _markdown(report: Report, context: _Context) -> str:
    config = context.config
    parts = ["# optik solver comparison", ""]
    if context.command:
        parts += [f"Command: `{context.command}`", ""]
    parts += ["## 1. Closed-form agreement", ""]
    if report.closed_form:
        parts += [
            _closed_form_intro(),
            "",
            markdown_table(CLOSED_FORM_HEADER, [closed_form_cells(s) for s in report.closed_form]),
            "",
        ]
    else:
        parts += [_no_backends_text(), ""]
    parts += ["## 2. Full IK per robot", "", protocol_text(config), ""]
    for problem, group in _per_problem(report.ik).items():
        parts += [f"### {problem}", "", _short_protocol(config), ""]
        parts += [markdown_table(SUMMARY_HEADER, [summary_cells(s) for s in group]), ""]
    if report.peers:
        parts += ["### Peer libraries", "", peers_intro(), ""]
        parts += [markdown_table(PEER_HEADER, [peer_cells(p) for p in report.peers]), ""]
    parts += ["## 3. Seed 001: pseudoinverse vs transpose on the DOBOT", ""]
    if report.seed001 is not None:
        header, body = seed001_table(report.seed001)
        parts += [
            _seed001_intro(),
            "",
            markdown_table(header, body),
            "",
            _finding(report.seed001),
            "",
        ]
    parts += ["## 4. Seed 003: the two-link example", ""]
    if report.seed003:
        header, body = _seed003_table(report.seed003)
        parts += [markdown_table(header, body), "", "Figure: `figures/planar_2r_trajectory.png`."]
        parts += [""]
    parts += ["## 5. Environment", ""]
    parts += [markdown_table(["item", "value"], _environment_rows(context.environment)), ""]
    parts += [f"Raw table: `results.csv` ({len(report.stats.rows)} rows)."]
    return "\n".join(parts) + "\n"


_CSS: Final[str] = """
body{font-family:system-ui,-apple-system,Segoe UI,Roboto,sans-serif;margin:2em auto;
max-width:1440px;padding:0 1em;color:#222;line-height:1.45}
h1{font-size:1.6em}h2{margin-top:2em;border-bottom:1px solid #ccc;padding-bottom:.2em}
table{border-collapse:collapse;font-size:.85em;margin:.6em 0 1.2em}
th,td{border:1px solid #ddd;padding:.25em .5em;text-align:right;white-space:nowrap}
th{background:#f3f3f3;white-space:normal;vertical-align:bottom}
td:first-child,th:first-child,td:nth-child(2),th:nth-child(2){text-align:left}
.wide{overflow-x:auto}.protocol{font-size:.9em;color:#444;background:#f8f8f4;
padding:.4em .7em;border-left:3px solid #cc9}img{max-width:100%;height:auto}
figure{margin:1em 0}figcaption{font-size:.9em;color:#555}code{font-size:.95em}
"""


def _html_table(header: Sequence[str], body: Sequence[Sequence[str]]) -> str:
    head = "".join(f"<th>{html.escape(str(h))}</th>" for h in header)
    rows = "".join(
        "<tr>" + "".join(f"<td>{html.escape(str(c))}</td>" for c in row) + "</tr>" for row in body
    )
    table = f"<table><thead><tr>{head}</tr></thead><tbody>{rows}</tbody></table>"
    return f'<div class="wide">{table}</div>'


def _img(images: dict[str, bytes], name: str, caption: str) -> str:
    if name not in images:
        return ""
    data = base64.b64encode(images[name]).decode("ascii")
    return (
        f'<figure id="fig-{name}"><img alt="{html.escape(caption)}" '
        f'src="data:image/png;base64,{data}"><figcaption>{html.escape(caption)}</figcaption>'
        "</figure>"
    )


def _p(text: str, cls: str = "") -> str:
    attr = f' class="{cls}"' if cls else ""
    return f"<p{attr}>{html.escape(text)}</p>"


def _html(report: Report, context: _Context) -> str:
    config = context.config
    e = html.escape
    body: list[str] = ["<h1>optik solver comparison</h1>"]
    meta = (
        f"Generated {context.environment['date']} in {report.elapsed_s:.1f} s; "
        f"{report.stats.written} rows run, {report.stats.skipped} resumed from the file."
    )
    body.append(_p(meta))
    if context.command:
        body.append(f"<p>Command: <code>{e(context.command)}</code></p>")
    if context.other_rows:
        body.append(
            _p(
                f"{context.other_rows} rows of results.csv belong to other settings and are "
                "not summarised here."
            )
        )
    body.append(
        "<nav><ol>"
        '<li><a href="#closed-form">Closed-form agreement</a></li>'
        '<li><a href="#full-ik">Full IK per robot</a></li>'
        '<li><a href="#seed001">Seed 001: pseudoinverse vs transpose</a></li>'
        '<li><a href="#seed003">Seed 003: the two-link example</a></li>'
        '<li><a href="#environment">Environment</a></li>'
        "</ol></nav>"
    )

    body.append('<section id="closed-form"><h2>1. Closed-form agreement</h2>')
    if report.closed_form:
        body.append(_p(_closed_form_intro()))
        body.append(
            _html_table(CLOSED_FORM_HEADER, [closed_form_cells(s) for s in report.closed_form])
        )
    else:
        body.append(_p(_no_backends_text()))
    body.append("</section>")

    body.append('<section id="full-ik"><h2>2. Full IK per robot</h2>')
    body.append(_p(protocol_text(config), "protocol"))
    body.append(
        _p(
            "Columns: success = verified by optik; claims ≠ = rows where the solver's own "
            "convergence flag disagreed with optik's verification / rows with a flag; SGM = "
            "shifted geometric mean of the time, normalised (best = 1.0) with its value in ms; "
            "acc. = fraction of targets with both errors within the level and the limits "
            "respected."
        )
    )
    for problem, group in _per_problem(report.ik).items():
        title = "All problems" if problem == "all" else problem
        body.append(f"<h3>{e(title)}</h3>")
        body.append(_p(_short_protocol(config), "protocol"))
        body.append(_html_table(SUMMARY_HEADER, [summary_cells(s) for s in group]))
    if report.peers:
        body.append('<h3 id="peers">Peer libraries</h3>')
        body.append(_p(peers_intro(), "protocol"))
        body.append(_html_table(PEER_HEADER, [peer_cells(p) for p in report.peers]))
    body.append(
        _img(
            context.images,
            "performance_profile",
            "Performance profile: fraction of targets solved within a time per call "
            "(log scale); the dotted line is the time limit.",
        )
    )
    body.append(
        _img(
            context.images,
            "error_distributions",
            "Cumulative distributions of the final position and orientation errors, all "
            "problems; dashed: the tolerance.",
        )
    )
    body.append(
        _img(
            context.images,
            "iteration_histograms",
            "Iterations per IK call (all attempts, symmetric-log scale), solved and failed.",
        )
    )
    body.append("</section>")

    body.append('<section id="seed001"><h2>3. Seed 001: pseudoinverse vs transpose</h2>')
    if report.seed001 is not None:
        header, rows = seed001_table(report.seed001)
        body.append(_p(_seed001_intro()))
        body.append(_html_table(header, rows))
        body.append(_p(_finding(report.seed001)))
    else:
        body.append(_p("Not run."))
    body.append("</section>")

    body.append('<section id="seed003"><h2>4. Seed 003: the two-link example</h2>')
    if report.seed003:
        body.append(
            _p(
                "Unit links, target (1.2, 1.3) m, start q = (0.5, 0.5) rad, update "
                "q <- q + alpha J^+ (x* - x) until ||x* - x|| < 0.01 m; the seed's alpha is "
                "0.001, the full step alpha = 1 is shown for contrast."
            )
        )
        header, rows = _seed003_table(report.seed003)
        body.append(_html_table(header, rows))
        body.append(
            _img(
                context.images,
                "planar_2r_trajectory",
                "Seed 003: the arm every 500 iterations (grey), the final links, the tool "
                "path and the target (alpha = 0.001).",
            )
        )
    else:
        body.append(_p("Not run."))
    body.append("</section>")

    body.append('<section id="environment"><h2>5. Environment</h2>')
    body.append(_html_table(["item", "value"], _environment_rows(context.environment)))
    body.append(
        _p(
            f"Raw table: results.csv ({len(report.stats.rows)} rows); summaries: summary.csv, "
            "summary.json, summary.md."
        )
    )
    body.append("</section>")
    return (
        '<!DOCTYPE html>\n<html lang="en">\n<head>\n<meta charset="utf-8">\n'
        "<title>optik solver comparison</title>\n"
        f"<style>{_CSS}</style>\n</head>\n<body>\n" + "\n".join(body) + "\n</body>\n</html>\n"
    )
