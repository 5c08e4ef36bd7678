"""The programs against their backends: ``diff_ik`` and QP / CasADi IK on the Panda.

Run: ``python benchmarks/bench_programs.py [--robot panda] [--steps 300] [--targets 100]
[--seed 0] [--clock wall|cpu] [--json FILE]`` (see benchmarks/README.md). pink's rows need
pink and Pinocchio (``/work/venv-bench``); without them they are listed as not run.

Two parts, each in one process, every method interleaved sample by sample in a fresh
seeded random order, garbage collection off inside the timed loop:

1. **One step.** ``--steps`` configurations drawn uniformly in the middle 80 % of each
   joint range, a twist of 0.1 m/s and rad/s per component (normal), ``dt = 0.01`` s,
   kept when the minimum-norm step lies inside the step bounds (a servo step away from
   the limits and from singularities). Rows:
   the Jacobian alone; ``diff_ik`` (least norm and least squares) with each backend; the
   raw backend solve of the same least-norm QP (built untimed) through
   ``qpsolvers.solve_qp`` and through the backend's own API; pink + daqp one step (the
   ``Configuration`` at ``q`` built inside the timed call, as ``diff_ik`` computes its
   Jacobian). The answers of ``diff_ik`` are compared with the raw solves (largest
   difference reported).
2. **Full IK.** ``--targets`` joint vectors uniform inside the limits, their FK poses as
   targets (full pose, tol 1e-6 m and rad); ``solve_ik`` with ``dls``, ``qp:<backend>`` and
   ``casadi:<plugin>``, and pink + daqp iterated to convergence (``optik.peers.pink.PinkPeer``).
   Success
   is decided here from FK and the limits. The first call of each method (compilation,
   code generation) is timed apart and reported as its first-call time.

Each call is timed on the wall clock (``--clock wall``, :func:`time.perf_counter`) or on
the calling thread's CPU time (``--clock cpu``, :func:`time.thread_time`): on a shared,
loaded machine a call of a few milliseconds is preempted far more often than one of
0.1 ms, which inflates long calls' wall times and their ratios; CPU time of the thread
is what the call costs (every method here computes on the calling thread).

Output: the tables (median and p95 time per call, ratios to the reference row: raw solve
+ Jacobian for the steps, ``dls`` for IK), the versions, the hardware and the load.
"""

from __future__ import annotations

import os

# numpy's BLAS stays on one thread: the machine is small and the programs are tiny.
for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import gc  # noqa: E402
import math  # noqa: E402
import shlex  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from collections.abc import Callable, Sequence  # noqa: E402
from dataclasses import dataclass, field  # noqa: E402
from pathlib import Path  # noqa: E402
from typing import Any  # noqa: E402

import numpy as np  # noqa: E402
from numpy.typing import NDArray  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))

import _record  # noqa: E402
import bench_ik  # noqa: E402

import optik  # noqa: E402
from optik.programs.diff_qp import build_program  # noqa: E402
from optik.solvers.qp import BACKEND_OPTIONS  # noqa: E402
from optik.spatial import exp_so3  # noqa: E402

Array = NDArray[np.float64]
STEP_BACKENDS = ("daqp", "proxqp", "osqp")
IK_SOLVERS = ("dls", "qp:daqp", "qp:proxqp", "casadi:sqpmethod", "casadi:ipopt")
TOL = 1e-6
TWIST_SCALE = 0.1  # m/s and rad/s per component
DT = 0.01  # s
GC_EVERY = 50
WARMUP = 3
CLOCKS: dict[str, Callable[[], float]] = {"wall": time.perf_counter, "cpu": time.thread_time}


@dataclass
class Row:
    """One method: a call per sample, its times and its answers."""

    name: str
    call: Callable[[int], Any]
    times: list[float] = field(default_factory=list)
    answers: list[Any] = field(default_factory=list)
    first_s: float = math.nan
    error: str = ""

    def median(self) -> float:
        """Median time per call (s)."""
        return float(np.median(self.times)) if self.times else math.nan

    def p95(self) -> float:
        """95th percentile of the time per call (s)."""
        return float(np.percentile(self.times, 95)) if self.times else math.nan


