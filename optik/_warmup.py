"""Compile optik's kernels before their first call: numba's cache, filled ahead of time.

numba compiles a kernel on its first call in an environment and keeps the machine code in
its on-disk cache (``__pycache__`` beside the sources), so only the first process pays:
about a minute of CPU for the kernels behind ``solve_ik``, ``solve_ik_batch`` and
``optik report --quick``. :func:`warm` pays it ahead: it runs the calls of :data:`GROUPS`
in worker processes (two stages: groups whose kernels overlap little side by side, then
the rest on what they compiled), and merges the kernels into the package's cache; the
groups of :data:`OPTIONAL` (closed forms that compile too long for every install) run
only when named. ``optik warmup`` runs it; the wheel's build hook (``hatch_build.py``)
runs it with a staging folder and ships the merged cache in the wheel.

Each worker compiles into a cache folder of its own (``NUMBA_CACHE_DIR``): numba's cache
is safe for one writer, but two processes that compile different signatures of one
kernel at once can each number their file ``.1.nbc`` and leave an index that names the
other's code. The merge gives every entry a fresh file number and writes each index
whole. A cache entry is keyed by the kernel's signature, its bytecode, the numba release
and the CPU; one compiled for another CPU or release is not used (numba compiles afresh).
"""

from __future__ import annotations

import argparse
import os
import pickle
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from numba.core import caching
from numba.misc.appdirs import AppDirs

from optik._files import write_atomic
from optik._kernel_cache import read_index
from optik.errors import OptikError

PACKAGE = Path(__file__).resolve().parent

__all__ = [
    "FIRST",
    "GROUPS",
    "GROUPS_ENV",
    "LAST",
    "OPTIONAL",
    "WarmReport",
    "axes_arm_robot",
    "cached_already",
    "groups_from_environment",
    "merge_caches",
    "parse_groups",
    "plan_stages",
    "rrp_wrist_robot",
    "run_groups",
    "warm",
]


def _problem_robot(name: str) -> Any:
    from optik.problems import load_problem

    return load_problem(name).robot


def _targets(robot: Any, n: int, seed: int) -> Any:
    """``n`` reachable poses (n, 4, 4) of in-limit configurations."""
    import numpy as np

    rng = np.random.default_rng(seed)
    Q = rng.uniform(robot.lower, robot.upper, size=(n, robot.dof))
    return np.stack([robot.fk(q) for q in Q])


def _closed_forms() -> None:
    """``solve_ik`` (its answer the closed form) and ``analytic_ik`` on the built-ins with one.

    Robots without a closed form are left to :func:`_numeric`: ``solve_ik`` would run the
    damped least squares here too, and both workers would compile it.
    """
    import optik
    from optik.analytic import family_of
    from optik.problems import builtin_problems

    for path in builtin_problems():
        robot = _problem_robot(path.stem)
        if family_of(robot) is None:
            continue
        targets = _targets(robot, 2, 0)
        optik.solve_ik(robot, targets[0])
        optik.analytic_ik(robot, targets[1])
    # A pose whose every branch lies outside the limits: the quick proof's kernel.
    puma = _problem_robot("puma560")
    boxed = puma.with_limits(puma.mid_limits - 0.1, puma.mid_limits + 0.1)
    optik.analytic_ik(boxed, puma.fk(puma.mid_limits + 0.7))


def _held_joint() -> None:
    """The Panda with joint 7 held: its closed form (:mod:`optik.analytic.free_joint`).

    ``analytic_ik`` with ``free_joint``, and ``solve_ik`` with the joint frozen (which
    answers with that closed form).
    """
    import optik

    panda = _problem_robot("panda")
    held = panda.joint_names[6]
    value = float(panda.mid_limits[6])
    target = _targets(panda, 1, 5)[0]
    optik.analytic_ik(panda, target, free_joint=held, free_value=value)
    optik.solve_ik(panda, target, frozen={held: value})


