"""The numpy steps after a closed form: wrap into the limits, filter, verify, dedupe, sort.

:func:`optik.analytic.analytic_ik` runs them on the raw branches of the families whose
closed form returns rows to Python, and on what the polish of a degenerate pose returns;
the compiled pipelines (:mod:`optik.analytic._pipeline`) run the same steps, row for row.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from optik._checks import MAX_LENGTH_M, FloatArray
from optik.analytic._base import (
    DUPLICATE_TOLERANCE,
    LIMIT_CLIP,
    VERIFY_TOLERANCE,
    verify_position_tolerance,
)
from optik.model import Robot
from optik.spatial import rotation_angle
from optik.verify import beyond_reach


def wrap_into_limits(
    Q: FloatArray,
    robot: Robot,
    q_ref: FloatArray,
    bounds: tuple[FloatArray, FloatArray] | None = None,
) -> FloatArray:
    """Shift revolute angles by multiples of 2 pi into the limits, nearest ``q_ref``.

    ``Q`` is (..., dof), ``q_ref`` broadcasts against it. A joint whose range spans more
    than 2 pi has several representatives: the one nearest ``q_ref`` is kept. An angle
    with no representative inside its limits stays at the representative nearest
    ``q_ref``. ``bounds``: a query's box ``(lower, upper)`` (frozen joints, a
    ``limit_margin``) instead of the robot's limits; a joint whose box has no width gets
    the box's value, to the bit, when a representative lies within 1e-9 rad of it.
    """
    two_pi = 2.0 * math.pi
    revolute, lower, upper = robot.cached(_wrap_bounds)
    if bounds is not None:
        lower, upper = bounds
    base = q_ref + np.remainder(Q - q_ref + math.pi, two_pi) - math.pi
    # Representatives base + 2 pi k inside [lower, upper]: k in [k_min, k_max].
    with np.errstate(invalid="ignore"):
        k_min = np.ceil((lower - base) / two_pi - 1e-12)
        k_max = np.floor((upper - base) / two_pi + 1e-12)
        k_near = np.round((q_ref - base) / two_pi)
    k = np.where(np.isfinite(k_min), np.maximum(k_near, k_min), k_near)
    k = np.where(np.isfinite(k_max), np.minimum(k, k_max), k)
    k = np.where(k_min > k_max, 0.0, k)
    k = np.where(np.isfinite(k), k, 0.0)
    wrapped = np.where(revolute, base + two_pi * k, Q)
    # A frozen joint (a box of zero width) gets the box's value to the bit, from the
    # angle or a 2 pi twin of it: the round trip through the remainder moves 2 % of
    # angles by an ulp.
    with np.errstate(invalid="ignore"):
        onto_box = revolute & (lower == upper) & (np.abs(wrapped - lower) <= _ON_BOX)
    return np.where(onto_box, lower, wrapped)


_ON_BOX = 1e-9
"""Largest distance (rad) of a representative from a zero-width box that is put on it."""


def _wrap_bounds(robot: Robot) -> tuple[NDArray[np.bool_], FloatArray, FloatArray]:
    """What :func:`wrap_into_limits` reads of the robot, kept per robot.

    ``(revolute, lower, upper)`` (dof,) each: which joints are revolute, and the limits
    with a limit that is not finite read as none.
    """
    revolute = np.array([j.kind == "revolute" for j in robot.joints])
    lower = np.where(np.isfinite(robot.lower), robot.lower, -np.inf)
    upper = np.where(np.isfinite(robot.upper), robot.upper, np.inf)
    for array in (revolute, lower, upper):
        array.flags.writeable = False
    return revolute, lower, upper


def _beyond_reach(robot: Robot, T_target: FloatArray, within_limits: bool = True) -> bool:
    """Whether the target (4, 4) lies beyond the reach sphere: a proof of no branch.

    The sphere's one test (:func:`optik.verify.beyond_reach`), free of overflow: a
    target 1e155 m away is ruled out. The sphere counts prismatic strokes up to their
    limits: for branches outside the limits (``within_limits=False``) it proves nothing
    on an arm with a prismatic joint.
    """
    return bool(beyond_reach_rows(robot, T_target[None], within_limits)[0])


def beyond_reach_rows(
    robot: Robot, T_targets: FloatArray, within_limits: bool = True
) -> NDArray[np.bool_]:
    """:func:`_beyond_reach` of each target of ``T_targets`` (N, 4, 4): (N,) bool."""
    if not within_limits and not robot.cached(_wrap_bounds)[0].all():  # a prismatic joint
        return np.zeros(len(T_targets), dtype=bool)
    return np.asarray(beyond_reach(robot, T_targets[:, :3, 3]), dtype=bool)


def _finish(
    robot: Robot,
    raw: list[FloatArray],
    T_target: FloatArray,
    mode: str,
    ref: FloatArray,
    sort: bool,
    within_limits: bool,
    held: tuple[int, float] | None = None,
) -> list[FloatArray]:
    """Wrap, filter by the limits, verify by FK, dedupe and sort raw branches (numpy).

    The steps of the compiled pipeline (:func:`optik.analytic._pipeline.solve`), for the
    families that run in Python: :func:`finish_batch` of one target. ``held = (index,
    value)``: that joint keeps exactly ``value`` (no 2 pi shift).
    """
    return finish_batch(robot, [raw], T_target[None], mode, ref[None], sort, within_limits, held)[0]


def finish_batch(
    robot: Robot,
    raws: list[list[FloatArray]],
    T_targets: FloatArray,
    mode: str,
    refs: FloatArray,
    sort: bool,
    within_limits: bool,
    held: tuple[int, float] | None = None,
) -> list[list[FloatArray]]:
    """:func:`_finish` of many targets: each step once over every target's rows.

    ``raws[k]`` are the raw branches (dof,) of target ``T_targets[k]`` (4, 4), with the
    reference ``refs[k]`` (dof,). The wrap, the limits and the FK check are elementwise
    (numpy, one compiled FK over all rows), so target ``k`` gets exactly the branches
    :func:`_finish` gives it alone; the dedupe and the sort then run per target.
    """
    counts = [len(raw) for raw in raws]
    finished: list[list[FloatArray]] = [[] for _ in raws]
    if not any(counts):
        return finished
    Q = np.array([q for raw in raws for q in raw], dtype=float)
    owner = np.repeat(np.arange(len(raws)), counts)
    # Finite rows inside the length range: a slide's branch 1e150 m out (a target as far
    # away) is no configuration that FK can judge.
    keep = np.all(np.abs(Q) <= MAX_LENGTH_M, axis=1)
    Q, owner = Q[keep], owner[keep]
    # One target (every single call): its reference and pose broadcast, not gathered.
    single = len(raws) == 1
    Q = wrap_into_limits(Q, robot, refs[0] if single else refs[owner])
    if held is not None:
        Q[:, held[0]] = held[1]
    if within_limits:
        keep = np.asarray(robot.within_limits(Q, LIMIT_CLIP), dtype=bool).reshape(-1)
        # Onto the bound a row off it by rounding (a branch at its limit): answers inside
        # their limits, which the FK check below judges (the held joint keeps its value).
        Q, owner = np.clip(Q[keep], robot.lower, robot.upper), owner[keep]
        if held is not None:
            Q[:, held[0]] = held[1]
    if len(Q) == 0:
        return finished
    keep = _verified(robot, Q, T_targets[0] if single else T_targets[owner], mode)
    for q, k in zip(Q[keep], owner[keep].tolist(), strict=True):
        branches = finished[k]
        if any(np.max(np.abs(q - other)) < DUPLICATE_TOLERANCE for other in branches):
            continue
        branches.append(q)
    if sort:
        for ref, branches in zip(refs, finished, strict=True):
            if len(branches) > 1:
                branches.sort(key=lambda q: float(np.linalg.norm(q - ref)))
    return finished


def _verified(robot: Robot, Q: FloatArray, T_target: FloatArray, mode: str) -> NDArray[np.bool_]:
    """(k,) whether each row of ``Q`` (k, dof) reaches its target by ``Robot.fk``.

    ``T_target`` is one target (4, 4) for every row or one per row (k, 4, 4). Position
    error within :func:`verify_position_tolerance` (m) and, in pose mode, the rotation
    angle within :data:`VERIFY_TOLERANCE` (rad); a row with a NaN is not verified.
    """
    T = robot.fk(Q)
    position_tol = robot.cached(verify_position_tolerance)
    with np.errstate(over="ignore"):  # a target 1e300 m away: an infinite miss
        good = np.linalg.norm(T[:, :3, 3] - T_target[..., :3, 3], axis=1) <= position_tol
    if mode == "pose":
        R_rel = np.swapaxes(T[:, :3, :3], 1, 2) @ T_target[..., :3, :3]
        angle = np.asarray(rotation_angle(R_rel), dtype=float).reshape(-1)
        good &= angle <= VERIFY_TOLERANCE
    return np.asarray(good, dtype=bool)
