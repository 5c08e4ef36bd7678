"""Batch IK over files: millions of targets, chunk by chunk, to Parquet part files.

Targets come from ``.npy`` ((N, 4, 4) poses, or (N, 3) positions for position mode) or
``.parquet`` (columns ``x, y, z`` in m, and ``qw, qx, qy, qz`` for an orientation, a unit
quaternion scalar first). Chunk ``c`` holds targets ``[c * chunk, (c + 1) * chunk)`` and
is solved by :func:`optik.solve_ik_batch` with the seed ``seed + c * chunk``, so target
``k`` always uses the restart stream ``seed + k``: the results are identical in-process,
on any number of workers and for any chunk size.

The output is a Parquet dataset: a folder of part files ``part-000000.parquet``, ... (one
per chunk, each written whole through a temporary file and a rename) and ``_optik.json``
(the run's settings, checked on resume). ``pyarrow.parquet.read_table(out)`` and
``pandas.read_parquet(out)`` read it; rows carry their target's ``index``.

Each part file carries the digest of its run's settings (:data:`PART_KEY`), and the
folder the token of the run writing it (:data:`RUN_FILE`): a run writes a part only into
a folder that still carries its token, and a resume refuses a part of another run.
"""

from __future__ import annotations

import contextlib
import functools
import hashlib
import json
import uuid
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from optik._checks import (
    FloatArray,
    as_float_array,
    check_bool,
    check_choice,
    check_int,
    check_progress,
    not_a_file,
)
from optik._files import check_folder, prepare_folder, write_atomic, write_atomic_with
from optik.campaign._deps import require
from optik.campaign.engine import (
    MAX_CHUNKS,
    ProgressOption,
    check_chunk_count,
    chunk_count,
    open_engine,
    refuse_reimported_script,
    run_chunks_with_progress,
)
from optik.campaign.provenance import (
    array_fingerprint,
    check_same_run,
    robot_fingerprint,
    versions,
)
from optik.errors import OptikError, OutputFileError, ShapeError
from optik.ik import DEFAULT_RESTARTS, MAX_BATCH_RESTARTS, MAX_ITERATIONS, MAX_SEED, solve_ik_batch
from optik.model import Robot
from optik.poses import pose
from optik.spatial import as_pose
from optik.task import MODES, make_task

DEFAULT_CHUNK = 10_000
"""Targets per chunk of a batch."""

POSITION_COLUMNS = ("x", "y", "z")
QUATERNION_COLUMNS = ("qw", "qx", "qy", "qz")
SETTINGS_FILE = "_optik.json"
RUN_FILE = ".optik-run"
"""The token of the run writing a folder (a hidden file: Parquet readers skip it)."""
PART_KEY = b"optik.settings_sha256"
"""A part file's key-value metadata: the SHA-256 of its run's settings file (hex)."""
RESUMED_KEY = b"optik.resumed_targets"
"""The schema metadata of :func:`solve_batch`'s table: the targets resumed, not solved, by
this call (their part files were written by an earlier run), in decimal."""


def read_targets(path: str | Path) -> FloatArray:
    """(N, 4, 4) target poses from a ``.npy`` or ``.parquet`` file (see the module).

    Positions without an orientation get the identity rotation; :func:`solve_batch`
    accepts them only in position mode.

    Args:
        path: the ``.npy`` or ``.parquet`` file.

    Raises:
        OptikError: a missing file, another suffix, an array of another shape, missing
            columns, non-finite values or a quaternion far from unit norm.
    """
    return _read(Path(path))[0]


