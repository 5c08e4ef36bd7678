"""Interleaved speed comparison of two optik source trees: old, new, old, new, ...

Run (from any directory, with the benchmark environment's python)::

    python benchmarks/interleave.py --old /work/bench-old --new /work/main

For each benchmark chosen with ``--bench`` (default: ``ik,analytic``), one script -- this
directory's ``bench_ik.py`` / ``bench_analytic.py``, unless ``--scripts`` or
``--own-scripts`` says otherwise -- is run against both trees: each run is a fresh
subprocess with ``PYTHONPATH`` set to that tree alone and its working directory in it, and
writes its figures with ``--json``. The package each run imported is checked to lie inside
its tree (an installed ``optik`` must not stand in for it). First one untimed warm-up run
per tree and benchmark fills that tree's numba cache, so that compilation is excluded;
then ``--rounds`` rounds, each running the trees one after the other (``--order
alternate``: old then new in every round; ``abba``: the order flips every round), so that
the load of a shared machine falls on both alike.

Every figure is a time per query in µs (lower is faster); batch rows also give the
throughput (queries per second = 1e6 / µs). Per figure the report gives the median over
rounds for each tree, the ratio new / old of the medians (> 1: new is slower), the
spread of the per-round ratios (new_i / old_i of the two runs of round i, min - max) and
the ratio of the best rounds (load from other processes only ever adds time, so the
fastest round of each tree is the one least disturbed). A
figure whose ratio exceeds ``1 + --threshold`` is marked SLOWER, one below
``1 - --threshold`` faster. The load average is recorded before and after, and its
maximum over the runs: the figures are only meaningful on a quiet machine (load well below
the core count). Peer libraries are left out (``--no-peers``) unless ``--peers`` is given.
"""

from __future__ import annotations

import argparse
import datetime
import json
import math
import os
import platform
import shlex
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

# _record.py beside this script, also when it is loaded from a path (tests).
sys.path.insert(0, str(Path(__file__).resolve().parent))

from _record import git_commit

HERE = Path(__file__).resolve().parent

# The options of each benchmark in the interleaved runs: the single-query solve_ik medians
# (dls and auto on the three robots) and the solve_ik_batch throughput of bench_ik.py,
# every row of bench_analytic.py for its two DH robots (not its URDF arms). Sized so that
# a default run (warm-up plus 7 rounds of both benchmarks in both trees) takes about 3
# minutes on a quiet 2-core machine, 6 when other processes keep both cores busy.
BENCHES: dict[str, tuple[str, tuple[str, ...]]] = {
    "ik": (
        "bench_ik.py",
        (
            "--robots", "panda,puma560,ur5",
            "--solvers", "auto,dls",
            "--no-q0-variants",
            "-n", "1000",
            "--batch-n", "5000",
            "--batch-repeat", "3",
            "--threads", "1,2",
        ),
    ),
    "analytic": (
        "bench_analytic.py",
        ("--robots", "puma560", "ur5", "--single", "500", "--batch", "20000", "--repeat", "9"),
    ),
}  # fmt: skip
ORDERS = ("alternate", "abba")
DEFAULT_ROUNDS = 7
DEFAULT_THRESHOLD = 0.05


class HarnessError(RuntimeError):
    """A run that failed or measured the wrong tree: the comparison cannot be made."""


@dataclass(frozen=True)
class Tree:
    """One source tree: its label (``old`` / ``new``), path and git commit."""

    label: str
    path: Path
    commit: str


@dataclass
class Series:
    """One figure of one benchmark, per round, in both trees."""

    bench: str
    name: str
    kind: str
    old: list[float] = field(default_factory=list)
    new: list[float] = field(default_factory=list)
    answers: dict[str, tuple[Any, Any]] = field(default_factory=dict)

    def summary(self, threshold: float) -> dict[str, Any]:
        """Medians (µs), the ratio new / old of the medians, the per-round ratio spread."""
        old_med = statistics.median(self.old) * 1e6
        new_med = statistics.median(self.new) * 1e6
        ratio = new_med / old_med
        per_round = [n / o for o, n in zip(self.old, self.new, strict=True)]
        verdict = "within"
        if ratio > 1.0 + threshold:
            verdict = "SLOWER"
        elif ratio < 1.0 - threshold:
            verdict = "faster"
        return {
            "bench": self.bench,
            "name": self.name,
            "kind": self.kind,
            "rounds": len(per_round),
            "old_median_us": old_med,
            "new_median_us": new_med,
            "ratio": ratio,
            "ratio_min": min(per_round),
            "ratio_max": max(per_round),
            "best_ratio": min(self.new) / min(self.old),
            "verdict": verdict,
            "answers": answer_note(self.answers),
            "old_us": [x * 1e6 for x in self.old],
            "new_us": [x * 1e6 for x in self.new],
        }


