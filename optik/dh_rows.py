"""Denavit–Hartenberg rows read into the chain's links (standard and modified DH).

:class:`DHJoint` is one row; :func:`dh_row` validates a row given as a ``DHJoint`` or a
mapping, :func:`checked_dh_rows` a table, and :func:`dh_links` turns the rows into the
:class:`optik.chain.ChainLink` s of the product ``K[0] M(t_1) K[1] ... M(t_n) K[n]`` that
:class:`optik.model.Robot` builds from every source.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from optik._checks import (
    FloatArray,
    check_bool,
    check_length,
    check_real,
)
from optik.chain import ChainLink, JointKind, Mimic
from optik.chain_checks import JOINT_KINDS
from optik.errors import ArgumentError, InvalidLimitsError, ModelError, OptikError
from optik.spatial import rot_x, rot_z, transform

_KINDS = JOINT_KINDS


@dataclass(frozen=True)
class DHJoint:
    """One row of a (standard or modified) Denavit–Hartenberg table, SI units.

    The joint variable adds to ``theta`` (revolute) or ``d`` (prismatic); the stated
    value of that parameter is the constant offset at ``q = 0``.

    Attributes:
        a: link length (m).
        alpha: link twist (rad).
        d: link offset (m); the offset of a prismatic joint.
        theta: joint angle (rad); the offset of a revolute joint.
        kind: ``"revolute"`` or ``"prismatic"``.
        name: joint name (default ``"j<i>"``, 1-based).
        role: ``"arm"``, ``"wrist"``, ``"spindle"`` or ``None`` (default limits).
        lower: lower limit (rad or m), ``None`` to use the role default.
        upper: upper limit (rad or m), ``None`` to use the role default.
        continuous: an unbounded revolute joint.
        mimic: make this a passive joint driven by another joint.
        velocity: speed limit (rad/s or m/s), ``None`` when unknown.
        acceleration: acceleration limit (rad/s² or m/s²), ``None`` when unknown.
    """

    a: float = 0.0
    alpha: float = 0.0
    d: float = 0.0
    theta: float = 0.0
    kind: JointKind = "revolute"
    name: str | None = None
    role: str | None = None
    lower: float | None = None
    upper: float | None = None
    continuous: bool = False
    mimic: Mimic | None = None
    velocity: float | None = None
    acceleration: float | None = None


_ChainLink = ChainLink  # the DH and URDF readers build these


def _tz(d: float) -> FloatArray:
    return transform(translation=(0.0, 0.0, d))


def _tx(a: float) -> FloatArray:
    return transform(translation=(a, 0.0, 0.0))


def _rz(t: float) -> FloatArray:
    return transform(rot_z(t))


def _rx(t: float) -> FloatArray:
    return transform(rot_x(t))


def joint_motion(kind: str, t: float) -> FloatArray:
    """The motion (4, 4) of a joint at ``t``: a turn about z (rad) or a slide along z (m)."""
    return _tz(t) if kind == "prismatic" else _rz(t)


def _row_field(label: str, key: str, check: Any, value: Any) -> Any:
    """Run one validator on a DH row's field, reporting a failure as a ModelError."""
    try:
        return check(key, value)
    except OptikError as exc:
        raise ModelError(f"{label}: {exc}") from exc


def _optional_str(name: str, value: Any) -> str | None:
    if value is not None and (not isinstance(value, str) or not value):
        raise ArgumentError(name, value, "a non-empty string or None")
    return value


def _limit(joint: str, lower: Any, upper: Any) -> tuple[float | None, float | None]:
    # NaN and infinite limits pass here: resolve_limits rejects them naming the joint.
    out = []
    for key, value in (("lower", lower), ("upper", upper)):
        try:
            out.append(
                None if value is None else check_real(key, value, allow_nan=True, allow_inf=True)
            )
        except OptikError as exc:
            raise InvalidLimitsError(joint, lower, upper, str(exc)) from exc
    return out[0], out[1]


def _mimic(label: str, value: Any) -> Mimic | None:
    if value is None:
        return None
    if isinstance(value, Mapping):
        unknown = sorted(map(str, set(value) - {"joint", "multiplier"}))
        if unknown or "joint" not in value:
            raise ModelError(
                f"{label}: mimic must be {{joint = <name>, multiplier = <x>}}, "
                f"got keys {sorted(map(str, value))}"
            )
        value = Mimic(value["joint"], value.get("multiplier", 1.0))
    if not isinstance(value, Mimic):
        raise ModelError(f"{label}: mimic must be a Mimic or a mapping, got {value!r}")
    joint = _row_field(label, "mimic.joint", _optional_str, value.joint)
    if joint is None:
        raise ModelError(f"{label}: mimic.joint must name a joint")
    multiplier = _row_field(label, "mimic.multiplier", check_real, value.multiplier)
    return Mimic(joint, multiplier)


