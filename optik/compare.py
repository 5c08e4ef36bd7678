"""Solver comparison runs: one long table of results, appended row by row.

A run (:func:`run`) produces the raw table of ``optik report``: one row per (section,
problem, target, solver, settings), written to a CSV file as soon as it is produced
(one ``write`` and a ``flush`` per row), so an interrupted run loses nothing and
``resume=True`` continues it, skipping the rows already present (keyed by
:meth:`ResultRow.key`). Summaries, plots and documents are built from this table by
:mod:`optik.report`; the schema is documented in ``docs/report.md``.

Four kinds of rows (column ``kind``):

* ``ik`` — full IK (:func:`optik.solve_ik`) on random in-limit configurations' FK poses,
  per robot, seeded: deterministic for a seed except the timings.
* ``closed_form`` — one differential-IK step program (least norm, least squares, damped
  least squares) solved by a QP backend (``qp:<name>``) or a CasADi conic plugin
  (``casadi:<plugin>``), compared with the closed forms :func:`optik.min_norm` /
  :func:`optik.least_squares`; the limits are in the program but inactive.
* ``seed001`` — the DOBOT chapter's comparison (its Table 2): pseudoinverse vs Jacobian
  transpose iterations on a three-part path.
* ``seed003`` — the two-link example of seed 003 (step 0.001, tolerance 0.01).
"""

from __future__ import annotations

import csv
import io
import json
import math
import os
import zlib
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from dataclasses import asdict, dataclass, field, fields, replace
from pathlib import Path
from typing import Any, Final, TextIO

import numpy as np

from optik._checks import FloatArray
from optik._progress import Progress
from optik.errors import OptikError
from optik.ik import solve_ik
from optik.linalg import least_squares, min_norm
from optik.model import Robot
from optik.problems import Problem, load_problem
from optik.solvers import IKQuery, available_solvers
from optik.solvers.iterative import DLSSolver, PinvSolver, TransposeSolver

__all__ = [
    "AGREEMENT_TOL",
    "CHAPTER_TABLE_2",
    "COLUMNS",
    "DOBOT_HOME",
    "KINDS",
    "Key",
    "ResultRow",
    "ResultsFile",
    "RunConfig",
    "RunStats",
    "StepCase",
    "closed_form_cases",
    "dobot_chapter_rows",
    "ik_settings",
    "planar_2r_example",
    "random_configurations",
    "read_results",
    "run",
    "solve_step",
    "step_backends",
]

#: Row kinds, in the order the report presents them.
KINDS: Final[tuple[str, ...]] = ("closed_form", "ik", "seed001", "seed003")

#: Largest deviation ``max |dq - dq*|`` (rad or m) of a step program's answer from the
#: closed form for the row to count as agreeing (design.md §5: "to 1e-8").
AGREEMENT_TOL: Final[float] = 1e-8

#: Iteration counts of the DOBOT chapter (seed 001, Table 2): (pseudoinverse, transpose).
CHAPTER_TABLE_2: Final[dict[str, tuple[int, int]]] = {
    "part1": (22, 55),
    "part2": (5, 34),
    "part3": (6, 68),
}

#: Start of the chapter's path: motor angles J1..J4 = 0 (rad), i.e. the rear arm vertical
#: and the forearm horizontal (the chapter does not print its start; this is our choice).
DOBOT_HOME: Final[tuple[float, ...]] = (0.0, 0.0, 0.0, 0.0)

#: Methods of the seed 001 section: the chapter's two, then damped least squares.
SEED001_SOLVERS: Final[tuple[str, ...]] = ("pinv", "transpose", "dls")

#: Iteration cap per part in the seed 001 section.
SEED001_MAX_ITER: Final[int] = 10_000

#: Seed 003's start (rad) and step sizes: the seed's 0.001, then the full step 1.
SEED003_Q0: Final[tuple[float, float]] = (0.5, 0.5)
SEED003_STEPS: Final[tuple[float, ...]] = (0.001, 1.0)

Key = tuple[str, str, str, str, str]
"""Identity of a row: (kind, problem, target, solver, settings)."""


