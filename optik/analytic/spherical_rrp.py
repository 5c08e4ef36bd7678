"""The spherical RRP arm of seed 000 (jumbo drilling boom), derived from its A-matrices.

With ``0A1 = DH(q1, 0, a1, +90)``, ``1A2 = DH(q2, 0, 0, -90)``, ``2A3 = DH(0, d3, 0, +90)``
the product gives (see docs/errata.md for the printed form)::

    p = (-c1 (s2 d3 - a1), -s1 (s2 d3 - a1), c2 d3)
    R = [[c1 c2, -c1 s2,  s1],
         [s1 c2, -s1 s2, -c1],
         [s2,     c2,     0 ]]

Position only (eq. 26-34): ``s1 px - c1 py = 0`` gives two ``q1``;
``s2 pz + (c1 px + s1 py - a1) c2 = 0`` gives two ``q2`` for each; then
``d3 = (a1 - c1 px - s1 py) s2 + pz c2``: four branches. Full pose (eq. 35-42, corrected):
``q1 = atan2(Ax, -Ay)``, ``q2 = atan2(Nz, Oz)``, ``d3`` as above: one branch.
"""

from __future__ import annotations

import math

import numpy as np

from optik._checks import FloatArray
from optik.analytic._base import AnalyticFamily, angles, dh_rows, is_right_angle, register
from optik.model import Robot


@register
class SphericalRRP(AnalyticFamily):
    """Seed 000's spherical arm: revolute, revolute, prismatic."""

    name = "spherical_rrp"
    modes = ("position", "pose")

    def fits(self, robot: Robot) -> bool:
        """The exact DH structure of seed 000, section III (any ``a1``)."""
        rows = dh_rows(robot)
        if robot.convention != "dh" or robot.dof != 3 or len(rows) != 3:
            return False
        r1, r2, r3 = rows
        return (
            [r.kind for r in rows] == ["revolute", "revolute", "prismatic"]
            and all(r.mimic is None for r in rows)
            and (is_right_angle(r1.alpha), is_right_angle(r2.alpha), is_right_angle(r3.alpha))
            == (1, -1, 1)
            and r1.d == 0.0
            and r1.theta == 0.0
            and r2.a == 0.0
            and r2.d == 0.0
            and r2.theta == 0.0
            and r3.a == 0.0
            and r3.theta == 0.0
        )

    def candidates(
        self, robot: Robot, T_0_target: FloatArray, mode: str, q_ref: FloatArray
    ) -> list[FloatArray]:
        """Four position branches (eq. 27, 33, 34) or the unique pose branch (35-42)."""
        r1, _, r3 = dh_rows(robot)
        a1 = r1.a
        px, py, pz = (float(v) for v in T_0_target[:3, 3])
        if mode == "pose":
            R = T_0_target[:3, :3]
            q1s: tuple[float, ...] = (math.atan2(R[0, 2], -R[1, 2]),)
        else:
            q1s = angles(-py, px, 0.0, float(q_ref[0]))
        out = []
        for q1 in q1s:
            c1, s1 = math.cos(q1), math.sin(q1)
            if mode == "pose":
                R = T_0_target[:3, :3]
                q2s: tuple[float, ...] = (math.atan2(R[2, 0], R[2, 1]),)
            else:
                q2s = angles(c1 * px + s1 * py - a1, pz, 0.0, float(q_ref[1]))
            for q2 in q2s:
                c2, s2 = math.cos(q2), math.sin(q2)
                d3 = (a1 - c1 * px - s1 * py) * s2 + pz * c2
                out.append(np.array([q1, q2, d3 - r3.d]))
        return out