def dh_row(row: Any, index: int) -> DHJoint:
    """Validate one DH row (a :class:`DHJoint` or a mapping of its fields).

    Every field is checked, a :class:`DHJoint` built directly included: ``a`` and ``d``
    are lengths (finite, at most :data:`~optik._checks.MAX_LENGTH_M`), ``alpha`` and
    ``theta`` finite angles, ``kind`` a known joint type, ``continuous`` a real bool,
    limits real numbers (or ``None``), ``name`` and ``role`` strings (or ``None``).

    Raises:
        ModelError: naming the row, the joint and the field
            (:class:`~optik.errors.InvalidLimitsError` for a limit).
    """
    if isinstance(row, DHJoint):
        data = dict(row.__dict__)
    elif isinstance(row, Mapping):
        allowed = set(DHJoint.__dataclass_fields__) | {"type"}
        unknown = sorted(map(str, set(row) - allowed))
        if unknown:
            raise ModelError(f"DH row {index}: unknown keys {unknown}")
        data = dict(row)
        if "type" in data:
            if "kind" in data:
                raise ModelError(f"DH row {index}: give either 'type' or 'kind', not both")
            data["kind"] = data.pop("type")
    else:
        raise ModelError(f"DH row {index}: expected a mapping or DHJoint, got {type(row).__name__}")
    out: dict[str, Any] = {}
    out["name"] = _row_field(f"DH row {index}", "name", _optional_str, data.get("name"))
    joint = out["name"] or f"j{index + 1}"
    label = f"DH row {index} (joint {joint!r})"
    kind = data.get("kind", "revolute")
    if not isinstance(kind, str) or kind not in _KINDS:
        raise ModelError(f"{label}: unknown joint type {kind!r} (expected {_KINDS})")
    out["kind"] = kind
    for key in ("a", "d"):
        out[key] = _row_field(label, key, check_length, data.get(key, 0.0))
    for key in ("alpha", "theta"):
        out[key] = _row_field(label, key, check_real, data.get(key, 0.0))
    out["role"] = _row_field(label, "role", _optional_str, data.get("role"))
    out["lower"], out["upper"] = _limit(joint, data.get("lower"), data.get("upper"))
    out["continuous"] = _row_field(label, "continuous", check_bool, data.get("continuous", False))
    out["mimic"] = _mimic(label, data.get("mimic"))
    for key in ("velocity", "acceleration"):
        value = data.get(key)
        out[key] = None if value is None else _row_field(label, key, _positive, value)
    return DHJoint(**out)


def _positive(key: str, value: Any) -> float:
    return check_real(key, value, positive=True)


def checked_dh_rows(rows: Any) -> list[Any]:
    """The DH rows as a list; anything but a sequence of rows is a ModelError."""
    if isinstance(rows, str | bytes | Mapping | DHJoint) or not isinstance(rows, Sequence):
        raise ModelError(
            f"rows: expected a sequence of DH rows (DHJoint or mappings), got {rows!r:.80}"
        )
    return list(rows)


def _check_kind(name: str, kind: str) -> None:
    if kind not in _KINDS:
        raise ModelError(f"joint {name!r}: unknown joint type {kind!r} (expected {_KINDS})")


def dh_links(rows: Sequence[Any], modified: bool) -> list[_ChainLink]:
    """The chain links of DH ``rows`` (validated :class:`DHJoint` s); ``modified``: MDH."""
    links = []
    for i, raw in enumerate(rows):
        row = dh_row(raw, i)
        name = row.name or f"j{i + 1}"
        _check_kind(name, row.kind)
        offset = row.d if row.kind == "prismatic" else row.theta
        if modified:
            # Craig: A_i = Rx(alpha_{i-1}) Tx(a_{i-1}) Rz(theta_i) Tz(d_i); the motion is
            # about z_i after the fixed twist and length, so it comes last.
            if row.kind == "prismatic":
                before = _rx(row.alpha) @ _tx(row.a) @ _rz(row.theta)
            else:
                before = _rx(row.alpha) @ _tx(row.a) @ _tz(row.d)
            after = np.eye(4)
        else:
            # Standard: A_i = Rz(theta_i) Tz(d_i) Tx(a_i) Rx(alpha_i); Rz and Tz commute,
            # so the motion goes first and the rest is a constant link transform.
            fixed = _tz(row.d) if row.kind == "revolute" else _rz(row.theta)
            before = np.eye(4)
            after = fixed @ _tx(row.a) @ _rx(row.alpha)
        links.append(
            _ChainLink(
                name=name,
                kind=row.kind,
                before=before,
                after=after,
                offset=offset,
                mimic=row.mimic,
                role=row.role,
                lower=row.lower,
                upper=row.upper,
                continuous=row.continuous,
                velocity=row.velocity,
                acceleration=row.acceleration,
            )
        )
    return links


__all__ = ["DHJoint", "checked_dh_rows", "dh_links", "dh_row", "joint_motion"]
