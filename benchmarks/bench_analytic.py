"""Speed of closed-form IK: optik's ``analytic_ik`` / ``analytic_ik_batch`` against EAIK.

Run: ``python benchmarks/bench_analytic.py [--single 500] [--batch 20000] [--repeat 9]
[--no-peers] [--json FIGURES.json]``

For the Puma 560 and the UR5 (problems/*.toml), and for the arms of makers' URDFs that
both libraries solve (``urdf:ur3``, ``urdf:ur5``, ``urdf:ur10`` from ``ur_description``
and ``urdf:kinova``, the Kinova j2s6s200, read from the ``example-robot-data`` package
when it is installed: the ``test`` extra), it times, after a warm-up:

- single calls ``analytic_ik(robot, T)``: every branch, wrapped into the limits, filtered
  by them and verified by forward kinematics (µs per pose), and the same with
  ``within_limits=False`` (every branch verified, none dropped);
- ``analytic_ik_batch(robot, T)`` over a batch of poses (poses per second, one core);
- EAIK (``pip install eaik``, the ``bench`` extra), in the same process when it imports:
  ``DhRobot(alpha, a, d).IK(T)`` for a DH robot, ``UrdfRobot(path).IK(T)`` for a URDF
  arm, per pose (alone, and followed by reading the solutions' ``.Q`` and ``.is_LS``,
  which a caller needs: optik's call returns its branches as arrays) and
  ``IK_batched(poses, num_worker_threads=1)``. Both libraries solve the same
  configurations' poses, each in its own end frame (EAIK's URDF end frame need not be
  optik's tip; its DH frame is the flange in frame 0). EAIK solves by subproblem
  decomposition in C++, ignores joint limits and does not verify its branches.

Load from other processes shifts every timing, so optik and EAIK alternate within each
timed run and the table gives medians over runs, the ratio of the medians, and the
one-minute load average read before and after. Targets: a single call no
slower than EAIK's; a batch at >= 400,000 poses per second. The branch counts are compared
too: optik without limits against EAIK's non-least-squares solutions. ``--no-peers``
leaves EAIK out; ``--json`` writes the figures (median seconds per pose of each row) in the
shape that ``interleave.py`` reads (see ``_record.py``). Only optik's public names are
used, so that this script can time the package of another source tree.
No assertions: speed is reported, never tested.
"""

from __future__ import annotations

import os

# One core for numpy as well (BLAS threads would make the comparison unfair).
for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import datetime  # noqa: E402
import math  # noqa: E402
import platform  # noqa: E402
import statistics  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from collections.abc import Callable, Sequence  # noqa: E402
from dataclasses import dataclass, field  # noqa: E402
from pathlib import Path  # noqa: E402
from typing import Any  # noqa: E402

import _record  # noqa: E402
import numba  # noqa: E402
import numpy as np  # noqa: E402
from numpy.typing import NDArray  # noqa: E402

from optik import Robot, analytic_ik, analytic_ik_batch, load_problem  # noqa: E402

Array = NDArray[np.float64]
ROBOTS = ("puma560", "ur5")
URDF_ARMS = {
    "urdf:ur3": ("ur_description/urdf/ur3_robot.urdf", "base_link", "tool0"),
    "urdf:ur5": ("ur_description/urdf/ur5_robot.urdf", "base_link", "tool0"),
    "urdf:ur10": ("ur_description/urdf/ur10_robot.urdf", "base_link", "tool0"),
    "urdf:kinova": (
        "kinova_description/robots/kinova.urdf",
        "j2s6s200_link_base",
        "j2s6s200_end_effector",
    ),
}
"""Arms of makers' URDFs (``example-robot-data``): path under its robots folder, base, tip."""
SINGLE_TARGET_FACTOR = 1.0  # optik single call / EAIK single call must be <= this
BATCH_TARGET = 400_000.0  # poses per second, one core (the six-joint families)


def invert_transform(T: Array) -> Array:
    """Inverse of a rigid transform, ``[R^T, -R^T p]`` (written here: no private import)."""
    out = np.eye(4)
    out[:3, :3] = T[:3, :3].T
    out[:3, 3] = -T[:3, :3].T @ T[:3, 3]
    return out


# ---------------------------------------------------------------------- robots
def urdf_robots_dir() -> Path | None:
    """The robots folder of ``example-robot-data`` (the makers' URDFs), if installed."""
    try:
        from importlib.metadata import PackageNotFoundError, distribution
    except ImportError:  # pragma: no cover - the standard library has it
        return None
    try:
        dist = distribution("example-robot-data")
    except PackageNotFoundError:
        return None
    path = Path(str(dist.locate_file("cmeel.prefix/share/example-robot-data/robots")))
    return path if path.is_dir() else None


