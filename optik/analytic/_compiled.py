"""The shared part of the compiled closed forms: robot parameters and DH arithmetic.

Each compiled family's closed form lives in its family's module
(:func:`optik.analytic.spherical_wrist.spherical_wrist_candidates`,
:func:`optik.analytic.ur.ur_candidates`), and the pipeline that runs it with the
post-processing of every branch in :mod:`optik.analytic._pipeline`. This module holds what
they share: the packed robot parameters and the compiled arithmetic of DH rotations and
transforms held in scalars (:func:`dh_rot`, :func:`mul3`, :func:`times_inverse_dh`, ...).

Robot data travel as one flat float64 vector, ``params`` (built once per robot by
:func:`pack_params`; layout in :data:`PARAMS_LAYOUT`), so that a call pays the numba
dispatcher's per-argument cost for few arguments. ``params`` also carries the tolerances
read from their home modules (``TANGENT_TOL``, ``LIMIT_TOLERANCE``, ...): numba freezes a
global's value into its on-disk cache, which is not invalidated when another module
changes, so a tolerance defined elsewhere must be passed, never read as a global. (The
layout indices below are structure, not tolerances: the kernels of the family modules
read them.)

A family kernel's contract (:data:`CandidateKernel`): ``kernel(dh, T, ref, kr, tols,
cand) -> n`` writes the raw branches of the flange target ``T`` (4, 4, in the chain's
frame 0) into rows ``0..n-1`` of ``cand`` (>= 8, 6): joint values (rad, m), not wrapped,
in the family's order. ``dh`` is the (6, 8) packed DH block (:func:`pack_dh`), ``tols``
the tolerance block (:data:`TOL_TRIG`, ...), and row ``kr`` of ``ref`` (M, 6) the
reference that joints left free at singularities take.

Every kernel is serial (``nogil``): callers may run them from several threads.
"""

from __future__ import annotations

import math
from abc import abstractmethod
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, ClassVar, NamedTuple

import numpy as np

from optik._checks import FloatArray
from optik._kernels import Rows12
from optik._math import sincos
from optik._numba import inline as _inline
from optik._numba import jit as _jit
from optik.analytic._base import (
    DUPLICATE_TOLERANCE,
    FAMILIES,
    FREE_RHS_TOL,
    SINGULAR_EPS,
    TANGENT_TOL,
    VERIFY_TOLERANCE,
    WRIST_SINGULAR,
    AnalyticFamily,
    fit_model,
    is_right_angle,
    table_target,
    verify_position_tolerance,
)
from optik.analytic.geometry import (
    LENGTH_TOL,
    DHModel,
    joint_axes,
    point_line_distance,
    wrist_centre,
)
from optik.errors import AnalyticIKError
from optik.limits import LIMIT_TOLERANCE
from optik.spatial import ROTATION_TOLERANCE, invert_transform

if TYPE_CHECKING:
    from optik.model import DHJoint, Robot


Rot9 = tuple[float, float, float, float, float, float, float, float, float]
"""A 3x3 rotation (or any 3x3 block), row-major, held in scalars."""

CandidateKernel = Callable[[np.ndarray, np.ndarray, np.ndarray, int, np.ndarray, np.ndarray], int]
"""A family's compiled closed form (see the module docstring)."""

SPHERICAL_WRIST = 1
"""Family id of :class:`optik.analytic.spherical_wrist.SphericalWrist`."""
UR = 2
"""Family id of :class:`optik.analytic.ur.URArm`."""

MAX_BRANCHES = 8
"""Most raw branches of a compiled family: two x two x two."""
SIN_ROWS = MAX_BRANCHES  # rows of the (24, 6) scratch block holding the branches' sines
COS_ROWS = 2 * MAX_BRANCHES  # ... and their cosines
DOF = 6
"""Joint count of every compiled family (chain joints = ``q`` entries, no coupling)."""

DH_COLUMNS = ("a", "alpha", "d", "theta", "is_prismatic", "cos_alpha", "sin_alpha", "right")
"""Columns of a packed DH row (:func:`pack_dh`); ``right`` is +1 / -1 for alpha = +-90 deg."""
NCOL = len(DH_COLUMNS)
COL_A, COL_ALPHA, COL_D, COL_THETA, COL_PRISMATIC, COL_CA, COL_SA, COL_RIGHT = range(NCOL)
"""Indices of the packed DH columns, in the order of :data:`DH_COLUMNS`."""