# ---------------------------------------------------------------------------- the table
@dataclass(frozen=True)
class ResultRow:
    """One row of the raw table (the columns of ``results.csv``, in order).

    Attributes:
        kind: one of :data:`KINDS`.
        problem: problem name (file stem of ``problems/*.toml`` for built-ins).
        robot: the robot's name.
        target: target id within the problem: ``t0007`` (``ik``), ``c02-pose-least_norm``
            (``closed_form``), ``part1`` (``seed001``), ``seed003``.
        solver: registry name (``dls``, ``qp:proxqp``, ``casadi:qrqp``, ``auto``...).
        settings: canonical JSON of the settings that define the row (sorted keys).
        success: optik's verdict: ``ik``/``seed*``: pose errors within ``tol`` and the
            limits respected; ``closed_form``: deviation within :data:`AGREEMENT_TOL`.
        status: ``ik``: :data:`optik.ik.STATUSES` or ``"error"``; ``closed_form``:
            ``"agrees"``, ``"deviates"``, ``"solver_failed"`` or ``"error"``.
        position_error: ``||p(q) - p*||``, m (empty for ``closed_form``).
        orientation_error: rotation angle of ``R*^T R(q)``, rad; 0 in position mode.
        limit_violation: largest excursion beyond a joint limit (rad or m); for
            ``closed_form`` the largest bound violation of the step.
        iterations: iterations reported (all attempts); -1 when the backend does not say.
        restarts: attempts after the first (``ik``).
        time_s: wall time of the call, s (``time.perf_counter``).
        backend_converged: the solver's own convergence claim; empty when it makes none
            (the closed form behind ``auto``).
        deviation: ``closed_form`` only: ``max_j |dq_j - dq*_j|`` (rad or m).
        method: what produced the answer (``analytic``, ``dls``...; for ``closed_form``
            the reference: ``min_norm`` or ``least_squares``).
        message: backend text or the reason of a failure.
    """

    kind: str
    problem: str
    robot: str
    target: str
    solver: str
    settings: str
    success: bool
    status: str
    position_error: float | None = None
    orientation_error: float | None = None
    limit_violation: float | None = None
    iterations: int | None = None
    restarts: int | None = None
    time_s: float = 0.0
    backend_converged: bool | None = None
    deviation: float | None = None
    method: str = ""
    message: str = ""

    def key(self) -> Key:
        """The row's identity for ``--resume``: (kind, problem, target, solver, settings)."""
        return (self.kind, self.problem, self.target, self.solver, self.settings)

    def to_record(self) -> list[str]:
        """The row as CSV cells.

        Floats are written with ``repr`` (lossless), booleans as ``true``/``false`` and
        ``None`` as an empty cell.
        """
        return [_cell(getattr(self, name)) for name in COLUMNS]

    @classmethod
    def from_record(cls, record: Mapping[str, str]) -> ResultRow:
        """Parse a CSV record (column name -> cell), the inverse of :meth:`to_record`."""
        values: dict[str, Any] = {}
        for f in fields(cls):
            text = record[f.name]
            kind = _COLUMN_TYPES[f.name]
            if kind is str:
                values[f.name] = text
            elif text == "":
                values[f.name] = None if f.name != "time_s" else 0.0
            elif kind is bool:
                values[f.name] = text == "true"
            elif kind is int:
                values[f.name] = int(text)
            else:
                values[f.name] = float(text)
        return cls(**values)


_COLUMN_TYPES: Final[dict[str, type]] = {
    "kind": str,
    "problem": str,
    "robot": str,
    "target": str,
    "solver": str,
    "settings": str,
    "success": bool,
    "status": str,
    "position_error": float,
    "orientation_error": float,
    "limit_violation": float,
    "iterations": int,
    "restarts": int,
    "time_s": float,
    "backend_converged": bool,
    "deviation": float,
    "method": str,
    "message": str,
}

#: Columns of ``results.csv``, in order (see :class:`ResultRow` and ``docs/report.md``).
COLUMNS: Final[tuple[str, ...]] = tuple(f.name for f in fields(ResultRow))


def _cell(value: Any) -> str:
    if value is None:
        return ""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return repr(value)
    return str(value)


def settings_json(settings: Mapping[str, Any]) -> str:
    """Canonical JSON of a settings mapping: sorted keys, no spaces (part of a row's key)."""
    return json.dumps(dict(settings), sort_keys=True, separators=(",", ":"))


def read_results(path: str | Path) -> list[ResultRow]:
    """Read a results file written by :class:`ResultsFile`.

    A last line without its newline (a run killed mid-write) is ignored.

    Raises:
        OptikError: the header is not :data:`COLUMNS` (another schema or another file).
    """
    text = Path(path).read_text(encoding="utf-8")
    if text and not text.endswith("\n"):
        text = text[: text.rfind("\n") + 1]
    return _parse(text, Path(path))