def _read(file: Path) -> tuple[FloatArray, bool]:
    """The poses of a targets file and whether it gives orientations."""
    if not file.is_file():
        raise OptikError(f"{file}: {not_a_file(file)} (the targets file)")
    suffix = file.suffix.lower()
    if suffix == ".npy":
        try:
            raw = np.load(file, allow_pickle=False)
        except (OSError, ValueError, EOFError) as exc:  # EOFError: an empty or cut file
            raise OptikError(f"{file}: not a NumPy .npy array ({exc})") from None
        array = as_float_array(str(file), raw)
        if array.ndim == 2 and array.shape[1] == 3:
            return _positions(str(file), array), False
        if array.ndim == 3 and array.shape[1:] == (4, 4):
            return as_pose(str(file), array, batch=True), True
        raise ShapeError(str(file), "(N, 4, 4) poses or (N, 3) positions", array.shape)
    if suffix == ".parquet":
        pq = require("pyarrow.parquet", "a Parquet targets file")
        try:
            table = pq.read_table(file)
        except Exception as exc:
            raise OptikError(f"{file}: not a Parquet file ({exc})") from None
        names = set(table.column_names)
        missing = [c for c in POSITION_COLUMNS if c not in names]
        if missing:
            raise OptikError(f"{file}: missing column(s) {missing} (need x, y, z in m)")
        P = np.column_stack([_column(file, table, c) for c in POSITION_COLUMNS])
        given = [c for c in QUATERNION_COLUMNS if c in names]
        if not given:
            return _positions(str(file), P), False
        if len(given) != 4:
            raise OptikError(f"{file}: an orientation needs all of qw, qx, qy, qz, got {given}")
        Q = np.column_stack([_column(file, table, c) for c in QUATERNION_COLUMNS])
        if len(P) == 0:
            return np.empty((0, 4, 4)), True
        try:
            poses = pose(P, quat_wxyz=Q)
        except OptikError as exc:
            raise OptikError(f"{file}: {exc}") from None
        return np.asarray(poses, dtype=np.float64).reshape(-1, 4, 4), True
    raise OptikError(f"{file}: targets must be a .npy or .parquet file, not {suffix or 'none'!r}")


def _column(file: Path, table: Any, name: str) -> FloatArray:
    values = table.column(name).to_numpy(zero_copy_only=False)
    array = as_float_array(f"{file} column {name!r}", values)
    if not np.all(np.isfinite(array)):
        row = int(np.flatnonzero(~np.isfinite(array))[0])
        raise OptikError(f"{file}: column {name!r} row {row}: values must be finite")
    return array


def _positions(name: str, P: FloatArray) -> FloatArray:
    if not np.all(np.isfinite(P)):
        row = int(np.flatnonzero(~np.all(np.isfinite(P), axis=1))[0])
        raise OptikError(f"{name}: row {row}: positions must be finite")
    poses = np.broadcast_to(np.eye(4), (len(P), 4, 4)).copy()
    poses[:, :3, 3] = P
    return poses


@dataclass(frozen=True)
class BatchSpec:
    """What every chunk of a batch shares (picklable).

    Attributes:
        robot: the robot.
        mode: the task mode (:func:`optik.solve_ik`).
        axis: the tool axis of ``mode="axis"``.
        tol: IK tolerance (m, rad).
        restarts: attempts after the first per target.
        max_iter: iterations per attempt.
        seed: base seed: target ``k`` uses the stream ``seed + k``.
        threads: threads of :func:`optik.solve_ik_batch` (``None``: numba's count).
    """

    robot: Robot
    mode: str
    axis: str
    tol: float | tuple[float, float]
    restarts: int
    max_iter: int
    seed: int
    threads: int | None = None


