"""The contract of a closed-form IK family and the registry of families."""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from collections.abc import Callable
from typing import TYPE_CHECKING, Any, ClassVar, NamedTuple

import numpy as np

from optik._checks import FloatArray
from optik._math import trig_roots
from optik.analytic.geometry import DHModel, NoTable, equivalent_dh, revolute_chain_reason
from optik.errors import AnalyticIKError
from optik.model import DHJoint, Robot
from optik.spatial import invert_transform

if TYPE_CHECKING:
    from optik.task import Task

TANGENT_TOL = 1e-11
"""Tolerance of the closed forms' trig equations (``tol`` of :func:`optik._math.trig_roots`,
linear: ``|r - |c|| <= TANGENT_TOL max(r, 1)`` is a tangent, double root). Ten times the
public :data:`optik.trig.TRIG_TOL`: a geometry read from a URDF's 12-digit numbers meets
its ideal arm only to about 1e-11, and a stretched arm's double root must stay one root
(two roots ``sqrt(2e-11 / r)`` apart would not give back the stretched configuration).
Where ``r >= 1`` the closed forms take a tenth of it (:func:`optik._math.trig_roots`: a
kilometre arm's 150 m shoulder equation left its tangent root 1.5e-9 m off at 1e-11
relative). The band is in the equation's units: the compiled elbows' distance
equations (m^2) are made relative first (:func:`optik.analytic._subproblems.elbow_roots`);
the planar 2R's and the DOBOT's, solved in Python, are not yet."""

SINGULAR_EPS = 1e-12
"""Below this magnitude (relative to ``max(|a|, |b|, |c|, 1)``) a coefficient pair of the
trig equation counts as zero."""

FREE_RHS_TOL = 1e-9
"""With ``a = b = 0``, ``|c|`` below this (relative, as above) makes the joint free."""

VERIFY_TOLERANCE = 1e-9
"""Largest orientation error (rad) of a returned branch, and its position error (m) on an
arm of up to 1 m at the world's origin (:func:`verify_position_tolerance`)."""

ROUNDING_ULPS = 256.0
"""Rounding allowed in the FK check's positions, in units of ``eps`` times the world
coordinates' size (:func:`verify_position_tolerance`)."""


def verify_position_tolerance(robot: Robot) -> float:
    """Largest position error (m) of a returned branch of ``robot``.

    :data:`VERIFY_TOLERANCE` relative to the arm's size where it exceeds 1 m (the reach
    sphere's radius ``r``), plus the rounding of world coordinates as large as the reach
    sphere's far side (``|c| + r``): ``1e-9 max(1, r) + 256 eps (|c| + r)``. A 1e8 m arm's
    forward kinematics rounds at about 1e-8 m, and an absolute 1e-9 m check rejected
    every exact branch of it (an unsound "unreachable").
    """
    centre, radius = robot.reach_sphere
    far = float(np.linalg.norm(centre)) + radius
    return VERIFY_TOLERANCE * max(1.0, radius) + ROUNDING_ULPS * np.finfo(float).eps * far


DUPLICATE_TOLERANCE = 1e-9
"""Two branches closer than this (max-abs, rad or m) are one."""

LIMIT_CLIP = 1e-9
"""A branch at most this beyond a limit (rad or m) is put on the bound, and the FK check
judges it there; farther, it is dropped. Next to a singularity a closed form's rounding
is that large (a Jaco 2 stretched, its wrist on its lower limit: 1e-10), and a
configuration on its limit would lose its branch."""

LIMIT_STEP = 1e-4
"""A compiled family's branch beyond a limit by more than :data:`LIMIT_CLIP` and at most
this (rad or m) is put on the bound too; where the FK check then fails, Newton steps with
that joint held on its bound move the others back onto the pose
(:func:`optik.analytic._pipeline.postprocess_rows`). Next to a wrist singularity the
closed form splits ``q4`` and ``q6`` only to ``eps / sin(q5)``: a Puma with ``q4`` on
its limit and ``q5 = 1e-8`` had its branch 3e-8 beyond the limit, and lost it, while
``q6`` turned by the same amount keeps the pose to 1e-15."""