def _parse(text: str, path: Path) -> list[ResultRow]:
    reader = csv.DictReader(io.StringIO(text, newline=""))
    if not text:
        return []
    if tuple(reader.fieldnames or ()) != COLUMNS:
        raise OptikError(
            f"{path}: not an optik results file of this version (columns "
            f"{reader.fieldnames} instead of {list(COLUMNS)})"
        )
    return [ResultRow.from_record(record) for record in reader]


class ResultsFile:
    """The raw table on disk, appended one flushed row at a time.

    Without ``resume`` the file is started afresh (header only). With ``resume`` an
    existing file is kept: a partial last line (a run killed mid-write) is cut off, its
    rows are loaded, and :meth:`has` tells which keys are already done.

    Args:
        path: the CSV file.
        resume: continue an existing file instead of starting a new one.

    Raises:
        OptikError: resuming a file whose header is not :data:`COLUMNS`.
    """

    def __init__(self, path: str | Path, resume: bool = False) -> None:
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self.rows: list[ResultRow] = []
        if resume and self.path.exists():
            raw = self.path.read_bytes()
            complete = raw[: raw.rfind(b"\n") + 1]
            if len(complete) != len(raw):
                with open(self.path, "r+b") as f:
                    f.truncate(len(complete))
            self.rows = _parse(complete.decode("utf-8"), self.path)
            if not complete:
                self._start()
        else:
            self._start()
        self._keys = {row.key() for row in self.rows}
        self._file: TextIO = open(self.path, "a", encoding="utf-8", newline="")  # noqa: SIM115

    def _start(self) -> None:
        with open(self.path, "w", encoding="utf-8", newline="") as f:
            f.write(_csv_line(list(COLUMNS)))

    def has(self, key: Key) -> bool:
        """Whether a row with this key is already in the file."""
        return key in self._keys

    def write(self, row: ResultRow) -> None:
        """Append ``row`` as one line and flush it to the operating system."""
        self._file.write(_csv_line(row.to_record()))
        self._file.flush()
        self.rows.append(row)
        self._keys.add(row.key())

    def close(self) -> None:
        """Close the file."""
        self._file.close()

    def __enter__(self) -> ResultsFile:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _csv_line(cells: Sequence[str]) -> str:
    buffer = io.StringIO()
    csv.writer(buffer, lineterminator="\n").writerow(cells)
    return buffer.getvalue()


# ---------------------------------------------------------------------------- run config
@dataclass(frozen=True)
class RunConfig:
    """What a comparison run covers.

    Attributes:
        problems: problem names or files for the full-IK section.
        solvers: solver names for the full-IK section (``"auto"`` allowed).
        n: targets per robot.
        seed: seed of the targets (and of each solve's restarts).
        tol: IK tolerance: position (m) and orientation (rad).
        timeout_s: time budget of one IK call, s; failures count at this time in the
            shifted geometric mean.
        mode: ``"pose"`` or ``"position"``.
        caps: per-solver cap on the number of targets per robot (slow solvers).
        closed_form_problems: problems of the closed-form section (default ``problems``).
        closed_form_configs: configurations per robot in the closed-form section.
        step_backends: step-program backends (``qp:<name>``, ``casadi:<plugin>``) of the
            closed-form section; ``None`` means every one installed (:func:`step_backends`).
        seeds: run the seed 001 and seed 003 sections.
    """

    problems: tuple[str, ...]
    solvers: tuple[str, ...]
    n: int = 20
    seed: int = 0
    tol: float = 1e-6
    timeout_s: float = 1.0
    mode: str = "pose"
    caps: Mapping[str, int] = field(default_factory=dict)
    closed_form_problems: tuple[str, ...] | None = None
    closed_form_configs: int = 3
    step_backends: tuple[str, ...] | None = None
    seeds: bool = True

    def __post_init__(self) -> None:
        if self.n < 0 or self.closed_form_configs < 0:
            raise OptikError("n and closed_form_configs must be non-negative")
        if not (self.tol > 0 and math.isfinite(self.tol)):
            raise OptikError(f"tol must be positive and finite, got {self.tol!r}")
        if not (self.timeout_s > 0 and math.isfinite(self.timeout_s)):
            raise OptikError(f"timeout_s must be positive and finite, got {self.timeout_s!r}")
        if self.mode not in ("pose", "position"):
            raise OptikError(f"mode must be 'pose' or 'position', got {self.mode!r}")
        known = {"auto", *available_solvers()}
        unknown = [s for s in self.solvers if s not in known]
        if unknown:
            raise OptikError(
                f"unknown or unavailable solver(s) {unknown}; available: {sorted(known)}"
            )

    def targets_for(self, solver: str) -> int:
        """Number of targets per robot that ``solver`` runs (``n``, or its cap)."""
        return min(self.n, self.caps.get(solver, self.n))

    def to_dict(self) -> dict[str, Any]:
        """The configuration as plain JSON-able data (recorded in ``summary.json``)."""
        data = asdict(self)
        data["caps"] = dict(self.caps)
        return data


