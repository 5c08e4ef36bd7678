"""Joint axes at the zero configuration and an equivalent standard-DH table built from them.

Whatever a robot was built from (standard DH, modified DH, URDF), its chain is
``K[0] Rz(q_1) K[1] ... Rz(q_n) K[n]`` (:mod:`optik.chain`), so joint ``i`` turns about the
z axis of the frame ``P_i = K[0] K[1] ... K[i-1]`` (at ``q = 0``): a line with direction
``z_i`` (the sign is the joint's: a positive ``q_i`` turns right-handed about it) through
the point ``p_i``, both in the world frame (the robot's base transform included).

The closed forms of :mod:`optik.analytic._compiled` take standard DH rows. From the axes,
:func:`equivalent_dh` builds DH frames ``F_0 .. F_n`` (world poses at ``q = 0``) by the
classical construction: ``F_{i-1}`` has its z axis on joint ``i``'s axis, with the
joint's direction, so that ``q_i`` adds to ``theta_i`` with no sign or scale; ``x_i`` runs
along the common normal of axes ``i`` and ``i + 1`` and the origin of ``F_i`` is its foot
on axis ``i + 1``. Then

    ``fk(q) = T_world_0 A_1(theta_1 + q_1) ... A_n(theta_n + q_n) T_n_tool``

with ``T_world_0 = F_0`` and a constant ``T_n_tool``. The cases:

- skew or intersecting axes (``|z_i x z_{i+1}| > ANGLE_TOL``): the common normal is
  unique, ``x_i = s (z_i x z_{i+1}) / |z_i x z_{i+1}|`` with a sign ``s`` the caller may
  choose (it gives ``alpha_i`` its sign, and ``a_i`` the same sign as the distance), ``d_i``
  the offset along axis ``i`` from ``F_{i-1}``'s origin to the normal;
- parallel axes: the normal through ``F_{i-1}``'s origin (``d_i = 0``), ``x_i`` towards
  axis ``i + 1`` (along ``x_{i-1}`` when the axes coincide); ``alpha_i`` is 0 for axes of
  the same direction; an axis opposite to the parallel one before it is taken reversed,
  with the joint variable ``-q`` (:func:`joint_senses`), since no compiled family takes
  a twist of 180 deg;
- ``F_0 = P_1`` (the chain's own frame of joint 1); the last row has ``a_n = alpha_n = 0``
  and ``d_n`` puts ``F_n``'s origin at the foot of the tool point on the last axis.

Values within the tolerances of their ideal (``alpha`` of 0, +-90 or 180 deg, a length
of 0) are set to it exactly, since the families test them exactly. The construction is
then proved, not trusted: the table's forward kinematics must equal ``Robot.fk`` on
random configurations to :data:`FK_TOL`. When the snapped table misses that proof but
reproduces ``Robot.fk`` to :data:`NEAR_FK_TOL` (axes in an ideal relation only to
within the tolerances, e.g. a URDF angle written to 11 digits: 1.57079632679), it is
kept and marked ``exact=False``: a family solves the ideal arm, and each branch then
takes one Newton step on the robot's own chain (:mod:`optik.analytic._newton`, inside
the FK check), which restores it to rounding. Beyond that, the table of the unsnapped
values is returned instead, and proved the same way, so the families see (and name) the
relation that is not exact.

Tolerances are relative to the arm's size ``L`` (:func:`arm_size`: the summed distances
between consecutive joint points at ``q = 0``, at least 1 mm): :data:`ANGLE_TOL` (rad) for
directions, ``LENGTH_TOL * L`` (m) for distances.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from optik._checks import FloatArray
from optik.model import DHJoint, Robot

ANGLE_TOL = 1e-9
"""Directions within this (rad) of parallel, perpendicular, ... count as such."""
LENGTH_TOL = 1e-9
"""Distances within this times the arm's size count as zero (two axes intersect)."""
FK_TOL = 1e-12
"""Largest entry difference between the table's FK and ``Robot.fk`` (rotation entries;
positions in units of ``max(1 m, L)``) on the check configurations."""
NEAR_FK_TOL = 1e-9
"""The same difference for a snapped table kept with ``exact=False``: the angle and
length tolerances' order, the most that their snapping moves the tool (scaled)."""
_CHECK_CONFIGS = 16  # random configurations of the FK check (plus q = 0)
_MIN_SIZE = 1e-3  # m: floor of the arm's size


