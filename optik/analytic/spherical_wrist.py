"""Six-joint arms with a spherical wrist: the 3+3 partition of seed 000, section IV.

Requirements (standard DH): joints 4-6 revolute with ``a4 = a5 = d5 = a6 = 0`` and
``alpha4, alpha5 = +-90 deg``, so axes 4, 5, 6 meet at the wrist centre ``W = o4``; and an
arm whose first twist is ``+-90 deg`` and that is either articulated (RRR with joints 2
and 3 parallel, e.g. the Puma 560) or spherical (RRP with ``alpha2 = +-90 deg``, e.g. the
Stanford arm and the jumbo drill).

1. ``W = p - d6 R (0, sin alpha6, cos alpha6)``: the wrist centre from the target.
2. Arm joints from ``W = A1 A2 A3 (0, 0, d4)``: one trig equation for ``q1``
   (``-s1 Wx + c1 Wy = -sin(alpha1) h``, where ``h`` is the arm's constant offset along
   joint 2's axis), then the planar distance gives ``q3`` (RRR, a trig equation) or the
   stroke (RRP, a square root), then ``q2`` by one atan2 difference.
3. Wrist joints from ``R_36 = R_03^T R``: ``cos q5`` from one entry, ``q4`` by atan2 of a
   column, ``q6`` by atan2 of the residual rotation ``(A4 A5)^T R_36``; at ``sin q5 = 0``
   only ``q4 + q6`` is defined and ``q4`` takes its reference value.

Up to 2 x 2 x 2 = 8 branches, in this order: shoulder (the two roots of the ``q1``
equation, ascending), elbow (``q3`` roots ascending; for RRP the stroke root ``+L`` then
``-L``), wrist (``sin q5 >= 0`` first).

Robots built otherwise (URDF, modified DH) or whose table differs fit when their joint
axes do (revolute joints only): axes 4, 5 and 6 meet in one point with axis 5
perpendicular to axes 4 and 6, axis 2 perpendicular to axis 1, and axes 2 and 3 parallel
with the same direction. The equivalent table of :mod:`optik.analytic.geometry` then
carries the closed form.

The closed form is compiled: :func:`optik.analytic._compiled.spherical_wrist_candidates`
is its one implementation, and :func:`optik.analytic.analytic_ik` runs it together with
the wrapping, limit filter and FK check in one compiled call.
"""

from __future__ import annotations

from optik._checks import FloatArray
from optik.analytic import _compiled
from optik.analytic._base import (
    AnalyticFamily,
    deg,
    fit_model,
    is_right_angle,
    opposite,
    register,
    table_target,
)
from optik.analytic.geometry import DHModel
from optik.errors import AnalyticIKError
from optik.model import DHJoint, Robot

_EPS = 1e-12


def _zero(*values: float) -> bool:
    return all(abs(v) < _EPS for v in values)


def _arm_reason(rows: tuple[DHJoint, ...]) -> str | None:
    """Why the first three rows are neither an RRR (articulated) nor an RRP arm."""
    r1, r2, r3 = rows[:3]
    if r1.kind != "revolute" or r2.kind != "revolute":
        return "joints 1 and 2 must be revolute"
    if not is_right_angle(r1.alpha):
        return f"alpha1 = {deg(r1.alpha)}, needs +-90 deg (axes 1 and 2 perpendicular)"
    if r3.kind == "revolute" and not _zero(r2.alpha):
        return (
            f"alpha2 = {deg(r2.alpha)}, needs 0 (axes 2 and 3 parallel, same direction)"
            f"{opposite(r2.alpha)}"
        )
    if r3.kind == "prismatic" and not is_right_angle(r2.alpha):
        return f"alpha2 = {deg(r2.alpha)}, needs +-90 deg (joint 3 sliding across axis 2)"
    return None


def rows_reason(rows: tuple[DHJoint, ...]) -> str | None:
    """Why a DH table has no spherical wrist of this family, or ``None`` when it has."""
    if len(rows) != 6:
        return f"{len(rows)} DH rows (the family takes 6)"
    if any(r.mimic is not None for r in rows):
        return "coupled (mimic) joints"
    r4, r5, r6 = rows[3:]
    if not all(r.kind == "revolute" for r in rows[3:]):
        return "joints 4 to 6 must be revolute"
    if not _zero(r4.a):
        return f"a4 = {r4.a:.6g} m: axes 4 and 5 do not intersect"
    if not _zero(r5.a, r5.d):
        return f"a5 = {r5.a:.6g} m, d5 = {r5.d:.6g} m: axis 6 misses the point of axes 4, 5"
    if not _zero(r6.a):
        return f"a6 = {r6.a:.6g} m, needs 0"
    if not is_right_angle(r4.alpha):
        return f"alpha4 = {deg(r4.alpha)}, needs +-90 deg (axes 4 and 5 perpendicular)"
    if not is_right_angle(r5.alpha):
        return f"alpha5 = {deg(r5.alpha)}, needs +-90 deg (axes 5 and 6 perpendicular)"
    return _arm_reason(rows)


def _fit(robot: Robot) -> DHModel | str:
    return fit_model(robot, rows_reason, ())


@register
class SphericalWrist(AnalyticFamily):
    """6-dof arms (RRR or RRP arm) with a spherical wrist, by the 3+3 partition."""

    name = "spherical_wrist"
    modes = ("pose",)
    kernel = _compiled.SPHERICAL_WRIST

    def fits(self, robot: Robot) -> bool:
        """See the module docstring for the structure required."""
        return not isinstance(robot.cached(_fit), str)

    def explain(self, robot: Robot) -> str | None:
        """The first relation of the structure that fails, or ``None``."""
        found = robot.cached(_fit)
        return found if isinstance(found, str) else None

    def model(self, robot: Robot) -> DHModel:
        """The table of ``robot`` (its own rows or the equivalent from its axes)."""
        found = robot.cached(_fit)
        if isinstance(found, str):
            raise AnalyticIKError(f"robot {robot.name!r}: no spherical wrist family: {found}")
        return found

    def candidates(
        self, robot: Robot, T_0_target: FloatArray, mode: str, q_ref: FloatArray
    ) -> list[FloatArray]:
        """Up to eight branches: two shoulders x two elbows x two wrists."""
        T = table_target(robot, self.model(robot), T_0_target)
        return _compiled.raw_candidates(
            _compiled.spherical_wrist_candidates, robot, self.kernel, T, q_ref
        )
