"""Cartesian paths: sampled primitives (line, arc, circle) and path files.

A path is an array of world poses ``(N, 4, 4)`` (m); position-only paths carry identity
rotations and are planned in ``mode="position"``. Orientation between two poses is
interpolated by slerp (constant angular rate about one axis).

File formats (see docs/planning.md):

- CSV: the header line ``x,y,z`` (position only) or ``x,y,z,roll,pitch,yaw`` (rad, the
  URDF ``rpy`` convention), then one waypoint per line; lengths in m. Any other first
  line is an error (a missing header would otherwise cost the first waypoint).
- NPZ: an array ``poses`` (N, 4, 4), or ``positions`` (N, 3); one (4, 4) pose or (3,)
  position is a path of one waypoint.
- TOML: ``positions = [[x, y, z], ...]`` and optionally ``rpy = [[r, p, y], ...]``, with
  optional ``length_unit`` / ``angle_unit`` as in problem files; any other key is an
  error.

The primitives check their arguments (poses, a positive finite ``step``, a radius of at
least :data:`MIN_RADIUS_M`) and refuse to produce more than :data:`MAX_PATH_SAMPLES`
samples. Coordinates beyond :data:`~optik._checks.MAX_LENGTH_M` are rejected everywhere.
"""

from __future__ import annotations

import csv
import math
import os
import sys
import zipfile
from pathlib import Path
from typing import Any

import numpy as np

from optik._checks import (
    MAX_LENGTH_M,
    FloatArray,
    check_bool,
    check_length_array,
    check_real,
    finite_array,
    not_a_file,
    read_number,
)
from optik.errors import OptikError, ShapeError
from optik.spatial import as_pose, exp_so3, log_so3, rpy_to_matrix, transform

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - exercised only on Python 3.10
    import tomli as tomllib


class PathFileError(OptikError):
    """A path file cannot be read; the message names the file and the problem."""


MAX_PATH_SAMPLES = 10_000_000
"""Most samples a primitive may produce (10 million poses are 1.3 GB of float64)."""

CSV_HEADERS = (("x", "y", "z"), ("x", "y", "z", "roll", "pitch", "yaw"))
"""The accepted header lines of a path CSV (case and spaces around names ignored)."""

MIN_RADIUS_M = 1e-9
"""Smallest radius of an arc or circle, m: :func:`arc` takes distances within 1e-9 m as
equal, so a smaller radius cannot be told from zero (and its square underflows)."""

_TOML_KEYS = {"positions", "rpy", "length_unit", "angle_unit"}


def _samples(length: float, step: float) -> int:
    """Sample count ``ceil(length / step) + 1`` (at least 2), capped by MAX_PATH_SAMPLES."""
    ratio = length / step
    if not ratio <= MAX_PATH_SAMPLES - 1:
        raise OptikError(
            f"step: {step!r} over a length of {length:.6g} asks for more than "
            f"{MAX_PATH_SAMPLES:,} samples; use a larger step"
        )
    return max(math.ceil(ratio - 1e-9), 1) + 1


def _check_poses(name: str, poses: FloatArray) -> FloatArray:
    """Path coordinates (m) must lie within ``MAX_LENGTH_M``; returns ``poses``."""
    check_length_array(f"{name} translation", poses[..., :3, 3])
    return poses


def _check_radius(what: str, radius: float) -> None:
    """Refuse a degenerate circle before its axis and sample count are computed."""
    if not radius >= MIN_RADIUS_M:
        raise OptikError(f"{what} {radius:.6g} m is below the minimum of {MIN_RADIUS_M:g} m")


def _endpoint(name: str, value: Any) -> FloatArray:
    return _check_poses(name, as_pose(name, value))


def _step(step: Any) -> float:
    return check_real("step", step, positive=True)


def slerp(R0: FloatArray, R1: FloatArray, s: FloatArray) -> FloatArray:
    """Rotations (len(s), 3, 3) from ``R0`` (s = 0) to ``R1`` (s = 1) at constant rate."""
    omega = log_so3(R0.T @ R1)
    return np.array([R0 @ exp_so3(float(t) * omega) for t in s])


