"""Problem files: robots and IK tasks as TOML data (format in docs/problems.md).

:func:`load_problem` converts every length and angle to SI units once, validates every
field, and raises :class:`~optik.errors.ProblemFileError` naming the file, the table and
the field of the first problem it finds.
"""

from __future__ import annotations

import difflib
import math
import os
import re
import sys
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from optik._checks import MAX_LENGTH_M, FloatArray, not_a_file
from optik.errors import AnalyticIKError, OptikError, ProblemFileError
from optik.model import DHJoint, Mimic, Robot
from optik.spatial import rpy_to_matrix, transform

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - exercised only on Python 3.10
    import tomli as tomllib

LENGTH_UNITS = {"m": 1.0, "cm": 0.01, "mm": 0.001}
ANGLE_UNITS = {"rad": 1.0, "deg": math.pi / 180.0}
CONVENTIONS = ("dh", "mdh", "urdf")
DEFAULT_TOLERANCE = 1e-6


def _problems_dir() -> Path:
    """The built-in problems: packaged into the wheel, or the source tree's folder."""
    packaged = Path(__file__).resolve().parent / "problems"
    return packaged if packaged.is_dir() else Path(__file__).resolve().parent.parent / "problems"


PROBLEMS_DIR = _problems_dir()


@dataclass(frozen=True)
class Target:
    """A named IK target in SI units.

    Attributes:
        name: target name.
        mode: ``"pose"`` (``pose`` is a full 4x4) or ``"position"`` (only its translation).
        pose: 4x4 world pose; for position targets the rotation is the identity.
        tolerance: accepted position error (m).
        angle_tolerance: accepted orientation error (rad), pose targets only.
    """

    name: str
    mode: str
    pose: FloatArray
    tolerance: float = DEFAULT_TOLERANCE
    angle_tolerance: float = DEFAULT_TOLERANCE

    @property
    def position(self) -> FloatArray:
        """Target position (3,), m."""
        return self.pose[:3, 3].copy()


@dataclass(frozen=True)
class CartesianPath:
    """A named sequence of waypoints (position-only or full poses), SI units."""

    name: str
    mode: str
    poses: FloatArray  # (N, 4, 4)
    tolerance: float = DEFAULT_TOLERANCE


@dataclass(frozen=True)
class Problem:
    """A robot with its named targets and paths, as read from a problem file."""

    name: str
    robot: Robot
    source: str
    path: Path | None = None
    description: str = ""
    targets: dict[str, Target] = field(default_factory=dict)
    paths: dict[str, CartesianPath] = field(default_factory=dict)


class _Reader:
    """Field access that reports the file, table and field of any error."""

    def __init__(self, path: str) -> None:
        self.path = path

    def fail(self, table: str, name: str, message: str) -> ProblemFileError:
        return ProblemFileError(self.path, table, name, message)

    def table(self, data: Mapping[str, Any], table: str, name: str) -> Mapping[str, Any]:
        value = data.get(name)
        if not isinstance(value, Mapping):
            raise self.fail(table, name, "missing or not a table")
        return value

    def string(
        self, data: Mapping[str, Any], table: str, name: str, default: str | None = None
    ) -> str:
        value = data.get(name, default)
        if value is None:
            raise self.fail(table, name, "missing (expected a non-empty string)")
        if not isinstance(value, str) or not value:
            raise self.fail(table, name, f"expected a non-empty string, got {value!r}")
        return value

    def choice(
        self, data: Mapping[str, Any], table: str, name: str, options: Any, default: str
    ) -> str:
        value = self.string(data, table, name, default)
        if value not in options:
            raise self.fail(table, name, f"{value!r} is not one of {sorted(options)}")
        return value

    def number(
        self,
        data: Mapping[str, Any],
        table: str,
        name: str,
        default: float | None = None,
        allow_inf: bool = False,
    ) -> float:
        value = data.get(name, default)
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise self.fail(table, name, f"expected a number, got {value!r}")
        try:
            value = float(value)
        except OverflowError:  # a TOML integer beyond float64 (1 followed by 400 zeros)
            digits = len(str(abs(value)))
            raise self.fail(
                table, name, f"expected a finite number, got an integer of {digits} digits"
            ) from None
        if math.isnan(value) or (math.isinf(value) and not allow_inf):
            raise self.fail(table, name, f"expected a finite number, got {value!r}")
        return value

    def length(
        self, data: Mapping[str, Any], table: str, name: str, scale: float, default: float = 0.0
    ) -> float:
        """A length field in SI units (``scale`` converts the file's unit to m), bounded."""
        value = self.number(data, table, name, default) * scale
        if abs(value) > MAX_LENGTH_M:
            raise self.fail(table, name, f"{value:g} m is beyond the {MAX_LENGTH_M:g} m bound")
        return value

    def lengths(
        self, data: Mapping[str, Any], table: str, name: str, size: int, scale: float
    ) -> FloatArray:
        """A vector of lengths in SI units, each bounded by ``MAX_LENGTH_M``."""
        out = self.vector(data, table, name, size) * scale
        for i, value in enumerate(out.tolist()):
            if abs(value) > MAX_LENGTH_M:
                raise self.fail(
                    table, f"{name}[{i}]", f"{value:g} m is beyond the {MAX_LENGTH_M:g} m bound"
                )
        return out

    def vector(self, data: Mapping[str, Any], table: str, name: str, size: int) -> FloatArray:
        value = data.get(name)
        if not isinstance(value, list) or len(value) != size:
            raise self.fail(table, name, f"expected a list of {size} numbers, got {value!r}")
        out = np.empty(size)
        for i, item in enumerate(value):
            out[i] = self.number({f"{name}[{i}]": item}, table, f"{name}[{i}]")
        return out

    def check_keys(self, data: Mapping[str, Any], table: str, allowed: set[str]) -> None:
        unknown = sorted(set(data) - allowed)
        if unknown:
            raise self.fail(table, unknown[0], f"unknown field (allowed: {sorted(allowed)})")