def solve_chunk(spec: BatchSpec, item: tuple[int, FloatArray]) -> dict[str, np.ndarray]:
    """Solve the targets ``item = (start, poses)`` (global indices from ``start``).

    Returns:
        The columns of the chunk's rows (see :func:`result_columns`).
    """
    start, poses = item
    targets = poses[:, :3, 3] if spec.mode == "position" else poses
    result = solve_ik_batch(
        spec.robot,
        targets,
        mode=spec.mode,
        axis=spec.axis,
        tol=spec.tol,
        restarts=spec.restarts,
        max_iter=spec.max_iter,
        seed=spec.seed + start,
        threads=spec.threads,
    )
    n = len(poses)
    columns: dict[str, np.ndarray] = {
        "index": np.arange(start, start + n, dtype=np.int64),
        "status": np.asarray(result.status, dtype=str),
        "success": np.asarray(result.success, dtype=bool),
    }
    for j, name in enumerate(spec.robot.joint_names):
        columns[f"q_{name}"] = result.q[:, j]
    columns["position_error"] = result.position_error
    columns["orientation_error"] = result.orientation_error
    columns["limit_violation"] = result.limit_violation
    columns["iterations"] = result.iterations.astype(np.int64)
    columns["restarts"] = result.restarts.astype(np.int64)
    return columns


def result_columns(robot: Robot) -> list[str]:
    """The columns of a batch's results, in order (SI: m, rad; q per joint, rad or m)."""
    q = [f"q_{name}" for name in robot.joint_names]
    errors = ["position_error", "orientation_error", "limit_violation"]
    return ["index", "status", "success", *q, *errors, "iterations", "restarts"]


def part_name(index: int) -> str:
    """File name of chunk ``index``'s part."""
    return f"part-{index:06d}.parquet"


def _write_part(folder: Path, index: int, result: dict[str, np.ndarray], digest: str) -> None:
    """Write chunk ``index``'s rows to its part file, whole (a temporary file renamed).

    The part carries ``digest`` (:data:`PART_KEY`). A folder removed meanwhile is not
    created again (:class:`~optik.errors.OutputFileError`).
    """
    pa = require("pyarrow", "a batch")
    pq = require("pyarrow.parquet", "a batch")
    table = pa.table(result).replace_schema_metadata({PART_KEY: digest.encode()})
    write_atomic_with(
        folder / part_name(index),
        lambda handle: pq.write_table(table, handle),
        binary=True,
        create_folder=False,
    )


@dataclass(frozen=True)
class PartWriter:
    """Writes a batch's part file where its chunk was computed.

    A :class:`~optik.campaign.engine.ChunkWriter`: it writes only into a folder stamped
    with its run's token.

    Attributes:
        folder: the output folder, absolute.
        run: the token of the run that writes it (the folder's :data:`RUN_FILE`).
        digest: the digest of the run's settings, written into each part (:data:`PART_KEY`).
    """

    folder: str
    run: str
    digest: str = ""

    def __call__(self, index: int, result: dict[str, np.ndarray]) -> bool:
        """Write chunk ``index``'s part whole (True), or nothing (False).

        False when the folder is not this run's from here (another machine's disk, or a
        run since replaced) or cannot be written from here: the client then writes it.
        """
        folder = Path(self.folder)
        try:
            if (folder / RUN_FILE).read_text(encoding="utf-8") != self.run:
                return False
            _write_part(folder, index, result, self.digest)
        except (OSError, OutputFileError):  # not there, or not writable from this worker
            return False
        return True


def _damaged(file: Path, exc: Exception) -> OptikError:
    """The error of a part file that does not read, saying how to recover."""
    return OptikError(
        f"{file}: a damaged part file ({exc}); delete it and resume the run "
        "(resume=True, or --resume) to compute its chunk again"
    )


def _foreign(file: Path) -> OptikError:
    """The error of a part file that another run wrote, saying how to recover."""
    return OptikError(
        f"{file}: a part file of another run (other settings or targets: a run at the same "
        "path, or a file copied in); delete it and resume the run (resume=True, or "
        "--resume) to compute its chunk again"
    )


def _check_part(file: Path, digest: str | None) -> None:
    """Raise unless a part file's Parquet footer reads and is this run's (the footer only).

    A part is renamed into place only when whole, so one that does not read was damaged
    from outside (a disk fault, a cut copy); resuming over it would fail only at the end.

    Args:
        file: the part file.
        digest: the run's settings digest the part must carry (``None``: not checked).

    Raises:
        OptikError: the file does not read as Parquet, or carries another run's digest
            (the message names it).
    """
    pq = require("pyarrow.parquet", "a batch")
    try:
        metadata = pq.read_metadata(file).metadata or {}
    except Exception as exc:  # pyarrow's ArrowInvalid (a ValueError), OSError, ...
        raise _damaged(file, exc) from None
    if digest is not None and metadata.get(PART_KEY) != digest.encode():
        raise _foreign(file)