def rrp_wrist_robot() -> Any:
    """The Stanford arm with ``rrp_wrist`` declared (its DH rows fit the DH family too)."""
    import optik

    stanford = _problem_robot("stanford_arm")
    return optik.Robot.from_dh(
        stanford.dh,
        limits=list(zip(stanford.lower.tolist(), stanford.upper.tolist(), strict=True)),
        base=stanford.T_world_base,
        tool=stanford.T_flange_tool,
        analytic="rrp_wrist",
    )


def _rrp_wrist() -> None:
    """A Stanford arm solved by ``rrp_wrist``, the family of such arms from URDF or MDH."""
    import optik

    robot = rrp_wrist_robot()
    optik.analytic_ik(robot, _targets(robot, 1, 6)[0])


def axes_arm_robot() -> Any:
    """A spherical wrist after a general arm (twists of 40-75 deg): ``spherical_axes``."""
    import math

    import optik

    rows = [(0.1, 1.05, 0.4), (0.5, 0.7, 0.1), (0.05, 1.3, 0.0)]
    rows += [(0.0, -math.pi / 2, 0.45), (0.0, math.pi / 2, 0.0), (0.0, 0.0, 0.1)]
    return optik.Robot.from_dh(
        [{"a": a, "alpha": alpha, "d": d, "lower": -3.0, "upper": 3.0} for a, alpha, d in rows]
    )


def _axes_arms() -> None:
    """Every arm kind of ``spherical_axes`` and ``three_parallel``: a pipeline each.

    ``analytic_ik``, ``analytic_ik_batch`` and the raw branches on a spherical wrist after
    a general arm compile its kind's kernels; every other kind's are compiled with the
    same signatures (:func:`optik.analytic.spherical_axes.kind_pipeline`).
    """
    import optik
    from optik.analytic import FAMILIES
    from optik.analytic.spherical_axes import KIND_NAMES, KindPipeline, axes_plan, kind_pipeline

    robot = axes_arm_robot()
    targets = _targets(robot, 2, 7)
    optik.analytic_ik(robot, targets[0])
    optik.analytic_ik_batch(robot, targets)
    # The raw branches alone, as an unreachable target's polish asks for them.
    FAMILIES["spherical_axes"].candidates(robot, targets[0], "pose", robot.mid_limits)
    compiled = kind_pipeline(robot.cached(axes_plan).kind)
    for kind in KIND_NAMES:
        kernels = kind_pipeline(kind)
        for name in KindPipeline._fields:
            for signature in getattr(compiled, name).signatures:
                getattr(kernels, name).compile(signature)


def _closed_form_batches() -> None:
    """``analytic_ik_batch`` on the built-ins with a closed form."""
    import optik
    from optik.analytic import family_of
    from optik.problems import builtin_problems

    for path in builtin_problems():
        robot = _problem_robot(path.stem)
        if family_of(robot) is not None:
            optik.analytic_ik_batch(robot, _targets(robot, 4, 4))


def _kinematics() -> None:
    """A robot's forward kinematics, Jacobian and frames, one configuration and a batch."""
    import numpy as np

    robot = _problem_robot("panda")
    q = robot.mid_limits
    robot.fk(q)
    robot.jacobian(q)
    robot.fk_jacobian(q)
    robot.fk(np.stack([q, q]))
    robot.fk_jacobian(np.stack([q, q]))
    robot.frames(q)


def _numeric() -> None:
    """The numeric solvers of ``solve_ik`` on the Panda, with and without a time limit."""
    import optik

    robot = _problem_robot("panda")
    targets = _targets(robot, 3, 1)
    optik.solve_ik(robot, targets[0])
    optik.solve_ik(robot, targets[1], timeout_s=1.0)
    for solver in ("pinv", "transpose"):
        optik.solve_ik(robot, targets[2], solver=solver, restarts=0, max_iter=5)
    # Graded weights: one iteration fails the search, so the compromise (lm_solve) runs.
    graded = [1.0, 1.0, 1.0, 0.5, 0.5, 0.5]
    optik.solve_ik(robot, targets[0], weights=graded, q0=robot.lower, restarts=0, max_iter=1)
    # The report's reference steps: this worker has time for their kernel.
    J = robot.jacobian(robot.mid_limits)
    optik.min_norm(J, J[:, 0])
    optik.least_squares(J.T, J[0])


