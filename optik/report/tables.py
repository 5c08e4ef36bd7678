"""The report's tables and sentences, shared by the terminal, Markdown and HTML outputs."""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from typing import Any, Final

from optik.compare import AGREEMENT_TOL, DOBOT_HOME, ResultRow, RunConfig
from optik.report.summaries import (
    ACCURACY_LEVELS,
    CLOSED_FORM_KINDS,
    SGM_SHIFT_S,
    ChapterComparison,
    ClosedFormSummary,
    SolverSummary,
    _level_name,
)

__all__ = [
    "CLOSED_FORM_HEADER",
    "SUMMARY_HEADER",
    "TERMINAL_COLUMNS",
    "closed_form_cells",
    "markdown_table",
    "protocol_text",
    "seed001_table",
    "summary_cells",
    "text_table",
]


def _ms(seconds: float) -> str:
    return "–" if not math.isfinite(seconds) else f"{seconds * 1e3:.3g}"


def _sci(value: float) -> str:
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return "–"
    if value == 0:
        return "0"
    if math.isinf(value):
        return "inf"
    return f"{value:.1e}"


def _pct(value: float) -> str:
    return f"{100 * value:.0f}%"


def _num(value: float) -> str:
    return "–" if not math.isfinite(value) else f"{value:.3g}"


SUMMARY_HEADER: Final[tuple[str, ...]] = (
    "problem",
    "solver",
    "n",
    "success",
    "claims ≠",
    "median ms",
    "p95 ms",
    "SGM (norm.)",
    "pos. err p50 / p95 / max (m)",
    "ori. err p50 / p95 / max (rad)",
    "iter. p50 / p95",
    *(f"acc. {_level_name(level)}" for level in ACCURACY_LEVELS),
)


#: The columns of :data:`SUMMARY_HEADER` printed on the terminal.
TERMINAL_COLUMNS: Final[tuple[str, ...]] = tuple(
    h for h in SUMMARY_HEADER if not h.startswith(("pos. err", "ori. err"))
)


def summary_cells(s: SolverSummary) -> list[str]:
    """The cells of one summary row, matching :data:`SUMMARY_HEADER`."""
    return [
        s.problem,
        s.solver,
        str(s.n),
        _pct(s.success_rate),
        f"{s.claims_disagree}/{s.claims}",
        _ms(s.time_median_s),
        _ms(s.time_p95_s),
        f"{_num(s.sgm_normalised)} ({_ms(s.sgm_s)} ms)",
        " / ".join(
            _sci(v) for v in (s.position_error_p50, s.position_error_p95, s.position_error_max)
        ),
        " / ".join(
            _sci(v)
            for v in (s.orientation_error_p50, s.orientation_error_p95, s.orientation_error_max)
        ),
        f"{_num(s.iterations_median)} / {_num(s.iterations_p95)}",
        *(_pct(s.accuracy[_level_name(level)]) for level in ACCURACY_LEVELS),
    ]


CLOSED_FORM_HEADER: Final[tuple[str, ...]] = (
    "backend",
    "programs",
    "agree",
    "max dev. least norm",
    "max dev. least squares",
    "max dev. damped LS",
    "claims ≠",
    "failures",
    "median ms",
)


def closed_form_cells(s: ClosedFormSummary) -> list[str]:
    """The cells of one closed-form summary row, matching :data:`CLOSED_FORM_HEADER`."""
    return [
        s.backend,
        str(s.cases),
        f"{s.agree}/{s.cases}",
        *(_sci(s.max_deviation[k]) for k in CLOSED_FORM_KINDS),
        str(s.claims_disagree),
        str(s.failures),
        _ms(s.time_median_s),
    ]


def seed001_table(comparison: ChapterComparison) -> tuple[list[str], list[list[str]]]:
    """Header and rows of the seed 001 table: the chapter's iterations beside ours."""
    extra = [
        s
        for s in dict.fromkeys(k for p in comparison.parts.values() for k in p)
        if not s.startswith("chapter_") and s not in ("pinv", "transpose")
    ]
    header = [
        "path part",
        "chapter pinv",
        "chapter transpose",
        "optik pinv",
        "optik transpose",
        *(f"optik {s} (beyond the chapter)" for s in extra),
        "pinv fewer?",
    ]
    body = []
    for part, counts in comparison.parts.items():
        ours = [counts.get(s) for s in ("pinv", "transpose", *extra)]
        fewer = counts.get("pinv", 0) < counts.get("transpose", 0)
        body.append(
            [
                part,
                str(counts["chapter_pinv"]),
                str(counts["chapter_transpose"]),
                *("–" if v is None else str(v) for v in ours),
                "yes" if fewer else "no",
            ]
        )
    return header, body


def text_table(header: Sequence[str], body: Sequence[Sequence[str]]) -> str:
    """A fixed-width plain-text table (for the terminal)."""
    widths = [max(len(str(c)) for c in column) for column in zip(header, *body, strict=True)]
    lines = ["  ".join(str(c).ljust(w) for c, w in zip(header, widths, strict=True))]
    lines.append("  ".join("-" * w for w in widths))
    lines += ["  ".join(str(c).ljust(w) for c, w in zip(row, widths, strict=True)) for row in body]
    return "\n".join(line.rstrip() for line in lines)