_JOINT_KEYS = {
    "name",
    "type",
    "role",
    "a",
    "alpha",
    "d",
    "theta",
    "lower",
    "upper",
    "continuous",
    "mimic",
    "velocity",
    "acceleration",
}
_ROBOT_KEYS = {
    "name",
    "convention",
    "length_unit",
    "angle_unit",
    "source",
    "analytic",
    "joints",
    "base",
    "tool",
    "urdf",
    "base_link",
    "tip_link",
    "description",
}


def _frame(reader: _Reader, data: Any, table: str, length: float, angle: float) -> FloatArray:
    if not isinstance(data, Mapping):
        raise reader.fail(table, "", "must be a table with translation and/or rpy")
    reader.check_keys(data, table, {"translation", "rpy"})
    p = reader.lengths(data, table, "translation", 3, length) if "translation" in data else None
    rpy = reader.vector(data, table, "rpy", 3) * angle if "rpy" in data else np.zeros(3)
    return transform(rpy_to_matrix(*rpy), p)


def _joint(
    reader: _Reader, data: Any, index: int, length: float, angle: float, modified: bool
) -> DHJoint:
    table = f"robot.joints[{index}]"
    if not isinstance(data, Mapping):
        raise reader.fail(table, "", "each [[robot.joints]] entry must be a table")
    reader.check_keys(data, table, _JOINT_KEYS)
    name = reader.string(data, table, "name", f"j{index + 1}")
    kind = reader.choice(data, table, "type", {"revolute", "prismatic"}, "revolute")
    role = data.get("role")
    if role is not None and role not in ("arm", "wrist", "spindle"):
        raise reader.fail(table, "role", f"{role!r} is not one of arm, wrist, spindle")
    limit_scale = length if kind == "prismatic" else angle
    bounds: list[float | None] = []
    for key in ("lower", "upper"):
        if key in data:
            bound = reader.number(data, table, key, allow_inf=True) * limit_scale
            if kind == "prismatic" and abs(bound) > MAX_LENGTH_M:
                raise reader.fail(
                    table, key, f"a prismatic range must lie within +-{MAX_LENGTH_M:g} m"
                )
            bounds.append(bound)
        else:
            bounds.append(None)
    lower, upper = bounds
    if (lower is None) != (upper is None):
        given, missing = ("lower", "upper") if upper is None else ("upper", "lower")
        raise reader.fail(table, missing, f"missing: {given} is given, so give both or neither")
    if lower is not None and upper is not None and lower > upper:
        raise reader.fail(
            table, "upper", f"{data['upper']!r:.40} is below lower {data['lower']!r:.40}"
        )
    continuous = data.get("continuous", False)
    if not isinstance(continuous, bool):
        raise reader.fail(table, "continuous", f"expected true or false, got {continuous!r}")
    mimic = None
    if "mimic" in data:
        m = data["mimic"]
        if not isinstance(m, Mapping):
            raise reader.fail(table, "mimic", "expected { joint = <name>, multiplier = <x> }")
        reader.check_keys(m, f"{table}.mimic", {"joint", "multiplier"})
        if "joint" not in m:
            raise reader.fail(table, "mimic", "expected { joint = <name>, multiplier = <x> }")
        mimic = Mimic(
            reader.string(m, f"{table}.mimic", "joint"),
            reader.number(m, f"{table}.mimic", "multiplier", 1.0),
        )
    rates: list[float | None] = []
    for key in ("velocity", "acceleration"):  # per second and per second squared
        rate = reader.number(data, table, key) * limit_scale if key in data else None
        if rate is not None and rate <= 0:
            raise reader.fail(table, key, f"must be positive, got {data[key]!r}")
        rates.append(rate)
    del modified  # the row format is the same for both conventions
    return DHJoint(
        a=reader.length(data, table, "a", length),
        alpha=reader.number(data, table, "alpha", 0.0) * angle,
        d=reader.length(data, table, "d", length),
        theta=reader.number(data, table, "theta", 0.0) * angle,
        kind=kind,  # type: ignore[arg-type]
        name=name,
        role=role,
        lower=bounds[0],
        upper=bounds[1],
        continuous=continuous,
        mimic=mimic,
        velocity=rates[0],
        acceleration=rates[1],
    )


