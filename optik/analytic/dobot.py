"""DOBOT Magician (seed 001, section 2.2): position plus the servo rotation.

The parallelogram keeps the forearm's angle to the horizontal equal to the motor angle
J3, so with the shoulder height ``h``, rear arm ``L1`` (from the vertical, J2) and
forearm ``L2`` (from the horizontal, J3), the wrist point is::

    r = L1 sin J2 + L2 cos J3,   z - h = L1 cos J2 - L2 sin J3,   (x, y) = r (cos J1, sin J1)

``J1 = atan2(y, x)`` (and ``+ pi`` with ``r < 0``). Eliminating J3 gives the trig equation
``(2 L1 z') cos J2 + (2 L1 r) sin J2 = r^2 + z'^2 + L1^2 - L2^2`` with ``z' = z - h``, then
``J3 = atan2(L1 cos J2 - z', r - L1 sin J2)``. The flange stays level and its yaw is
``J1 + J4``, which fixes J4 in pose mode; in position mode J4 keeps its reference value.
"""

from __future__ import annotations

import math

import numpy as np

from optik._checks import FloatArray
from optik.analytic._base import AnalyticFamily, angles, dh_rows, register
from optik.model import Robot

ON_AXIS_TOL = 1e-12
"""A flange this close to the base axis (relative to the arm's length ``L1 + L2``) is on
it: its azimuth is rounding's, and J1, free there, keeps its reference."""

_PATTERN = (
    # (alpha deg, theta deg, mimic of, multiplier)
    (-90.0, 0.0, None, None),
    (0.0, -90.0, None, None),
    (0.0, 90.0, "J2", -1.0),
    (0.0, 0.0, None, None),
    (90.0, 0.0, "J3", -1.0),
    (0.0, 0.0, None, None),
)


@register
class Dobot(AnalyticFamily):
    """The DOBOT Magician chain of problems/dobot_magician.toml (any link lengths)."""

    name = "dobot"
    modes = ("position", "pose")

    def fits(self, robot: Robot) -> bool:
        """Six DH rows with the parallelogram pattern and four coordinates."""
        rows = dh_rows(robot)
        if robot.convention != "dh" or robot.dof != 4 or len(rows) != 6:
            return False
        names = robot.chain_names
        for row, (alpha, theta, of, mult) in zip(rows, _PATTERN, strict=True):
            if row.kind != "revolute":
                return False
            if abs(row.alpha - math.radians(alpha)) > 1e-12:
                return False
            if abs(row.theta - math.radians(theta)) > 1e-12:
                return False
            if of is None and row.mimic is not None:
                return False
            if of is not None:
                source = {"J2": names[1], "J3": names[3]}[of]
                if row.mimic is None or row.mimic.joint != source or row.mimic.multiplier != mult:
                    return False
        other = [
            rows[0].a,
            rows[1].d,
            rows[2].a,
            rows[2].d,
            rows[3].d,
            rows[4].a,
            rows[4].d,
            rows[5].a,
            rows[5].d,
        ]
        return all(abs(v) < 1e-12 for v in other)

    def candidates(
        self, robot: Robot, T_0_target: FloatArray, mode: str, q_ref: FloatArray
    ) -> list[FloatArray]:
        """Up to four position branches (two of them with the arm reaching backwards)."""
        rows = dh_rows(robot)
        h, L1, L2 = rows[0].d, rows[1].a, rows[3].a
        x, y, z = (float(v) for v in T_0_target[:3, 3])
        zp = z - h
        radius = math.hypot(x, y)
        yaw = math.atan2(float(T_0_target[1, 0]), float(T_0_target[0, 0]))
        j1_free = float(q_ref[0])
        if radius <= ON_AXIS_TOL * (abs(L1) + abs(L2)):
            # Over the base axis (its azimuth is rounding's): J1 is free, at its reference.
            radius = 0.0
        out = []
        for r in (radius, -radius) if radius > 0 else (0.0,):
            j1 = math.atan2(y, x) if r > 0 else (math.atan2(-y, -x) if r < 0 else j1_free)
            rhs = r * r + zp * zp + L1 * L1 - L2 * L2
            for j2 in angles(2 * L1 * zp, 2 * L1 * r, rhs, float(q_ref[1])):
                j3 = math.atan2(L1 * math.cos(j2) - zp, r - L1 * math.sin(j2))
                j4 = yaw - j1 if mode == "pose" else float(q_ref[3])
                out.append(np.array([j1, j2, j3, j4]))
        return out