def default_robots() -> list[str]:
    """The DH problems, then the URDF arms when ``example-robot-data`` is installed."""
    return list(ROBOTS) + (list(URDF_ARMS) if urdf_robots_dir() is not None else [])


def load_robot(name: str) -> Robot:
    """A problem's robot, or a URDF arm of :data:`URDF_ARMS` (``urdf:...``)."""
    if name not in URDF_ARMS:
        return load_problem(name).robot
    root = urdf_robots_dir()
    if root is None:
        raise SystemExit(f"{name}: needs the example-robot-data package (the 'test' extra)")
    path, base, tip = URDF_ARMS[name]
    return Robot.from_urdf(root / path, base, tip)


# ---------------------------------------------------------------------- EAIK
def eaik_version() -> str | None:
    """EAIK's version if it imports, else ``None``."""
    try:
        from importlib.metadata import version

        import eaik  # noqa: F401
    except ImportError:
        return None
    try:
        return version("eaik")
    except Exception:  # pragma: no cover - an unusual install
        return "unknown version"


def eaik_robot(name: str, robot: Robot) -> Any | None:
    """EAIK's robot for ``name``, or ``None`` (EAIK absent, or the robot not comparable).

    A URDF arm gets EAIK's ``UrdfRobot`` of the same file; a standard-DH robot with zero
    joint offsets its ``DhRobot``. EAIK's DH constructor takes ``alpha, a, d`` (no
    ``theta`` offsets) and solves for the flange in frame 0; its forward kinematics is
    checked against optik's here.
    """
    if eaik_version() is None:
        return None
    if name in URDF_ARMS:
        from eaik.IK_URDF import UrdfRobot

        root = urdf_robots_dir()
        return None if root is None else UrdfRobot(str(root / URDF_ARMS[name][0]))
    if robot.dh is None or robot.convention != "dh":
        return None
    if any(abs(r.theta) > 0.0 or r.kind != "revolute" for r in robot.dh):
        return None
    from eaik.IK_DH import DhRobot

    bot = DhRobot(
        np.array([r.alpha for r in robot.dh]),
        np.array([r.a for r in robot.dh]),
        np.array([r.d for r in robot.dh]),
    )
    q = np.random.default_rng(1).uniform(robot.lower, robot.upper)
    T_0 = invert_transform(robot.T_world_base) @ robot.fk(q) @ invert_transform(robot.T_flange_tool)
    if float(np.max(np.abs(bot.fwdKin(q) - T_0))) > 1e-9:
        return None  # a different convention: not comparable
    return bot


def eaik_branches(solution: Any) -> Array:
    """EAIK's exact (not least-squares) solutions of one pose, duplicates removed, (k, 6)."""
    Q = np.asarray(solution.Q, dtype=float).reshape(-1, 6)
    exact = Q[~np.asarray(solution.is_LS, dtype=bool).reshape(-1)]
    out: list[Array] = []
    for q in exact:
        wrapped = np.remainder(q + math.pi, 2 * math.pi) - math.pi
        if all(np.max(np.abs(np.remainder(wrapped - o + math.pi, 2 * math.pi) - math.pi)) > 1e-9
               for o in out):  # fmt: skip
            out.append(wrapped)
    return np.array(out).reshape(-1, 6)


# ---------------------------------------------------------------------- timing
@dataclass
class Series:
    """Seconds per pose of one method over the timed runs."""

    runs: list[float] = field(default_factory=list)

    @property
    def median(self) -> float:
        """Median seconds per pose."""
        return statistics.median(self.runs) if self.runs else math.nan

    @property
    def best(self) -> float:
        """Best run's seconds per pose."""
        return min(self.runs) if self.runs else math.nan


def interleaved(
    methods: dict[str, Callable[[], object]], count: int, repeat: int
) -> dict[str, Series]:
    """Time each method (one call handles ``count`` poses) ``repeat`` times, alternating.

    Each method runs once untimed first (numba loads its kernels); then every run times
    the methods one after the other, so a burst of load hits them alike.
    """
    for fn in methods.values():
        fn()
    series = {name: Series() for name in methods}
    for _ in range(repeat):
        for name, fn in methods.items():
            start = time.perf_counter()
            fn()
            series[name].runs.append((time.perf_counter() - start) / count)
    return series