def _read_part(pq: Any, file: Path, digest: str | None) -> Any:
    """The rows of one part file, or a clear error naming it (see :func:`_check_part`)."""
    try:
        table = pq.read_table(file)
    except Exception as exc:  # damaged since the run checked its footer
        raise _damaged(file, exc) from None
    if digest is not None and (table.schema.metadata or {}).get(PART_KEY) != digest.encode():
        raise _foreign(file)  # written in by another run since this one started
    return table


class PartStore:
    """Parquet part files in a folder, one per chunk (``None`` folder: in memory).

    A run that writes the folder (a new one or a resumed one) gives it a new token
    (:meth:`for_run`); the workers write their own parts (:meth:`writer`) when they find
    that token there, and the client writes a part only while it is there
    (:meth:`write`). With ``digest``, every part must carry it (:data:`PART_KEY`).
    """

    def __init__(
        self, folder: Path | None, run: str | None = None, digest: str | None = None
    ) -> None:
        self.folder = folder
        self.memory: dict[int, Any] = {}
        self.run = run
        self.digest = digest

    @classmethod
    def for_run(cls, folder: Path | None, digest: str | None = None) -> PartStore:
        """The store of a run about to write ``folder``, stamped with a new run token.

        Temporary files that killed writes left in the folder are removed.

        Args:
            folder: the output folder (``None``: in memory).
            digest: the digest of the run's settings that its parts carry.
        """
        if folder is None:
            return cls(None)
        run = uuid.uuid4().hex
        write_atomic(folder / RUN_FILE, run)
        # The folder is this run's now: a temporary file of a write that was killed (a
        # process killed mid-part) is nobody's, and would stay there for good.
        for pattern in (".part-*.tmp", f".{RUN_FILE}.*.tmp"):
            for leftover in folder.glob(pattern):
                leftover.unlink(missing_ok=True)
        return cls(folder, run, digest)

    part_name = staticmethod(part_name)

    def finished(self) -> set[int]:
        """Chunks whose part file exists (each checked to read as Parquet).

        Raises:
            OptikError: a part file that does not read (see :func:`_check_part`).
        """
        if self.folder is None:
            return set(self.memory)
        done = set()
        for file in self.folder.glob("part-*.parquet"):
            stem = file.stem.removeprefix("part-")
            if stem.isdigit():
                _check_part(file, self.digest)
                done.add(int(stem))
        return done

    def write(self, index: int, result: dict[str, np.ndarray]) -> None:
        """Write chunk ``index`` whole (here, in the client), into this run's folder only.

        Raises:
            OptikError: the folder was removed, or replaced by another run, since this
                run stamped it (:meth:`check_own`); nothing is written then.
        """
        if self.folder is None:
            pa = require("pyarrow", "a batch")
            self.memory[index] = pa.table(result)
            return
        self.check_own()
        try:
            _write_part(self.folder, index, result, self.digest or "")
        except OutputFileError:
            self.check_own()  # removed between the check and the write: say so
            raise

    def check_own(self) -> None:
        """Raise unless the folder still carries this run's token (a stamped folder only).

        Raises:
            OptikError: the folder was removed, or now belongs to another run (its token
                differs): this run must stop rather than write into it or create it again.
        """
        if self.folder is None or self.run is None:
            return
        try:
            token: str | None = (self.folder / RUN_FILE).read_text(encoding="utf-8")
        except OSError:
            token = None
        if token == self.run:
            return
        if not self.folder.exists():
            raise OptikError(
                f"{self.folder}: the output folder was removed while this run was writing "
                "it; the run stopped (run it again to compute every chunk)"
            )
        raise OptikError(
            f"{self.folder}: the output folder was replaced by another run at the same path "
            "while this run was writing it; the run stopped without writing into it (give "
            "each run its own output path)"
        )

    def writer(self) -> PartWriter | None:
        """The workers' writer of this folder (``None`` in memory or unstamped)."""
        if self.folder is None or self.run is None:
            return None
        return PartWriter(str(self.folder.resolve()), self.run, self.digest or "")

    def table(self) -> Any:
        """Every row, sorted by target index."""
        pa = require("pyarrow", "a batch")
        pq = require("pyarrow.parquet", "a batch")
        if self.folder is None:
            parts = [self.memory[i] for i in sorted(self.memory)]
        else:
            files = sorted(self.folder.glob("part-*.parquet"))
            parts = [_read_part(pq, f, self.digest) for f in files]
        if not parts:
            return None
        try:
            return pa.concat_tables(parts).sort_by("index")
        except (pa.ArrowInvalid, pa.ArrowTypeError, KeyError) as exc:
            raise OptikError(
                f"{self.folder}: its part files do not fit together ({exc}); a part of "
                "another run? remove the folder and run again"
            ) from None


