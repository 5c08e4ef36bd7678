"""IK benchmark: optik's solvers against peer libraries, on the same targets, same process.

Run: ``python benchmarks/bench_ik.py [--robots puma560,ur5,panda] [-n 500] [--seed 0]
[--solvers auto,dls,...] [--no-peers] [--out results.json]`` (see benchmarks/README.md).

Protocol, for each robot: ``n`` joint vectors drawn uniformly inside the joint limits
(seeded), their forward-kinematics poses as targets; full pose, tolerance 1e-6 (m and rad),
hard joint limits; every method starts from mid-limits (optik's default ``q0``). A query
succeeds when the benchmark itself finds, from optik's forward kinematics of the returned
``q``, position error <= tol, orientation angle <= tol and every joint inside its limits
(1e-12): never from a method's own flag. Each query is timed with ``time.perf_counter``
after a warm-up (numba compiles on first call); methods run interleaved, target by target,
so that the load of the machine falls on all of them alike. Slow methods (``pinv``,
``transpose``, ``qp:*``, ``casadi:*``, ikpy, pink, pybullet) run on the first ``--n-slow`` targets.

Output: the long table (one row per robot and method: settings, n, success rate, median
and p95 time per query, mean iterations), then the summaries (ratios optik / RTB), with
the versions, the hardware and the load (``uptime``) recorded. ``--out`` writes every
query as a row (CSV, or JSON with the metadata and the summary); ``--json`` writes only the
figures (median time per query of each row, batch wall / n) in the shape that
``interleave.py`` reads (see ``_record.py``).
"""

from __future__ import annotations

import os

# numpy's BLAS stays on one thread: the machine is small and the queries are tiny.
for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import csv  # noqa: E402
import datetime  # noqa: E402
import gc  # noqa: E402
import importlib.metadata  # noqa: E402
import json  # noqa: E402
import math  # noqa: E402
import platform  # noqa: E402
import shlex  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
import zlib  # noqa: E402
from collections import Counter  # noqa: E402
from collections.abc import Callable, Sequence  # noqa: E402
from dataclasses import dataclass, field  # noqa: E402
from pathlib import Path  # noqa: E402
from typing import Any  # noqa: E402

import numpy as np  # noqa: E402
from numpy.typing import NDArray  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))

import _record  # noqa: E402

import optik  # noqa: E402
from optik.peers import Peer, PeerUnavailable, get_peer  # noqa: E402
from optik.spatial import pose_error  # noqa: E402

Array = NDArray[np.float64]
DEFAULT_ROBOTS = ("puma560", "ur5", "panda")
DEFAULT_SOLVERS = ("auto", "dls", "pinv", "qp:osqp", "qp:proxqp", "casadi:ipopt")
SLOW_SOLVERS = ("pinv", "transpose", "qp:", "casadi:")
LIMIT_TOL = 1e-12
WARMUP = 3
GC_EVERY = 100
RTB_ROW = "rtb ik_LM"
VERSIONED = (
    "optik",
    "numpy",
    "scipy",
    "numba",
    "qpsolvers",
    "osqp",
    "proxsuite",
    "casadi",
    "roboticstoolbox-python",
    "ikpy",
    "pin-pink",
    "pin",
    "daqp",
    "eaik",
    "pybullet",
)

Solve = Callable[[Array, Array], tuple[Any, int | None, str]]


@dataclass
class PeerRow:
    """A peer adapter (``optik.peers``) as one row of the benchmark."""

    label: str
    peer: Peer
    settings: str
    slow: bool = False


@dataclass
class Method:
    """One row of the long table: a way to answer a query, and its measurements."""

    name: str
    settings: str
    n: int
    solve: Solve
    iterations_known: bool = True
    n_note: str = ""
    times: list[float] = field(default_factory=list)
    rows: list[dict[str, Any]] = field(default_factory=list)
    spent: float = 0.0
    stopped: str = ""
    batch_walls: list[float] = field(default_factory=list)


