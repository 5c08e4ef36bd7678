"""UR-type arms: three parallel axes (joints 2-4) and no spherical wrist.

The DH structure of Universal Robots' arms (``alpha = 90, 0, 0, 90, -90, 0`` deg,
``a1 = a4 = a5 = a6 = 0``). With ``h = d2 + d3 + d4`` (the offset along the parallel axes):

1. ``p5 = p - d6 z6``; joint 1 from ``s1 p5x - c1 p5y = h`` (two shoulders).
2. In frame 1 (``T_16 = A1^-1 T``): ``cos q5 = T_16[2, 2]`` and
   ``sin q5 (cos q6, -sin q6) = T_16[2, :2]``, so ``q5 = atan2(+-|T_16[2, :2]|, T_16[2, 2])``
   (two wrists) and ``q6 = atan2(-+T_16[2, 1], +-T_16[2, 0])`` (free when ``sin q5 = 0``).
3. ``T_14 = T_16 A6^-1 A5^-1``; joints 2 and 3 are a planar two-link arm reaching the
   origin of frame 4 (two elbows) and ``q4 = atan2(T_14[1, 0], T_14[0, 0]) - q2 - q3``.

Up to eight branches, all from the trig equation and atan2.
"""

from __future__ import annotations

import math

import numpy as np

from optik._checks import FloatArray
from optik.analytic._base import AnalyticFamily, angles, dh_matrix, dh_rows, register
from optik.model import Robot
from optik.spatial import invert_transform

_ALPHAS_DEG = (90.0, 0.0, 0.0, 90.0, -90.0, 0.0)
_SINGULAR = 1e-10


@register
class URArm(AnalyticFamily):
    """Universal Robots-type 6R arms (UR3/5/10 and e-series share the structure)."""

    name = "ur"
    modes = ("pose",)

    def fits(self, robot: Robot) -> bool:
        """Six revolute DH joints with the UR twists and zero ``a1, a4, a5, a6``."""
        rows = dh_rows(robot)
        if robot.convention != "dh" or robot.dof != 6 or len(rows) != 6:
            return False
        return (
            all(r.kind == "revolute" and r.mimic is None for r in rows)
            and all(
                abs(r.alpha - math.radians(a)) < 1e-12
                for r, a in zip(rows, _ALPHAS_DEG, strict=True)
            )
            and all(abs(rows[i].a) < 1e-12 for i in (0, 3, 4, 5))
        )

    def candidates(
        self, robot: Robot, T_0_target: FloatArray, mode: str, q_ref: FloatArray
    ) -> list[FloatArray]:
        """Up to eight branches: two shoulders x two wrists x two elbows."""
        rows = dh_rows(robot)
        r1, r2, r3, r4, r5, r6 = rows
        h = r2.d + r3.d + r4.d
        p5 = T_0_target[:3, 3] - r6.d * T_0_target[:3, 2]
        out = []
        for t1 in angles(-float(p5[1]), float(p5[0]), h, r1.theta + float(q_ref[0])):
            T_16 = invert_transform(dh_matrix(r1, t1 - r1.theta)) @ T_0_target
            # cos q5 = T_16[2, 2] and sin q5 (c6, -s6) = T_16[2, :2]: atan2 of both keeps
            # q5 accurate near 0 and pi, where the cosine alone is flat.
            s5_mag = math.hypot(float(T_16[2, 0]), float(T_16[2, 1]))
            c5 = float(T_16[2, 2])
            if s5_mag < _SINGULAR:
                wrists = [(math.atan2(0.0, c5), r6.theta + float(q_ref[5]))]
            else:
                wrists = [
                    (
                        math.atan2(sign * s5_mag, c5),
                        math.atan2(-sign * float(T_16[2, 1]), sign * float(T_16[2, 0])),
                    )
                    for sign in (1.0, -1.0)
                ]
            for t5, t6 in wrists:
                A5 = dh_matrix(r5, t5 - r5.theta)
                A6 = dh_matrix(r6, t6 - r6.theta)
                T_14 = T_16 @ invert_transform(A6) @ invert_transform(A5)
                x, y = float(T_14[0, 3]), float(T_14[1, 3])
                a2, a3 = r2.a, r3.a
                t234 = math.atan2(float(T_14[1, 0]), float(T_14[0, 0]))
                for t3 in angles(
                    2 * a2 * a3, 0.0, x * x + y * y - a2 * a2 - a3 * a3, r3.theta + float(q_ref[2])
                ):
                    t2 = math.atan2(y, x) - math.atan2(a3 * math.sin(t3), a2 + a3 * math.cos(t3))
                    t4 = t234 - t2 - t3
                    q = np.array([t1, t2, t3, t4, t5, t6]) - np.array([r.theta for r in rows])
                    out.append(q)
        return out
