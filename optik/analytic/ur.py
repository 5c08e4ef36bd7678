"""UR-type arms: three parallel axes (joints 2-4) and no spherical wrist.

The DH structure of Universal Robots' arms (``alpha = 90, 0, 0, 90, -90, 0`` deg,
``a1 = a4 = a5 = a6 = 0``). With ``h = d2 + d3 + d4`` (the offset along the parallel axes):

1. ``p5 = p - d6 z6``; joint 1 from ``s1 p5x - c1 p5y = h`` (two shoulders).
2. In frame 1 (``T_16 = A1^-1 T``): ``cos q5 = T_16[2, 2]`` and
   ``sin q5 (cos q6, -sin q6) = T_16[2, :2]``, so ``q5 = atan2(+-|T_16[2, :2]|, T_16[2, 2])``
   (two wrists) and ``q6 = atan2(-+T_16[2, 1], +-T_16[2, 0])`` (free when ``sin q5 = 0``).
3. ``T_14 = T_16 A6^-1 A5^-1``; joints 2 and 3 are a planar two-link arm reaching the
   origin of frame 4 (two elbows) and ``q4 = atan2(T_14[1, 0], T_14[0, 0]) - q2 - q3``.

Up to eight branches, all from the trig equation and atan2, in this order: shoulder
(``q1`` roots ascending), wrist (``sin q5 >= 0`` first), elbow (``q3`` roots ascending).

The closed form is compiled: :func:`optik.analytic._compiled.ur_candidates` is its one
implementation, and :func:`optik.analytic.analytic_ik` runs it together with the
wrapping, limit filter and FK check in one compiled call.
"""

from __future__ import annotations

import math

from optik._checks import FloatArray
from optik.analytic import _compiled
from optik.analytic._base import AnalyticFamily, dh_rows, register
from optik.model import Robot

_ALPHAS_DEG = (90.0, 0.0, 0.0, 90.0, -90.0, 0.0)


@register
class URArm(AnalyticFamily):
    """Universal Robots-type 6R arms (UR3/5/10 and e-series share the structure)."""

    name = "ur"
    modes = ("pose",)
    kernel = _compiled.UR

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
        return _compiled.raw_candidates(
            _compiled.ur_candidates, robot, self.kernel, T_0_target, q_ref
        )