def line(start: Any, end: Any, step: float) -> FloatArray:
    """Poses along the segment from ``start`` to ``end`` (4x4 each), at most ``step`` m apart.

    Orientation is slerped; the number of samples is ``ceil(length / step) + 1`` (at least
    2), both ends included. For a pure rotation (zero length) ``step`` applies in radians.

    Raises:
        OptikError: a pose that is not a rigid transform (or is complex, boolean, ...), a
            coordinate beyond ``MAX_LENGTH_M``, a ``step`` that is not a positive finite
            number, or more than :data:`MAX_PATH_SAMPLES` samples.
    """
    step = _step(step)
    T0 = _endpoint("start", start)
    T1 = _endpoint("end", end)
    length = float(np.linalg.norm(T1[:3, 3] - T0[:3, 3]))
    angle = float(np.linalg.norm(log_so3(T0[:3, :3].T @ T1[:3, :3])))
    s = np.linspace(0.0, 1.0, _samples(max(length, angle if length == 0 else 0.0), step))
    poses = np.empty((len(s), 4, 4))
    poses[:] = np.eye(4)
    poses[:, :3, 3] = T0[:3, 3] + s[:, None] * (T1[:3, 3] - T0[:3, 3])
    poses[:, :3, :3] = slerp(T0[:3, :3], T1[:3, :3], s)
    return poses


def arc(start: Any, end: Any, center: Any, step: float, *, long_way: bool = False) -> FloatArray:
    """Poses along the circular arc from ``start`` to ``end`` about ``center`` (3,), m.

    Both ends must lie at the same distance from ``center`` (to 1e-9 relative); the arc
    is the shorter one unless ``long_way``. Orientation is slerped along the arc.

    Raises:
        OptikError: as :func:`line`; also ends at different distances from ``center``,
            a radius below :data:`MIN_RADIUS_M`, or ends collinear with ``center``.
    """
    step = _step(step)
    long_way = check_bool("long_way", long_way)
    T0 = _endpoint("start", start)
    T1 = _endpoint("end", end)
    c = check_length_array("center", finite_array("center", center, (3,)))
    u, v = T0[:3, 3] - c, T1[:3, 3] - c
    # hypot, unlike np.linalg.norm, does not underflow to 0 for a radius of 1e-300.
    radius = math.hypot(*u)
    _check_radius("arc: radius (distance from start to center)", radius)
    if abs(math.hypot(*v) - radius) > 1e-9 * max(radius, 1.0):
        raise OptikError("arc: start and end must be at the same distance from center")
    normal = np.cross(u, v)
    sweep = math.atan2(float(np.linalg.norm(normal)), float(u @ v))
    if float(np.linalg.norm(normal)) < 1e-12 * radius * radius:
        raise OptikError("arc: start, end and center are collinear; use circle() with a normal")
    axis = normal / np.linalg.norm(normal)
    if long_way:
        sweep, axis = 2 * math.pi - sweep, -axis
    return _sweep(T0, T1, c, axis, sweep, step)


def circle(start: Any, center: Any, normal: Any, step: float) -> FloatArray:
    """Poses around the full circle through ``start`` about ``center``, turning about ``normal``.

    The orientation turns with the circle (the start rotation carried about ``normal``);
    the last sample coincides with the first.

    Raises:
        OptikError: as :func:`line`; also a zero ``normal``, or ``start`` closer than
            :data:`MIN_RADIUS_M` to the axis through ``center``.
    """
    step = _step(step)
    T0 = _endpoint("start", start)
    c = check_length_array("center", finite_array("center", center, (3,)))
    n = finite_array("normal", normal, (3,))
    largest = float(np.max(np.abs(n)))
    if largest == 0.0:
        raise OptikError("circle: normal must be non-zero")
    # Scale first: the norm of (1e300, 1e300, 0) overflows, that of (1e-300, 0, 0) underflows.
    axis = n / largest
    axis = axis / np.linalg.norm(axis)
    u = T0[:3, 3] - c
    _check_radius(
        "circle: radius (distance from start to the axis through center)",
        math.hypot(*(u - axis * float(axis @ u))),
    )
    T1 = T0.copy()
    return _sweep(T0, T1, c, axis, 2 * math.pi, step, carry_rotation=True)


def _sweep(
    T0: FloatArray,
    T1: FloatArray,
    center: FloatArray,
    axis: FloatArray,
    sweep: float,
    step: float,
    carry_rotation: bool = False,
) -> FloatArray:
    u = T0[:3, 3] - center
    radius = float(np.linalg.norm(u - axis * float(axis @ u)))
    s = np.linspace(0.0, 1.0, _samples(radius * sweep, step))
    rotations = slerp(T0[:3, :3], T1[:3, :3], s)
    poses = np.empty((len(s), 4, 4))
    for k, t in enumerate(s):
        R_turn = exp_so3(axis * sweep * float(t))
        poses[k] = transform(
            R_turn @ T0[:3, :3] if carry_rotation else rotations[k], center + R_turn @ u
        )
    return poses