def ik_settings(config: RunConfig, solver: str) -> str:
    """The settings JSON of an ``ik`` row: mode, tol, timeout, seed and warm start.

    ``auto`` keeps :func:`optik.solve_ik`'s analytic warm start (its answer is the closed
    form when the robot has one); every named solver runs with ``warm_start="q0"`` and no
    ``q0``, so it is measured from the same starts as the others (the seed table's nearest
    entries, then seeded uniform draws; see :mod:`optik.ik`).
    """
    return settings_json(
        {
            "mode": config.mode,
            "seed": config.seed,
            "timeout_s": config.timeout_s,
            "tol": config.tol,
            "warm_start": "analytic" if solver == "auto" else "q0",
        }
    )


@dataclass
class RunStats:
    """What :func:`run` did.

    Attributes:
        written: rows produced and appended by this call.
        skipped: rows already in the file (``resume``).
        rows: every row of the file after the run, old and new.
        step_backends: the closed-form section's backends (empty: none installed).
        trajectory: seed 003's joint trajectory (K, 2), rad, for the plot.
        planned: the keys of every row this configuration asks for (the report summarises
            only these; a resumed file may hold rows of other settings).
    """

    written: int = 0
    skipped: int = 0
    rows: list[ResultRow] = field(default_factory=list)
    step_backends: tuple[str, ...] = ()
    trajectory: FloatArray | None = None
    planned: set[Key] = field(default_factory=set)


# ---------------------------------------------------------------------------- targets
def _stable_id(name: str) -> int:
    return zlib.crc32(name.encode("utf-8"))


def _bounded_box(robot: Robot, shrink: float = 0.0) -> tuple[FloatArray, FloatArray]:
    lower = np.where(np.isfinite(robot.lower), robot.lower, -math.pi)
    upper = np.where(np.isfinite(robot.upper), robot.upper, math.pi)
    margin = shrink * (upper - lower)
    return lower + margin, upper - margin


def random_configurations(
    robot: Robot, name: str, n: int, seed: int, shrink: float = 0.0
) -> FloatArray:
    """``n`` joint vectors drawn uniformly inside the limits, (n, dof), rad / m.

    Configuration ``k`` comes from its own generator seeded with ``(seed, crc32(name),
    k)``: it does not depend on ``n`` or on the other robots, so a larger ``n`` adds targets
    and keeps the first ones. Joints without limits draw in [-pi, pi].

    Args:
        robot: the robot.
        name: the problem's name (part of the seed).
        n: number of configurations.
        seed: the run's seed.
        shrink: keep this fraction of each joint's range away from both limits.
    """
    lower, upper = _bounded_box(robot, shrink)
    Q = np.empty((n, robot.dof))
    for k in range(n):
        rng = np.random.default_rng([seed, _stable_id(name), k])
        Q[k] = rng.uniform(lower, upper)
    return Q


def _solve_seed(seed: int, name: str, k: int) -> int:
    """The restart seed of target ``k`` of problem ``name`` (deterministic, well mixed)."""
    return int(np.random.SeedSequence([seed, _stable_id(name), k]).generate_state(1)[0])


# ---------------------------------------------------------------------------- full IK
def _ik_row(
    problem: Problem,
    target_id: str,
    pose: FloatArray,
    solver: str,
    config: RunConfig,
    solve_seed: int,
) -> ResultRow:
    robot = problem.robot
    settings = ik_settings(config, solver)
    try:
        result = solve_ik(
            robot,
            pose,
            mode=config.mode,
            solver=solver,
            warm_start="analytic" if solver == "auto" else "q0",
            tol=config.tol,
            timeout_s=config.timeout_s,
            seed=solve_seed,
        )
    except Exception as exc:  # a crash is a row, not the end of the run
        return ResultRow(
            kind="ik",
            problem=problem.name,
            robot=robot.name,
            target=target_id,
            solver=solver,
            settings=settings,
            success=False,
            status="error",
            message=f"{type(exc).__name__}: {exc}",
        )
    return ResultRow(
        kind="ik",
        problem=problem.name,
        robot=robot.name,
        target=target_id,
        solver=solver,
        settings=settings,
        success=bool(result.success),
        status=result.status,
        position_error=float(result.position_error),
        orientation_error=float(result.orientation_error),
        limit_violation=float(result.limit_violation),
        iterations=int(result.iterations),
        restarts=int(result.restarts),
        time_s=float(result.time_s),
        backend_converged=result.backend_converged,
        method=result.solver,
        message=result.message,
    )