def _batch() -> None:
    """``solve_ik_batch`` (compiled kernel on worker threads; a closed form's batch)."""
    import optik

    robot = _problem_robot("panda")
    targets = _targets(robot, 16, 2)
    optik.solve_ik_batch(robot, targets)
    puma = _problem_robot("puma560")
    optik.solve_ik_batch(puma, _targets(puma, 8, 2))
    graded = [1.0, 1.0, 1.0, 0.5, 0.5, 0.5]
    optik.solve_ik_batch(robot, targets[:1], weights=graded, q0=robot.lower, restarts=0, max_iter=1)


def _programs() -> None:
    """``diff_ik`` and ``solve_ik`` through every installed ``qp:*`` backend."""
    import numpy as np

    import optik

    robot = _problem_robot("panda")
    q = robot.mid_limits
    twist = np.array([0.05, 0.0, 0.0, 0.0, 0.0, 0.0])
    targets = _targets(robot, 1, 3)
    for solver in optik.available_solvers(kind="step"):
        if solver.startswith("qp:"):
            optik.diff_ik(robot, q, twist, dt=0.01, solver=solver)
    for solver in optik.available_solvers(kind="ik"):
        if solver.startswith("qp:"):
            optik.solve_ik(robot, targets[0], solver=solver, restarts=0, max_iter=5)


def _report() -> None:
    """``optik report --quick``'s runs (one target per robot; nothing rendered)."""
    from optik.compare.runner import run
    from optik.report.building import quick_config

    with tempfile.TemporaryDirectory() as folder:
        run(quick_config(n=1), Path(folder) / "results.csv", progress=False)


#: The calls that :func:`warm` runs, by name: what a first session runs first.
GROUPS: dict[str, Callable[[], None]] = {
    "closed_forms": _closed_forms,
    "closed_form_batches": _closed_form_batches,
    "rrp_wrist": _rrp_wrist,
    "kinematics": _kinematics,
    "numeric": _numeric,
    "batch": _batch,
    "programs": _programs,
    "report": _report,
}

#: Groups run only when named (``optik warmup --groups``, ``$OPTIK_WARMUP_GROUPS``), after
#: the others: closed forms whose pipelines compile too long for every install (about 11
#: s of CPU; the seven arm kinds 11-20 s for the first a robot calls, 5-15 s for each
#: other, their post-processing being shared), left to their first call unless asked for
#: here.
OPTIONAL: dict[str, Callable[[], None]] = {
    "held_joint": _held_joint,
    "axes_arms": _axes_arms,
}

#: Groups compiled side by side first, a worker each (with two workers): the kernels of
#: one worker's groups share little with the other's (the closed forms, the ``qp:*``
#: programs and ``rrp_wrist``; the damped least squares, its batch and the kinematics),
#: and the two take about as long (about 35 and 26 s alone, side by side on two cores).
FIRST: tuple[tuple[str, ...], ...] = (
    ("closed_forms", "programs", "rrp_wrist"),
    ("numeric", "batch", "kinematics"),
)
#: Groups run last, side by side, each worker starting from every kernel compiled before:
#: the report calls nearly every kernel and compiles only what the first stage left (and
#: its ``casadi:*`` programs' C code, cached outside the package); the closed forms'
#: batches beside it find nearly every kernel compiled (a single target's share the
#: batch's signatures) and compile what is left. :data:`OPTIONAL` groups named join this
#: stage, spread over its workers (they share the closed forms' pieces compiled by then).
LAST: tuple[tuple[str, ...], ...] = (("report",), ("closed_form_batches",))


#: Environment variable naming the groups to warm (comma-separated; default: all).
GROUPS_ENV = "OPTIK_WARMUP_GROUPS"


def _check_groups(names: Sequence[str], source: str = "") -> Sequence[str]:
    """``names``, if every one names a group (:data:`GROUPS`, :data:`OPTIONAL`).

    Raises:
        OptikError: an unknown name (the known ones listed; after ``source``, if given).
    """
    known = sorted({*GROUPS, *OPTIONAL})
    unknown = [name for name in names if name not in known]
    if unknown:
        where = f"{source}: " if source else ""
        raise OptikError(f"{where}unknown warm-up groups {unknown}; known: {known}")
    return names


