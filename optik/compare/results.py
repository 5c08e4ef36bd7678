"""The raw table of a comparison: one :class:`ResultRow` per line of ``results.csv``.

The file is appended one flushed row at a time (:class:`ResultsFile`), so an interrupted
run loses nothing and ``resume=True`` continues it; :func:`read_results` reads it back.
The columns are documented in ``docs/report.md``.
"""

from __future__ import annotations

import csv
import io
import json
import math
import re
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, fields
from pathlib import Path
from typing import IO, Any, Final, TextIO

from optik._closing import Closing
from optik._files import prepare_folder, write_atomic_with
from optik.errors import OutputFileError, ResultsFileError
from optik.problems import Problem

__all__ = [
    "COLUMNS",
    "KINDS",
    "Key",
    "ResultRow",
    "ResultsFile",
    "problem_row",
    "read_results",
    "rows_of",
    "settings_json",
    "write_rows",
]

#: Row kinds, in the order the report presents them.
KINDS: Final[tuple[str, ...]] = ("closed_form", "ik", "seed001", "seed003")

Key = tuple[str, str, str, str, str]
"""Identity of a row: (kind, problem, target, solver, settings)."""


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
        status: ``ik``: :data:`optik.ik_result.STATUSES` or ``"error"``; ``closed_form``:
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
        """Parse a CSV record (column name -> cell), the inverse of :meth:`to_record`.

        Args:
            record: one cell (text) per column name of :data:`COLUMNS`.

        Raises:
            ValueError: a cell that :meth:`to_record` cannot have written (an unknown
                ``kind``, a boolean other than ``true``/``false``, an empty ``success``,
                a number not written as ``str`` or ``repr`` writes it, a ``time_s`` that
                is negative or not finite); the message names the column.
        """
        values: dict[str, Any] = {}
        for f in fields(cls):
            text = record[f.name]
            kind = _COLUMN_TYPES[f.name]
            if kind is str:
                values[f.name] = text
            elif text == "" and f.name != "success":
                values[f.name] = None if f.name != "time_s" else 0.0
            elif kind is bool:
                if text not in ("true", "false"):
                    raise ValueError(f"column {f.name!r}: {text!r} is not true or false")
                values[f.name] = text == "true"
            else:
                # Only what to_record writes: int() and float() also take "1_000" and " 3 ".
                if not (_INT if kind is int else _FLOAT).fullmatch(text):
                    raise ValueError(f"column {f.name!r}: {text!r} is not a number")
                values[f.name] = kind(text)
        time_s = values["time_s"]
        if not (math.isfinite(time_s) and time_s >= 0):
            raise ValueError(f"column 'time_s': {time_s!r} is not a time (finite, >= 0)")
        if values["kind"] not in KINDS:
            raise ValueError(f"column 'kind': {values['kind']!r} is not one of {list(KINDS)}")
        return cls(**values)


#: The numbers :meth:`ResultRow.to_record` writes: ``str`` of an int, ``repr`` of a float
#: (or ``str`` of an int given for one).
_INT: Final[re.Pattern[str]] = re.compile(r"-?[0-9]+")
_FLOAT: Final[re.Pattern[str]] = re.compile(r"-?([0-9]+(\.[0-9]*)?([eE][-+]?[0-9]+)?|inf|nan)")

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


def problem_row(
    kind: str, problem: Problem, target: str, solver: str, settings: str, **columns: Any
) -> ResultRow:
    """A row of ``problem`` (its name and its robot's name filled in), other columns given."""
    return ResultRow(
        kind=kind,
        problem=problem.name,
        robot=problem.robot.name,
        target=target,
        solver=solver,
        settings=settings,
        **columns,
    )


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

    Args:
        path: the results file.

    Raises:
        ResultsFileError: the file cannot be read (missing, a folder, no access), its
            header is not :data:`COLUMNS` (another schema or another file), a row is
            corrupted (wrong number of cells, a cell that does not parse, not UTF-8), or
            two rows have the same key (:meth:`ResultRow.key`); the message names the file
            and the line (both lines for a duplicate; line 0 when it cannot be read).
    """
    raw = _read_bytes(Path(path))
    return _parse(raw[: raw.rfind(b"\n") + 1], Path(path))


def _read_bytes(path: Path) -> bytes:
    """The bytes of a results file; an unreadable one is a ResultsFileError naming it."""
    try:
        return path.read_bytes()
    except OSError as exc:
        raise ResultsFileError(str(path), 0, f"cannot read it: {exc.strerror or exc}") from None


def _parse(raw: bytes, path: Path) -> list[ResultRow]:
    """The rows of a results file's complete lines; strict (see :func:`read_results`)."""
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = raw[: exc.start].count(b"\n") + 1
        raise ResultsFileError(str(path), line, "not UTF-8 text (a corrupted row)") from None
    if not text:
        return []
    reader = csv.reader(io.StringIO(text, newline=""))
    header = next(reader)
    if tuple(header) != COLUMNS:
        raise ResultsFileError(
            str(path),
            1,
            f"not an optik results file of this version (columns {header} instead of "
            f"{list(COLUMNS)})",
        )
    rows: list[ResultRow] = []
    first_line: dict[Key, int] = {}
    start = reader.line_num + 1  # a cell may hold a newline: a row may span lines
    while True:
        try:
            cells = next(reader, None)
        except csv.Error as exc:
            raise ResultsFileError(str(path), start, f"corrupted row: {exc}") from None
        if cells is None:
            break
        line, start = start, reader.line_num + 1
        if not cells:
            continue  # a blank line holds no row
        if len(cells) != len(COLUMNS):
            raise ResultsFileError(
                str(path), line, f"corrupted row: {len(cells)} cells instead of {len(COLUMNS)}"
            )
        try:
            row = ResultRow.from_record(dict(zip(COLUMNS, cells, strict=True)))
        except ValueError as exc:
            raise ResultsFileError(str(path), line, f"corrupted row: {exc}") from None
        key = row.key()
        if key in first_line:
            raise ResultsFileError(
                str(path),
                line,
                f"duplicate of the row at line {first_line[key]} (same kind, problem, "
                "target, solver and settings); delete one of the two lines and resume",
            )
        first_line[key] = line
        rows.append(row)
    return rows


