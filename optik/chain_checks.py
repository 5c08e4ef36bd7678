"""Checks of the chain links a :class:`optik.Robot` is built from (:mod:`optik.chain`).

Every reader (DH rows, URDF) and a direct ``Robot(links)`` go through them: a link is a
:class:`~optik.chain.ChainLink` with rigid finite frames and a known joint kind; base and
tool frames are made exactly rigid; a prismatic mimic's stroke is bounded.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np

from optik._checks import MAX_LENGTH_M, FloatArray, check_real
from optik.chain import ChainLink
from optik.errors import ModelError, OptikError
from optik.spatial import as_pose

JOINT_KINDS = ("revolute", "prismatic")
"""The joint kinds of a chain link."""


def rigid(T: FloatArray) -> FloatArray:
    """``T`` with its rotation made exactly orthonormal (the nearest rotation, by SVD).

    :func:`optik.spatial.as_pose` accepts a rotation within its tolerance (1e-6); kept as
    given, a base or tool would scale the robot's own FK, which then fails that check.
    """
    R = T[:3, :3]
    if float(np.max(np.abs(R.T @ R - np.eye(3)))) <= 4e-16:
        return T  # orthonormal to rounding already: kept bit for bit
    U, _, Vt = np.linalg.svd(R)
    out = np.array(T, dtype=float)
    out[:3, :3] = U @ Vt
    return out


def checked_link(robot: str, i: int, link: Any) -> ChainLink:
    """``link`` checked as a chain link (rigid finite frames, a known kind), frames made rigid."""
    where = f"robot {robot!r}: link {i}"
    if not isinstance(link, ChainLink):
        raise ModelError(
            f"{where} is a {type(link).__name__}, expected a ChainLink (build robots "
            "from DH rows with Robot.from_dh or from_mdh, or with Robot.from_urdf)"
        )
    if not isinstance(link.name, str) or not link.name:
        raise ModelError(f"{where}: name must be a non-empty string, got {link.name!r}")
    where = f"robot {robot!r}: joint {link.name!r}"
    if link.kind not in JOINT_KINDS:
        raise ModelError(f"{where}: unknown joint type {link.kind!r} (expected {JOINT_KINDS})")
    try:
        offset = check_real("offset", link.offset)
        before = rigid(as_pose("before", link.before))
        after = rigid(as_pose("after", link.after))
    except OptikError as exc:
        raise ModelError(f"{where}: {exc}") from None
    for key in ("velocity", "acceleration"):
        value = getattr(link, key)
        if value is not None and not (
            isinstance(value, int | float) and not isinstance(value, bool) and value > 0.0
        ):
            raise ModelError(f"{where}: {key} must be a positive number or None, got {value!r}")
    return dataclasses.replace(link, offset=offset, before=before, after=after)


def check_mimic_range(
    link: ChainLink, driver: str, lower: float, upper: float, multiplier: float
) -> None:
    """A prismatic mimic's stroke stays within :data:`~optik._checks.MAX_LENGTH_M`.

    ``driver`` is the joint ``link`` follows, ``lower`` and ``upper`` its limits (rad).
    """
    if link.kind != "prismatic":
        return
    reach = max(abs(lower), abs(upper))
    if not math.isfinite(reach):
        raise ModelError(
            f"joint {link.name!r}: a prismatic joint cannot mimic {driver!r}, whose "
            "range is unbounded (its stroke would be too)"
        )
    if abs(multiplier) * reach > MAX_LENGTH_M:
        raise ModelError(
            f"joint {link.name!r}: mimic multiplier {multiplier:g} times the range of "
            f"{driver!r} makes a stroke beyond {MAX_LENGTH_M:g} m"
        )