def parse_groups(text: str, source: str) -> list[str]:
    """The group names of a comma-separated ``text`` (spaces around a name ignored).

    Args:
        text: e.g. ``"closed_forms, held_joint"``.
        source: where ``text`` came from, for the message (``"--groups"``).

    Raises:
        OptikError: no name, or a name that is no group (the known ones listed).
    """
    names = [name.strip() for name in text.split(",")]
    names = [name for name in names if name]
    if not names:
        # Not the default (every group): an empty list would compile nothing and succeed.
        raise OptikError(f"{source}: no group named in {text!r}")
    return list(_check_groups(names, source))


def groups_from_environment() -> list[str] | None:
    """The groups named in ``$OPTIK_WARMUP_GROUPS``; None when it is unset or blank.

    Raises:
        OptikError: it names no group or an unknown one (:func:`parse_groups`).
    """
    text = os.environ.get(GROUPS_ENV, "")
    return parse_groups(text, f"${GROUPS_ENV}") if text.strip() else None


def run_groups(names: Sequence[str]) -> None:
    """Run the calls of the groups named ``names`` (:data:`GROUPS`, :data:`OPTIONAL`) here."""
    _check_groups(names)
    known = {**GROUPS, **OPTIONAL}
    for name in names:
        known[name]()


def _package_folders(package: Path) -> list[Path]:
    """``package`` and its sub-packages (folders holding Python sources)."""
    folders = {path.parent for path in package.rglob("*.py")}
    return sorted(folder for folder in folders if "__pycache__" not in folder.parts)


def _cache_subfolder(folder: Path) -> str:
    """The sub-folder of ``NUMBA_CACHE_DIR`` where numba keeps the kernels of ``folder``."""
    locator = caching._CacheLocator
    return str(locator.get_suitable_cache_subpath(str(folder / "__init__.py")))


def _merge_index(source: Path, target_folder: Path) -> int:
    """Add the entries of index ``source`` to the same index in ``target_folder``.

    Returns the number of entries added. A target index of another numba release or
    source stamp is stale and replaced.
    """
    version, stamp, overloads = read_index(source)
    target = target_folder / source.name
    merged: dict[Any, str] = {}
    if target.exists():
        try:
            old_version, old_stamp, old = read_index(target)
        except (OSError, EOFError, pickle.UnpicklingError):
            old_version, old_stamp, old = "", None, {}
        if (old_version, old_stamp) == (version, stamp):
            merged = old
    base = source.name[: -len(".nbi")]
    taken = set(merged.values())
    added = 0
    for key, name in overloads.items():
        if key in merged:
            continue
        number = 1
        while f"{base}.{number}.nbc" in taken or (target_folder / f"{base}.{number}.nbc").exists():
            number += 1
        fresh = f"{base}.{number}.nbc"
        write_atomic(target_folder / fresh, (source.parent / name).read_bytes())
        merged[key] = fresh
        taken.add(fresh)
        added += 1
    if added:
        index = pickle.dumps(version, protocol=-1) + pickle.dumps((stamp, merged), protocol=-1)
        write_atomic(target, index)
    return added


def merge_caches(
    caches: Sequence[Path], package: Path, destination: Path, *, cache_dir: bool = False
) -> int:
    """Merge workers' ``NUMBA_CACHE_DIR`` folders into ``destination``.

    Args:
        caches: the workers' cache folders.
        package: the package folder the workers imported.
        destination: with ``cache_dir=False``, the folder that holds the package
            (``package.parent`` fills the package's own ``__pycache__`` folders; a staging
            folder collects them for a wheel); with ``cache_dir=True``, a
            ``NUMBA_CACHE_DIR`` for later processes of this package.
        cache_dir: lay the kernels out as numba does in a ``NUMBA_CACHE_DIR``.

    Returns:
        The number of kernels (signatures) merged.
    """
    total = 0
    for folder in _package_folders(package):
        subfolder = _cache_subfolder(folder)
        if cache_dir:
            target = destination / subfolder
        else:
            target = destination / folder.relative_to(package.parent) / "__pycache__"
        for cache in caches:
            for index in sorted((cache / subfolder).glob("*.nbi")):
                target.mkdir(parents=True, exist_ok=True)
                total += _merge_index(index, target)
    return total


