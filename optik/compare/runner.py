"""The comparison run: tasks of every section, warm-ups, and the resumable row loop."""

from __future__ import annotations

import functools
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from optik._checks import FloatArray, check_progress
from optik._interrupts import reraise_interrupt
from optik._progress import Progress
from optik.compare.backends import solve_step, step_backends
from optik.compare.config import RunConfig, RunStats, ik_settings
from optik.compare.ik_runs import _ik_row
from optik.compare.peer_runs import PeerStatus, _peer_row, peer_settings, peer_solver, prepare_peer
from optik.compare.results import Key, ResultRow, ResultsFile
from optik.compare.seeds import (
    CHAPTER_TABLE_2,
    SEED001_MAX_ITER,
    SEED001_SOLVERS,
    SEED003_Q0,
    SEED003_STEPS,
    _seed001_settings,
    _seed003_settings,
    dobot_chapter_rows,
    planar_2r_example,
)
from optik.compare.steps import _closed_form_row, closed_form_cases
from optik.compare.targets import _solve_seed, random_configurations
from optik.errors import OptikError
from optik.problems import Problem, load_problem

__all__ = ["run"]


@dataclass
class _Task:
    """Rows produced together (one IK call, one step solve, or a seed's chain)."""

    keys: list[Key]
    produce: Callable[[], list[ResultRow]]
    note: str
    group: tuple[str, ...] = ()
    warm_up: Callable[[], object] | None = None


def _problem(problem: str | Problem) -> Problem:
    return problem if isinstance(problem, Problem) else load_problem(problem)


def _same_robot(a: Problem, b: Problem) -> bool:
    """Whether two problems of one name are the same robot: read from one file, or one object."""
    if a is b:
        return True
    if a.path is None or b.path is None:
        return False
    return a.path.resolve() == b.path.resolve() and a.source == b.source


def _distinct(problems: Sequence[str | Problem]) -> list[Problem]:
    """The problems loaded, each once; two different robots of one name are refused.

    A row's key names its problem, not its file: the second robot of a name would find its
    rows already written and be skipped without a word. The same problem given twice (its
    name and its file) runs once.

    Raises:
        OptikError: two problems of the same name from different files (or objects).
    """
    loaded: dict[str, Problem] = {}
    for given in problems:
        problem = _problem(given)
        first = loaded.setdefault(problem.name, problem)
        if not _same_robot(first, problem):
            where = [str(p.path) if p.path is not None else p.source for p in (first, problem)]
            raise OptikError(
                f"two problems are named {problem.name!r} ({where[0]} and {where[1]}): the "
                "rows of results.csv name their problem, so each needs its own name (the "
                "[robot] table's name)"
            )
    return list(loaded.values())


def _rows(row: Callable[..., ResultRow], *args: Any) -> list[ResultRow]:
    """``[row(*args)]``: a task of one row."""
    return [row(*args)]


def _peer_rows(answers: dict[Key, FloatArray], *args: Any) -> list[ResultRow]:
    """``[_peer_row(*args)]``, its answer ``q`` (when any) kept in ``answers``."""
    row, q = _peer_row(*args)
    if q is not None:
        answers[row.key()] = q
    return [row]


def _try_step(program: Any, backend: str) -> object:
    """A warm-up solve of a step program: its answer, or the exception it raised."""
    try:
        return solve_step(program, backend)
    except Exception as exc:  # the timed call will record it
        reraise_interrupt(exc)  # Ctrl-C is the caller's, not a failure
        return exc


def _ik_tasks(config: RunConfig, problems: Sequence[Problem]) -> Iterator[_Task]:
    for problem in problems:
        robot = problem.robot
        counts = {s: config.targets_for(s) for s in config.solvers}
        total = max(counts.values(), default=0)
        Q = random_configurations(robot, problem.name, total, config.seed)
        poses = robot.fk(Q) if total else np.empty((0, 4, 4))
        home = robot.fk(robot.mid_limits)
        for solver in config.solvers:
            settings = ik_settings(config, solver)
            warm_up = functools.partial(_ik_row, problem, "warm-up", home, solver, config, 0)
            for k in range(counts[solver]):
                target_id = f"t{k:04d}"
                seed = _solve_seed(config.seed, problem.name, k)
                yield _Task(
                    [("ik", problem.name, target_id, solver, settings)],
                    functools.partial(
                        _rows, _ik_row, problem, target_id, poses[k], solver, config, seed
                    ),
                    f"ik {problem.name} {solver}",
                    ("ik", problem.name, solver),
                    warm_up,
                )


def _peer_tasks(
    config: RunConfig,
    problems: Sequence[Problem],
    statuses: list[PeerStatus],
    answers: dict[Key, FloatArray],
) -> Iterator[_Task]:
    """The peers' rows: each prepared peer on the problem's ``ik`` targets."""
    for problem in problems:
        robot = problem.robot
        home = robot.fk(robot.mid_limits)
        for name in config.peers:
            peer, status = prepare_peer(name, problem, config.mode, config.tol, config.timeout_s)
            statuses.append(status)
            if not status.available:
                continue
            solver = peer_solver(name)
            settings = peer_settings(peer, config.mode, config.seed, config.timeout_s, config.tol)
            count = config.targets_for(solver)
            poses = robot.fk(random_configurations(robot, problem.name, count, config.seed))
            warm_up = functools.partial(
                _peer_row, problem, "warm-up", home, peer, "", config.tol, 0
            )
            for k in range(count):
                target_id = f"t{k:04d}"
                seed = _solve_seed(config.seed, problem.name, k)
                yield _Task(
                    [("ik", problem.name, target_id, solver, settings)],
                    functools.partial(
                        _peer_rows,
                        answers,
                        problem,
                        target_id,
                        poses[k],
                        peer,
                        settings,
                        config.tol,
                        seed,
                    ),
                    f"ik {problem.name} {solver}",
                    ("ik", problem.name, solver),
                    warm_up,
                )