# ---------------------------------------------------------------- verification
def verify(robot: optik.Robot, q: Any, T_target: Array, tol: float) -> dict[str, Any]:
    """The benchmark's own check of an answer: FK errors and the joint limits."""
    if q is None:
        return dict(
            success=False,
            position_error=math.nan,
            orientation_error=math.nan,
            limit_violation=math.nan,
        )
    q = np.asarray(q, dtype=float).reshape(-1)
    if q.shape != (robot.dof,) or not np.all(np.isfinite(q)):
        return dict(
            success=False,
            position_error=math.nan,
            orientation_error=math.nan,
            limit_violation=math.nan,
        )
    position, angle = pose_error(robot.fk(q), T_target)
    violation = float(max(0.0, np.max(robot.lower - q), np.max(q - robot.upper)))
    success = position <= tol and angle <= tol and violation <= LIMIT_TOL
    return dict(
        success=bool(success),
        position_error=position,
        orientation_error=angle,
        limit_violation=violation,
    )


# ---------------------------------------------------------------- environment record
def load_average() -> str:
    """``uptime``'s output (the 1, 5 and 15 minute load averages)."""
    try:
        return subprocess.run(["uptime"], capture_output=True, text=True, check=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return "load average: {:.2f}, {:.2f}, {:.2f}".format(*os.getloadavg())


def run_meta(command: str) -> dict[str, Any]:
    """The head of a benchmark's meta: the command, the date (UTC), which optik, the machine."""
    source = _record.optik_source()
    return {
        "command": command,
        "date_utc": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
        "optik_commit": source["optik_commit"],
        "optik_path": source["optik_path"],
        "cpu": cpu_model(),
        "cores": os.cpu_count(),
    }


def cpu_model() -> str:
    """CPU model name from /proc/cpuinfo (or platform's guess)."""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "?"


def numba_layer() -> str:
    """The threading layer numba chose for ``solve_ik_batch`` (after a parallel call)."""
    import numba

    try:
        return f"{numba.threading_layer()}, NUMBA_NUM_THREADS={numba.config.NUMBA_NUM_THREADS}"
    except ValueError:
        return "not initialised"


def versions() -> dict[str, str]:
    """Installed versions of optik, its backends and the peers."""
    out = {"python": platform.python_version()}
    for dist in VERSIONED:
        try:
            out[dist] = importlib.metadata.version(dist)
        except importlib.metadata.PackageNotFoundError:
            out[dist] = "not installed"
    return out


# ---------------------------------------------------------------- methods
def is_slow(solver: str) -> bool:
    """Whether an optik solver runs on the reduced target set."""
    return any(solver == s or (s.endswith(":") and solver.startswith(s)) for s in SLOW_SOLVERS)


def optik_methods(
    robot: optik.Robot, args: argparse.Namespace, available: Sequence[str], skipped: list[str]
) -> list[Method]:
    """``solve_ik`` rows: each requested solver, default warm start, and from ``q0``."""
    methods = []
    has_closed_form = robot.analytic is not None
    for solver in args.solvers:
        if solver != "auto" and solver not in available:
            reason = f"optik {solver}: not in optik.available_solvers() = {list(available)}"
            if reason not in skipped:
                skipped.append(reason)
            continue
        slow = is_slow(solver)
        n = min(args.n, args.n_slow) if slow else args.n
        starts = ["analytic"]
        if args.q0_variants and has_closed_form and solver != "auto":
            starts.append("q0")
        for warm_start in starts:

            def solve(T: Array, q0: Array, solver: str = solver, ws: str = warm_start) -> Any:
                res = optik.solve_ik(
                    robot, T, solver=solver, warm_start=ws, tol=args.tol, seed=args.seed
                )
                return res.q, res.iterations, res.status

            label = f"optik {solver}" + (" (warm_start=q0)" if warm_start == "q0" else "")
            settings = f"solve_ik(solver={solver!r}, warm_start={warm_start!r})"
            if solver == "auto":
                settings += " closed form" if has_closed_form else " -> dls"
            methods.append(
                Method(label, settings, n, solve, n_note=f"slow: n={n}" if n < args.n else "")
            )
    return methods


def make_peers(args: argparse.Namespace) -> list[PeerRow]:
    """The peer rows in report order, configured for the benchmark tolerance."""
    tol, seed, restarts = args.tol, args.seed, args.peer_restarts
    rtb_tol = 0.5 * tol * tol
    return [
        PeerRow(
            "rtb ik_LM",
            get_peer("rtb", tol=tol, seed=seed),
            f"ETS.ik_LM C++, tol={rtb_tol:.0e} (=½·tol²), slimit=100, joint_limits",
        ),
        PeerRow(
            "rtb ik_LM tol=1e-6",
            get_peer("rtb", tol=tol, seed=seed, rtb_tol=1e-6),
            "ETS.ik_LM C++, RTB default tol=1e-6 on ½‖e‖² (looser than 1e-6)",
        ),
        PeerRow(
            "ikpy",
            get_peer("ikpy", tol=tol, seed=seed, restarts=restarts),
            f"least_squares, bounds, tol=1e-12, {restarts} restarts",
            slow=True,
        ),
        PeerRow(
            "pink",
            get_peer("pink", tol=tol, seed=seed, restarts=restarts, qp_solver=args.pink_solver),
            f"{args.pink_solver}, dt=1, ConfigurationLimit(0.5), 100 it, {restarts} restarts",
            slow=True,
        ),
        PeerRow(
            "eaik",
            get_peer("eaik", tol=tol, seed=seed),
            "closed form, branches wrapped into limits",
        ),
        PeerRow(
            "pybullet",
            get_peer("pybullet", tol=tol, seed=seed, restarts=restarts),
            f"calculateInverseKinematics, 20 rounds of 100 it, {restarts} restarts, "
            "limits not passed (its null-space variant solved none)",
            slow=True,
        ),
    ]


def peer_methods(
    key: str,
    robot: optik.Robot,
    peers: list[PeerRow],
    args: argparse.Namespace,
    model_notes: list[str],
    skipped: list[str],
) -> list[Method]:
    """Peer rows for one robot; a peer that cannot model it is reported, not run."""
    methods = []
    for row in peers:
        peer = row.peer
        try:
            notes = peer.prepare(robot)
        except PeerUnavailable as exc:
            skipped.append(f"{row.label} on {key}: {exc.reason}")
            continue
        except Exception as exc:  # a peer's own bug must not stop the benchmark
            skipped.append(f"{row.label} on {key}: prepare failed: {type(exc).__name__}: {exc}")
            continue
        for note in notes:
            if f"{key}: {note}" not in model_notes:
                model_notes.append(f"{key}: {note}")

        def solve(T: Array, q0: Array, peer: Peer = peer) -> Any:
            answer = peer.solve(T, q0)
            return answer.q, answer.iterations, answer.note

        n = min(args.n, args.n_slow) if row.slow else args.n
        methods.append(
            Method(
                row.label,
                f"{row.settings} [{peer.distribution} {peer.version}]",
                n,
                solve,
                iterations_known=peer.reports_iterations,
                n_note=f"slow: n={n}" if n < args.n else "",
            )
        )
    return methods


def run_query(method: Method, robot: optik.Robot, T: Array, q0: Array, tol: float) -> None:
    """Time one query, verify it, record the row."""
    t0 = time.perf_counter()
    try:
        q, iterations, note = method.solve(T, q0)
    except Exception as exc:  # a crash is a failed query, with its text
        q, iterations, note = None, None, f"{type(exc).__name__}: {exc}"[:120]
    elapsed = time.perf_counter() - t0
    method.times.append(elapsed)
    method.spent += elapsed
    row = dict(time_s=elapsed, iterations=iterations, note=note, **verify(robot, q, T, tol))
    method.rows.append(row)


def warm_up(method: Method, targets: Array, q0: Array) -> str:
    """Untimed first calls (compilation, caches); returns an error text or ''."""
    for T in targets:
        try:
            method.solve(T, q0)
        except Exception as exc:
            return f"{type(exc).__name__}: {exc}"[:160]
    return ""


def bench_robot(
    key: str,
    args: argparse.Namespace,
    peers: list[PeerRow],
    model_notes: list[str],
    skipped: list[str],
) -> list[tuple[str, Method]]:
    """All methods on one robot, interleaved target by target; then the batch solve."""
    robot = optik.load_problem(key).robot
    rng = np.random.default_rng([args.seed, zlib.crc32(key.encode())])
    Q = rng.uniform(robot.lower, robot.upper, (args.n, robot.dof))
    targets = robot.fk(Q)
    warm_targets = robot.fk(rng.uniform(robot.lower, robot.upper, (WARMUP, robot.dof)))
    q0 = robot.mid_limits

    methods = optik_methods(robot, args, optik.available_solvers(), skipped)
    if args.peers:
        methods += peer_methods(key, robot, peers, args, model_notes, skipped)
    for method in methods:
        error = warm_up(method, warm_targets, q0)
        if error:
            method.stopped = f"warm-up failed: {error}"
    print(f"[{key}] {robot.dof} dof, {len(methods)} methods, n={args.n} ...", file=sys.stderr)
    # Garbage collection is off during the loop (as in timeit) and runs every
    # GC_EVERY targets, outside the timed calls: a full collection walks every object of the
    # process and leaves the caches cold, which made the next query 2-3x slower when it
    # ran after every target. The methods run in a fresh (seeded) random order for each
    # target, so that the state left by the previous method falls on none in particular.
    order_rng = np.random.default_rng(args.seed)
    gc.disable()
    try:
        for k, T in enumerate(targets):
            for j in order_rng.permutation(len(methods)):
                method = methods[j]
                if k >= method.n or method.stopped:
                    continue
                if method.spent > args.budget_s:
                    method.stopped = (
                        f"stopped after {len(method.rows)} queries: budget {args.budget_s} s"
                    )
                    continue
                run_query(method, robot, T, q0, args.tol)
            if (k + 1) % GC_EVERY == 0:
                gc.collect()
    finally:
        gc.enable()
        gc.collect()
    extra = rng.uniform(robot.lower, robot.upper, (max(args.batch_n - args.n, 0), robot.dof))
    batch_targets = np.concatenate([targets, robot.fk(extra)])[: max(args.batch_n, 1)]
    methods += [bench_batch(robot, batch_targets, args, threads) for threads in args.threads]
    for method in methods:
        for i, row in enumerate(method.rows):
            row.update(robot=key, method=method.name, index=i)
    return [(key, m) for m in methods]


def bench_batch(
    robot: optik.Robot, targets: Array, args: argparse.Namespace, threads: int
) -> Method:
    """``solve_ik_batch`` over all targets in ``--threads`` numba threads."""
    import numba

    threads = min(threads, numba.config.NUMBA_NUM_THREADS)
    name = f"optik solve_ik_batch ({threads} thread{'s' if threads > 1 else ''})"
    method = Method(
        name,
        f"solve_ik_batch, mid-limits start, {threads} numba thread(s), median wall of "
        f"{args.batch_repeat} runs",
        len(targets),
        lambda T, q: (None, None, ""),
    )
    walls: list[float] = []
    result = None
    try:
        optik.solve_ik_batch(robot, targets[:WARMUP], tol=args.tol, seed=args.seed, threads=threads)
        for _ in range(max(args.batch_repeat, 1)):
            t0 = time.perf_counter()
            result = optik.solve_ik_batch(
                robot, targets, tol=args.tol, seed=args.seed, threads=threads
            )
            walls.append(time.perf_counter() - t0)
    except Exception as exc:  # reported as a row that did not run
        method.n_note = f"failed: {type(exc).__name__}: {exc}"[:160]
        method.stopped = "batch"
        return method
    if result is None:  # pragma: no cover - the loop runs at least once
        return method
    wall = float(np.median(walls))
    per_query = wall / len(targets)
    for i, T in enumerate(targets):
        row = dict(
            time_s=per_query,
            iterations=int(result.iterations[i]),
            note="",
            **verify(robot, result.q[i], T, args.tol),
        )
        method.rows.append(row)
        method.times.append(per_query)
    method.n_note = f"{len(targets) / wall:,.0f} solves/s (time = batch wall / n)"
    method.stopped = "batch"
    method.batch_walls = walls
    return method


# ---------------------------------------------------------------- report
def summarize(key: str, method: Method) -> dict[str, Any]:
    """One line of the long table."""
    rows = method.rows
    n = len(rows)
    ok = sum(r["success"] for r in rows)
    times = np.array(method.times) * 1e6
    iterations = [r["iterations"] for r in rows if r["iterations"] is not None]
    failures = Counter(r["note"] or "wrong answer" for r in rows if not r["success"])
    batch = method.stopped == "batch"
    return {
        "robot": key,
        "method": method.name,
        "settings": method.settings,
        "n": n,
        "success": ok,
        "success_rate": ok / n if n else math.nan,
        "median_us": float(np.median(times)) if n else math.nan,
        "p95_us": float(np.percentile(times, 95)) if n and not batch else math.nan,
        "mean_iterations": float(np.mean(iterations))
        if iterations and method.iterations_known
        else math.nan,
        "notes": "; ".join(
            x
            for x in (
                method.n_note,
                "" if batch else method.stopped,
                ", ".join(f"{k}: {v}" for k, v in failures.most_common(3)),
            )
            if x
        ),
    }


def fmt(x: float, spec: str) -> str:
    """A number, or an em dash for NaN."""
    return "—" if isinstance(x, float) and math.isnan(x) else format(x, spec)


def print_tables(
    summary: list[dict[str, Any]],
    ratio_rows: list[dict[str, Any]],
    results: list[tuple[str, Method]],
) -> None:
    """The long table, then the ratios to RTB."""
    print("\n## Results (one row per robot and method; time per query, µs)\n")
    print("| robot | method | n | success | median µs | p95 µs | mean iter | notes |")
    print("| --- | --- | ---: | ---: | ---: | ---: | ---: | --- |")
    for s in summary:
        print(
            f"| {s['robot']} | {s['method']} | {s['n']} | {fmt(100 * s['success_rate'], '.1f')} % "
            f"| {fmt(s['median_us'], '.1f')} | {fmt(s['p95_us'], '.1f')} "
            f"| {fmt(s['mean_iterations'], '.1f')} | {s['notes']} |"
        )
    print("\n## Settings\n")
    seen = set()
    for s in summary:
        if s["method"] not in seen:
            seen.add(s["method"])
            print(f"- **{s['method']}**: {s['settings']}")
    print(f"\n## Ratios optik / RTB `{RTB_ROW}` (same robot, same targets; time target <= 1.0)\n")
    print(
        "| robot | optik method | n | median time ratio | success ratio | RTB median µs "
        "| RTB success |"
    )
    print("| --- | --- | ---: | ---: | ---: | ---: | ---: |")
    for r in ratio_rows:
        flag = " ✓" if r["time_ratio"] <= 1.0 else ""
        print(
            f"| {r['robot']} | {r['method']} | {r['n']} | {fmt(r['time_ratio'], '.2f')}{flag} "
            f"| {fmt(r['success_ratio'], '.3f')} | {r['rtb_median_us']:.1f} "
            f"| {100 * r['rtb_success_rate']:.1f} % |"
        )
    missing = sorted({key for key, _ in results} - {r["robot"] for r in ratio_rows})
    for key in missing:
        print(f"| {key} | — | — | RTB not run | — | — | — |")


def ratios(results: list[tuple[str, Method]]) -> list[dict[str, Any]]:
    """Ratios optik / RTB of median time and success rate, on the same targets.

    Slow rows ran on the first ``--n-slow`` targets: RTB is summarised over those only.
    """
    rtb = {key: m for key, m in results if m.name == RTB_ROW and m.rows}
    out = []
    for key, method in results:
        if key not in rtb or not method.name.startswith("optik") or not method.rows:
            continue
        n = len(method.rows)
        rtb_times = np.array(rtb[key].times[:n])
        rtb_rate = float(np.mean([r["success"] for r in rtb[key].rows[:n]]))
        rate = float(np.mean([r["success"] for r in method.rows]))
        time_ratio = float(np.median(method.times)) / float(np.median(rtb_times))
        out.append(
            {
                "robot": key,
                "method": method.name,
                "n": min(n, len(rtb_times)),
                "time_ratio": time_ratio,
                "success_ratio": rate / rtb_rate if rtb_rate > 0 else math.nan,
                "rtb_median_us": float(np.median(rtb_times)) * 1e6,
                "rtb_success_rate": rtb_rate,
            }
        )
    return out


def figures(results: list[tuple[str, Method]]) -> list[dict[str, Any]]:
    """The ``--json`` figures: per row, median seconds per query (batch: wall / n)."""
    out = []
    for key, method in results:
        s = summarize(key, method)
        if not method.rows:
            continue
        batch = method.stopped == "batch"
        out.append(
            _record.metric(
                f"{key}: {method.name}",
                "batch" if batch else "single",
                s["median_us"] * 1e-6,
                s["n"],
                runs_s=[w / s["n"] for w in method.batch_walls] if batch else None,
                success_rate=s["success_rate"],
                mean_iterations=s["mean_iterations"],
            )
        )
    return out


def write_out(
    path: Path,
    rows: list[dict[str, Any]],
    meta: dict[str, Any],
    summary: list[dict[str, Any]],
    ratio_rows: list[dict[str, Any]],
) -> None:
    """Raw rows as CSV, or JSON with metadata and summary."""
    columns = [
        "robot",
        "method",
        "index",
        "success",
        "time_s",
        "position_error",
        "orientation_error",
        "limit_violation",
        "iterations",
        "note",
    ]
    path.parent.mkdir(parents=True, exist_ok=True)
    if path.suffix == ".json":
        data = {
            "meta": meta,
            "summary": summary,
            "ratios": ratio_rows,
            "rows": [{c: r[c] for c in columns} for r in rows],
        }
        path.write_text(json.dumps(data, indent=1, default=float) + "\n", encoding="utf-8")
        return
    with path.open("w", newline="", encoding="utf-8") as f:
        writer = csv.DictWriter(f, fieldnames=columns, extrasaction="ignore")
        writer.writeheader()
        writer.writerows(rows)


def parse_args(argv: Sequence[str] | None) -> argparse.Namespace:
    """Command line."""
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument(
        "--robots",
        default=",".join(DEFAULT_ROBOTS),
        help="comma-separated problem names (default: %(default)s)",
    )
    p.add_argument("-n", type=int, default=500, help="targets per robot (default: %(default)s)")
    p.add_argument(
        "--n-slow",
        type=int,
        default=50,
        help="targets for slow methods: pinv, transpose, qp:*, casadi:*, ikpy, pink, pybullet "
        "(default: %(default)s)",
    )
    p.add_argument("--seed", type=int, default=0, help="seed of targets and restarts")
    p.add_argument(
        "--solvers",
        default=",".join(DEFAULT_SOLVERS),
        help="optik solver names; those not available are reported (default: %(default)s)",
    )
    p.add_argument(
        "--q0-variants",
        action=argparse.BooleanOptionalAction,
        default=True,
        help="also run numeric solvers with warm_start='q0' on robots with a closed form",
    )
    p.add_argument(
        "--peers",
        action=argparse.BooleanOptionalAction,
        default=True,
        help="run the peer libraries that import (default: yes)",
    )
    p.add_argument(
        "--peer-restarts",
        type=int,
        default=10,
        help="random restarts for ikpy, pink and pybullet (default: %(default)s)",
    )
    p.add_argument("--pink-solver", default="daqp", help="QP backend of pink (default: daqp)")
    p.add_argument("--tol", type=float, default=1e-6, help="pose tolerance, m and rad")
    p.add_argument(
        "--threads",
        default="1,2",
        help="numba thread counts of solve_ik_batch, one row each (default: %(default)s)",
    )
    p.add_argument("--batch-repeat", type=int, default=5, help="timed runs of the batch")
    p.add_argument(
        "--batch-n",
        type=int,
        default=20_000,
        help="targets of the solve_ik_batch rows: the n targets, then more drawn the same "
        "way (default: %(default)s; a batch of a few hundred measures thread start-up)",
    )
    p.add_argument(
        "--budget-s",
        type=float,
        default=300.0,
        help="time budget per robot and method; a method past it stops",
    )
    p.add_argument("--out", type=Path, help="write every query to this .csv or .json")
    p.add_argument(
        "--json",
        type=Path,
        help="write the figures (median time per query of each row, batch wall / n) to this "
        "file, as interleave.py reads them",
    )
    args = p.parse_args(argv)
    args.robots = [r for r in args.robots.split(",") if r]
    args.solvers = [s for s in args.solvers.split(",") if s]
    args.threads = [int(t) for t in args.threads.split(",") if t]
    if args.n < 1 or args.n_slow < 1:
        p.error("-n and --n-slow must be positive")
    return args


def main(argv: Sequence[str] | None = None) -> int:
    """Run the benchmark and print the report."""
    args = parse_args(argv)
    command = "python benchmarks/bench_ik.py " + shlex.join(sys.argv[1:] if argv is None else argv)
    load_before = load_average()
    peers: list[PeerRow] = []
    peer_status: list[str] = []
    skipped: list[str] = []
    model_notes: list[str] = []
    if args.peers:
        for row in make_peers(args):
            try:
                row.peer.load()
            except PeerUnavailable as exc:
                peer_status.append(f"{row.label}: not installed ({exc.reason})")
                continue
            peers.append(row)
            peer_status.append(f"{row.label}: {row.peer.distribution} {row.peer.version}")

    results: list[tuple[str, Method]] = []
    for key in args.robots:
        results += bench_robot(key, args, peers, model_notes, skipped)
    load_after = load_average()

    summary = [summarize(key, m) for key, m in results]
    meta = {
        **run_meta(command),
        "platform": platform.platform(),
        "load_before": load_before,
        "load_after": load_after,
        "versions": versions(),
        "optik_available_solvers": optik.available_solvers(),
        "numba_threading_layer": numba_layer(),
        "peers": peer_status,
        "skipped": skipped,
        "model_checks": model_notes,
        "protocol": f"uniform in-limit q (seed {args.seed}), FK pose targets, full pose, tol "
        f"{args.tol:g} m/rad, hard limits (1e-12), start mid-limits; success verified here",
    }
    print("# optik IK benchmark\n")
    for k in (
        "command",
        "date_utc",
        "optik_commit",
        "optik_path",
        "cpu",
        "cores",
        "numba_threading_layer",
        "platform",
        "load_before",
        "load_after",
        "protocol",
    ):
        print(f"- {k}: {meta[k]}")
    print("- versions: " + ", ".join(f"{k} {v}" for k, v in meta["versions"].items()))
    print(f"- optik.available_solvers(): {meta['optik_available_solvers']}")
    for title, items in (
        ("peers", peer_status),
        ("model checks", model_notes),
        ("not run", skipped),
    ):
        if items:
            print(f"- {title}:")
            for item in items:
                print(f"  - {item}")
    ratio_rows = ratios(results)
    print_tables(summary, ratio_rows, results)
    if args.out:
        write_out(args.out, [r for _, m in results for r in m.rows], meta, summary, ratio_rows)
        print(f"\nraw rows: {args.out}")
    if args.json:
        _record.write_json(args.json, "bench_ik.py", meta, figures(results))
        print(f"figures: {args.json}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