@dataclass
class WarmReport:
    """What :func:`warm` did.

    ``kernels``: signatures added to the destination (those it held already are not
    counted); ``seconds``; ``stages``: the groups of each worker by stage; ``compiled``:
    signatures the workers compiled in all; ``cached``: every kernel of the groups was
    in the cache already, so no worker ran (:func:`cached_already`).
    """

    kernels: int
    seconds: float
    stages: list[list[tuple[str, ...]]] = field(default_factory=list)
    compiled: int = 0
    cached: bool = False


def _count_entries(cache: Path) -> int:
    """Signatures held by the numba cache folder ``cache`` (all its indexes)."""
    return sum(len(read_index(index)[2]) for index in cache.rglob("*.nbi"))


def plan_stages(processes: int, groups: Sequence[str] | None = None) -> list[list[tuple[str, ...]]]:
    """The workers' groups, stage by stage, for ``processes`` workers side by side.

    ``groups`` keeps only those groups (default: every one of :data:`GROUPS`); the
    :data:`OPTIONAL` ones among them join the last stage, one per worker in turn.
    """
    keep = set(GROUPS) if groups is None else set(_check_groups(groups))
    first, last = _only(FIRST, keep), _only(LAST, keep)
    workers = list(last)
    for i, name in enumerate(name for name in OPTIONAL if name in keep):
        if i < len(workers):
            workers[i] += (name,)
        else:
            workers.append((name,))
    last = tuple(workers)
    if processes <= 1:
        stages = [[tuple(name for stage in (first, last) for w in stage for name in w)]]
    else:
        stages = [_spread(first, processes), _spread(last, processes)]
    return [[w for w in stage if w] for stage in stages if any(stage)]


def _only(stage: tuple[tuple[str, ...], ...], keep: set[str]) -> tuple[tuple[str, ...], ...]:
    """``stage``'s workers with only the groups in ``keep``, empty workers dropped."""
    workers = (tuple(name for name in worker if name in keep) for worker in stage)
    return tuple(worker for worker in workers if worker)


def _spread(stage: tuple[tuple[str, ...], ...], processes: int) -> list[tuple[str, ...]]:
    """``stage``'s groups over ``processes`` workers (as planned, when the count fits)."""
    if processes == len(stage):
        return list(stage)
    names = [name for worker in stage for name in worker]
    count = min(processes, len(names))
    return [tuple(names[i::count]) for i in range(count)]


def _run_stage(
    stage: Sequence[tuple[str, ...]],
    caches: Sequence[Path],
    env: dict[str, str],
    log: Callable[[str], None] | None,
    start: float,
    scratch: Path,
) -> None:
    """Run each worker of ``stage`` in a process of its own, side by side, and wait.

    Each worker's output goes to a file in ``scratch`` (a pipe read only at the end
    could fill and stall it) and each is logged when it ends. Workers still running when
    this returns (an error, an interrupt, a termination) are stopped: none compiles on
    into a scratch folder that is gone.
    """
    workers = []
    try:
        for k, (cache, names) in enumerate(zip(caches, stage, strict=True)):
            command = [sys.executable, "-m", "optik._warmup", "--run", ",".join(names)]
            with tempfile.NamedTemporaryFile(
                dir=scratch, prefix=f"worker{k}-", suffix=".log", delete=False
            ) as handle:
                process = subprocess.Popen(
                    command,
                    env={**env, "NUMBA_CACHE_DIR": str(cache)},
                    stdout=handle,
                    stderr=subprocess.STDOUT,
                )
            workers.append((process, names, Path(handle.name)))
        failures = []
        running = list(workers)
        while running:
            time.sleep(_POLL_S)
            for worker in [w for w in running if w[0].poll() is not None]:
                running.remove(worker)
                process, names, output = worker
                if process.returncode != 0:
                    text = output.read_text(errors="replace")[-2000:]
                    failures.append(f"{','.join(names)}: {text}")
                elif log is not None:
                    log(f"compiled {', '.join(names)} ({time.perf_counter() - start:.0f} s)")
        if failures:
            raise RuntimeError("kernel warm-up failed:\n" + "\n".join(failures))
    finally:
        for process, _, _ in workers:
            if process.poll() is None:
                process.terminate()
        for process, _, _ in workers:
            try:
                process.wait(timeout=_STOP_S)
            except subprocess.TimeoutExpired:
                process.kill()
                process.wait()