def _closed_form_tasks(
    config: RunConfig, problems: Sequence[Problem], backends: Sequence[str]
) -> Iterator[_Task]:
    for problem in problems:
        cases = closed_form_cases(
            problem.robot, problem.name, config.closed_form_configs, config.seed
        )
        for case in cases:
            program = case.program(problem.robot)
            settings = case.settings(config.seed)
            for backend in backends:
                key = ("closed_form", problem.name, case.target, backend, settings)
                shape = (str(program.dof), str(program.task_dim), case.objective)
                yield _Task(
                    [key],
                    functools.partial(
                        _rows, _closed_form_row, problem, case, backend, config.seed, program
                    ),
                    f"closed form {problem.name} {backend}",
                    ("closed_form", backend, *shape),
                    functools.partial(_try_step, program, backend),
                )


def _seed_tasks(trajectory: list[FloatArray]) -> Iterator[_Task]:
    dobot = load_problem("dobot_magician")
    keys001: list[Key] = []
    for solver in SEED001_SOLVERS:
        for part in CHAPTER_TABLE_2:
            settings = _seed001_settings(dobot.targets[part].tolerance, SEED001_MAX_ITER)
            keys001.append(("seed001", dobot.name, part, solver, settings))
    yield _Task(keys001, lambda: dobot_chapter_rows(dobot), "seed 001 DOBOT")
    planar = load_problem("planar_2r")

    def produce003() -> list[ResultRow]:
        rows, path = planar_2r_example(planar)
        trajectory.append(path)
        return rows

    tol = planar.targets["seed003"].tolerance
    q0 = np.array(SEED003_Q0)
    keys003: list[Key] = [
        ("seed003", planar.name, "seed003", "pinv", _seed003_settings(a, q0, tol))
        for a in SEED003_STEPS
    ]
    yield _Task(keys003, produce003, "seed 003 planar 2R")


def run(
    config: RunConfig,
    results_path: str | Path,
    *,
    resume: bool = False,
    progress: bool | None = None,
    on_row: Callable[[ResultRow], None] | None = None,
) -> RunStats:
    """Run the comparison and append its rows to ``results_path``.

    Sections in order: closed-form agreement, full IK (optik's solvers, then the peers of
    ``config.peers``, each prepared once per problem), seed 001, seed 003. Before the
    first timed row of each (problem, solver) pair of the IK section (and each backend and
    program shape of the closed-form section) one untimed warm-up call runs, so one-off
    costs (numba compilation, CasADi program construction) are not counted.

    Args:
        config: what to run.
        results_path: the CSV file (created, or continued with ``resume``).
        resume: keep the rows already in the file and skip their keys.
        progress: draw a progress bar on stderr (``None``: only on a terminal).
        on_row: called after each row is written (tests use it to interrupt a run).

    Returns:
        A :class:`RunStats`; seed 003's trajectory is recomputed when its row was skipped.

    Raises:
        OptikError: two different problems of the same name (a row's key names the
            problem), before anything is written.
    """
    progress = check_progress(progress, call=False)
    problems = _distinct(config.problems)
    cf_names = (
        config.problems if config.closed_form_problems is None else config.closed_form_problems
    )
    cf_problems = _distinct(cf_names)
    backends = step_backends() if config.step_backends is None else config.step_backends
    trajectory: list[FloatArray] = []
    tasks: list[_Task] = []
    if backends and config.closed_form_configs:
        tasks += _closed_form_tasks(config, cf_problems, backends)
    tasks += _ik_tasks(config, problems)
    statuses: list[PeerStatus] = []
    answers: dict[Key, FloatArray] = {}
    tasks += _peer_tasks(config, problems, statuses, answers)
    if config.seeds:
        tasks += _seed_tasks(trajectory)
    stats = RunStats(
        step_backends=tuple(backends),
        planned={k for t in tasks for k in t.keys},
        peers=statuses,
        answers=answers,
    )
    with ResultsFile(results_path, resume=resume) as results:
        pending = [t for t in tasks if not all(results.has(k) for k in t.keys)]
        stats.skipped = sum(len(t.keys) for t in tasks) - sum(len(t.keys) for t in pending)
        warmed: set[tuple[str, ...]] = set()
        with Progress(sum(len(t.keys) for t in pending), enabled=progress) as bar:
            for task in pending:
                if task.warm_up is not None and task.group not in warmed:
                    task.warm_up()
                    warmed.add(task.group)
                for row in task.produce():
                    if results.has(row.key()):
                        continue
                    results.write(row)
                    stats.written += 1
                    bar.advance(note=task.note)
                    if on_row is not None:
                        on_row(row)
        stats.rows = list(results.rows)
    if config.seeds:
        stats.trajectory = trajectory[0] if trajectory else planar_2r_example()[1]
    return stats