def answer_note(answers: dict[str, tuple[Any, Any]]) -> str:
    """``same`` when both trees found the same success rate and mean iterations, else both."""
    diffs = []
    for key, (old, new) in answers.items():
        if old is None and new is None:
            continue
        if old is None or new is None or not math.isclose(old, new, rel_tol=1e-9, abs_tol=1e-12):
            diffs.append(f"{key} {old} -> {new}")
    return "; ".join(diffs) if diffs else "same"


def round_order(rounds: int, order: str) -> list[tuple[str, str]]:
    """The labels of each round in the order its runs go.

    ``alternate``: old first in every round; ``abba``: new first in every other round.
    """
    if order not in ORDERS:
        raise ValueError(f"order must be one of {ORDERS}, got {order!r}")
    out = []
    for r in range(rounds):
        flip = order != "alternate" and r % 2 == 1
        out.append(("new", "old") if flip else ("old", "new"))
    return out


def check_tree(label: str, path: Path) -> Tree:
    """A source tree must hold the ``optik`` package at its root."""
    path = path.expanduser().resolve()
    if not (path / "optik" / "__init__.py").is_file():
        raise HarnessError(f"--{label} {path}: no optik/__init__.py there (not a source tree)")
    return Tree(label, path, git_commit(path))


def load_line() -> str:
    """The 1, 5 and 15 minute load averages, with the core count."""
    one, five, fifteen = os.getloadavg()
    return f"{one:.2f}, {five:.2f}, {fifteen:.2f} (1, 5, 15 min; {os.cpu_count()} cores)"


@dataclass
class Run:
    """One benchmark run against one tree, in a fresh subprocess.

    ``PYTHONPATH`` is the tree alone, so the tree's ``optik`` shadows any installed one;
    the figures record which package was imported, and it must be the tree's.
    """

    python: str
    script: Path
    args: Sequence[str]
    tree: Tree
    out_dir: Path
    tag: str
    timeout: float
    proc: subprocess.Popen[bytes] | None = None
    started: float = 0.0

    @property
    def figures(self) -> Path:
        """The run's ``--json`` file."""
        return self.out_dir / f"{self.tag}.json"

    @property
    def log(self) -> Path:
        """The run's standard output and error."""
        return self.out_dir / f"{self.tag}.log"

    def start(self) -> None:
        """Start the subprocess (its output goes to the log)."""
        env = dict(os.environ)
        env["PYTHONPATH"] = str(self.tree.path)
        cmd = [self.python, str(self.script), *self.args, "--json", str(self.figures)]
        with self.log.open("w", encoding="utf-8") as f:
            f.write(f"$ PYTHONPATH={shlex.quote(str(self.tree.path))} {shlex.join(cmd)}\n")
        self.started = time.perf_counter()
        with self.log.open("a", encoding="utf-8") as f:
            self.proc = subprocess.Popen(
                cmd, cwd=self.tree.path, env=env, stdout=f, stderr=subprocess.STDOUT
            )

    def finish(self) -> tuple[dict[str, Any], float]:
        """Wait for the subprocess; its figures and wall time (s)."""
        assert self.proc is not None, "start() first"
        try:
            code = self.proc.wait(timeout=max(self.timeout - self.elapsed(), 0.1))
        except subprocess.TimeoutExpired as exc:
            self.proc.kill()
            self.proc.wait()
            raise HarnessError(
                f"{self.tag}: no answer after {self.timeout:g} s (log: {self.log})"
            ) from exc
        wall = self.elapsed()
        if code != 0 or not self.figures.is_file():
            text = self.log.read_text(encoding="utf-8", errors="replace")
            tail = "\n".join(text.splitlines()[-15:])
            raise HarnessError(
                f"{self.tag}: {self.script.name} against {self.tree.path} exited with {code}"
                f" (log: {self.log}); last lines:\n{tail}"
            )
        data: dict[str, Any] = json.loads(self.figures.read_text(encoding="utf-8"))
        imported = Path(data.get("meta", {}).get("optik_path", "?")).resolve()
        if not imported.is_relative_to(self.tree.path):
            raise HarnessError(
                f"{self.tag}: the run imported optik from {imported}, "
                f"not from the tree {self.tree.path}"
            )
        return data, wall

    def elapsed(self) -> float:
        """Seconds since the start."""
        return time.perf_counter() - self.started

    def stop(self) -> None:
        """End the subprocess if it still runs (after an interrupt)."""
        if self.proc is not None and self.proc.poll() is None:
            self.proc.kill()
            self.proc.wait()