def solve_batch(
    robot: Robot,
    targets: Any,
    *,
    mode: str = "pose",
    axis: str = "z",
    tol: float | tuple[float, float] = 1e-6,
    restarts: int = DEFAULT_RESTARTS,
    max_iter: int = 100,
    seed: int = 0,
    chunk: int = DEFAULT_CHUNK,
    client: Any = None,
    workers: int | None = None,
    scheduler: str | None = None,
    out: str | Path | None = None,
    resume: bool = False,
    progress: ProgressOption = None,
) -> Any:
    """Solve many targets chunk by chunk, in-process or on Dask, to Parquet part files.

    Args:
        robot: the robot.
        targets: (N, 4, 4) poses or (N, 3) positions (m), or a ``.npy`` / ``.parquet``
            file of them (:func:`read_targets`).
        mode: ``"pose"``, ``"position"``, ``"orientation"`` or ``"axis"``
            (:func:`optik.solve_ik_batch`).
        axis: the tool axis of ``mode="axis"`` (in other modes it is not read, and stored
            as ``"z"``).
        tol: one tolerance, or ``(position_tol_m, orientation_tol_rad)``.
        restarts: attempts after the first per target.
        max_iter: iterations per attempt.
        seed: base seed (target ``k`` uses ``seed + k``).
        chunk: targets per chunk (the results do not depend on it).
        client: a :class:`distributed.Client` to run on.
        workers: run on a local cluster of this many worker processes.
        scheduler: run on the Dask scheduler at this address.
        out: the output folder (a Parquet dataset; default: in memory only).
        resume: finish the run at ``out`` (same settings and targets), skipping the
            chunks already written.
        progress: a progress bar (default: when stderr is a terminal), or a callable
            ``progress(done, total)`` (chunks).

    Returns:
        A :class:`pyarrow.Table` of every target's row, sorted by ``index``
        (:func:`result_columns`: status, success, q per joint, the three errors,
        iterations, restarts). Its ``schema.metadata[RESUMED_KEY]`` is the number of
        targets this call resumed from ``out`` rather than solved (``b"0"`` for a new run).

    Raises:
        OptikError: malformed targets or options; more than
            :data:`~optik.campaign.engine.MAX_CHUNKS` chunks (give a larger ``chunk``);
            ``out`` exists and ``resume`` is false, or is a place that cannot be written;
            a stored run with other settings, or a part file of another run, on
            ``resume``; ``out`` removed or replaced by another run while this one writes
            it (the run stops); an unreachable scheduler.
    """
    if not isinstance(robot, Robot):
        raise OptikError(f"robot: expected an optik.Robot, got {type(robot).__name__}")
    refuse_reimported_script(workers)  # before its output is checked or created
    require("pyarrow", "a batch")
    check_choice("mode", mode, MODES)
    task = make_task(mode, axis=axis, tol=tol)
    restarts = check_int("restarts", restarts, minimum=0, maximum=MAX_BATCH_RESTARTS)
    max_iter = check_int("max_iter", max_iter, minimum=1, maximum=MAX_ITERATIONS)
    seed = check_int("seed", seed, minimum=0, maximum=MAX_SEED - 2**41)
    chunk = check_int("chunk", chunk, minimum=1, maximum=10_000_000)
    resume = check_bool("resume", resume)
    progress = check_progress(progress)
    # A place it cannot be written to fails before the targets are read, not at the end.
    folder = None if out is None else check_folder(out)
    if resume and folder is None:
        raise OptikError("resume: finishes a stored run; give its folder as out=")
    # The validated values, as plain Python numbers: a numpy scalar would not go into the
    # settings file, and every check must pass before anything is written.
    # Read in axis mode only: the stored settings must not differ over it on a resume.
    axis = str(axis) if task.mode == "axis" else "z"
    tol = (
        (task.position_tol, task.orientation_tol)
        if isinstance(tol, tuple | list)
        else task.position_tol
    )
    poses = _as_poses(targets, task.mode)
    if len(poses) > 2**40:
        raise OptikError(f"targets: at most 2**40 per batch, got {len(poses)}")
    chunks = chunk_count(len(poses), chunk)
    smallest = chunk_count(len(poses), MAX_CHUNKS)
    check_chunk_count(chunks, f"{len(poses)} targets in chunks of {chunk} make", smallest)
    settings = {
        "robot": robot.name,
        "robot_fingerprint": robot_fingerprint(robot),
        "mode": task.mode,
        "axis": axis,
        "tol": list(tol) if isinstance(tol, tuple) else tol,
        "restarts": restarts,
        "max_iter": max_iter,
        "seed": seed,
        "chunk": chunk,
        "targets": len(poses),
        "targets_fingerprint": array_fingerprint(poses),
        "seed_rule": "target k uses stream seed + k",
        "optik": versions()["optik"],
    }
    text = json.dumps(settings, indent=1)
    digest = hashlib.sha256(text.encode()).hexdigest()  # the same text on a resume
    new = _check_out(folder, settings, resume)
    items = [(s, poses[s : s + chunk]) for s in range(0, len(poses), chunk)]
    with open_engine(client=client, workers=workers, scheduler=scheduler) as engine:
        # Written only now: a bad engine option leaves no folder behind either.
        if folder is not None and new:
            _create(folder, text)
        store = PartStore.for_run(folder, digest)
        done = store.finished()  # a part of another run is refused here, before any work
        threads = engine.threads_for(chunks)
        spec = BatchSpec(robot, task.mode, axis, tol, restarts, max_iter, seed, threads)
        work = functools.partial(solve_chunk, spec)
        note = f"batch {robot.name}"
        run_chunks_with_progress(engine, work, items, store, progress, note, finished=done)
    store.check_own()  # not another run's rows: the folder may have been replaced since
    table = store.table()
    pa = require("pyarrow", "a batch")
    if table is None:
        table = pa.table(solve_chunk(spec, (0, np.empty((0, 4, 4)))))
    _check_rows(table, len(poses), folder, chunk)
    resumed = sum(len(items[i][1]) for i in done if i < len(items))
    return table.replace_schema_metadata({RESUMED_KEY: str(resumed).encode()})