ELBOW_REACH_TOL = 1e-4
"""A wrist centre beyond a DH arm's elbow reach (stretched or folded) by at most this,
relative to the elbow equation's coefficient ``2 a2 a3``, takes the tangent elbow. The
reach computed near a singularity carries more than rounding: at a shoulder singularity
joint 1 is a tangent root, off by up to ``sqrt(2 TANGENT_TOL)`` (4.5e-6 rad), which moves
the wrist centre by that times the reach and the elbow equation by about four times
that, relative; next to the wrist's, the angle ``q6`` that places the wrist centre
comes from two entries of order ``sin q5``; a URDF's angles fit the ideal arm only to its
own digits. A stretched arm's target would fall just out of exact reach, with no branch
at all; the FK check judges the tangent row (after the Newton steps of a near miss,
:func:`optik.analytic._row_steps._near_miss`)."""

WRIST_SINGULAR = 1e-10
"""``|sin q5|`` below which a six-joint arm's wrist axes 4 and 6 count as aligned: only
``q4 + q6`` (or ``q6`` alone) is defined, and the free joint takes its reference (the
spherical wrists add the split nearest the reference as a second branch)."""


class AnalyticFamily(ABC):
    """A closed-form IK solver for one kinematic structure.

    Subclasses state which robots they fit and return raw candidate branches; the caller
    (:func:`optik.analytic.analytic_ik`) wraps angles into the limits, verifies every
    branch by forward kinematics and filters by the limits.

    A family whose closed form is compiled (:mod:`optik.analytic._compiled`) sets
    ``kernel`` to its id there; ``analytic_ik`` and ``analytic_ik_batch`` then run the
    whole pipeline (closed form, wrapping, limits, FK check, sorting) in one compiled
    call. Such a family must fit only six-joint DH robots without coupled joints. A
    six-joint family without a DH table compiles its own pipeline on its own parameters
    and returns it from :meth:`compiled` (``spherical_axes``).
    """

    name: str = ""
    modes: tuple[str, ...] = ("pose",)
    kernel: ClassVar[int] = 0
    """Id of the family's compiled pipeline (0: none, the family runs in Python)."""
    fast: ClassVar[bool] = True
    """Whether :func:`optik.solve_ik` answers with the family by default (microseconds);
    ``general_6r`` (an eigenproblem in Python, about 2 ms, 20 times a numeric solve) sets
    ``False``: ``solve_ik`` then solves numerically, while ``analytic_ik``,
    ``solve_ik_all`` and ``plan_path`` use its branches."""
    proves_unreachable: ClassVar[bool] = True
    """Whether an empty branch set proves the target unreachable (exact closed forms); a
    numerical family (``general_6r``) sets ``False`` and callers search instead."""
    tool_point: ClassVar[bool] = False
    """Whether position mode solves for the tool point itself, so any tool offset is
    allowed; the others place the flange, so their position mode needs a tool without
    an offset (:func:`places_tool_point`)."""

    @abstractmethod
    def fits(self, robot: Robot) -> bool:
        """Whether this family's closed form applies to ``robot``."""

    def explain(self, robot: Robot) -> str | None:
        """Why this family does not fit ``robot`` (one line), or ``None`` when it fits.

        The default, for families that read the robot's own standard DH rows; the
        families that work from the joint axes say which relation fails.
        """
        if self.fits(robot):
            return None
        if robot.convention != "dh":
            return f"reads standard DH rows; the robot was built from {robot.convention}"
        return f"{robot.dof} joints: its DH rows do not have the family's structure"

    def model(self, robot: Robot) -> DHModel:
        """The DH table (and base and tool transforms) the compiled kernel solves.

        Only for a compiled family (``kernel`` set) that fits ``robot``; the Python
        families solve from the robot's own rows and have no such table.

        Raises:
            AnalyticIKError: the family has no compiled kernel.
        """
        raise AnalyticIKError(f"family {self.name!r} has no compiled kernel, so no DH table")

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

    def compiled(self, robot: Robot) -> CompiledPipeline | None:
        """The compiled pipeline that solves ``robot`` in pose mode, or ``None``.

        For a family without a DH table (``kernel`` 0) whose closed form and
        post-processing are compiled on its own parameters; the DH families' pipeline is
        :mod:`optik.analytic._pipeline`'s, chosen by ``kernel``.

        Args:
            robot: the robot (fits this family).
        """
        return None