_POLL_S = 0.1
"""How often (s) :func:`_run_stage` looks for workers that ended."""
_STOP_S = 5.0
"""How long (s) a terminated worker may take to end before it is killed."""


@contextmanager
def _termination_as_exit() -> Iterator[None]:
    """Inside: SIGTERM raises ``SystemExit(143)`` (in the main thread).

    The ``finally`` clauses then stop the workers and remove the scratch folder; Python's
    own handling ends the process at once, leaving both behind.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def _exit(signum: int, frame: Any) -> None:
        raise SystemExit(128 + signum)

    previous = signal.signal(signal.SIGTERM, _exit)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


def _write_probe(folder: Path) -> None:
    """Make ``folder`` (and its parents) and write a temporary file in it, as numba does.

    Raises:
        OSError: it cannot be made or written.
    """
    folder.mkdir(parents=True, exist_ok=True)
    with tempfile.NamedTemporaryFile(dir=folder, prefix=".optik-probe-"):
        pass


def _writable(package: Path) -> bool:
    """Whether numba can keep kernels beside ``package``'s sources (its ``__pycache__``)."""
    try:
        _write_probe(package / "__pycache__")
    except OSError:
        return False
    return True


def _check_destination(folders: Sequence[Path]) -> None:
    """Refuse, before compiling, a destination whose ``folders`` cannot be written.

    Raises:
        OptikError: a folder that cannot be made or written (with the reason).
    """
    for folder in folders:
        try:
            _write_probe(folder)
        except OSError as exc:
            in_the_way = isinstance(exc, FileExistsError | NotADirectoryError)
            reason = "a file is in the way" if in_the_way else exc.strerror or str(exc)
            raise OptikError(
                f"cannot write the kernels into {folder}: {reason}; set NUMBA_CACHE_DIR "
                "to a folder you can write (numba then keeps them there)"
            ) from None


_PROBE = """
import os
import sys

from numba.core import event


class FirstCompilation(event.Listener):
    def on_start(self, ev):
        os._exit(3)

    def on_end(self, ev):
        pass


event.register("numba:compile", FirstCompilation())
from optik._warmup import run_groups

run_groups(sys.argv[1].split(","))
"""
"""Runs groups' calls and ends (exit 3) at numba's first compilation."""