def interleave(
    rows: list[Row], count: int, seed: int, clock: Callable[[], float] = time.perf_counter
) -> None:
    """Time every row on samples ``0..count-1``, in a fresh random order per sample.

    The first call of each row runs untimed before the loop (its wall time is kept as
    ``first_s``: compilation, code generation, caches), then ``WARMUP`` more on the first
    samples. A row that raises stops, with the error kept. ``clock`` times the calls
    (s): :func:`time.perf_counter` or :func:`time.thread_time`.
    """
    for row in rows:
        t0 = time.perf_counter()
        try:
            row.call(0)
            row.first_s = time.perf_counter() - t0
            for k in range(1, min(WARMUP, count)):
                row.call(k)
        except Exception as exc:  # a broken method is reported, the rest still run
            row.error = f"{type(exc).__name__}: {exc}"[:160]
    order = np.random.default_rng(seed)
    gc.disable()
    try:
        for k in range(count):
            for j in order.permutation(len(rows)):
                row = rows[j]
                if row.error:
                    continue
                t0 = clock()
                try:
                    answer = row.call(k)
                except Exception as exc:
                    row.error = f"sample {k}: {type(exc).__name__}: {exc}"[:160]
                    continue
                row.times.append(clock() - t0)
                row.answers.append(answer)
            if (k + 1) % GC_EVERY == 0:
                gc.collect()
    finally:
        gc.enable()


# ---------------------------------------------------------------- one step
def raw_daqp(P: Array, c: Array, J: Array, v: Array, lb: Array, ub: Array) -> Array:
    """DAQP's own one-shot call: bounds first, then the equality rows (sense 5)."""
    import daqp

    n, m = J.shape[1], J.shape[0]
    sense = np.zeros(n + m, dtype=np.intc)
    sense[n:] = 5
    upper = np.concatenate([ub, v])
    lower = np.concatenate([lb, v])
    x, _, flag, _ = daqp.solve(P, c, J, upper, lower, sense, **BACKEND_OPTIONS["daqp"])
    if flag <= 0:
        raise RuntimeError(f"daqp exit flag {flag}")
    return np.asarray(x)


def raw_proxqp(P: Array, c: Array, J: Array, v: Array, lb: Array, ub: Array) -> Array:
    """ProxQP's own dense API with box constraints (qpsolvers turns them into rows)."""
    from proxsuite import proxqp

    n, m = J.shape[1], J.shape[0]
    qp = proxqp.dense.QP(n, m, 0, True)
    qp.settings.eps_abs = 1e-12
    qp.settings.eps_rel = 0.0
    qp.settings.max_iter = 10_000
    qp.init(P, c, J, v, None, None, None, lb, ub)
    qp.solve()
    return np.array(qp.results.x)


def raw_osqp(P: Array, c: Array, J: Array, v: Array, lb: Array, ub: Array) -> Array:
    """OSQP's own API: setup then solve (rows: J, then the identity for the bounds)."""
    import osqp
    import scipy.sparse as spa

    n = J.shape[1]
    A = spa.csc_matrix(np.vstack([J, np.eye(n)]))
    options = dict(BACKEND_OPTIONS["osqp"], verbose=False)
    solver = osqp.OSQP()
    solver.setup(
        spa.csc_matrix(np.triu(P)),
        c,
        A,
        np.concatenate([v, lb]),
        np.concatenate([v, ub]),
        **options,
    )
    return np.asarray(solver.solve().x)


RAW_OWN = {"daqp": raw_daqp, "proxqp": raw_proxqp, "osqp": raw_osqp}