@dataclass
class Row:
    """One line of the result table."""

    robot: str
    operation: str
    series: Series
    batch: bool
    reference: Series | None = None
    target: str = ""
    met: bool | None = None
    count: int = 0

    def value(self, seconds: float) -> float:
        """µs per pose for single calls, poses per second for batches."""
        return 1.0 / seconds if self.batch else seconds * 1e6


def print_table(rows: Sequence[Row]) -> None:
    """Print the results as a plain-text table."""
    header = (
        f"{'robot':<13}{'operation':<42}{'unit':<9}{'median':>10}{'(best)':>10}"
        f"{'vs EAIK':>9}  {'target':<16}{'met':<4}"
    )
    print(header)
    print("-" * len(header))
    for r in rows:
        unit = "poses/s" if r.batch else "us/pose"
        fmt = "{:10.3g}" if r.batch else "{:10.2f}"
        cells = fmt.format(r.value(r.series.median)) + fmt.format(r.value(r.series.best))
        ratio = "-"
        if r.reference is not None:
            # time ratio: > 1 means optik is slower than EAIK
            ratio = f"{r.series.median / r.reference.median:.2f}x"
        met = "-" if r.met is None else ("yes" if r.met else "NO")
        print(f"{r.robot:<13}{r.operation:<42}{unit:<9}{cells}{ratio:>9}  {r.target:<16}{met:<4}")


# ---------------------------------------------------------------------- runs
def random_configurations(robot: Robot, count: int, seed: int) -> Array:
    """Configurations (count, dof) drawn uniformly inside the limits.

    A revolute joint's range is clipped to one turn (+-pi rad): a continuous joint has
    infinite limits.
    """
    rng = np.random.default_rng(seed)
    revolute = np.array([joint.kind == "revolute" for joint in robot.joints])
    lower = np.where(revolute, np.maximum(robot.lower, -math.pi), robot.lower)
    upper = np.where(revolute, np.minimum(robot.upper, math.pi), robot.upper)
    return rng.uniform(lower, upper, size=(count, robot.dof))


def branch_agreement(
    robot: Robot, bot: Any, poses: Array, poses_eaik: Sequence[Array]
) -> tuple[int, int, float]:
    """Poses where optik (no limits) and EAIK find the same branch count; EAIK's FK error.

    ``poses`` are optik's targets, ``poses_eaik`` the same configurations' poses in EAIK's
    end frame. Returns ``(agreeing poses, poses, largest position error, in EAIK's own
    forward kinematics, of EAIK's exact branches)``.
    """
    same = 0
    worst = 0.0
    for T, T_eaik in zip(poses, poses_eaik, strict=True):
        ours = analytic_ik(robot, T, within_limits=False)
        theirs = eaik_branches(bot.IK(T_eaik))
        same += len(ours) == len(theirs)
        for q in theirs:
            worst = max(worst, float(np.linalg.norm(bot.fwdKin(q)[:3, 3] - T_eaik[:3, 3])))
    return same, len(poses), worst