def cached_already(names: Sequence[str], env: dict[str, str]) -> bool:
    """Whether a process with ``env`` loads every kernel of the groups ``names`` from cache.

    A probe process runs the groups' calls and ends at numba's first compilation (exit
    3): until then numba only reads its cache, so the probe writes no kernel. About 5 s
    for every group when all are cached, a few seconds when the first call compiles. A
    probe that fails otherwise counts as not cached (the warm-up then runs and reports
    the failure).
    """
    command = [sys.executable, "-c", _PROBE, ",".join(names)]
    done = subprocess.run(command, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return done.returncode == 0


def warm(
    destination: Path | None = None,
    *,
    processes: int = 2,
    groups: Sequence[str] | None = None,
    package: Path = PACKAGE,
    log: Callable[[str], None] | None = None,
) -> WarmReport:
    """Compile the kernels of :data:`GROUPS` in worker processes and merge their caches.

    The groups of :data:`FIRST` run side by side, each worker into a cache folder of its
    own; their caches are merged; then the groups of :data:`LAST` run side by side on
    the merged kernels, compile what is left, and are merged in turn. With one process,
    every group runs in one worker. Warming this environment's own cache (no
    ``destination``), a probe first checks whether its processes would compile anything
    for the groups (:func:`cached_already`); if not, no worker runs.

    Args:
        destination: the folder that holds the ``optik`` package whose ``__pycache__``
            folders receive the kernels (default: where the processes of this
            environment look: ``NUMBA_CACHE_DIR`` when it is set, else the package's own
            ``__pycache__`` folders, or numba's cache of this user, ``~/.cache/numba``,
            when those cannot be written, since numba then reads and writes there).
        processes: worker processes side by side (default 2).
        groups: the groups of :data:`GROUPS` and :data:`OPTIONAL` to run (default:
            those named in ``$OPTIK_WARMUP_GROUPS``, comma-separated, else every one of
            :data:`GROUPS`).
        package: the ``optik`` package folder the workers import.
        log: called with a line per finished worker (default: nothing).

    Returns:
        A :class:`WarmReport`.

    Raises:
        OptikError: ``$OPTIK_WARMUP_GROUPS`` names no group or an unknown one; the
            destination cannot be written (checked before anything compiles).
        RuntimeError: a worker failed (its output is in the message).
    """
    if groups is None:
        groups = groups_from_environment()
    stages = plan_stages(int(processes), groups)
    own_cache = destination is None
    user_cache = os.environ.get("NUMBA_CACHE_DIR") if destination is None else None
    if destination is None and not user_cache and not _writable(package):
        # Where numba keeps this user's kernels of a package it cannot write beside.
        user_cache = AppDirs(appname="numba", appauthor=False).user_cache_dir
    if destination is None:
        destination = Path(user_cache) if user_cache else package.parent
    if user_cache:
        _check_destination([destination])
    else:
        folders = _package_folders(package)
        _check_destination(
            [destination / f.relative_to(package.parent) / "__pycache__" for f in folders]
        )
    start = time.perf_counter()
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(package.parent), env.get("PYTHONPATH")]))
    if own_cache:
        # Where the environment's processes read: the user's cache when the package's
        # folder cannot be written (numba falls back to it, as the merge below does).
        probe_env = {**env, "NUMBA_CACHE_DIR": str(destination)} if user_cache else env
        names = [name for stage in stages for worker in stage for name in worker]
        with _termination_as_exit():
            if cached_already(names, probe_env):
                return WarmReport(0, time.perf_counter() - start, stages, 0, cached=True)
    with _termination_as_exit(), tempfile.TemporaryDirectory(prefix="optik-warmup-") as scratch:
        logs = Path(scratch) / "logs"
        logs.mkdir()
        combined = Path(scratch) / "combined"
        for k, stage in enumerate(stages):
            if len(stage) == 1:  # a lone worker writes the combined cache itself
                caches = [combined]
            else:
                caches = [Path(scratch) / f"stage{k}-worker{i}" for i in range(len(stage))]
                for cache in caches:
                    if combined.exists():
                        shutil.copytree(combined, cache)
            _run_stage(stage, caches, env, log, start, logs)
            separate = [cache for cache in caches if cache != combined]
            if separate:
                merge_caches(separate, package, combined, cache_dir=True)
        compiled = _count_entries(combined)
        kernels = merge_caches([combined], package, destination, cache_dir=bool(user_cache))
    return WarmReport(kernels, time.perf_counter() - start, stages, compiled)


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m optik._warmup``: warm the package, or (``--run``) run groups here."""
    parser = argparse.ArgumentParser(prog="python -m optik._warmup", description=__doc__)
    parser.add_argument("--run", help="comma-separated groups to run in this process")
    parser.add_argument("--destination", type=Path, help="folder holding the optik package")
    parser.add_argument("--processes", type=int, default=2, help="worker processes")
    args = parser.parse_args(argv)
    if args.run:
        run_groups(args.run.split(","))
        return 0
    try:
        report = warm(args.destination, processes=args.processes, log=print)
    except OptikError as exc:
        # A setting to correct (exit 2), told apart from a failed compilation.
        print(f"python -m optik._warmup: error: {exc}", file=sys.stderr)
        return 2
    print(f"{report.compiled} kernels compiled, {report.kernels} merged, in {report.seconds:.0f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