# Layout of ``params`` (flat float64): offsets of each block.
AT_FAMILY = 0  # (1,) the family id (SPHERICAL_WRIST, UR)
AT_DH = AT_FAMILY + 1  # (6, 8) packed DH rows, see DH_COLUMNS
AT_LOWER = AT_DH + NCOL * DOF  # (6,) lower limits (rad or m), -inf allowed
AT_UPPER = AT_LOWER + DOF  # (6,) upper limits, +inf allowed
AT_BASE_INV = AT_UPPER + DOF  # (4, 4) inverse of T_world_base, row-major
AT_TOOL_INV = AT_BASE_INV + 16  # (4, 4) inverse of T_flange_tool, row-major
AT_MID = AT_TOOL_INV + 16  # (6,) mid-limits (the default reference)
AT_CHAIN = AT_MID + DOF  # (7, 3, 4) top rows of the robot's chain transforms _K (FK check)
AT_REFINE = AT_CHAIN + 12 * (DOF + 1)  # (1,) 1.0 when the table is not exact (refine)
AT_FLIPPED = AT_REFINE + 1  # (1,) 1.0 when a table variable is -q (a sense of -1)
AT_SENSES = AT_FLIPPED + 1  # (6,) table variable = sense * q (DHModel.senses)
AT_WRIST = AT_SENSES + DOF  # (3,) where axes 4, 5, 6 meet, in the tool's frame (m), or NaN
AT_TOLS = AT_WRIST + 3  # tolerances, in the order of _TOL_NAMES
_TOL_NAMES = (
    "TANGENT_TOL",  # optik.analytic._base: trig equation tangent / degenerate tests
    "SINGULAR_EPS",  # optik.analytic._base: a = b = 0 in angles()
    "FREE_RHS_TOL",  # optik.analytic._base: c = 0 in angles() (free joint)
    "LIMIT_TOLERANCE",  # optik.limits: slack on a bound
    "VERIFY_TOLERANCE",  # optik.analytic._base: FK check, m and rad
    "DUPLICATE_TOLERANCE",  # optik.analytic._base: two branches are one
    "ROTATION_TOLERANCE",  # optik.spatial: max |R^T R - I| of a target
    "BOTTOM_ROW_TOL",  # optik.spatial.as_pose: |last row - (0 0 0 1)|
    "WRIST_SINGULAR",  # optik.analytic._base: |sin q5| of an aligned wrist
    "VERIFY_POSITION",  # optik.analytic._base.verify_position_tolerance: FK check, m
)
TOL_TRIG, TOL_SINGULAR, TOL_FREE_RHS, TOL_LIMIT, TOL_VERIFY, TOL_DUPLICATE = range(6)
TOL_ROTATION, TOL_BOTTOM_ROW, TOL_WRIST, TOL_VERIFY_POSITION = range(6, 10)
"""Indices of the tolerances in the block (:func:`tolerances`), in ``_TOL_NAMES``'s order."""
_N_PARAMS = AT_TOLS + len(_TOL_NAMES)
PARAMS_LAYOUT: dict[str, tuple[int, tuple[int, ...]]] = {
    "family": (AT_FAMILY, (1,)),
    "dh": (AT_DH, (DOF, NCOL)),
    "lower": (AT_LOWER, (DOF,)),
    "upper": (AT_UPPER, (DOF,)),
    "T_base_world": (AT_BASE_INV, (4, 4)),
    "T_tool_flange": (AT_TOOL_INV, (4, 4)),
    "mid_limits": (AT_MID, (DOF,)),
    "chain": (AT_CHAIN, (DOF + 1, 3, 4)),
    "refine": (AT_REFINE, (1,)),
    "flipped": (AT_FLIPPED, (1,)),
    "senses": (AT_SENSES, (DOF,)),
    "wrist": (AT_WRIST, (3,)),
    "tolerances": (AT_TOLS, (len(_TOL_NAMES),)),
}
"""Name -> (offset, shape) of each block of ``params``."""