# ---------------------------------------------------------------------------- closed form
def step_backends() -> tuple[str, ...]:
    """Backends that solve a step program here: the registry's ``"step"`` solvers.

    ``qp:<name>`` (the ``qpsolvers`` backends that import) and ``casadi:<plugin>`` (the
    conic plugins that pass their probe), from :func:`optik.solvers.available_solvers`.
    """
    from optik.solvers import available_solvers

    return tuple(available_solvers(kind="step"))


@dataclass(frozen=True)
class StepCase:
    """One differential-IK step program with its closed-form answer.

    Attributes:
        target: row id, ``c{config}-{task}-{objective}[-damped]``.
        q: configuration (dof,), rad / m.
        task: ``"position"`` (Jacobian rows 0-2) or ``"pose"`` (all six rows).
        objective: ``"least_norm"`` or ``"least_squares"``.
        damping: ``lambda`` of least squares (0: undamped).
        v: task displacement (m,), scaled so that the answer stays at most half way to
            every bound (the limits are in the program but inactive).
        reference: the closed form's answer ``dq*`` (dof,).
        method: ``"min_norm"`` or ``"least_squares"``.
    """

    target: str
    q: FloatArray
    task: str
    objective: str
    damping: float
    v: FloatArray
    reference: FloatArray
    method: str

    @property
    def rows(self) -> tuple[int, ...]:
        """Indices of the Jacobian rows of the task."""
        return (0, 1, 2) if self.task == "position" else (0, 1, 2, 3, 4, 5)

    def settings(self, seed: int) -> str:
        """The settings JSON of the case's rows."""
        return settings_json(
            {
                "damping": self.damping,
                "limits": "inactive",
                "objective": self.objective,
                "seed": seed,
                "task": self.task,
            }
        )

    def program(self, robot: Robot) -> Any:
        """The step program (:class:`optik.programs.diff_qp.DiffIKProgram`)."""
        from optik.programs.diff_qp import build_program

        return build_program(
            robot,
            self.q,
            self.v,
            objective=self.objective,  # type: ignore[arg-type]
            damping=self.damping if self.objective == "least_squares" else None,
            rows=self.rows,
        )


#: Largest 2-norm condition number of a configuration's task Jacobian in the closed-form
#: section (configurations near a singularity are redrawn: the comparison is about the
#: backends, not about ill-conditioning).
_MAX_CONDITION: Final[float] = 1e4

#: Size of the closed form's answer before the scaling that keeps the bounds inactive.
_STEP_SIZE: Final[float] = 0.05


def closed_form_cases(
    robot: Robot, name: str, count: int, seed: int, damping: float | None = None
) -> list[StepCase]:
    """The closed-form section's programs for one robot.

    For ``count`` configurations drawn inside the limits (10 % away from each limit, task
    Jacobians with condition number at most 1e4) and each task (position, pose) with
    Jacobian rows ``J`` (m, dof): least norm against :func:`optik.min_norm` when
    ``m <= dof``; undamped least squares against :func:`optik.least_squares` when
    ``m >= dof``; always damped least squares (``lambda`` = the programs' default) against
    ``least_squares(J, v, damping=lambda)``. ``v`` is random and scaled so that
    ``max |dq*| = 0.05`` and then to at most half the distance to every bound.

    Args:
        robot: the robot.
        name: its problem name (part of the seed).
        count: number of configurations.
        seed: the run's seed.
        damping: ``lambda`` of the damped case (default: the programs' default).
    """
    if damping is None:
        try:
            from optik.programs.diff_qp import DEFAULT_DAMPING
        except ImportError:
            return []
        damping = DEFAULT_DAMPING
    from optik.programs.diff_qp import step_bounds

    cases: list[StepCase] = []
    draws = random_configurations(robot, f"{name}/closed_form", 50 * max(count, 1), seed, 0.1)
    rng = np.random.default_rng([seed, _stable_id(name), 7])
    used = 0
    for q in draws:
        if used == count:
            break
        J6 = robot.jacobian(q)
        tasks = [("position", J6[:3]), ("pose", J6)]
        if any(np.linalg.cond(_nonzero_rows(J)) > _MAX_CONDITION for _, J in tasks):
            continue
        lower, upper = step_bounds(robot, q)
        for task, J in tasks:
            m, n = J.shape
            specs: list[tuple[str, float, str]] = []
            if m <= n:
                specs.append(("least_norm", 0.0, "min_norm"))
            if m >= n:
                specs.append(("least_squares", 0.0, "least_squares"))
            specs.append(("least_squares", float(damping), "least_squares"))
            for objective, lam, method in specs:
                if objective == "least_norm" and len(_nonzero_rows(J)) < m:
                    continue  # a zero row makes J dq = v infeasible for random v
                v = rng.normal(size=m)
                reference = _closed_form(J, v, method, lam)
                scale = _STEP_SIZE / max(float(np.max(np.abs(reference))), 1e-300)
                scale *= min(1.0, 0.5 * _room(reference * scale, lower, upper))
                v, reference = v * scale, _closed_form(J, v * scale, method, lam)
                suffix = "-damped" if lam > 0 else ""
                cases.append(
                    StepCase(
                        f"c{used:02d}-{task}-{objective}{suffix}",
                        q.copy(),
                        task,
                        objective,
                        lam,
                        v,
                        reference,
                        method,
                    )
                )
        used += 1
    return cases