class DHModel(NamedTuple):
    """A robot's kinematics as standard DH rows between two constant transforms.

    ``fk(q) = T_world_0 @ A_1(q_1) @ ... @ A_n(q_n) @ T_n_tool`` for every ``q``.

    Attributes:
        rows: standard DH rows (m, rad; ``theta`` the offset at ``q = 0``).
        T_world_0: (4, 4) world pose of DH frame 0.
        T_n_tool: (4, 4) pose of the tool in the last DH frame.
        source: ``"dh rows"`` (the robot's own table) or ``"joint axes"`` (built here).
        exact: ``False`` for a snapped table that reproduces ``Robot.fk`` only to
            :data:`NEAR_FK_TOL` (its branches need one Newton step on the robot's axes).
        senses: per joint, +1 or -1: the table's joint variable is ``senses[i] * q[i]``
            (:func:`joint_senses`); empty: all +1.
    """

    rows: tuple[DHJoint, ...]
    T_world_0: FloatArray
    T_n_tool: FloatArray
    source: str
    exact: bool = True
    senses: tuple[float, ...] = ()


class Axes(NamedTuple):
    """Joint axes at ``q = 0`` in the world frame.

    Attributes:
        directions: (n, 3) unit direction of each axis (the joint's positive sense).
        points: (n, 3) a point on each axis (the origin of the chain's joint frame), m.
        tool: (4, 4) world pose of the tool at ``q = 0``.
        size: the arm's size ``L`` (m), the scale of the length tolerance.
    """

    directions: FloatArray
    points: FloatArray
    tool: FloatArray
    size: float


class NoTable(Exception):
    """No equivalent DH table: the message says why (caught inside the package)."""


def revolute_chain_reason(robot: Robot, dof: int) -> str | None:
    """Why ``robot`` is not a plain chain of ``dof`` revolute joints, or ``None``."""
    chain = robot.chain
    if robot.dof != dof:
        return f"{robot.dof} joints (the family takes {dof})"
    if chain.n != dof or not chain.identity:
        return "coupled (mimic) joints"
    if bool(np.any(chain.prismatic)):
        kinds = "".join("P" if p else "R" for p in chain.prismatic.tolist())
        return f"joints {kinds}: the family takes revolute joints only"
    return None


def joint_kinds_reason(robot: Robot, kinds: str) -> str | None:
    """Why ``robot`` is not a plain chain of joints of ``kinds``, or ``None``.

    ``kinds`` spells the joints in order, ``"R"`` (revolute) or ``"P"`` (prismatic) each,
    e.g. ``"RRP"``.
    """
    chain = robot.chain
    if robot.dof != len(kinds):
        return f"{robot.dof} joints (the family takes {len(kinds)})"
    if chain.n != len(kinds) or not chain.identity:
        return "coupled (mimic) joints"
    found = "".join("P" if p else "R" for p in chain.prismatic.tolist())
    if found != kinds:
        return f"joints {found}: the family takes {kinds}"
    return None


def joint_axes(robot: Robot) -> Axes:
    """Each chain joint's axis (direction, point) at ``q = 0``, world frame."""
    K = robot.chain.K
    n = K.shape[0] - 1
    P = K[0].copy()
    directions = np.empty((n, 3))
    points = np.empty((n, 3))
    for i in range(n):
        directions[i] = P[:3, 2] / np.linalg.norm(P[:3, 2])
        points[i] = P[:3, 3]
        P = P @ K[i + 1]
    return Axes(directions, points, P, arm_size(points))


