"""Planar two-link arm (seed 003): both elbow branches in closed form.

With link lengths ``a1, a2`` and the target ``(x, y)`` in the arm's plane,
``x^2 + y^2 = a1^2 + a2^2 + 2 a1 a2 cos q2`` is the trig equation
``(2 a1 a2) cos q2 + 0 sin q2 = x^2 + y^2 - a1^2 - a2^2`` (two elbow branches), and
``q1 = atan2(y, x) - atan2(a2 sin q2, a1 + a2 cos q2)`` (free, kept at its reference,
when ``a1 = a2`` and the arm folds onto the base).
"""

from __future__ import annotations

import math

import numpy as np

from optik._checks import FloatArray
from optik.analytic._base import AnalyticFamily, angles, dh_rows, register
from optik.model import Robot


@register
class Planar2R(AnalyticFamily):
    """Two parallel revolute joints (standard DH, ``alpha = 0``)."""

    name = "planar_2r"
    modes = ("position", "pose")

    def fits(self, robot: Robot) -> bool:
        """Two revolute DH joints with parallel axes and no coupling."""
        rows = dh_rows(robot)
        return (
            robot.convention == "dh"
            and robot.dof == 2
            and len(rows) == 2
            and all(r.kind == "revolute" and r.mimic is None and r.alpha == 0.0 for r in rows)
        )

    def candidates(
        self, robot: Robot, T_0_target: FloatArray, mode: str, q_ref: FloatArray
    ) -> list[FloatArray]:
        """Both elbow branches; the pose's orientation is checked by the caller's FK."""
        r1, r2 = dh_rows(robot)
        x, y = float(T_0_target[0, 3]), float(T_0_target[1, 3])
        a1, a2 = r1.a, r2.a
        out = []
        for t2 in angles(2.0 * a1 * a2, 0.0, x * x + y * y - a1 * a1 - a2 * a2, float(q_ref[1])):
            if math.hypot(x, y) <= 1e-12 * max(a1, a2, 1.0):
                # Folded onto the base axis (a1 = a2): every shoulder angle works.
                t1 = r1.theta + float(q_ref[0])
            else:
                t1 = math.atan2(y, x) - math.atan2(a2 * math.sin(t2), a1 + a2 * math.cos(t2))
            out.append(np.array([t1 - r1.theta, t2 - r2.theta]))
        return out