class PlannedFamily(AnalyticFamily):
    """A family that reads a robot once into a plan, which says whether it fits.

    ``plan(robot)`` (cached per robot, :meth:`optik.model.Robot.cached`) returns a named
    tuple whose ``reason`` is ``""`` when the family fits, else why not (one line); the
    family's :meth:`candidates` solve from the same cached plan.
    """

    plan: Callable[[Robot], Any]
    """How the family reads a robot (set in each subclass as a ``staticmethod``)."""

    def fits(self, robot: Robot) -> bool:
        """Whether the plan of ``robot`` has no reason against the family."""
        return not robot.cached(self.plan).reason

    def explain(self, robot: Robot) -> str | None:
        """The plan's reason why the family does not fit ``robot``, or ``None`` when it does."""
        return robot.cached(self.plan).reason or None


class CompiledPipeline(NamedTuple):
    """A compiled pose-mode pipeline of one robot (:meth:`AnalyticFamily.compiled`).

    Attributes:
        solve: ``solve(params, T, ref, flags, out) -> n``, as
            :func:`optik.analytic._pipeline.solve` (six joints).
        solve_batch: ``solve_batch(params, T, ref, flags) -> (Q, counts)``, as
            :func:`optik.analytic._pipeline.solve_batch`.
        params: the robot's parameter vector for both.
        mid: (6,) the default reference (mid-limits), rad.
    """

    solve: Any
    solve_batch: Any
    params: FloatArray
    mid: FloatArray


FAMILIES: dict[str, AnalyticFamily] = {}


class FamilyMatch(NamedTuple):
    """Whether one family fits a robot, and why not (:func:`match_families`).

    Attributes:
        family: the family's registered name.
        fits: whether its closed form applies.
        reason: ``""`` when it fits, else the first relation that fails (one line).
        source: where the fitting table comes from: ``"dh rows"`` (the robot's own),
            ``"joint axes"`` (built from the geometry) or ``""`` (not a compiled family
            or no fit).
    """

    family: str
    fits: bool
    reason: str
    source: str


def match_families(robot: Robot) -> list[FamilyMatch]:
    """Every registered family, in detection order, with whether and why it fits.

    Args:
        robot: the robot.
    """
    matches = []
    for family in FAMILIES.values():
        reason = family.explain(robot)
        source = family.model(robot).source if reason is None and family.kernel else ""
        matches.append(FamilyMatch(family.name, reason is None, reason or "", source))
    return matches


def explain_family(robot: Robot) -> str:
    """A readable account of the robot's closed-form family: which one, and why not others.

    One line for the outcome (the declared family, the first detected one, or none),
    then one line per registered family: ``fits`` (with the table's source) or the
    relation that fails. Never raises for a well-formed robot: a declared family that
    does not fit is reported, not raised.

    Args:
        robot: the robot.
    """
    matches = match_families(robot)
    if robot.analytic is not None:
        found = next((m for m in matches if m.family == robot.analytic), None)
        if found is None:
            head = f"declared family {robot.analytic!r} is not registered"
        elif found.fits:
            head = f"family {found.family!r} (declared)"
        else:
            head = f"declared family {found.family!r} does not fit: {found.reason}"
    else:
        first = next((m for m in matches if m.fits), None)
        head = "no closed-form family" if first is None else f"family {first.family!r} (detected)"
    lines = [f"robot {robot.name!r}: {head}"]
    for m in matches:
        status = f"fits ({m.source})" if m.fits and m.source else "fits" if m.fits else m.reason
        lines.append(f"  {m.family}: {status}")
    return "\n".join(lines)


def places_tool_point(family: AnalyticFamily, robot: Robot) -> bool:
    """Whether ``family``'s position mode reaches ``robot``'s tool point.

    A family that solves for the tool point (``tool_point``) does for any tool; the
    others place the flange, which is the tool point only when the tool has no offset.

    Args:
        family: a closed-form family.
        robot: the robot (its tool transform is read).
    """
    return family.tool_point or not np.any(np.abs(robot.T_flange_tool[:3, 3]) > 0.0)