def _check_rows(table: Any, n: int, folder: Path | None, chunk: int) -> None:
    """Every target's row once, in order: a stray part file in the folder is an error.

    The message names the first part file that does not hold its chunk's rows (chunk
    ``c`` of ``chunk`` targets holds the targets ``c chunk`` onwards), if one does not.
    """
    index = np.asarray(table.column("index").to_numpy(zero_copy_only=False))
    if len(index) == n and np.array_equal(index, np.arange(n)):
        return
    stray = None if folder is None else _stray_part(folder, n, chunk)
    if stray is not None:
        raise OptikError(f"{stray}; delete it and resume to compute its chunk")
    raise OptikError(
        f"{folder}: its part files hold {len(index)} rows for {n} targets (a part "
        "file of another run, or copied in?); remove the folder and run again"
    )


def _stray_part(folder: Path, n: int, chunk: int) -> str | None:
    """The first part file whose rows are not its chunk's, in words; ``None`` if none."""
    pq = require("pyarrow.parquet", "a batch")
    for file in sorted(folder.glob("part-*.parquet")):
        stem = file.stem.removeprefix("part-")
        if not stem.isdigit():
            continue
        number = int(stem)
        column = pq.read_table(file, columns=["index"]).column("index")
        rows = np.asarray(column.to_numpy(zero_copy_only=False))
        expected = np.arange(number * chunk, min((number + 1) * chunk, n))
        if not np.array_equal(rows, expected):
            held = f"rows {rows[0]} to {rows[-1]}" if len(rows) else "no rows"
            if len(expected) == 0:
                return f"{file}: holds {held}, but the run has no chunk {number}"
            return (
                f"{file}: holds {held}, not chunk {number}'s targets "
                f"{expected[0]} to {expected[-1]} (copied in?)"
            )
    return None