def _check_names(reader: _Reader, rows: list[DHJoint]) -> None:
    """Each joint's name once, and each mimic naming another joint of the table."""
    names = [row.name or f"j{i + 1}" for i, row in enumerate(rows)]  # as _joint names them
    index: dict[str, int] = {}
    for i, name in enumerate(names):
        if name in index:
            raise reader.fail(
                f"robot.joints[{i}]", "name", f"{name!r} is joint {index[name]}'s name too"
            )
        index[name] = i
    for i, row in enumerate(rows):
        if row.mimic is not None and (row.mimic.joint not in index or row.mimic.joint == names[i]):
            others = [name for name in names if name != names[i]]
            raise reader.fail(
                f"robot.joints[{i}].mimic",
                "joint",
                f"{row.mimic.joint!r} is not another joint of this table (joints: {others})",
            )


_JOINT_PREFIX = re.compile(r"joint '([^']*)': ")


def _joint_error(reader: _Reader, rows: list[DHJoint], exc: OptikError) -> ProblemFileError:
    """The model's error at the row it names (``joint 'NAME': ...``), else at the table."""
    found = _JOINT_PREFIX.match(str(exc))
    if found is not None:
        for i, row in enumerate(rows):
            if row.name == found.group(1):
                return reader.fail(f"robot.joints[{i}]", "", str(exc)[found.end() :])
    return reader.fail("robot", "joints", str(exc))


def _robot(
    reader: _Reader, data: Mapping[str, Any], base_dir: Path, default_source: str | None = None
) -> tuple[Robot, str]:
    robot = reader.table(data, "", "robot")
    reader.check_keys(robot, "robot", _ROBOT_KEYS)
    name = reader.string(robot, "robot", "name")
    convention = reader.choice(robot, "robot", "convention", CONVENTIONS, "dh")
    length = LENGTH_UNITS[reader.choice(robot, "robot", "length_unit", LENGTH_UNITS, "m")]
    angle = ANGLE_UNITS[reader.choice(robot, "robot", "angle_unit", ANGLE_UNITS, "rad")]
    if "source" not in robot and default_source is None:
        # A robot table alone (optik robot, --dh) needs none; a problem file cites one.
        raise reader.fail(
            "robot", "source", "missing: a problem file names where its robot comes from "
            '(source = "..."); a robot table without one loads with --dh FILE',
        )  # fmt: skip
    source = reader.string(robot, "robot", "source", default_source)
    analytic = robot.get("analytic")
    if analytic is not None and not isinstance(analytic, str):
        raise reader.fail("robot", "analytic", f"expected a family name, got {analytic!r}")
    base = _frame(reader, robot["base"], "robot.base", length, angle) if "base" in robot else None
    tool = _frame(reader, robot["tool"], "robot.tool", length, angle) if "tool" in robot else None
    rows: list[DHJoint] = []
    try:
        if convention == "urdf":
            if "joints" in robot:
                raise reader.fail("robot", "joints", "a urdf robot takes its joints from the file")
            urdf = base_dir / reader.string(robot, "robot", "urdf")
            if not _is_file(urdf):
                raise reader.fail("robot", "urdf", f"{not_a_file(urdf)}: {urdf}")
            base_link = reader.string(robot, "robot", "base_link")
            tip_link = reader.string(robot, "robot", "tip_link")
            try:
                model = Robot.from_urdf(
                    urdf, base_link, tip_link, name=name, tool=tool, analytic=analytic
                )
            except AnalyticIKError as exc:  # the declared family does not fit
                raise reader.fail("robot", "analytic", str(exc)) from exc
            except OptikError as exc:
                raise reader.fail("robot", "urdf", str(exc)) from exc
            if base is not None:
                raise reader.fail("robot", "base", "not supported for urdf robots")
            return model, source
        for key in ("urdf", "base_link", "tip_link"):
            if key in robot:  # read only by a urdf robot: not silently dropped
                raise reader.fail(
                    "robot", key, f'belongs to convention = "urdf", not {convention!r}'
                )
        joints = robot.get("joints")
        if not isinstance(joints, list) or not joints:
            raise reader.fail("robot", "joints", "expected one or more [[robot.joints]] tables")
        rows = [
            _joint(reader, j, i, length, angle, convention == "mdh") for i, j in enumerate(joints)
        ]
        _check_names(reader, rows)
        build = Robot.from_mdh if convention == "mdh" else Robot.from_dh
        return build(rows, name=name, base=base, tool=tool, analytic=analytic), source
    except ProblemFileError:
        raise
    except AnalyticIKError as exc:  # the declared family does not fit
        raise reader.fail("robot", "analytic", str(exc)) from exc
    except OptikError as exc:
        raise _joint_error(reader, rows, exc) from exc