def _positions_to_poses(positions: FloatArray, rpy: FloatArray | None) -> FloatArray:
    poses = np.broadcast_to(np.eye(4), (len(positions), 4, 4)).copy()
    poses[:, :3, 3] = positions
    if rpy is not None:
        for k, (r, p, y) in enumerate(rpy):
            poses[k, :3, :3] = rpy_to_matrix(r, p, y)
    return poses


def read_path(path: str | Path) -> tuple[FloatArray, str]:
    """Read a path file (CSV, NPZ or TOML); returns ``(poses (N, 4, 4), mode)``.

    ``mode`` is ``"pose"`` when the file gives orientations, else ``"position"``.

    Raises:
        PathFileError: ``path`` not a path, missing or unreadable file, not UTF-8,
            unknown extension, or malformed content: a CSV whose first line is not one of
            :data:`CSV_HEADERS`, a TOML key other than ``positions``, ``rpy``,
            ``length_unit``, ``angle_unit``, an ``.npz`` that is not an archive (a bare
            ``.npy`` array) or holds an array it does not read, no waypoints, a
            coordinate beyond ``MAX_LENGTH_M`` (the message names the file and the line or
            key).
    """
    if not isinstance(path, str | os.PathLike) or isinstance(path, bytes):
        raise PathFileError(f"path: expected a file path, got {path!r:.80}")
    file = Path(path)
    if not file.is_file():
        raise PathFileError(f"{file}: {not_a_file(file)}")
    suffix = file.suffix.lower()
    try:
        if suffix == ".csv":
            return _read_csv(file)
        if suffix == ".npz":
            return _read_npz(file)
        if suffix == ".toml":
            return _read_toml(file)
    except UnicodeDecodeError as exc:
        raise PathFileError(f"{file}: not a UTF-8 text file ({exc})") from exc
    except (ShapeError, ValueError) as exc:
        if isinstance(exc, PathFileError):
            raise
        raise PathFileError(f"{file}: {exc}") from exc
    except (OSError, EOFError, zipfile.BadZipFile) as exc:
        raise PathFileError(f"{file}: cannot read the file ({exc})") from exc
    raise PathFileError(f"{file}: unknown path format {suffix!r} (expected .csv, .npz, .toml)")


def _csv_rows(file: Path) -> list[tuple[int, list[str]]]:
    """The rows of a path CSV, each with the file line it starts on (1-based).

    Blank and ``#`` lines are left out after the numbering, so errors name the file's lines.
    """
    rows = []
    # utf-8-sig: a spreadsheet's CSV export may begin with a byte-order mark.
    with file.open(newline="", encoding="utf-8-sig") as handle:
        reader = csv.reader(handle)
        start = 1
        try:
            for row in reader:
                if row and not row[0].startswith("#"):
                    rows.append((start, row))
                start = reader.line_num + 1  # a quoted cell may hold a newline
        except csv.Error as exc:  # a cell beyond the csv module's field limit (128 KiB)
            raise PathFileError(f"{file}: line {start}: {exc}") from exc
    return rows


def _read_csv(file: Path) -> tuple[FloatArray, str]:
    rows = _csv_rows(file)
    if len(rows) < 2:
        raise PathFileError(f"{file}: expected a header line and at least one waypoint")
    first, cells = rows[0]
    header = tuple(cell.strip().lower() for cell in cells)
    if header not in CSV_HEADERS:
        # A first line of numbers would otherwise be taken for a header and lost.
        raise PathFileError(
            f"{file}: line {first} must be the header 'x,y,z' or 'x,y,z,roll,pitch,yaw', "
            f"got {','.join(cells)!r}"
        )
    width = len(header)
    values = np.empty((len(rows) - 1, width))
    for k, (line, row) in enumerate(rows[1:]):
        if len(row) != width:
            raise PathFileError(f"{file}: line {line}: expected {width} values, got {len(row)}")
        try:
            values[k] = [read_number(v) for v in row]
        except ValueError as exc:
            raise PathFileError(f"{file}: line {line}: {exc}") from exc
        if not np.all(np.isfinite(values[k])):
            raise PathFileError(f"{file}: line {line}: NaN or infinite value")
        if np.max(np.abs(values[k, :3])) > MAX_LENGTH_M:
            raise PathFileError(
                f"{file}: line {line}: a coordinate beyond {MAX_LENGTH_M:g} m ({','.join(row[:3])})"
            )
    rpy = values[:, 3:6] if width == 6 else None
    return _positions_to_poses(values[:, :3], rpy), "pose" if width == 6 else "position"