def collect(
    series: dict[tuple[str, str], Series], bench: str, label: str, data: dict[str, Any]
) -> None:
    """Add one run's figures to the series of its benchmark and tree."""
    for m in data["metrics"]:
        if m["seconds_per_query"] is None:
            continue
        key = (bench, m["name"])
        s = series.setdefault(key, Series(bench, m["name"], m["kind"]))
        getattr(s, label).append(float(m["seconds_per_query"]))
        for field_name in ("success_rate", "mean_iterations"):
            pair = list(s.answers.get(field_name, (None, None)))
            pair[0 if label == "old" else 1] = m.get(field_name)
            s.answers[field_name] = (pair[0], pair[1])


def summarize(
    series: dict[tuple[str, str], Series], threshold: float
) -> tuple[list[dict[str, Any]], list[str]]:
    """Summaries of the figures measured in every round of both trees; the others named."""
    rows, missing = [], []
    for s in series.values():
        if not s.old or not s.new or len(s.old) != len(s.new):
            where = "old" if not s.old else "new" if not s.new else "some rounds"
            missing.append(f"{s.bench}: {s.name} (missing in {where})")
            continue
        rows.append(s.summary(threshold))
    return rows, missing


def load_warning(max_load: float, cores: int) -> str:
    """A warning when other processes took CPU time during the runs, else ``""``.

    The harness itself keeps about one core busy (two in the 2-thread batch rows), so a
    one-minute load average above the core count means that others were running too.
    """
    if max_load <= cores:
        return ""
    return (
        f"WARNING: the load average reached {max_load:.2f} on {cores} cores during the runs: "
        "other processes took CPU time and the medians carry their noise. The best column "
        "(fastest round of each tree) is the less disturbed figure; re-run on a quiet machine "
        "before reading a 5 % difference."
    )


def print_report(
    rows: list[dict[str, Any]], missing: list[str], header: dict[str, Any], threshold: float
) -> None:
    """The report: header lines, then one table row per figure."""
    print("# optik interleaved benchmark: new / old\n")
    for key, value in header.items():
        if key != "warning":  # printed after the table, where it is read
            print(f"- {key}: {value}")
    print(
        "\nTime per query in µs (lower is faster); batch rows also give queries/s. ratio = "
        "median new / median old (> 1: new slower); spread = min - max of the per-round "
        "ratios; best = fastest round new / fastest round old; verdict (on the ratio) at "
        f"±{100 * threshold:g} %.\n"
    )
    print("| bench | figure | old µs | new µs | ratio | spread | best | verdict | old /s "
          "| new /s | answers |")  # fmt: skip
    print("| --- | --- | ---: | ---: | ---: | --- | ---: | --- | ---: | ---: | --- |")
    for r in rows:
        rate = ("", "")
        if r["kind"] == "batch":
            rate = (f"{1e6 / r['old_median_us']:,.0f}", f"{1e6 / r['new_median_us']:,.0f}")
        print(
            f"| {r['bench']} | {r['name']} | {r['old_median_us']:.2f} | {r['new_median_us']:.2f} "
            f"| {r['ratio']:.3f} | {r['ratio_min']:.3f} - {r['ratio_max']:.3f} "
            f"| {r['best_ratio']:.3f} | {r['verdict']} "
            f"| {rate[0]} | {rate[1]} | {r['answers']} |"
        )
    if missing:
        print("\nNot compared (not measured in every round of both trees):")
        for m in missing:
            print(f"- {m}")
    slower = [r for r in rows if r["verdict"] == "SLOWER"]
    print(
        f"\n{len(rows)} figures, {len(slower)} slower than {1 + threshold:g} x old. The figures "
        "are only meaningful on a quiet machine: compare the spread with the noise floor "
        "(old against a copy of itself, benchmarks/README.md)."
    )
    if header.get("warning"):
        print(f"\n{header['warning']}")


