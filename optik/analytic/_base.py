"""The contract of a closed-form IK family and the registry of families."""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from typing import ClassVar

from optik._checks import FloatArray
from optik._math import trig_roots
from optik.model import DHJoint, Robot
from optik.trig import TRIG_TOL

SINGULAR_EPS = 1e-12
"""Below this magnitude (relative to ``max(|a|, |b|, |c|, 1)``) a coefficient pair of the
trig equation counts as zero."""

FREE_RHS_TOL = 1e-9
"""With ``a = b = 0``, ``|c|`` below this (relative, as above) makes the joint free."""

VERIFY_TOLERANCE = 1e-9
"""Largest position (m) and orientation (rad) error of a returned branch."""

DUPLICATE_TOLERANCE = 1e-9
"""Two branches closer than this (max-abs, rad or m) are one."""


class AnalyticFamily(ABC):
    """A closed-form IK solver for one kinematic structure.

    Subclasses state which robots they fit and return raw candidate branches; the caller
    (:func:`optik.analytic.analytic_ik`) wraps angles into the limits, verifies every
    branch by forward kinematics and filters by the limits.

    A family whose closed form is compiled (:mod:`optik.analytic._compiled`) sets
    ``kernel`` to its id there; ``analytic_ik`` and ``analytic_ik_batch`` then run the
    whole pipeline (closed form, wrapping, limits, FK check, sorting) in one compiled
    call. Such a family must fit only six-joint DH robots without coupled joints.
    """

    name: str = ""
    modes: tuple[str, ...] = ("pose",)
    kernel: ClassVar[int] = 0
    """Id of the family's compiled pipeline (0: none, the family runs in Python)."""

    @abstractmethod
    def fits(self, robot: Robot) -> bool:
        """Whether this family's closed form applies to ``robot``."""

    @abstractmethod
    def candidates(
        self, robot: Robot, T_0_target: FloatArray, mode: str, q_ref: FloatArray
    ) -> list[FloatArray]:
        """Raw joint vectors (dof,) reaching ``T_0_target`` in the chain's frame 0.

        Args:
            robot: the robot (fits this family).
            T_0_target: target pose of the flange (tool removed) in frame 0 (base
                removed), 4x4; in position mode only its translation is meaningful.
            mode: ``"pose"`` or ``"position"``.
            q_ref: reference configuration, used for joints left free at singularities.
        """


FAMILIES: dict[str, AnalyticFamily] = {}


def register(family_cls: type[AnalyticFamily]) -> type[AnalyticFamily]:
    """Class decorator adding a family to the registry under its ``name``."""
    instance = family_cls()
    FAMILIES[instance.name] = instance
    return family_cls


def angles(a: float, b: float, c: float, free: float) -> tuple[float, ...]:
    """Solutions of ``a cos t + b sin t = c``; ``(free,)`` when the equation is ``0 = 0``.

    ``a = b = 0`` arises at singular configurations (a shoulder over the base, a wrist
    aligned): the joint is then free when ``c = 0`` and the caller's reference is used.
    The compiled :func:`optik._math.trig_roots` with the closed forms' tolerances
    (:data:`SINGULAR_EPS`, :data:`FREE_RHS_TOL`, :data:`optik.trig.TRIG_TOL`); the
    compiled families call it directly.
    """
    n, t1, t2 = trig_roots(
        float(a), float(b), float(c), float(free), TRIG_TOL, SINGULAR_EPS, FREE_RHS_TOL
    )
    return (float(t1), float(t2))[:n]


def dh_rows(robot: Robot) -> tuple[DHJoint, ...]:
    """The robot's DH rows, or an empty tuple for robots not built from DH."""
    return robot.dh or ()


def is_right_angle(alpha: float) -> int:
    """``+1``/``-1`` when ``alpha`` is +-90 degrees, else 0."""
    if abs(alpha - math.pi / 2) < 1e-12:
        return 1
    if abs(alpha + math.pi / 2) < 1e-12:
        return -1
    return 0