def _pose_from(
    reader: _Reader, data: Mapping[str, Any], table: str, length: float, angle: float
) -> tuple[str, FloatArray]:
    position = reader.lengths(data, table, "position", 3, length)
    if "rpy" in data:
        R = rpy_to_matrix(*(reader.vector(data, table, "rpy", 3) * angle))
        return "pose", transform(R, position)
    return "position", transform(None, position)


def _named_tables(
    reader: _Reader, data: Mapping[str, Any], key: str, keys: set[str]
) -> Iterator[tuple[str, Mapping[str, Any], str]]:
    """``(table label, table, name)`` of each ``[[key]]`` table, checked; names unique."""
    items = data.get(key, [])
    if not isinstance(items, list):
        raise reader.fail("", key, f"expected [[{key}]] tables")
    names: set[str] = set()
    for i, item in enumerate(items):
        table = f"{key}[{i}]"
        if not isinstance(item, Mapping):
            raise reader.fail(table, "", "must be a table")
        reader.check_keys(item, table, keys)
        name = reader.string(item, table, "name")
        if name in names:
            raise reader.fail(table, "name", f"duplicate {key[:-1]} name {name!r}")
        names.add(name)
        yield table, item, name


def _targets(
    reader: _Reader, data: Mapping[str, Any], length: float, angle: float
) -> dict[str, Target]:
    out: dict[str, Target] = {}
    keys = {"name", "position", "rpy", "tolerance", "angle_tolerance"}
    for table, item, name in _named_tables(reader, data, "targets", keys):
        mode, pose = _pose_from(reader, item, table, length, angle)
        tol = reader.number(item, table, "tolerance", DEFAULT_TOLERANCE / length) * length
        atol = reader.number(item, table, "angle_tolerance", DEFAULT_TOLERANCE / angle) * angle
        for key, value in (("tolerance", tol), ("angle_tolerance", atol)):
            if value <= 0:
                raise reader.fail(table, key, f"tolerances must be positive, got {value:g}")
        out[name] = Target(name, mode, pose, tol, atol)
    return out


def _paths(
    reader: _Reader, data: Mapping[str, Any], length: float, angle: float
) -> dict[str, CartesianPath]:
    out: dict[str, CartesianPath] = {}
    keys = {"name", "positions", "rpy", "tolerance"}
    for table, item, name in _named_tables(reader, data, "paths", keys):
        points = item.get("positions")
        if not isinstance(points, list) or not points:
            raise reader.fail(table, "positions", "expected a non-empty list of [x, y, z]")
        rpys = item.get("rpy")
        if rpys is not None and (not isinstance(rpys, list) or len(rpys) != len(points)):
            raise reader.fail(table, "rpy", "expected one [r, p, y] per position")
        poses = np.empty((len(points), 4, 4))
        for k, point in enumerate(points):
            entry: dict[str, Any] = {"position": point}
            if rpys is not None:
                entry["rpy"] = rpys[k]
            _, poses[k] = _pose_from(reader, entry, f"{table}.positions[{k}]", length, angle)
        tol = reader.number(item, table, "tolerance", DEFAULT_TOLERANCE / length) * length
        if tol <= 0:
            raise reader.fail(table, "tolerance", "tolerances must be positive")
        out[name] = CartesianPath(name, "pose" if rpys else "position", poses, tol)
    return out