def reversed_axes(axes: Axes) -> Axes:
    """The axes of the chain read backwards, seen from the tool at ``q = 0``.

    ``fk(q) = R_1(q_1) ... R_n(q_n) M`` gives ``fk(q)^-1 = M^-1 R_n(-q_n) ... R_1(-q_1)``:
    a chain whose axes are the original ones in the tool's frame, in reverse order, with
    reversed directions (so its joint values are the original ones), and whose tool at
    ``q = 0`` is ``M^-1``; its targets are the inverses of the original targets.
    """
    M_inv = np.linalg.inv(axes.tool)
    R, t = M_inv[:3, :3], M_inv[:3, 3]
    z = -(axes.directions[::-1] @ R.T)
    p = axes.points[::-1] @ R.T + t
    return Axes(z, p, np.asarray(M_inv, dtype=np.float64), axes.size)


def line_distance(z1: FloatArray, p1: FloatArray, z2: FloatArray, p2: FloatArray) -> float:
    """Distance (m) between two lines (unit directions ``z``, points ``p``)."""
    c = np.cross(z1, z2)
    sn = float(np.linalg.norm(c))
    r = p2 - p1
    if sn <= ANGLE_TOL:
        return float(np.linalg.norm(r - (r @ z1) * z1))
    return abs(float(r @ c)) / sn


def wrist_centre(axes: Axes, first: int = 3) -> FloatArray:
    """(3,) where axes ``first + 1`` and ``first + 2`` meet, in the tool's frame at ``q = 0`` (m).

    The midpoint of the two lines' common normal (axes that meet only to within the
    tolerances meet there best); NaN when they are parallel. With the wrist's first two
    axes (``first``: axes 4 and 5 of a six-joint arm by default) it is fixed in the last
    link, so ``fk(q) @ (c, 1)`` is the wrist centre at any ``q``.
    """
    z4, z5 = axes.directions[first], axes.directions[first + 1]
    p4, p5 = axes.points[first], axes.points[first + 1]
    k = float(z4 @ z5)
    den = 1.0 - k * k
    if den <= ANGLE_TOL * ANGLE_TOL:
        return np.full(3, np.nan)
    r = p5 - p4
    a, b = float(r @ z4), float(r @ z5)
    world = 0.5 * (p4 + (a - k * b) / den * z4 + p5 + (k * a - b) / den * z5)
    R, t = axes.tool[:3, :3], axes.tool[:3, 3]
    return np.asarray(R.T @ (world - t), dtype=np.float64)


def point_line_distance(z: FloatArray, p: FloatArray, x: FloatArray) -> float:
    """Distance (m) of point ``x`` from the line through ``p`` along the unit ``z``."""
    r = x - p
    return float(np.linalg.norm(r - (r @ z) * z))


def arm_size(points: FloatArray) -> float:
    """Summed distances between consecutive joint points (m), at least 1 mm."""
    steps = np.linalg.norm(np.diff(points, axis=0), axis=1) if len(points) > 1 else []
    return max(float(np.sum(steps)), _MIN_SIZE)


def _unit(v: FloatArray) -> FloatArray:
    return np.asarray(v / np.linalg.norm(v), dtype=float)


def _snap_angle(angle: float) -> float:
    """``angle`` set exactly to the nearest multiple of 90 deg when within ANGLE_TOL."""
    quarter = round(angle / (0.5 * math.pi))
    if abs(angle - quarter * 0.5 * math.pi) < ANGLE_TOL:
        return quarter * (0.5 * math.pi)  # exactly math.pi / 2, math.pi, ... (or 0)
    return angle


def _snap_length(value: float, tol: float) -> float:
    return 0.0 if abs(value) < tol else value