def _nonzero_rows(J: FloatArray) -> FloatArray:
    """``J`` without its identically zero rows (a planar arm's out-of-plane rows)."""
    keep = np.any(np.abs(J) > 1e-12, axis=1)
    return J[keep]


def _closed_form(J: FloatArray, v: FloatArray, method: str, damping: float) -> FloatArray:
    if method == "min_norm":
        return np.asarray(min_norm(J, v), dtype=float)
    if damping > 0:
        return np.asarray(least_squares(J, v, damping=damping), dtype=float)
    return np.asarray(least_squares(_nonzero_rows(J), v[np.any(np.abs(J) > 1e-12, axis=1)]))


def _room(dq: FloatArray, lower: FloatArray, upper: FloatArray) -> float:
    """Largest factor ``s`` with ``lower <= s dq <= upper`` (bounds contain 0; may be inf)."""
    ratios = [math.inf]
    for d, lo, hi in zip(dq, lower, upper, strict=True):
        if d > 0 and math.isfinite(hi):
            ratios.append(hi / d)
        elif d < 0 and math.isfinite(lo):
            ratios.append(lo / d)
    return max(min(ratios), 0.0)


def solve_step(program: Any, backend: str) -> Any:
    """Solve a step program with a registered ``"step"`` backend, unchecked.

    Args:
        program: a :class:`optik.programs.diff_qp.DiffIKProgram`.
        backend: a name from :func:`step_backends`.

    Returns:
        The backend's :class:`optik.programs.diff_qp.QPSolution` (``x``, ``found``,
        ``status``, ``iterations``).

    Raises:
        UnknownSolverError: not a registered step backend here.
    """
    from optik.solvers import get_solver

    return get_solver(backend, kind="step").solve(program)


def _closed_form_row(
    problem: Problem, case: StepCase, backend: str, seed: int, program: Any
) -> ResultRow:
    from optik.solvers._base import now

    base = ResultRow(
        kind="closed_form",
        problem=problem.name,
        robot=problem.robot.name,
        target=case.target,
        solver=backend,
        settings=case.settings(seed),
        success=False,
        status="error",
        method=case.method,
    )
    start = now()
    try:
        solution = solve_step(program, backend)
    except Exception as exc:  # a crash is a row, not the end of the run
        return replace(base, time_s=now() - start, message=f"{type(exc).__name__}: {exc}")
    elapsed = now() - start
    if solution.x is None or not np.all(np.isfinite(solution.x)):
        return replace(
            base,
            status="solver_failed",
            iterations=int(solution.iterations),
            time_s=elapsed,
            backend_converged=bool(solution.found),
            message=str(solution.status),
        )
    x = np.asarray(solution.x, dtype=float)
    deviation = float(np.max(np.abs(x - case.reference)))
    agrees = deviation <= AGREEMENT_TOL
    return replace(
        base,
        success=agrees,
        status="agrees" if agrees else "deviates",
        limit_violation=float(program.bound_violation(x)),
        iterations=int(solution.iterations),
        time_s=elapsed,
        backend_converged=bool(solution.found),
        deviation=deviation,
        message="" if solution.found else str(solution.status),
    )


# ---------------------------------------------------------------------------- seeds
def _seed001_settings(tol: float, max_iter: int) -> str:
    return settings_json(
        {
            "chain": "part1>part2>part3",
            "max_iter": max_iter,
            "mode": "position",
            "start_rad": list(DOBOT_HOME),
            "tol": tol,
        }
    )