def write_json_atomic(path: Path, data: dict[str, Any]) -> None:
    """Write the whole comparison or nothing (a temporary file, then a rename)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", dir=path.parent)
    try:
        with os.fdopen(fd, "w", encoding="utf-8") as f:
            f.write(json.dumps(data, indent=1) + "\n")
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def parse_args(argv: Sequence[str] | None) -> argparse.Namespace:
    """Command line."""
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--old", type=Path, required=True, help="the reference source tree")
    p.add_argument("--new", type=Path, required=True, help="the source tree under test")
    p.add_argument(
        "--bench",
        default=",".join(BENCHES),
        help=f"comma-separated benchmarks out of {', '.join(BENCHES)} (default: %(default)s)",
    )
    p.add_argument(
        "--rounds",
        type=int,
        default=DEFAULT_ROUNDS,
        help="timed rounds, each one run per tree (default: %(default)s)",
    )
    p.add_argument(
        "--order",
        choices=ORDERS,
        default="alternate",
        help="alternate: old, new in every round; abba: the order flips every round",
    )
    p.add_argument(
        "--peers",
        action=argparse.BooleanOptionalAction,
        default=False,
        help="also time the peer libraries in each run (default: no, runs stay short)",
    )
    scripts = p.add_mutually_exclusive_group()
    scripts.add_argument(
        "--scripts",
        type=Path,
        default=HERE,
        help="folder of the benchmark scripts run against both trees (default: this one)",
    )
    scripts.add_argument(
        "--own-scripts",
        action="store_true",
        help="run each tree's own benchmarks/ scripts instead (they must have --json): only "
        "when the new scripts cannot run against the old tree",
    )
    p.add_argument(
        "--extra",
        action="append",
        default=[],
        metavar="BENCH=ARGS",
        help="more options for one benchmark's script, e.g. --extra 'ik=--batch-n 20000' "
        "(appended after the defaults: a repeated option overrides)",
    )
    p.add_argument(
        "--threshold",
        type=float,
        default=DEFAULT_THRESHOLD,
        help="relative change marked SLOWER or faster (default: %(default)s)",
    )
    p.add_argument("--python", default=sys.executable, help="interpreter of the runs")
    p.add_argument("--timeout", type=float, default=900.0, help="seconds allowed per run")
    p.add_argument("--keep", type=Path, help="keep each run's log and figures in this folder")
    p.add_argument("--json", type=Path, help="write the comparison (every round) to this file")
    args = p.parse_args(argv)
    args.bench = [b for b in args.bench.split(",") if b]
    unknown = [b for b in args.bench if b not in BENCHES]
    if unknown or not args.bench:
        p.error(f"--bench: unknown {unknown}; choose from {list(BENCHES)}")
    if args.rounds < 1:
        p.error("--rounds must be at least 1")
    if not 0.0 < args.threshold < 1.0:
        p.error("--threshold must lie in (0, 1)")
    extra: dict[str, list[str]] = {b: [] for b in BENCHES}
    for item in args.extra:
        bench, sep, rest = item.partition("=")
        if not sep or bench not in BENCHES:
            p.error(f"--extra {item!r}: expected BENCH=ARGS with BENCH in {list(BENCHES)}")
        extra[bench] += shlex.split(rest)
    args.extra = extra
    return args


def main(argv: Sequence[str] | None = None) -> int:
    """Run the interleaved comparison and print the report."""
    args = parse_args(argv)
    started = time.perf_counter()
    started_utc = datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds")
    try:
        trees = {"old": check_tree("old", args.old), "new": check_tree("new", args.new)}
    except HarnessError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    if trees["old"].path == trees["new"].path:
        print(
            "warning: --old and --new are the same folder; for a noise floor use two "
            "checkouts of one commit (git worktree add --detach)",
            file=sys.stderr,
        )

    def script_for(bench: str, label: str) -> Path:
        folder = trees[label].path / "benchmarks" if args.own_scripts else args.scripts
        return Path(folder).resolve() / BENCHES[bench][0]

    def bench_args(bench: str) -> list[str]:
        return [
            *BENCHES[bench][1],
            "--peers" if args.peers else "--no-peers",
            *args.extra[bench],
        ]

    for bench in args.bench:
        for label in ("old", "new"):
            if not script_for(bench, label).is_file():
                print(f"error: no script {script_for(bench, label)}", file=sys.stderr)
                return 2

    load_before = load_line()
    loads: list[float] = []
    series: dict[tuple[str, str], Series] = {}
    walls: dict[str, list[float]] = {}
    with tempfile.TemporaryDirectory(prefix="optik-interleave-") as tmp:
        out_dir = args.keep.resolve() if args.keep else Path(tmp)
        out_dir.mkdir(parents=True, exist_ok=True)
        plan = round_order(args.rounds, args.order)

        def run(bench: str, labels: Sequence[str], prefix: str) -> list[dict[str, Any]]:
            """Run ``bench`` for each tree label, one after the other."""
            runs = [
                Run(
                    args.python,
                    script_for(bench, label),
                    bench_args(bench),
                    trees[label],
                    out_dir,
                    f"{prefix}-{bench}-{label}",
                    args.timeout,
                )
                for label in labels
            ]
            out = []
            try:
                for label, r in zip(labels, runs, strict=True):
                    loads.append(os.getloadavg()[0])
                    r.start()
                    data, wall = r.finish()
                    walls.setdefault(f"{bench} {label}", []).append(wall)
                    print(f"  {r.tag}: {wall:.1f} s", file=sys.stderr)
                    out.append(data)
            finally:
                for r in runs:
                    r.stop()
            return out

        try:
            print("warm-up (untimed, fills each tree's numba cache):", file=sys.stderr)
            for bench in args.bench:
                run(bench, ("old", "new"), "warmup")
            per_round = sum(statistics.median(w) for w in walls.values())
            print(
                f"{args.rounds} rounds of about {per_round:.0f} s each "
                f"(about {args.rounds * per_round / 60:.1f} min; from the warm-up runs, an upper "
                "bound when they compiled)",
                file=sys.stderr,
            )
            walls.clear()
            for r, labels in enumerate(plan, start=1):
                print(f"round {r}/{args.rounds}:", file=sys.stderr)
                for bench in args.bench:
                    for label, data in zip(labels, run(bench, labels, f"round{r}"), strict=True):
                        collect(series, bench, label, data)
        except HarnessError as exc:
            print(f"error: {exc}", file=sys.stderr)
            if not args.own_scripts:
                print(
                    "If the scripts of --scripts cannot run against one of the trees, "
                    "--own-scripts runs each tree's own scripts (they need --json).",
                    file=sys.stderr,
                )
            return 1

    rows, missing = summarize(series, args.threshold)
    elapsed = time.perf_counter() - started
    header = {
        "command": "python benchmarks/interleave.py "
        + shlex.join(sys.argv[1:] if argv is None else argv),
        "started (UTC)": started_utc,
        "old": f"{trees['old'].path} ({trees['old'].commit})",
        "new": f"{trees['new'].path} ({trees['new'].commit})",
        "scripts": "each tree's own benchmarks/"
        if args.own_scripts
        else str(Path(args.scripts).resolve()),
        "runs": "; ".join(f"{b}: {shlex.join(bench_args(b))}" for b in args.bench),
        "rounds": f"{args.rounds} ({args.order}), after one untimed warm-up run per tree",
        "python": f"{args.python} ({platform.python_version()} for this harness)",
        "machine": f"{platform.machine()}, {os.cpu_count()} cores, {platform.platform()}",
        "load average before": load_before,
        "load average after": load_line(),
        "load average max over runs (1 min)": f"{max(loads):.2f}",
        "wall time": f"{elapsed:.0f} s",
        "warning": load_warning(max(loads), os.cpu_count() or 1),
    }
    if not header["warning"]:
        del header["warning"]
    print_report(rows, missing, header, args.threshold)
    if args.json:
        write_json_atomic(
            args.json,
            {"header": header, "threshold": args.threshold, "figures": rows, "missing": missing},
        )
        print(f"\ncomparison: {args.json}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