def run(name: str, single: int, batch: int, repeat: int, peers: bool) -> tuple[list[Row], str]:
    """Time one robot; returns its table rows and a line on branch agreement."""
    robot = load_robot(name)
    bot = eaik_robot(name, robot) if peers else None
    configurations = random_configurations(robot, single, seed=0)
    big_configurations = random_configurations(robot, batch, seed=1)
    poses = robot.fk(configurations)
    big = robot.fk(big_configurations)

    def optik_single() -> None:
        for T in poses:
            analytic_ik(robot, T)

    def optik_single_all() -> None:
        for T in poses:
            analytic_ik(robot, T, within_limits=False)

    singles: dict[str, Callable[[], object]] = {
        "optik": optik_single,
        "optik_all": optik_single_all,
    }
    batches: dict[str, Callable[[], object]] = {"optik": lambda: analytic_ik_batch(robot, big)}
    if bot is not None:
        # The same configurations' poses in EAIK's own end frame (for a DH robot the
        # flange in frame 0: its FK was checked against optik's above).
        poses_0 = [np.asarray(bot.fwdKin(q)) for q in configurations]
        big_0 = [np.asarray(bot.fwdKin(q)) for q in big_configurations]

        def eaik_single() -> None:
            for T in poses_0:
                bot.IK(T)

        def eaik_single_read() -> None:
            for T in poses_0:
                solution = bot.IK(T)
                solution.Q, solution.is_LS  # noqa: B018 - reading them is the point

        singles["eaik"] = eaik_single
        singles["eaik_read"] = eaik_single_read
        batches["eaik"] = lambda: bot.IK_batched(big_0, num_worker_threads=1)
    s = interleaved(singles, single, repeat)
    b = interleaved(batches, batch, max(3, repeat // 2))
    e_s, e_b = s.get("eaik"), b.get("eaik")
    rows = [
        Row(name, "analytic_ik (limits, FK-verified)", s["optik"], False, e_s,
            f"<= EAIK x{SINGLE_TARGET_FACTOR:g}",
            None if e_s is None else s["optik"].median <= SINGLE_TARGET_FACTOR * e_s.median,
            single),
        Row(name, "analytic_ik (no limits, FK-verified)", s["optik_all"], False, e_s,
            count=single),
        Row(name, f"analytic_ik_batch, N = {batch:,}", b["optik"], True, e_b,
            f">= {BATCH_TARGET:,.0f}/s", 1.0 / b["optik"].median >= BATCH_TARGET, batch),
    ]  # fmt: skip
    if e_s is not None and e_b is not None:
        rows += [
            Row(name, "EAIK IK (no limits, not verified)", e_s, False, count=single),
            Row(name, "EAIK IK, then reading .Q and .is_LS", s["eaik_read"], False,
                count=single),
            Row(name, f"EAIK IK_batched, 1 thread, N = {batch:,}", e_b, True, count=batch),
        ]  # fmt: skip
    note = f"{name}: EAIK not available or not comparable"
    if not peers:
        note = f"{name}: EAIK not run (--no-peers)"
    if bot is not None:
        count = min(200, single)
        same, total, worst = branch_agreement(robot, bot, poses[:count], poses_0[:count])
        note = (
            f"{name}: branch count (optik without limits vs EAIK exact solutions) equal on "
            f"{same}/{total} poses; EAIK's worst FK position error {worst:.1e} m"
        )
    return rows, note


def main(argv: Sequence[str] | None = None) -> None:
    """Run the benchmark and print the table."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--single", type=int, default=500, help="poses per single-call run")
    parser.add_argument("--batch", type=int, default=20_000, help="poses per batch")
    parser.add_argument("--repeat", type=int, default=9, help="timed runs (median)")
    parser.add_argument(
        "--robots",
        nargs="+",
        default=None,
        help="problem names and URDF arms (" + ", ".join(URDF_ARMS) + "); default: the "
        "problems " + ", ".join(ROBOTS) + " and, with example-robot-data, the URDF arms",
    )
    parser.add_argument(
        "--peers",
        action=argparse.BooleanOptionalAction,
        default=True,
        help="time EAIK beside optik when it imports (default: yes)",
    )
    parser.add_argument(
        "--json",
        type=Path,
        help="write the figures (median seconds per pose of each row) to this file, as "
        "interleave.py reads them",
    )
    args = parser.parse_args(argv)

    version = eaik_version() if args.peers else None
    print(
        f"optik closed-form IK benchmark; python {platform.python_version()}, numpy "
        f"{np.__version__}, numba {numba.__version__}, EAIK {version or 'not installed'}, "
        f"{platform.machine()}, {os.cpu_count()} CPUs (everything runs on one core)"
    )
    load_before = os.getloadavg()[0]
    rows: list[Row] = []
    notes: list[str] = []
    for name in args.robots or default_robots():
        robot_rows, note = run(name, args.single, args.batch, args.repeat, args.peers)
        rows += robot_rows
        notes.append(note)
    load_after = os.getloadavg()[0]
    print(
        f"median of {args.repeat} runs ({args.single} poses each; batches: "
        f"{max(3, args.repeat // 2)} runs), optik and EAIK alternating; 1-min load average "
        f"{load_before:.2f} before, {load_after:.2f} after"
    )
    print()
    print_table(rows)
    print()
    print("vs EAIK: optik median time / EAIK median time for the same poses (< 1: faster)")
    for note in notes:
        print(note)
    if version is None and args.peers:
        print("EAIK is not installed: pip install eaik (the 'bench' extra) to compare")
    if args.json:
        meta = {
            "command": "python benchmarks/bench_analytic.py "
            + " ".join(sys.argv[1:] if argv is None else argv),
            "date_utc": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
            **_record.optik_source(),
            "load_before": f"load average: {load_before:.2f}",
            "load_after": f"load average: {load_after:.2f}",
            "eaik": version or "not run",
        }
        metrics = [
            _record.metric(
                f"{r.robot}: {r.operation}",
                "batch" if r.batch else "single",
                r.series.median,
                r.count,
                runs_s=list(r.series.runs),
            )
            for r in rows
        ]
        _record.write_json(args.json, "bench_analytic.py", meta, metrics)
        print(f"figures: {args.json}")


if __name__ == "__main__":
    main()