def _seed003_settings(alpha: float, q0: FloatArray, tol: float) -> str:
    return settings_json({"mode": "position", "q0": q0.tolist(), "step": alpha, "tol": tol})


def dobot_chapter_rows(
    problem: Problem | None = None,
    solvers: Sequence[str] = SEED001_SOLVERS,
    max_iter: int = SEED001_MAX_ITER,
) -> list[ResultRow]:
    """Seed 001's Table 2 rebuilt: iterations per method along the three-part path.

    Each method starts at :data:`DOBOT_HOME` and goes through the targets ``part1``,
    ``part2``, ``part3`` of ``problems/dobot_magician.toml`` in sequence, each part
    starting where the previous one ended; position only, accepted error 0.2 mm (the
    targets' tolerance). ``pinv`` is :class:`~optik.solvers.iterative.PinvSolver` (unit
    step), ``transpose`` is :class:`~optik.solvers.iterative.TransposeSolver` (the optimal
    scalar step); ``dls`` (damped least squares, which the chapter names as its next step)
    is added beyond the chapter.

    Args:
        problem: the DOBOT problem (default: the built-in one).
        solvers: methods, among ``pinv``, ``transpose``, ``dls``.
        max_iter: iteration cap per part.

    Returns:
        One ``seed001`` row per (part, method), ``iterations`` being the exact count.
    """
    from optik.solvers._base import now

    problem = problem or load_problem("dobot_magician")
    robot = problem.robot
    factories: dict[str, Callable[[], Any]] = {
        "pinv": PinvSolver,
        "transpose": TransposeSolver,
        "dls": DLSSolver,
    }
    rows: list[ResultRow] = []
    for name in solvers:
        solver = factories[name]()
        q = np.array(DOBOT_HOME, dtype=float)
        for part in CHAPTER_TABLE_2:
            target = problem.targets[part]
            query = IKQuery(robot, target.pose, "position", target.tolerance)
            settings = _seed001_settings(target.tolerance, max_iter)
            start = now()
            out = solver.solve(query, q, max_iter, math.inf)
            elapsed = now() - start
            position = float(np.linalg.norm(robot.fk(out.q)[:3, 3] - target.position))
            violation = float(robot.limit_violation(out.q))
            ok = position <= target.tolerance and violation <= 1e-12
            rows.append(
                ResultRow(
                    kind="seed001",
                    problem=problem.name,
                    robot=robot.name,
                    target=part,
                    solver=name,
                    settings=settings,
                    success=ok,
                    status="converged" if ok else "max_iter",
                    position_error=position,
                    orientation_error=0.0,
                    limit_violation=violation,
                    iterations=int(out.iterations),
                    restarts=0,
                    time_s=elapsed,
                    backend_converged=bool(out.converged),
                    method=name,
                    message=out.message if not ok else "",
                )
            )
            q = out.q
    return rows


def planar_2r_example(
    problem: Problem | None = None,
    steps: Sequence[float] = SEED003_STEPS,
    max_iter: int = 100_000,
) -> tuple[list[ResultRow], FloatArray]:
    """Seed 003's two-link example: ``q <- q + alpha J^+ (x* - x)`` from q = (0.5, 0.5) rad.

    Unit links, target (1.2, 1.3) m, stop when ``||x* - x|| < 0.01`` m. The seed's step
    ``alpha = 0.001`` is run one step at a time to record the trajectory; ``alpha = 1``
    (the full pseudoinverse step) is run beside it for contrast.

    Args:
        problem: the planar 2R problem (default: the built-in ``planar_2r``).
        steps: the values of ``alpha``; the first one's trajectory is returned.
        max_iter: iteration cap.

    Returns:
        The ``seed003`` rows (one per step size) and the first step's trajectory (K, 2),
        rad: ``q0`` then the joint vector after every iteration.
    """
    from optik.solvers._base import now

    if not steps:
        raise OptikError("planar_2r_example needs at least one step size")
    problem = problem or load_problem("planar_2r")
    robot = problem.robot
    target = problem.targets["seed003"]
    q0 = np.array(SEED003_Q0)
    rows: list[ResultRow] = []
    first: FloatArray | None = None
    for alpha in steps:
        solver = PinvSolver(step=alpha)
        query = IKQuery(robot, target.pose, "position", target.tolerance)
        trajectory = [q0]
        q = q0
        iterations = 0
        start = now()
        converged = False
        while iterations < max_iter:
            out = solver.solve(query, q, 1, math.inf)
            iterations += out.iterations
            q = out.q
            if out.iterations:
                trajectory.append(q)
            if out.converged:
                converged = True
                break
        elapsed = now() - start
        position = float(np.linalg.norm(robot.fk(q)[:3, 3] - target.position))
        ok = position <= target.tolerance
        rows.append(
            ResultRow(
                kind="seed003",
                problem=problem.name,
                robot=robot.name,
                target="seed003",
                solver="pinv",
                settings=_seed003_settings(alpha, q0, target.tolerance),
                success=ok,
                status="converged" if ok else "max_iter",
                position_error=position,
                orientation_error=0.0,
                limit_violation=float(robot.limit_violation(q)),
                iterations=iterations,
                restarts=0,
                time_s=elapsed,
                backend_converged=converged,
                method=f"pinv, step {alpha:g}",
            )
        )
        if first is None:
            first = np.array(trajectory)
    return rows, first if first is not None else np.array([q0])