def dh_matrix(a: float, alpha: float, d: float, theta: float) -> FloatArray:
    """``Rz(theta) Tz(d) Tx(a) Rx(alpha)``."""
    ct, st = math.cos(theta), math.sin(theta)
    ca, sa = math.cos(alpha), math.sin(alpha)
    return np.array(
        [
            [ct, -st * ca, st * sa, a * ct],
            [st, ct * ca, -ct * sa, a * st],
            [0.0, sa, ca, d],
            [0.0, 0.0, 0.0, 1.0],
        ]
    )


def dh_fk(model: DHModel, q: FloatArray) -> FloatArray:
    """World pose of the tool of ``model`` at ``q`` (dof,), by the DH product."""
    T = model.T_world_0.copy()
    senses = model.senses or (1.0,) * len(model.rows)
    for row, qi, si in zip(model.rows, q.tolist(), senses, strict=True):
        T = T @ dh_matrix(row.a, row.alpha, row.d, row.theta + si * qi)
    return np.asarray(T @ model.T_n_tool, dtype=float)


def equivalent_dh(robot: Robot, signs: tuple[int, ...] = (), snap: bool = True) -> DHModel:
    """An equivalent standard-DH table of a revolute chain, proved by FK.

    The table with near-ideal values set to their ideal when that still reproduces the
    robot's FK to :data:`FK_TOL`, or to :data:`NEAR_FK_TOL` (then marked
    ``exact=False``); otherwise (axes near an ideal relation but not within the
    tolerances of it, e.g. a URDF angle written to 5 digits) the table of the values as
    they are, so that a family's test names the relation that is not exact.

    Args:
        robot: a robot whose chain joints are all revolute, without coupling.
        signs: optional sign (+1 or -1) of ``x_i`` for the first rows, for non-parallel
            consecutive axes: the sign of ``alpha_i`` (and of ``a_i``). Default +1.
        snap: try the snapped table first (default); ``False``: the table of the values
            as they are, always (for a solver that takes any table and needs it exact).

    Returns:
        The table (``source="joint axes"``), with ``T_world_0`` and ``T_n_tool``.

    Raises:
        NoTable: neither table reproduces ``Robot.fk`` to :data:`FK_TOL` (with the size
            of the difference); not expected for a well-formed chain.
    """
    axes = joint_axes(robot)
    if not snap:
        exact = _build(robot, axes, signs, snap=False)
        _prove(robot, exact, axes.size)
        return exact
    snapped = _build(robot, axes, signs, snap=True)
    mismatch = fk_mismatch(robot, snapped, axes.size)
    if mismatch <= FK_TOL:
        return snapped
    if mismatch <= NEAR_FK_TOL:
        return snapped._replace(exact=False)
    exact = _build(robot, axes, signs, snap=False)
    _prove(robot, exact, axes.size)
    return exact


def joint_senses(directions: FloatArray) -> tuple[float, ...]:
    """+1 or -1 per joint: the senses that make each run of parallel axes point alike.

    A joint that turns about the reversed direction of the parallel axis before it
    (a URDF axis written the other way, e.g. the Kinova j2s6s200's third joint) is the
    same joint with ``q -> -q``: the table takes it with its direction reversed and the
    variable ``-q`` (``DHModel.senses``), so that its twist is 0, not 180 deg. Joints
    whose axis is not parallel to the one before keep their sense (a twist absorbs it).
    """
    senses = [1.0]
    for i in range(1, len(directions)):
        u = senses[-1] * directions[i - 1]
        w = directions[i]
        parallel = float(np.linalg.norm(np.cross(u, w))) <= ANGLE_TOL
        senses.append(-1.0 if parallel and float(u @ w) < 0.0 else 1.0)
    return tuple(senses)