_BOTTOM_ROW_TOL = 1e-9  # the literal of optik.spatial.as_pose


# ---------------------------------------------------------------------- packing (Python)
def pack_dh(rows: Sequence[DHJoint]) -> FloatArray:
    """Standard DH rows as a (dof, 8) array, columns :data:`DH_COLUMNS`.

    ``a, alpha, d, theta`` (m, rad; ``theta`` is the revolute offset, ``d`` the prismatic
    one), ``is_prismatic`` (0 or 1), then derived constants the kernels would otherwise
    recompute at every call: ``cos alpha``, ``sin alpha`` and ``right``
    (:func:`optik.analytic._base.is_right_angle`: +1 / -1 for alpha = +-90 deg, else 0).
    """
    return np.array(
        [
            [
                r.a,
                r.alpha,
                r.d,
                r.theta,
                1.0 if r.kind == "prismatic" else 0.0,
                math.cos(r.alpha),
                math.sin(r.alpha),
                float(is_right_angle(r.alpha)),
            ]
            for r in rows
        ],
        dtype=np.float64,
    ).reshape(-1, NCOL)


def pack_params(robot: Robot, family: int) -> FloatArray:
    """The flat parameter vector of a six-joint robot for the compiled pipeline.

    Everything a kernel needs about the robot, in one argument (see
    :data:`PARAMS_LAYOUT`): the family id, packed DH rows, limits, base and tool
    inverses, mid-limits, the robot's own chain transforms ``_K`` (the FK check uses the
    kinematics of ``Robot.fk``, not the DH rows), the senses of the table's variables
    (``DHModel.senses``), the wrist centre in the tool's frame (a spherical wrist: the
    Newton step of a table that is not exact, ``DHModel.exact``, is solved around it,
    :mod:`optik.analytic._newton`), and the tolerances. The caller caches it
    per robot (a :class:`~optik.Robot` does not change after construction;
    ``Robot.with_limits`` starts a fresh cache).

    The DH rows and the two transforms are the family's table of the robot
    (``AnalyticFamily.model``): the robot's own standard DH rows with its base and tool,
    or the equivalent table built from its joint axes with the world pose of its frame 0
    (stored as ``T_base_world``) and the tool in its last frame (``T_tool_flange``).

    Args:
        robot: a robot of a compiled family (six joints, no coupling) that fits it.
        family: the family id (:data:`SPHERICAL_WRIST` or :data:`UR`).
    """
    model = next(f for f in FAMILIES.values() if f.kernel == family).model(robot)
    params = np.empty(_N_PARAMS)
    params[AT_FAMILY] = family
    params[AT_DH:AT_LOWER] = pack_dh(model.rows).reshape(-1)
    params[AT_LOWER:AT_UPPER] = robot.lower
    params[AT_UPPER:AT_BASE_INV] = robot.upper
    params[AT_BASE_INV:AT_TOOL_INV] = invert_transform(model.T_world_0).reshape(-1)
    params[AT_TOOL_INV:AT_MID] = invert_transform(model.T_n_tool).reshape(-1)
    params[AT_MID:AT_CHAIN] = robot.mid_limits
    params[AT_CHAIN:AT_REFINE] = robot.chain.K[:, :3, :].reshape(-1)
    params[AT_REFINE] = 0.0 if model.exact else 1.0
    senses = np.array(model.senses or (1.0,) * DOF)
    params[AT_FLIPPED] = 1.0 if np.any(senses < 0.0) else 0.0
    params[AT_SENSES:AT_WRIST] = senses
    params[AT_WRIST:AT_TOLS] = np.nan
    if family == SPHERICAL_WRIST:
        params[AT_WRIST:AT_TOLS] = axes_wrist_centre(robot)
    params[AT_TOLS:] = tolerance_block()
    params[AT_TOLS + TOL_VERIFY_POSITION] = verify_position_tolerance(robot)
    return params


def tolerance_block() -> FloatArray:
    """The tolerances, from their home modules, in the order of ``_TOL_NAMES``."""
    return np.array(
        [
            TANGENT_TOL,
            SINGULAR_EPS,
            FREE_RHS_TOL,
            LIMIT_TOLERANCE,
            VERIFY_TOLERANCE,
            DUPLICATE_TOLERANCE,
            ROTATION_TOLERANCE,
            _BOTTOM_ROW_TOL,
            WRIST_SINGULAR,
            VERIFY_TOLERANCE,  # a robot's own: set where its parameters are packed
        ]
    )