def load_problem(path: str | Path) -> Problem:
    """Read and validate a problem file; SI units throughout the result.

    Args:
        path: a ``.toml`` file, or the name of a built-in problem (e.g. ``"puma560"``).

    Raises:
        ProblemFileError: ``path`` is not a path, the file is missing, unreadable, not
            UTF-8 or not TOML, has an unknown key in any table, or has a bad field (a
            ``continuous`` that is not a TOML boolean, a length beyond
            :data:`~optik._checks.MAX_LENGTH_M`, ...); the message names the file, the table
            and the field.
    """
    return _load(path, default_source=None)


def load_robot(path: str | Path) -> Problem:
    """Read a robot file: a problem file whose ``[robot]`` table may omit ``source``.

    A DH table for ``optik --dh FILE`` is such a file: a ``[robot]`` table (``name``,
    ``convention = "dh"`` or ``"mdh"``, units, ``base``, ``tool``) and its
    ``[[robot.joints]]`` rows, exactly as in a problem file; targets and paths are read if
    present. A missing ``source`` reads as ``"robot file <path>"``.

    Args:
        path: a ``.toml`` file, or the name of a built-in problem.

    Raises:
        ProblemFileError: as :func:`load_problem`.
    """
    return _load(path, default_source="")


def _is_file(path: Path) -> bool:
    """``path.is_file()``, false for a path the system cannot look up (too long, NUL)."""
    try:
        return path.is_file()
    except (OSError, ValueError):
        return False


def _load(path: str | Path, default_source: str | None) -> Problem:
    if not isinstance(path, str | os.PathLike) or isinstance(path, bytes):
        raise ProblemFileError(
            repr(path), "", "", "path: expected a file path or the name of a built-in problem"
        )
    if not str(path):  # Path("") is "." (the working folder)
        raise ProblemFileError("''", "", "", "path: empty (expected a file path or a name)")
    file = Path(path)
    if not _is_file(file) and file.suffix == "" and _is_file(PROBLEMS_DIR / f"{file}.toml"):
        file = PROBLEMS_DIR / f"{file}.toml"
    reader = _Reader(str(file))
    if not _is_file(file):
        reason = not_a_file(file)
        if reason == "file not found":
            reason += " (or a path the system cannot look up)" + _hint(file)
        raise reader.fail("", "", reason)
    try:
        text = file.read_text(encoding="utf-8")
    except UnicodeDecodeError as exc:
        raise reader.fail("", "", f"not a UTF-8 text file: {exc}") from exc
    except OSError as exc:
        raise reader.fail("", "", f"cannot read the file: {exc}") from exc
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise reader.fail("", "", f"not valid TOML: {exc}") from exc
    reader.check_keys(data, "", {"robot", "targets", "paths", "description"})
    if default_source is not None:
        default_source = f"robot file {file}"
    robot, source = _robot(reader, data, file.parent, default_source)
    robot_table = data["robot"]
    length = LENGTH_UNITS[robot_table.get("length_unit", "m")]
    angle = ANGLE_UNITS[robot_table.get("angle_unit", "rad")]
    description = data.get("description", "")
    if not isinstance(description, str):
        raise reader.fail("", "description", "expected a string")
    return Problem(
        name=robot.name,
        robot=robot,
        source=source,
        path=file,
        description=description,
        targets=_targets(reader, data, length, angle),
        paths=_paths(reader, data, length, angle),
    )


def _hint(file: Path) -> str:
    """For a bare name that is not a file: the built-in problems, the nearest first if close."""
    if file.suffix or len(file.parts) != 1:
        return ""
    names = [p.stem for p in builtin_problems()]
    close = difflib.get_close_matches(file.name[:200], names, n=1)
    guess = f"; did you mean {close[0]!r}?" if close else ""
    return f", nor the name of a built-in problem{guess} (built-in problems: {', '.join(names)})"


def builtin_problems() -> list[Path]:
    """Paths of the problem files shipped in ``problems/``, sorted by name."""
    return sorted(PROBLEMS_DIR.glob("*.toml"))
