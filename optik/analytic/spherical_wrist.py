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

The closed form is compiled: :func:`optik.analytic._compiled.spherical_wrist_candidates`
is its one implementation, and :func:`optik.analytic.analytic_ik` runs it together with
the wrapping, limit filter and FK check in one compiled call.
"""

from __future__ import annotations

from optik._checks import FloatArray
from optik.analytic import _compiled
from optik.analytic._base import AnalyticFamily, dh_rows, is_right_angle, register
from optik.model import DHJoint, Robot

_EPS = 1e-12


def _zero(*values: float) -> bool:
    return all(abs(v) < _EPS for v in values)


def _arm_kind(rows: tuple[DHJoint, ...]) -> str | None:
    """``"rrr"`` (articulated), ``"rrp"`` (spherical) or ``None`` for the first three rows."""
    r1, r2, r3 = rows[:3]
    if r1.kind != "revolute" or r2.kind != "revolute" or not is_right_angle(r1.alpha):
        return None
    if r3.kind == "revolute" and _zero(r2.alpha):
        return "rrr"
    if r3.kind == "prismatic" and is_right_angle(r2.alpha):
        return "rrp"
    return None


@register
class SphericalWrist(AnalyticFamily):
    """6-dof arms (RRR or RRP arm) with a spherical wrist, by the 3+3 partition."""

    name = "spherical_wrist"
    modes = ("pose",)
    kernel = _compiled.SPHERICAL_WRIST

    def fits(self, robot: Robot) -> bool:
        """See the module docstring for the structure required."""
        rows = dh_rows(robot)
        if robot.convention != "dh" or robot.dof != 6 or len(rows) != 6:
            return False
        if any(r.mimic is not None for r in rows):
            return False
        r4, r5, r6 = rows[3:]
        return (
            all(r.kind == "revolute" for r in rows[3:])
            and _zero(r4.a, r5.a, r5.d, r6.a)
            and bool(is_right_angle(r4.alpha))
            and bool(is_right_angle(r5.alpha))
            and _arm_kind(rows) is not None
        )

    def candidates(
        self, robot: Robot, T_0_target: FloatArray, mode: str, q_ref: FloatArray
    ) -> list[FloatArray]:
        """Up to eight branches: two shoulders x two elbows x two wrists."""
        return _compiled.raw_candidates(
            _compiled.spherical_wrist_candidates, robot, self.kernel, T_0_target, q_ref
        )