class AxesOffsets(NamedTuple):
    """Offsets of the blocks of a parameter vector built on the joint axes (flat float64).

    The families solved from the joint axes at ``q = 0`` (``spherical_axes``, the
    held-joint form of :mod:`optik.analytic.free_joint`) put a head of their own entries
    first, then these blocks, for a chain of ``dof`` joints:

    Attributes:
        kind: (dof,) 1.0 for a prismatic joint.
        lower: (dof,) lower limits (rad or m), -inf allowed.
        upper: (dof,) upper limits, +inf allowed.
        chain: (dof + 1, 3, 4) top rows of the robot's chain ``_K`` (the FK check).
        directions: (dof, 3) unit joint directions at ``q = 0`` of the chain solved.
        points: (dof, 3) a point on each of its axes (m).
        tool: (4, 4) its tool at ``q = 0``, row-major.
        wrist: (3,) where the robot's last three axes meet, in its tool's frame (m), or
            NaN (:func:`axes_wrist_centre`): the Newton step's wrist centre.
        tols: the tolerance block (:func:`tolerance_block`).
    """

    kind: int
    lower: int
    upper: int
    chain: int
    directions: int
    points: int
    tool: int
    wrist: int
    tols: int

    @property
    def layout(self) -> tuple[int, int, int, int, int, int, int]:
        """Where :func:`optik.analytic._pipeline.postprocess_rows` finds the robot's data."""
        return (self.kind, 1, self.lower, self.upper, self.chain, self.tols, self.wrist)


def axes_offsets(dof: int, head: int) -> AxesOffsets:
    """The :class:`AxesOffsets` of a ``dof``-joint chain after ``head`` entries."""
    lower = head + dof
    upper = lower + dof
    chain = upper + dof
    directions = chain + 12 * (dof + 1)
    points = directions + 3 * dof
    tool = points + 3 * dof
    wrist = tool + 16
    return AxesOffsets(head, lower, upper, chain, directions, points, tool, wrist, wrist + 3)


def axes_wrist_centre(robot: Robot) -> FloatArray:
    """(3,) where a robot's own last three axes meet, in its tool's frame (m).

    NaN unless each of the three passes within the geometry's length tolerance
    (``LENGTH_TOL`` times the arm's size) of that point: then the Newton step of a branch
    is referred to it (:func:`optik.analytic._newton.newton_step`, two 3 x 3 solves),
    whatever chain the closed form solved (read backwards, a spherical shoulder's; around
    a held arm joint of a seven-joint arm).
    """
    missing = np.full(3, np.nan)
    axes = joint_axes(robot)
    n = len(axes.points)
    if n < 6 or n != robot.dof or np.any(robot.chain.prismatic[-3:]):
        return missing
    first = n - 3
    centre = wrist_centre(axes, first)
    if not np.all(np.isfinite(centre)):
        return missing
    world = axes.tool[:3, :3] @ centre + axes.tool[:3, 3]
    tol = LENGTH_TOL * axes.size
    for i in (first, first + 1, first + 2):
        if point_line_distance(axes.directions[i], axes.points[i], world) > tol:
            return missing
    return centre