def _read_npz(file: Path) -> tuple[FloatArray, str]:
    loaded = np.load(file)
    if not isinstance(loaded, np.lib.npyio.NpzFile):
        # np.load reads a .npy file (one bare array) whatever its name.
        raise PathFileError(
            f"{file}: not an .npz archive (a single .npy array?); save the path with "
            "np.savez(file, poses=...) or np.savez(file, positions=...)"
        )
    with loaded as data:
        names = set(data.files)
        if "poses" in names:
            # A saved PathPlan (PathPlan.save) holds its poses and its results.
            _refuse_npz_arrays(file, names - {"poses", *_PLAN_ARRAYS}, "poses")
            # One (4, 4) pose is one waypoint, as a single CSV or TOML position is.
            poses = as_pose("poses", data["poses"], batch=True).reshape(-1, 4, 4).copy()
            return _nonempty(file, _check_poses("poses", poses)), "pose"
        if "positions" in names:
            _refuse_npz_arrays(file, names - {"positions", "rpy"}, "positions")
            positions = np.atleast_2d(
                finite_array("positions", data["positions"], (3,), batch=True)
            )
            check_length_array("positions", positions)
            rpy = None
            if "rpy" in names:
                rpy = np.atleast_2d(finite_array("rpy", data["rpy"], (3,), batch=True))
                if len(rpy) != len(positions):
                    raise PathFileError(
                        f"{file}: 'rpy' holds {len(rpy)} rows for {len(positions)} positions"
                    )
            poses = _positions_to_poses(positions, rpy)
            return _nonempty(file, poses), "position" if rpy is None else "pose"
    raise PathFileError(
        f"{file}: expected an array named 'poses' (N, 4, 4), or 'positions' (N, 3) in m "
        "with 'rpy' (N, 3) in rad or without"
    )


_PLAN_ARRAYS = ("q", "status", "limit_margin", "manipulability", "step", "candidates")
"""The arrays a saved :class:`optik.planning.PathPlan` holds beside its ``poses``."""


def _refuse_npz_arrays(file: Path, unknown: set[str], read: str) -> None:
    """An array the path would not use is an error, not silently dropped."""
    if unknown:
        raise PathFileError(
            f"{file}: array {sorted(unknown)[0]!r} is not read beside {read!r} (give 'poses' "
            "(N, 4, 4), or 'positions' (N, 3) in m with 'rpy' (N, 3) in rad or without)"
        )


def _nonempty(file: Path, poses: FloatArray) -> FloatArray:
    """An empty array is no path (a CSV or TOML file without waypoints is refused too)."""
    if len(poses) == 0:
        raise PathFileError(f"{file}: expected at least one waypoint, got none")
    return poses


def _read_toml(file: Path) -> tuple[FloatArray, str]:
    from optik.problems import ANGLE_UNITS, LENGTH_UNITS

    try:
        data = tomllib.loads(file.read_text(encoding="utf-8"))
    except tomllib.TOMLDecodeError as exc:
        raise PathFileError(f"{file}: not valid TOML: {exc}") from exc
    unknown = sorted(set(data) - _TOML_KEYS)
    if unknown:
        raise PathFileError(
            f"{file}: unknown key {unknown[0]!r} (allowed: {', '.join(sorted(_TOML_KEYS))})"
        )
    units = []
    for key, table, default in (
        ("length_unit", LENGTH_UNITS, "m"),
        ("angle_unit", ANGLE_UNITS, "rad"),
    ):
        value = data.get(key, default)
        if not isinstance(value, str) or value not in table:
            raise PathFileError(f"{file}: {key} must be one of {sorted(table)}, got {value!r}")
        units.append(table[value])
    length, angle = units
    if "positions" not in data:
        raise PathFileError(f"{file}: missing 'positions'")
    positions = finite_array("positions", data["positions"], (3,), batch=True) * length
    positions = np.atleast_2d(positions)  # a single [x, y, z] is one waypoint
    check_length_array("positions", positions)
    rpy = None
    if "rpy" in data:
        rpy = np.atleast_2d(finite_array("rpy", data["rpy"], (3,), batch=True) * angle)
        if len(rpy) != len(positions):
            raise PathFileError(f"{file}: 'rpy' needs one entry per position")
    return _positions_to_poses(positions, rpy), "pose" if rpy is not None else "position"