def markdown_table(header: Sequence[str], body: Sequence[Sequence[str]]) -> str:
    """A GitHub-flavoured Markdown table."""
    escape = str.maketrans({"|": "\\|"})
    lines = ["| " + " | ".join(str(h).translate(escape) for h in header) + " |"]
    lines.append("|" + "|".join("---" for _ in header) + "|")
    lines += ["| " + " | ".join(str(c).translate(escape) for c in row) + " |" for row in body]
    return "\n".join(lines)


def protocol_text(config: RunConfig, step: bool = False) -> str:
    """The protocol of the full-IK section in one paragraph (stated above every table)."""
    run = {*config.solvers, *(f"peer:{name}" for name in config.peers)}
    caps = ", ".join(f"{s}: {n}" for s, n in config.caps.items() if n < config.n and s in run)
    text = (
        f"Protocol: {config.n} targets per robot, the FK poses of configurations drawn "
        f"uniformly inside the joint limits (seed {config.seed}); mode {config.mode}; "
        f"success = position error ≤ {config.tol:g} m and orientation error ≤ "
        f"{config.tol:g} rad and every joint inside its limits, verified by optik from FK; "
        f"timeout {config.timeout_s * 1e3:g} ms per call (restarts within it); named solvers "
        "start from the seed table then seeded random restarts, auto uses the closed form "
        "where the robot has one; one untimed warm-up per (problem, solver). Times are wall "
        "times per call and include failures (a failure usually runs to the timeout); the "
        f"SGM (shift {SGM_SHIFT_S * 1e3:g} ms) counts each failure at the timeout and is "
        "normalised to the best solver of the problem (1.0)."
    )
    if caps:
        text += f" Capped solvers (targets per robot): {caps}."
    return text


def _seed003_table(rows: Sequence[ResultRow]) -> tuple[list[str], list[list[str]]]:
    header = ["step alpha", "iterations", "final error (m)", "time (ms)", "within 0.01 m"]
    body = []
    for r in rows:
        alpha = json.loads(r.settings)["step"]
        body.append(
            [
                f"{alpha:g}",
                str(r.iterations),
                f"{r.position_error:.6f}" if r.position_error is not None else "–",
                _ms(r.time_s),
                "yes" if r.success else "no",
            ]
        )
    return header, body


def _load_text(load: Sequence[float] | None) -> str:
    return ", ".join(map(str, load)) if load else "unknown"


def _environment_rows(env: dict[str, Any]) -> list[list[str]]:
    cpu = f"{env['cpu_model']} ({env['cpu_count']} logical CPUs, "
    cpu += f"{env['cpu_affinity'] or '?'} usable by this process)"
    rows = [
        ["Python", env["python"]],
        ["OS", env["os"]],
        ["CPU", cpu],
        ["load average (1, 5, 15 min) before the run", _load_text(env.get("load_average_before"))],
        ["load average (1, 5, 15 min) after the run", _load_text(env["load_average"])],
        ["optik", f"{env['optik']['version']} (git {env['optik']['git'] or 'unknown'})"],
    ]
    rows += [[name, version or "not installed"] for name, version in env["packages"].items()]
    rows.append(["qpsolvers backends", ", ".join(env["qpsolvers_backends"]) or "none"])
    rows.append(["step-program backends", ", ".join(env["step_backends"]) or "none"])
    rows.append(["IK solvers", ", ".join(env["ik_solvers"])])
    rows.append(["date (UTC)", env["date"]])
    return rows


def _per_problem(summaries: Sequence[SolverSummary]) -> dict[str, list[SolverSummary]]:
    groups: dict[str, list[SolverSummary]] = {}
    for s in summaries:
        groups.setdefault(s.problem, []).append(s)
    overall = groups.pop("all", None)
    return {"all": overall, **groups} if overall else groups


def _short_protocol(config: RunConfig) -> str:
    return (
        f"tol {config.tol:g} m / rad, timeout {config.timeout_s * 1e3:g} ms, seed "
        f"{config.seed}, mode {config.mode}; times include failures; SGM counts failures "
        "at the timeout."
    )


def _closed_form_intro() -> str:
    return (
        "Each backend solves differential-IK step programs (least norm, undamped least "
        "squares, damped least squares with the programs' default lambda) at random in-limit "
        "configurations away from singularities; the joint limits are in each program but "
        "inactive (the step is scaled to at most half the distance to every bound). "
        "Deviation = max |dq - dq*| (rad or m) from optik.min_norm / optik.least_squares; a "
        f"program agrees when the deviation is at most {AGREEMENT_TOL:g}."
    )


def _no_backends_text() -> str:
    return (
        "No step-program backend was found (optik.solvers.qp / optik.programs.casadi_qp "
        "missing, or no qpsolvers backend / CasADi conic plugin installed): nothing to compare."
    )


def _seed001_intro() -> str:
    home = ", ".join(f"{v:g}" for v in DOBOT_HOME)
    return (
        f"From the home configuration J = ({home}) (rear arm vertical, forearm horizontal; "
        "the chapter does not print its start, this is our choice) through the three targets "
        "of the chapter's Table 2 in sequence, each part starting where the previous one "
        "ended; position only, accepted error 0.2 mm. pinv: unit step with the SVD "
        "pseudoinverse; transpose: the step alpha = <e, J J^T e> / ||J J^T e||^2."
    )


def _finding(comparison: ChapterComparison) -> str:
    verdict = "holds" if comparison.finding_holds else "does not hold"
    return (
        "The chapter's finding (the pseudoinverse needs fewer iterations than the transpose) "
        f"{verdict} in our run"
        + ("" if comparison.all_converged else " (some parts did not converge)")
        + "."
    )