def _refuse_unfinished_header(raw: bytes, path: Path) -> None:
    """Refuse a file without a complete line unless it is the start of optik's header.

    A run killed while writing the header leaves a prefix of it (started over); anything
    else there is another file, not to be replaced.
    """
    if not _csv_line(list(COLUMNS)).encode().startswith(raw):
        raise ResultsFileError(
            str(path),
            1,
            "not an optik results file (no complete line, and not the start of its header); "
            "remove it or choose another folder",
        )


class ResultsFile(Closing):
    """The raw table on disk, appended one flushed row at a time.

    Without ``resume`` the file is started afresh (header only). With ``resume`` an
    existing file is kept: it is checked whole, then a partial last line (a run killed
    mid-write) is cut off, its rows are loaded, and :meth:`has` tells which keys are
    already done. A file that fails the check is left as it was.

    Args:
        path: the CSV file.
        resume: continue an existing file instead of starting a new one.

    Raises:
        OutputFileError: ``path`` is a folder, its folder cannot be created or written,
            or (without ``resume``) it holds a file that is not an optik results table.
        ResultsFileError: resuming a file whose header is not :data:`COLUMNS`, with a
            corrupted row or with two rows of the same key (see :func:`read_results`), or
            without a complete line that is not the start of the header.
    """

    def __init__(self, path: str | Path, resume: bool = False) -> None:
        self.path = Path(path)
        if self.path.is_dir():
            raise OutputFileError(str(self.path), "it is a folder")
        prepare_folder(self.path.parent)
        self.rows: list[ResultRow] = []
        try:
            if resume and self.path.exists():
                raw = _read_bytes(self.path)
                complete = raw[: raw.rfind(b"\n") + 1]
                # Checked whole before any change: a run that fails leaves the file as it was.
                self.rows = _parse(complete, self.path)
                if not complete:
                    _refuse_unfinished_header(raw, self.path)
                    self._start()
                elif len(complete) != len(raw):
                    with open(self.path, "r+b") as f:
                        f.truncate(len(complete))
            else:
                self._refuse_foreign()
                self._start()
            self._keys = {row.key() for row in self.rows}
            self._file: TextIO = open(self.path, "a", encoding="utf-8", newline="")  # noqa: SIM115
        except OSError as exc:
            raise OutputFileError(str(self.path), exc.strerror or str(exc)) from None

    def _refuse_foreign(self) -> None:
        """Refuse to start over a file that is not an optik results table (user data)."""
        if not self.path.is_file() or self.path.stat().st_size == 0:
            return
        with open(self.path, "rb") as f:
            first = f.readline()
        if first != _csv_line(list(COLUMNS)).encode():
            raise OutputFileError(
                str(self.path),
                "it exists and is not an optik results table; remove it or choose another "
                "folder (a results table of an earlier run is started over)",
            )

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


def _csv_line(cells: Sequence[str]) -> str:
    buffer = io.StringIO()
    csv.writer(buffer, lineterminator="\n").writerow(cells)
    return buffer.getvalue()


def rows_of(rows: Iterable[ResultRow], kind: str) -> list[ResultRow]:
    """The rows of one kind, in file order."""
    return [row for row in rows if row.kind == kind]


def write_rows(rows: Iterable[ResultRow], path: str | Path) -> Path:
    """Write rows to a new results file at once, whole (for exports and tests)."""

    def write(handle: IO[str]) -> None:
        handle.write(_csv_line(list(COLUMNS)))
        for row in rows:
            handle.write(_csv_line(row.to_record()))

    return write_atomic_with(path, write)
