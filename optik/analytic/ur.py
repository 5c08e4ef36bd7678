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

Robots built otherwise (URDF, modified DH) or whose table differs fit when their joint
axes do: axes 1 and 2 perpendicular and intersecting, axes 2, 3 and 4 parallel with the
same direction, axis 5 perpendicular to axis 4 and meeting it, axis 6 perpendicular to
axis 5 and meeting it. The equivalent table of :mod:`optik.analytic.geometry` (twist signs
chosen as above) then carries the closed form.

The closed form is compiled: :func:`optik.analytic._compiled.ur_candidates` is its one
implementation, and :func:`optik.analytic.analytic_ik` runs it together with the
wrapping, limit filter and FK check in one compiled call.
"""

from __future__ import annotations

import math

from optik._checks import FloatArray
from optik.analytic import _compiled
from optik.analytic._base import (
    AnalyticFamily,
    deg,
    fit_model,
    opposite,
    register,
    table_target,
)
from optik.analytic.geometry import DHModel
from optik.errors import AnalyticIKError
from optik.model import DHJoint, Robot

_ALPHAS_DEG = (90.0, 0.0, 0.0, 90.0, -90.0, 0.0)
_SIGNS = (1, 0, 0, 1, -1)  # twist signs of the equivalent table: +90, -, -, +90, -90
_ALPHA_MEANING = (
    "axes 1 and 2 perpendicular",
    "axes 2 and 3 parallel, same direction",
    "axes 3 and 4 parallel, same direction",
    "axes 4 and 5 perpendicular",
    "axes 5 and 6 perpendicular",
    "no twist after axis 6",
)
_A_MEANING = {
    0: "axes 1 and 2 do not intersect",
    3: "axes 4 and 5 do not intersect",
    4: "axes 5 and 6 do not intersect",
    5: "the last frame is offset from axis 6",
}


def rows_reason(rows: tuple[DHJoint, ...]) -> str | None:
    """Why a DH table is not of the UR type, or ``None`` when it is."""
    if len(rows) != 6:
        return f"{len(rows)} DH rows (the UR type has 6)"
    for i, r in enumerate(rows):
        if r.kind != "revolute" or r.mimic is not None:
            return f"joint {i + 1} is not an independent revolute joint"
    for i, (r, a) in enumerate(zip(rows, _ALPHAS_DEG, strict=True)):
        if abs(r.alpha - math.radians(a)) >= 1e-12:
            return (
                f"alpha{i + 1} = {deg(r.alpha)}, needs {a:g} deg ({_ALPHA_MEANING[i]})"
                f"{opposite(r.alpha)}"
            )
    for i, meaning in _A_MEANING.items():
        if abs(rows[i].a) >= 1e-12:
            return f"a{i + 1} = {rows[i].a:.6g} m, needs 0 ({meaning})"
    return None


def _fit(robot: Robot) -> DHModel | str:
    return fit_model(robot, rows_reason, _SIGNS)


@register
class URArm(AnalyticFamily):
    """Universal Robots-type 6R arms (UR3/5/10 and e-series share the structure)."""

    name = "ur"
    modes = ("pose",)
    kernel = _compiled.UR

    def fits(self, robot: Robot) -> bool:
        """The UR structure, in the robot's DH rows or in its joint axes."""
        return not isinstance(robot.cached(_fit), str)

    def explain(self, robot: Robot) -> str | None:
        """The first UR relation that fails, or ``None``."""
        found = robot.cached(_fit)
        return found if isinstance(found, str) else None

    def model(self, robot: Robot) -> DHModel:
        """The UR table of ``robot`` (its own rows or the equivalent from its axes)."""
        found = robot.cached(_fit)
        if isinstance(found, str):
            raise AnalyticIKError(f"robot {robot.name!r} is not of the UR type: {found}")
        return found

    def candidates(
        self, robot: Robot, T_0_target: FloatArray, mode: str, q_ref: FloatArray
    ) -> list[FloatArray]:
        """Up to eight branches: two shoulders x two wrists x two elbows."""
        T = table_target(robot, self.model(robot), T_0_target)
        return _compiled.raw_candidates(_compiled.ur_candidates, robot, self.kernel, T, q_ref)