# ---------------------------------------------------------------------------- the run
@dataclass
class _Task:
    """Rows produced together (one IK call, one step solve, or a seed's chain)."""

    keys: list[Key]
    produce: Callable[[], list[ResultRow]]
    note: str
    group: tuple[str, ...] = ()
    warm_up: Callable[[], object] | None = None


def _ik_tasks(config: RunConfig, problems: Sequence[Problem]) -> Iterator[_Task]:
    for problem in problems:
        robot = problem.robot
        counts = {s: config.targets_for(s) for s in config.solvers}
        total = max(counts.values(), default=0)
        Q = random_configurations(robot, problem.name, total, config.seed)
        poses = robot.fk(Q) if total else np.empty((0, 4, 4))
        for solver in config.solvers:
            settings = ik_settings(config, solver)
            for k in range(counts[solver]):
                target_id = f"t{k:04d}"
                pose = poses[k]

                def produce(
                    problem: Problem = problem,
                    t: str = target_id,
                    pose: FloatArray = pose,
                    solver: str = solver,
                    k: int = k,
                ) -> list[ResultRow]:
                    seed = _solve_seed(config.seed, problem.name, k)
                    return [_ik_row(problem, t, pose, solver, config, seed)]

                def warm_up(problem: Problem = problem, solver: str = solver) -> object:
                    robot = problem.robot
                    return _ik_row(
                        problem, "warm-up", robot.fk(robot.mid_limits), solver, config, 0
                    )

                yield _Task(
                    [("ik", problem.name, target_id, solver, settings)],
                    produce,
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

                def produce(
                    problem: Problem = problem,
                    case: StepCase = case,
                    backend: str = backend,
                    program: Any = program,
                ) -> list[ResultRow]:
                    return [_closed_form_row(problem, case, backend, config.seed, program)]

                def warm_up(backend: str = backend, program: Any = program) -> object:
                    try:
                        return solve_step(program, backend)
                    except Exception as exc:  # the timed call will record it
                        return exc

                key = ("closed_form", problem.name, case.target, backend, settings)
                shape = (str(program.dof), str(program.task_dim), case.objective)
                yield _Task(
                    [key],
                    produce,
                    f"closed form {problem.name} {backend}",
                    ("closed_form", backend, *shape),
                    warm_up,
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

    Sections in order: closed-form agreement, full IK, seed 001, seed 003. Before the
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
    """
    problems = [load_problem(p) for p in config.problems]
    cf_names = (
        config.problems if config.closed_form_problems is None else config.closed_form_problems
    )
    cf_problems = [load_problem(p) for p in cf_names]
    backends = step_backends() if config.step_backends is None else config.step_backends
    trajectory: list[FloatArray] = []
    tasks: list[_Task] = []
    if backends and config.closed_form_configs:
        tasks += _closed_form_tasks(config, cf_problems, backends)
    tasks += _ik_tasks(config, problems)
    if config.seeds:
        tasks += _seed_tasks(trajectory)
    stats = RunStats(step_backends=tuple(backends), planned={k for t in tasks for k in t.keys})
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


def rows_of(rows: Iterable[ResultRow], kind: str) -> list[ResultRow]:
    """The rows of one kind, in file order."""
    return [row for row in rows if row.kind == kind]


def write_rows(rows: Iterable[ResultRow], path: str | Path) -> Path:
    """Write rows to a new results file at once (for exports and tests)."""
    path = Path(path)
    tmp = path.with_name(f".{path.name}.tmp-{os.getpid()}")
    with open(tmp, "w", encoding="utf-8", newline="") as f:
        f.write(_csv_line(list(COLUMNS)))
        for row in rows:
            f.write(_csv_line(row.to_record()))
    os.replace(tmp, path)
    return path