def _build(robot: Robot, axes: Axes, signs: tuple[int, ...], snap: bool) -> DHModel:
    """The DH table of the construction (module docstring), optionally snapped."""
    n = len(axes.directions)
    tol = LENGTH_TOL * axes.size
    senses = joint_senses(axes.directions)
    z = axes.directions * np.array(senses)[:, None]
    p = axes.points
    K0 = robot.chain.K[0]
    origin = p[0].copy()
    x_prev = _unit(K0[:3, 0] - (K0[:3, 0] @ z[0]) * z[0])
    frames = [_frame(x_prev, z[0], origin)]
    rows: list[DHJoint] = []
    names = robot.chain_names
    for i in range(n):
        u = z[i]
        if i + 1 < n:
            w = z[i + 1]
            c = np.cross(u, w)
            sn = float(np.linalg.norm(c))
            sign = float(signs[i]) if i < len(signs) and signs[i] else 1.0
            if sn > ANGLE_TOL:
                r = p[i + 1] - origin
                s = float(np.cross(r, w) @ c) / (sn * sn)
                t = float(np.cross(r, u) @ c) / (sn * sn)
                foot = origin + s * u
                nxt = p[i + 1] + t * w
                x = sign * c / sn
                d = float((foot - origin) @ u)
            else:
                foot = origin
                nxt = p[i + 1] + float((origin - p[i + 1]) @ w) * w
                v = nxt - foot
                dist = float(np.linalg.norm(v))
                x = sign * v / dist if dist > tol else x_prev
                d = 0.0
            x = _unit(x - (x @ w) * w)
            a = float((nxt - foot) @ x)
            alpha = math.atan2(float(w @ np.cross(x, u)), float(w @ u))
        else:
            # The last frame: z along the last axis, a = alpha = 0, origin at the foot of
            # the tool point on it.
            w = u
            x = x_prev
            d = float((axes.tool[:3, 3] - origin) @ u)
            nxt = origin + d * u
            a = 0.0
            alpha = 0.0
        theta = math.atan2(float(np.cross(x_prev, x) @ u), float(x_prev @ x))
        rows.append(
            DHJoint(
                a=_snap_length(a, tol) if snap else a,
                alpha=_snap_angle(alpha) if snap else alpha,
                d=_snap_length(d, tol) if snap else d,
                theta=theta,
                name=names[i],
            )
        )
        origin = nxt
        x_prev = x
        frames.append(_frame(x, w, origin))
    T_world_0 = frames[0]
    model = DHModel(tuple(rows), T_world_0, np.eye(4), "joint axes", senses=senses)
    T_n = dh_fk(model, np.zeros(n))
    return model._replace(T_n_tool=np.asarray(np.linalg.solve(T_n, axes.tool), dtype=float))


def _frame(x: FloatArray, z: FloatArray, origin: FloatArray) -> FloatArray:
    T = np.eye(4)
    T[:3, 0] = x
    T[:3, 1] = np.cross(z, x)
    T[:3, 2] = z
    T[:3, 3] = origin
    return T


def fk_mismatch(robot: Robot, model: DHModel, size: float) -> float:
    """Largest scaled entry difference between ``model``'s FK and ``Robot.fk``.

    Over ``q = 0`` and :data:`_CHECK_CONFIGS` random configurations in ``[-pi, pi]``
    (a fixed seed: the same robot always gives the same figure); positions are divided
    by ``max(1 m, size)``.
    """
    rng = np.random.default_rng(20261201)
    Q = np.vstack(
        [np.zeros(robot.dof), rng.uniform(-math.pi, math.pi, (_CHECK_CONFIGS, robot.dof))]
    )
    T_robot = robot.fk(Q)
    scale = max(1.0, size)
    worst = 0.0
    for q, T in zip(Q, T_robot, strict=True):
        diff = np.abs(dh_fk(model, q) - T)
        worst = max(worst, float(np.max(diff[:3, :3])), float(np.max(diff[:3, 3])) / scale)
    return worst


def _prove(robot: Robot, model: DHModel, size: float) -> None:
    """Raise :class:`NoTable` unless ``model`` reproduces ``Robot.fk`` to :data:`FK_TOL`."""
    worst = fk_mismatch(robot, model, size)
    if not worst <= FK_TOL:
        raise NoTable(
            f"the equivalent DH table reproduces the robot's FK only to {worst:.1e} "
            f"(needs {FK_TOL:.0e})"
        )