def pack_axes_vector(
    robot: Robot,
    head: Sequence[float],
    directions: FloatArray,
    points: FloatArray,
    tool: FloatArray,
    tols: FloatArray,
    wrist: FloatArray | None = None,
) -> FloatArray:
    """The flat parameter vector of a family solved on the joint axes (:class:`AxesOffsets`).

    Args:
        robot: the robot (its limits, prismatic flags and chain transforms ``_K``: the
            FK check uses the kinematics of ``Robot.fk``).
        head: the family's own leading entries.
        directions: (dof, 3) unit joint directions at ``q = 0`` of the chain solved.
        points: (dof, 3) a point on each of its axes (m).
        tool: (4, 4) its tool at ``q = 0``.
        tols: the tolerance block (:func:`tolerance_block`; numba freezes globals).
        wrist: (3,) the wrist centre of the Newton step (:func:`axes_wrist_centre`);
            ``None``: none (the damped step).
    """
    at = axes_offsets(robot.dof, len(head))
    params = np.zeros(at.tols + len(tols))
    params[: len(head)] = head
    params[at.kind : at.lower] = robot.chain.prismatic
    params[at.lower : at.upper] = robot.lower
    params[at.upper : at.chain] = robot.upper
    params[at.chain : at.directions] = robot.chain.K[:, :3, :].reshape(-1)
    params[at.directions : at.points] = directions.reshape(-1)
    params[at.points : at.tool] = points.reshape(-1)
    params[at.tool : at.wrist] = tool.reshape(-1)
    params[at.wrist : at.tols] = np.nan if wrist is None else wrist
    params[at.tols :] = tols
    params[at.tols + TOL_VERIFY_POSITION] = verify_position_tolerance(robot)
    return params


def params_of(robot: Robot, family: int) -> FloatArray:
    """:func:`pack_params` of ``robot``, cached in the robot (do not modify it)."""
    kernel = _PACKERS[family]
    return robot.cached(kernel)


def _pack_spherical_wrist(robot: Robot) -> FloatArray:
    return pack_params(robot, SPHERICAL_WRIST)


def _pack_ur(robot: Robot) -> FloatArray:
    return pack_params(robot, UR)


_PACKERS = {SPHERICAL_WRIST: _pack_spherical_wrist, UR: _pack_ur}


class CompiledFamily(AnalyticFamily):
    """A six-joint family whose closed form is a compiled kernel, solved on a DH table.

    The table is the robot's own standard DH rows when they have the family's structure,
    else the equivalent table built from its joint axes (:func:`fit_model`). A subclass
    names its pipeline id (``kernel``), its closed form (``closed_form``, a
    :data:`CandidateKernel`), the test of a DH table it solves (``rows_test``: ``None`` or
    why the table does not fit), the twist signs its table wants (``twist_signs``, see
    :func:`optik.analytic.geometry.equivalent_dh`) and what :meth:`model` says of a robot
    that does not fit (``mismatch``, formatted with the robot's ``name``).
    """

    modes = ("pose",)
    closed_form: ClassVar[CandidateKernel]
    twist_signs: ClassVar[tuple[int, ...]] = ()
    mismatch: ClassVar[str] = "robot {name!r} does not fit the family"

    @staticmethod
    @abstractmethod
    def rows_test(rows: tuple[DHJoint, ...]) -> str | None:
        """``None`` when a DH table has the family's structure, else why not."""

    def fit(self, robot: Robot) -> DHModel | str:
        """The family's table of ``robot``, or why there is none (the robot caches it).

        :func:`optik.analytic._base.fit_model` with the family's ``rows_test`` and
        ``twist_signs``.
        """
        return fit_model(robot, self.rows_test, self.twist_signs)

    def fits(self, robot: Robot) -> bool:
        """Whether the structure holds, in the robot's DH rows or in its joint axes."""
        return not isinstance(robot.cached(self.fit), str)

    def explain(self, robot: Robot) -> str | None:
        """The first relation of the structure that fails, or ``None``."""
        found = robot.cached(self.fit)
        return found if isinstance(found, str) else None

    def model(self, robot: Robot) -> DHModel:
        """The table of ``robot`` (its own rows or the equivalent from its axes)."""
        found = robot.cached(self.fit)
        if isinstance(found, str):
            raise AnalyticIKError(f"{self.mismatch.format(name=robot.name)}: {found}")
        return found

    def candidates(
        self, robot: Robot, T_0_target: FloatArray, mode: str, q_ref: FloatArray
    ) -> list[FloatArray]:
        """The raw branches of the closed form (before wrapping and verification).

        In the robot's variables (a table's ``-q``, ``DHModel.senses``, turned back). For a
        table that is not exact (``DHModel.exact``), the branches of the ideal arm, before
        the Newton step the pipeline gives each
        (:func:`optik.analytic._pipeline.postprocess_rows`).

        Args:
            robot: the robot.
            T_0_target: 4x4 flange target in frame 0.
            mode: ``"pose"``.
            q_ref: (dof,) reference for joints left free at singularities.
        """
        model = self.model(robot)
        T = table_target(robot, model, T_0_target)
        params = params_of(robot, self.kernel)
        senses = params[AT_SENSES:AT_WRIST]
        out = np.empty((MAX_BRANCHES, DOF))
        # The class's attribute: a compiled function read from an instance binds to it.
        n = type(self).closed_form(
            dh_block(params),
            np.ascontiguousarray(T, dtype=np.float64),
            np.ascontiguousarray(senses * q_ref, dtype=np.float64).reshape(1, -1),
            0,
            tolerances(params),
            out,
        )
        return list(out[:n] * senses)