def step_samples(robot: optik.Robot, count: int, seed: int) -> tuple[Array, Array, list[Any]]:
    """Configurations, twists and least-norm programs whose closed form is inside the bounds.

    A servo step far from the limits and from singularities: drawn until ``count``
    samples have the minimum-norm answer ``J^+ v`` inside the step bounds.
    """
    rng = np.random.default_rng(seed)
    lo, hi = robot.lower, robot.upper
    Q, twists, programs = [], [], []
    while len(Q) < count:
        q = lo + (hi - lo) * rng.uniform(0.1, 0.9, robot.dof)
        twist = TWIST_SCALE * rng.normal(size=6)
        program = build_program(robot, q, twist * DT, dt=DT)
        dq = np.linalg.pinv(program.J) @ program.v
        if np.all(dq > program.lower) and np.all(dq < program.upper):
            Q.append(q)
            twists.append(twist)
            programs.append(program)
    return np.array(Q), np.array(twists), programs


def step_rows(robot: optik.Robot, args: argparse.Namespace) -> tuple[list[Row], list[str]]:
    """The rows of part 1 and notes (backends or peers not run)."""
    import qpsolvers

    Q, twists, programs = step_samples(robot, args.steps, args.seed)
    notes: list[str] = []
    rows = [Row("jacobian", lambda k: robot.jacobian(Q[k]))]
    for backend in STEP_BACKENDS:
        if backend not in qpsolvers.available_solvers:
            notes.append(f"{backend}: not installed")
            continue
        solver = f"qp:{backend}"
        opts = BACKEND_OPTIONS[backend]
        rows.append(
            Row(
                f"diff_ik {solver} least_norm",
                lambda k, s=solver: optik.diff_ik(robot, Q[k], twists[k], dt=DT, solver=s),
            )
        )
        rows.append(
            Row(
                f"diff_ik {solver} least_squares",
                lambda k, s=solver: optik.diff_ik(
                    robot, Q[k], twists[k], dt=DT, solver=s, objective="least_squares"
                ),
            )
        )

        def via_qpsolvers(k: int, backend: str = backend, opts: dict[str, Any] = opts) -> Array:
            qp = programs[k].qp
            x = qpsolvers.solve_qp(
                qp.P, qp.q, A=qp.A, b=qp.b, lb=qp.lb, ub=qp.ub, solver=backend, **opts
            )
            if x is None:
                raise RuntimeError("no solution")
            return np.asarray(x)

        rows.append(Row(f"qpsolvers.solve_qp {backend}", via_qpsolvers))

        def own(k: int, fn: Callable[..., Array] = RAW_OWN[backend]) -> Array:
            p = programs[k]
            return fn(p.P, p.c, p.J, p.v, p.lower, p.upper)

        rows.append(Row(f"{backend} own API", own))
    pink_row = pink_step_row(args.robot, robot, Q, twists, notes)
    if pink_row is not None:
        rows.append(pink_row)
    return rows, notes


def pink_step_row(
    key: str, robot: optik.Robot, Q: Array, twists: Array, notes: list[str]
) -> Row | None:
    """Pink + daqp, one step towards the pose ``exp(twist dt)`` ahead (or None, noted)."""
    try:
        import pink
        import pinocchio as pin
        from pink.limits import ConfigurationLimit
        from pink.tasks import FrameTask
    except ImportError as exc:
        notes.append(f"pink one step: not installed ({exc})")
        return None
    from optik.peers._chain import TOOL_LINK, urdf_text

    tool = TOOL_LINK
    model = pin.buildModelFromXML(urdf_text(robot, "pink"))
    data = model.createData()
    limits = [ConfigurationLimit(model, config_limit_gain=0.5)]
    task = FrameTask(tool, position_cost=1.0, orientation_cost=1.0, gain=1.0)
    targets = []
    for q, twist in zip(Q, twists, strict=True):
        T = robot.fk(q)
        T_next = T.copy()
        T_next[:3, 3] += twist[:3] * DT
        T_next[:3, :3] = exp_so3(twist[3:] * DT) @ T[:3, :3]
        targets.append(pin.SE3(T_next[:3, :3].copy(), T_next[:3, 3].copy()))

    def call(k: int) -> Array:
        task.set_target(targets[k])
        config = pink.Configuration(model, data, Q[k])
        return np.asarray(
            pink.solve_ik(config, [task], dt=DT, solver="daqp", limits=limits, safety_break=False)
        )

    return Row("pink + daqp one step", call)