def family_solves(family: AnalyticFamily, robot: Robot, task: Task) -> bool:
    """Whether ``family``'s branches are the exact answers of ``task`` on ``robot``.

    The rule :func:`optik.solve_ik` and :func:`optik.solve_ik_batch` share: a pose or a
    point (graded positive weights too, whose exact answers are the same, :mod:`optik.task`)
    in a mode the family solves; for position-only IK the family must reach the tool
    point (:func:`places_tool_point`).
    """
    if not (task.is_pose_or_position or task.search.is_pose_or_position):
        return False
    if task.mode not in family.modes:
        return False
    return task.mode != "position" or places_tool_point(family, robot)


Vector3 = tuple[float, float, float]


def flange_turn(rows: list[list[float]], v: Vector3) -> Vector3:
    """``R v``: the vector ``v`` (flange frame) turned by the target's rotation ``R``.

    ``rows``: the flange target's first three rows (``T[:3].tolist()``); plain floats, for
    the families that run per target in Python.
    """
    (r00, r01, r02, _), (r10, r11, r12, _), (r20, r21, r22, _) = rows
    x, y, z = v
    return (
        r00 * x + r01 * y + r02 * z,
        r10 * x + r11 * y + r12 * z,
        r20 * x + r21 * y + r22 * z,
    )


def flange_point(rows: list[list[float]], offset: Vector3) -> Vector3:
    """``R offset + t``: the point ``offset`` of the flange frame (m) at the target.

    ``rows`` as :func:`flange_turn`'s; a zero ``offset`` gives the translation as it is.
    """
    if not (offset[0] or offset[1] or offset[2]):
        return rows[0][3], rows[1][3], rows[2][3]
    x, y, z = flange_turn(rows, offset)
    return x + rows[0][3], y + rows[1][3], z + rows[2][3]


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
    (:data:`SINGULAR_EPS`, :data:`FREE_RHS_TOL`, :data:`TANGENT_TOL`); the
    compiled families call it directly.
    """
    n, t1, t2 = trig_roots(
        float(a), float(b), float(c), float(free), TANGENT_TOL, SINGULAR_EPS, FREE_RHS_TOL
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


def fit_model(
    robot: Robot,
    rows_reason: Callable[[tuple[DHJoint, ...]], str | None],
    signs: tuple[int, ...],
) -> DHModel | str:
    """The DH table a six-joint family solves ``robot`` with, or why there is none.

    The robot's own standard DH rows when they fit (``rows_reason`` returns ``None``);
    else, for a chain of six revolute joints without coupling, the equivalent table
    built from its joint axes (:func:`optik.analytic.geometry.equivalent_dh`, ``signs``
    choosing the signs of the twists), proved by FK, when that fits.

    Args:
        robot: the robot.
        rows_reason: the family's test of a DH table: ``None`` or why it does not fit.
        signs: the twist signs the family's table wants (see ``equivalent_dh``).
    """
    if robot.convention == "dh" and robot.dh is not None:
        own = rows_reason(robot.dh)
        if own is None and robot.chain.identity:
            return DHModel(robot.dh, robot.T_world_base, robot.T_flange_tool, "dh rows")
    reason = revolute_chain_reason(robot, 6)
    if reason is not None:
        return reason
    try:
        model = equivalent_dh(robot, signs)
    except NoTable as exc:
        return str(exc)
    return rows_reason(model.rows) or model


def table_target(robot: Robot, model: DHModel, T_0_target: FloatArray) -> FloatArray:
    """A flange target in the robot's frame 0 as the target of ``model``'s last frame.

    ``T_0_target`` is what :meth:`AnalyticFamily.candidates` receives (base and tool
    removed); a table built from the joint axes has its own frame 0 and last frame. For
    a robot's own DH rows it is returned as it is.
    """
    if model.source == "dh rows":
        return T_0_target
    T_world_flange = robot.T_world_base @ T_0_target
    T_world_tool = T_world_flange @ robot.T_flange_tool
    return np.asarray(
        invert_transform(model.T_world_0) @ T_world_tool @ invert_transform(model.T_n_tool),
        dtype=float,
    )


def opposite(alpha: float) -> str:
    """A note for a twist of 180 deg: parallel axes of opposite directions."""
    if abs(abs(alpha) - math.pi) < 1e-12:
        return "; they are parallel but opposite, which would take q -> -q"
    return ""


def deg(angle: float) -> str:
    """``angle`` (rad) in degrees, for messages."""
    return f"{math.degrees(angle):.12g} deg"