def _as_poses(targets: Any, mode: str) -> FloatArray:
    if isinstance(targets, str | Path):
        poses, oriented = _read(Path(targets))
        if mode != "position" and not oriented:
            raise OptikError(
                f"{targets}: positions only; mode {mode!r} needs orientations (an (N, 4, 4) "
                "array, or qw, qx, qy, qz columns); or give mode 'position'"
            )
        return poses
    array = as_float_array("targets", targets)
    if array.ndim == 2 and array.shape[1] == 3:
        if mode != "position":
            raise ShapeError("targets", f"(N, 4, 4) in mode {mode!r}", array.shape)
        return _positions("targets", array)
    if array.ndim == 3 and array.shape[1:] == (4, 4):
        return as_pose("targets", array, batch=True)
    raise ShapeError("targets", "(N, 4, 4) poses or (N, 3) positions", array.shape)


def _check_out(folder: Path | None, settings: dict[str, Any], resume: bool) -> bool:
    """Whether the output folder is to be created; a resumed one must match ``settings``.

    Reads only: nothing is written until every option has been checked.
    """
    if folder is None:
        return False
    marker = folder / SETTINGS_FILE
    if not folder.exists():
        if not folder.parent.is_dir():  # a typo is not a path to create (as a map)
            raise OutputFileError(str(folder), f"its folder {folder.parent} does not exist")
        return True
    if not resume:
        raise OutputFileError(str(folder), "it exists (resume=True, or --resume, finishes it)")
    if not marker.is_file():
        raise OptikError(f"{folder}: not a batch run to resume (no {SETTINGS_FILE})")
    try:
        stored = json.loads(marker.read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        raise OptikError(f"{marker}: unreadable settings ({exc})") from None
    if not isinstance(stored, dict):
        raise OptikError(
            f"{marker}: unreadable settings (a JSON {type(stored).__name__}, not an object); "
            "give another output path"
        )
    check_same_run(str(folder), stored, settings)
    return False


def _create(folder: Path, text: str) -> None:
    """Create the output folder with its settings file, or leave no folder behind."""
    existed = folder.exists()
    prepare_folder(folder)
    try:
        write_atomic(folder / SETTINGS_FILE, text)
    except BaseException:
        if not existed:  # ours and empty: a rerun must not find it "existing"
            with contextlib.suppress(OSError):
                folder.rmdir()
        raise


__all__ = [
    "DEFAULT_CHUNK",
    "PART_KEY",
    "RESUMED_KEY",
    "BatchSpec",
    "PartStore",
    "PartWriter",
    "read_targets",
    "result_columns",
    "solve_batch",
    "solve_chunk",
]