# ---------------------------------------------------------------- full IK
def ik_rows(
    robot: optik.Robot, args: argparse.Namespace, targets: Array
) -> tuple[list[Row], list[str]]:
    """The rows of part 2: ``solve_ik`` per solver, pink iterated (or noted)."""
    notes: list[str] = []
    rows = []
    available = optik.available_solvers()
    for solver in args.solvers:
        if solver not in available:
            notes.append(f"{solver}: not in optik.available_solvers()")
            continue

        def call(k: int, solver: str = solver) -> Any:
            res = optik.solve_ik(robot, targets[k], solver=solver, tol=TOL, seed=args.seed)
            return res.q

        rows.append(Row(f"solve_ik {solver}", call))
    from optik.peers.pink import PinkPeer

    peer = PinkPeer(tol=TOL, seed=args.seed, qp_solver="daqp", restarts=10)
    try:
        peer.load()
        peer.prepare(robot)
    except Exception as exc:  # not installed, or cannot model the robot
        notes.append(f"pink full IK: {type(exc).__name__}: {exc}")
    else:
        mid = robot.mid_limits
        rows.append(Row("pink + daqp full IK", lambda k: peer.solve(targets[k], mid).q))
    return rows, notes


# ---------------------------------------------------------------- report
def us(x: float) -> str:
    return "—" if not math.isfinite(x) else f"{1e6 * x:.1f}"


def ratio(a: float, b: float) -> str:
    return "—" if not (math.isfinite(a) and math.isfinite(b) and b > 0) else f"{a / b:.2f}"


def step_table(rows: list[Row], robot: optik.Robot) -> list[dict[str, Any]]:
    by = {r.name: r for r in rows}
    jac = by["jacobian"].median()
    print("\n## One step (Panda, least norm unless said; times per call)\n")
    print("| call | median µs | p95 µs | vs raw own API + J | vs solve_qp + J | max |dq - raw| |")
    print("| --- | ---: | ---: | ---: | ---: | ---: |")
    out = []
    for r in rows:
        backend = next((b for b in STEP_BACKENDS if f" {b}" in r.name or f":{b}" in r.name), None)
        own = by.get(f"{backend} own API") if backend else None
        via = by.get(f"qpsolvers.solve_qp {backend}") if backend else None
        vs_own = vs_via = diff = "—"
        if r.name.startswith("diff_ik") and own is not None and via is not None:
            vs_own = ratio(r.median(), own.median() + jac)
            vs_via = ratio(r.median(), via.median() + jac)
            if "least_norm" in r.name and r.answers and len(own.answers) == len(r.answers):
                d = max(
                    float(np.max(np.abs(a - b)))
                    for a, b in zip(r.answers, own.answers, strict=True)
                )
                diff = f"{d:.1e}"
        note = f" ({r.error})" if r.error else ""
        print(
            f"| {r.name}{note} | {us(r.median())} | {us(r.p95())} | {vs_own} | {vs_via} | {diff} |"
        )
        out.append(_record.metric(f"{robot.name}: {r.name}", "single", r.median(), len(r.times)))
    return out