def tolerances(params: FloatArray) -> FloatArray:
    """The tolerance block of ``params`` (a view), in the order of ``_TOL_NAMES``."""
    return params[AT_TOLS:]


def mid_limits(params: FloatArray) -> FloatArray:
    """The mid-limits block of ``params`` (a view), the default reference configuration."""
    return params[AT_MID:AT_CHAIN]


def dh_block(params: FloatArray) -> FloatArray:
    """The (6, 8) packed DH block of ``params`` (a view)."""
    return params[AT_DH:AT_LOWER].reshape(DOF, NCOL)


def pose_tolerances() -> tuple[float, float]:
    """``(ROTATION_TOLERANCE, bottom-row tolerance)`` for :func:`first_bad_pose`."""
    return ROTATION_TOLERANCE, _BOTTOM_ROW_TOL


@_inline
def axes_block(params: np.ndarray, at: int, dof: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Copies of the joint axes stored in ``params`` from offset ``at``: ``(z, p, M)``.

    ``z`` (dof, 3) unit joint directions at ``q = 0``, ``p`` (dof, 3) a point on each axis
    (m) and ``M`` (4, 4) the tool at ``q = 0`` (row-major), stored one after the other as
    :func:`pack_axes_vector` stores them (at ``AxesOffsets.directions``).
    """
    z = np.empty((dof, 3))
    p = np.empty((dof, 3))
    M = np.empty((4, 4))
    for i in range(dof):
        for a in range(3):
            z[i, a] = params[at + 3 * i + a]
            p[i, a] = params[at + 3 * dof + 3 * i + a]
    for a in range(4):
        for b in range(4):
            M[a, b] = params[at + 6 * dof + 4 * a + b]
    return z, p, M


@_inline
def dh_row(dh: np.ndarray, i: int) -> tuple[float, float, float, float, float, float, float, float]:
    """Row ``i`` of a packed DH block, the columns of :data:`DH_COLUMNS` in order.

    ``(a, alpha, d, theta, is_prismatic, cos alpha, sin alpha, right)``; inlined, so the
    columns a caller ignores are never read.
    """
    return (
        dh[i, COL_A], dh[i, COL_ALPHA], dh[i, COL_D], dh[i, COL_THETA],
        dh[i, COL_PRISMATIC], dh[i, COL_CA], dh[i, COL_SA], dh[i, COL_RIGHT],
    )  # fmt: skip


@_inline
def store_branch(
    cand: np.ndarray, n: int, q: tuple[float, float, float, float, float, float]
) -> int:
    """Write the joint values ``q`` (rad, m) to row ``n`` of ``cand``; return ``n + 1``."""
    for j in range(DOF):
        cand[n, j] = q[j]
    return n + 1


@_inline
def closed_form_tols(tols: np.ndarray) -> tuple[float, float, float, float]:
    """The closed forms' tolerances from the tolerance block (:func:`tolerances`).

    ``(TANGENT_TOL, SINGULAR_EPS, FREE_RHS_TOL, WRIST_SINGULAR)``; the first three are
    :func:`optik._math.trig_roots`'s.
    """
    return tols[TOL_TRIG], tols[TOL_SINGULAR], tols[TOL_FREE_RHS], tols[TOL_WRIST]


@_jit
def dh_rot(ct: float, st: float, ca: float, sa: float) -> Rot9:
    """Rotation block of ``Rz(theta) Rx(alpha)`` from the cosines and sines, row-major."""
    return (ct, -st * ca, st * sa, st, ct * ca, -ct * sa, 0.0, sa, ca)


@_jit
def dh_rotation(theta: float, ca: float, sa: float) -> Rot9:
    """Rotation block of ``Rz(theta) Rx(alpha)``, row-major 9-tuple."""
    st, ct = sincos(theta)
    return dh_rot(ct, st, ca, sa)


@_jit
def mul3(
    A: Rot9,
    B: Rot9,
) -> Rot9:
    """``A @ B`` for row-major 3x3 9-tuples."""
    return (
        A[0] * B[0] + A[1] * B[3] + A[2] * B[6],
        A[0] * B[1] + A[1] * B[4] + A[2] * B[7],
        A[0] * B[2] + A[1] * B[5] + A[2] * B[8],
        A[3] * B[0] + A[4] * B[3] + A[5] * B[6],
        A[3] * B[1] + A[4] * B[4] + A[5] * B[7],
        A[3] * B[2] + A[4] * B[5] + A[5] * B[8],
        A[6] * B[0] + A[7] * B[3] + A[8] * B[6],
        A[6] * B[1] + A[7] * B[4] + A[8] * B[7],
        A[6] * B[2] + A[7] * B[5] + A[8] * B[8],
    )


@_inline
def transpose3(A: Rot9) -> Rot9:
    """``A^T`` for a row-major 3x3 9-tuple (no arithmetic: the entries move)."""
    return (A[0], A[3], A[6], A[1], A[4], A[7], A[2], A[5], A[8])


@_jit
def mul3tn(A: Rot9, B: Rot9) -> Rot9:
    """``A^T @ B`` for row-major 3x3 9-tuples: :func:`mul3` of :func:`transpose3`."""
    return mul3(transpose3(A), B)


@_jit
def _row_times_inverse_dh(
    t0: float,
    t1: float,
    t2: float,
    t3: float,
    R: Rot9,
    inv_p: tuple[float, float, float],
) -> tuple[float, float, float, float]:
    """One row ``(t0, t1, t2, t3)`` of a transform times ``A^-1 = [R^T, -R^T p]``."""
    return (
        t0 * R[0] + t1 * R[1] + t2 * R[2],
        t0 * R[3] + t1 * R[4] + t2 * R[5],
        t0 * R[6] + t1 * R[7] + t2 * R[8],
        t0 * inv_p[0] + t1 * inv_p[1] + t2 * inv_p[2] + t3,
    )


@_jit
def times_inverse_dh(
    T: Rows12,
    ct: float,
    st: float,
    ca: float,
    sa: float,
    a: float,
    d: float,
) -> Rows12:
    """``T[:3] @ A^-1`` for the top rows of ``T`` (a row-major 12-tuple).

    ``A`` is the DH matrix (theta, d, a, alpha) and ``A^-1 = [R^T, -R^T p]`` with
    ``p = (a cos theta, a sin theta, d)``; ``ct, st`` are ``cos theta, sin theta``.
    """
    R = dh_rot(ct, st, ca, sa)
    px = a * ct
    py = a * st
    inv_p = (
        -(R[0] * px + R[3] * py + R[6] * d),
        -(R[1] * px + R[4] * py + R[7] * d),
        -(R[2] * px + R[5] * py + R[8] * d),
    )
    r0 = _row_times_inverse_dh(T[0], T[1], T[2], T[3], R, inv_p)
    r1 = _row_times_inverse_dh(T[4], T[5], T[6], T[7], R, inv_p)
    r2 = _row_times_inverse_dh(T[8], T[9], T[10], T[11], R, inv_p)
    return (r0[0], r0[1], r0[2], r0[3], r1[0], r1[1], r1[2], r1[3], r2[0], r2[1], r2[2], r2[3])


@_jit
def cos_sin(theta: float, t: float, x: float, y: float) -> tuple[float, float]:
    """``cos, sin`` of ``theta``, which the caller formed from ``t = atan2(y, x)``.

    When ``theta == t`` (a zero DH offset) they are ``x / r, y / r`` (``r = hypot(x, y)``
    > 0), one square root and two divisions; otherwise :func:`sincos`.
    """
    if theta == t:
        r = math.sqrt(x * x + y * y)
        if r > 0.0:
            return x / r, y / r
    st, ct = sincos(theta)
    return ct, st