def ik_table(rows: list[Row], robot: optik.Robot, targets: Array) -> list[dict[str, Any]]:
    by = {r.name: r for r in rows}
    dls = by.get("solve_ik dls")
    print("\n## Full IK (Panda, full pose, tol 1e-6; times per query)\n")
    print("| method | success | median µs | p95 µs | median / dls | p95 / dls | first call ms |")
    print("| --- | ---: | ---: | ---: | ---: | ---: | ---: |")
    out = []
    for r in rows:
        ok = [
            bench_ik.verify(robot, q, targets[k], TOL)["success"] for k, q in enumerate(r.answers)
        ]
        rate = float(np.mean(ok)) if ok else math.nan
        m = dls.median() if dls else math.nan
        p = dls.p95() if dls else math.nan
        note = f" ({r.error})" if r.error else ""
        print(
            f"| {r.name}{note} | {rate:.3f} | {us(r.median())} | {us(r.p95())} | "
            f"{ratio(r.median(), m)} | {ratio(r.p95(), p)} | {1e3 * r.first_s:.1f} |"
        )
        out.append(
            _record.metric(
                f"{robot.name}: {r.name}", "single", r.median(), len(r.times), success_rate=rate
            )
        )
    return out


def parse_args(argv: Sequence[str] | None) -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--robot", default="panda", help="problem name (default: %(default)s)")
    p.add_argument("--steps", type=int, default=300, help="one-step samples")
    p.add_argument("--targets", type=int, default=100, help="full-IK targets")
    p.add_argument("--seed", type=int, default=0, help="seed of samples and order")
    p.add_argument(
        "--solvers", default=",".join(IK_SOLVERS), help="solve_ik solvers, comma-separated"
    )
    p.add_argument(
        "--clock",
        choices=sorted(CLOCKS),
        default="wall",
        help="time calls on the wall clock or on the thread's CPU time (default: %(default)s)",
    )
    p.add_argument("--no-steps", action="store_true", help="skip part 1")
    p.add_argument("--no-ik", action="store_true", help="skip part 2")
    p.add_argument("--json", type=Path, help="write the figures (see _record.py)")
    args = p.parse_args(argv)
    args.solvers = [s for s in args.solvers.split(",") if s]
    return args


def main(argv: Sequence[str] | None = None) -> int:
    """Run both parts and print the report."""
    args = parse_args(argv)
    command = "python benchmarks/bench_programs.py " + shlex.join(
        sys.argv[1:] if argv is None else argv
    )
    load_before = bench_ik.load_average()
    robot = optik.load_problem(args.robot).robot
    figures: list[dict[str, Any]] = []
    notes: list[str] = []
    step_results: list[Row] = []
    ik_results: list[Row] = []
    targets = np.zeros((0, 4, 4))
    if not args.no_steps:
        step_results, more = step_rows(robot, args)
        notes += more
        interleave(step_results, args.steps, args.seed, CLOCKS[args.clock])
    if not args.no_ik:
        rng = np.random.default_rng([args.seed, 1])
        targets = robot.fk(rng.uniform(robot.lower, robot.upper, (args.targets, robot.dof)))
        ik_results, more = ik_rows(robot, args, targets)
        notes += more
        interleave(ik_results, args.targets, args.seed, CLOCKS[args.clock])
    load_after = bench_ik.load_average()
    meta = {
        **bench_ik.run_meta(command),
        "load_before": load_before,
        "load_after": load_after,
        "clock": args.clock,
        "versions": bench_ik.versions(),
        "not_run": notes,
    }
    print("# optik programs benchmark\n")
    for key in ("command", "date_utc", "optik_commit", "optik_path", "cpu", "cores"):
        print(f"- {key}: {meta[key]}")
    print(f"- load: before {load_before}; after {load_after}")
    print(f"- clock: {'thread CPU time' if args.clock == 'cpu' else 'wall time'} per call")
    print("- versions: " + ", ".join(f"{k} {v}" for k, v in meta["versions"].items()))
    for note in notes:
        print(f"- not run: {note}")
    if step_results:
        figures += step_table(step_results, robot)
    if ik_results:
        figures += ik_table(ik_results, robot, targets)
    if args.json:
        _record.write_json(args.json, "bench_programs.py", meta, figures)
        print(f"\nfigures: {args.json}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
