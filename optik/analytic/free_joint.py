"""Seven-joint arms around a held joint: the six others by a closed form from their axes.

With joint ``k`` held at ``v``, the chain's product of exponentials (joint axes at
``q = 0``, :func:`optik.analytic.geometry.joint_axes`) is a six-joint one: the axes after
``k`` and the tool's pose at ``q = 0`` turned about axis ``k`` by ``v`` (``R_k(v)
R_j(t) = (R_k(v) R_j(t) R_k(v)^-1) R_k(v)``, a rotation about the turned axis), the axes
before ``k`` as they are. When those six axes are a meeting pair, an elbow and a
spherical wrist (:mod:`optik.analytic.pair_wrist`) the closed form there gives every
branch; when the chain read backwards is (a spherical shoulder before the held joint,
a meeting pair after it: a joint of the wrist held), the same closed form solves the
reversed chain, ``T^-1 = M^-1 R_6(-q_6) ... R_1(-q_1)``, whose axes are the original
ones seen from the tool at ``q = 0``, with reversed directions, in reverse order.

For a spherical-shoulder, spherical-wrist arm (KUKA iiwa: axes 1-3 meet, axes 5-7 meet)
holding joint 1, 2 or 3 gives the direct form, joint 5, 6 or 7 the reversed one; holding
the elbow (joint 4) leaves the shoulder-wrist distance fixed: no closed form.

The structure is decided from the geometry, once per robot and held joint: it must hold
whatever the held value, and does when it holds at three distinct values (whether two
lines meet is a first-order trig polynomial in the angle that turns one of them: the
reciprocal product of their Plücker coordinates).
"""

from __future__ import annotations

from typing import NamedTuple

import numba as nb
import numpy as np

from optik._checks import FloatArray
from optik.analytic._subproblems import rotation
from optik.analytic.geometry import Axes, joint_axes, revolute_chain_reason
from optik.analytic.pair_wrist import pair_wrist_candidates, structure_reason
from optik.model import Robot

_jit = nb.njit(cache=True, nogil=True, error_model="numpy")

CHECK_VALUES = (0.0, 2.0, -2.5)
"""Held values (rad) at which the structure is checked (distinct modulo 2 pi)."""

FREE_DOF = 7
"""Joint count of the arms solved around a held joint."""


class FreeJointPlan(NamedTuple):
    """How a seven-joint robot is solved with one joint held (:func:`free_joint_plan`).

    Attributes:
        held: the held joint's index in ``q``.
        reverse: whether the closed form solves the chain read backwards.
        directions: (7, 3) unit joint directions at ``q = 0`` (world).
        points: (7, 3) a point on each axis (m).
        tool: (4, 4) world pose of the tool at ``q = 0``.
        reason: ``""`` when the six fit, else why not (then the arrays are unused).
    """

    held: int
    reverse: bool
    directions: FloatArray
    points: FloatArray
    tool: FloatArray
    reason: str


def _turned(axes: Axes, k: int, v: float) -> Axes:
    """The six axes (and tool at ``q = 0``) left when joint ``k`` is held at ``v``."""
    R = np.array(rotation(tuple(axes.directions[k].tolist()), v)).reshape(3, 3)
    centre = axes.points[k]
    keep = [j for j in range(len(axes.directions)) if j != k]
    z = np.array([axes.directions[j] if j < k else R @ axes.directions[j] for j in keep])
    p = np.array(
        [axes.points[j] if j < k else R @ (axes.points[j] - centre) + centre for j in keep]
    )
    E = np.eye(4)
    E[:3, :3] = R
    E[:3, 3] = centre - R @ centre
    return Axes(z, p, E @ axes.tool, axes.size)


def _reversed(axes: Axes) -> Axes:
    """The axes of the chain read backwards (seen from the tool at ``q = 0``)."""
    M_inv = np.linalg.inv(axes.tool)
    R, t = M_inv[:3, :3], M_inv[:3, 3]
    z = -(axes.directions[::-1] @ R.T)
    p = axes.points[::-1] @ R.T + t
    return Axes(z, p, np.asarray(M_inv, dtype=np.float64), axes.size)


def free_joint_plan(robot: Robot, k: int) -> FreeJointPlan:
    """Whether (and how) ``robot`` with joint ``k`` held has the pair-wrist closed form."""
    axes = joint_axes(robot)
    empty = np.empty((0, 3))
    base = FreeJointPlan(k, False, axes.directions, axes.points, axes.tool, "")
    reason = revolute_chain_reason(robot, FREE_DOF)
    if reason is not None:
        return base._replace(directions=empty, points=empty, reason=reason)
    names = tuple(n for j, n in enumerate(robot.chain_names) if j != k)
    reasons = []
    for reverse in (False, True):
        why = None
        for v in CHECK_VALUES:
            six = _turned(axes, k, v)
            if reverse:
                why = structure_reason(_reversed(six), names[::-1])
            else:
                why = structure_reason(six, names)
            if why is not None:
                why = f"{why} (joint {robot.chain_names[k]!r} at {v:g} rad)"
                break
        if why is None:
            return base._replace(reverse=reverse)
        reasons.append(why)
    return base._replace(
        reason=f"the other six joints in order: {reasons[0]}; read backwards: {reasons[1]}"
    )


@_jit
def free_joint_candidates(
    z7: np.ndarray,
    p7: np.ndarray,
    tool: np.ndarray,
    k: int,
    value: float,
    reverse: bool,
    T: np.ndarray,
    ref: np.ndarray,
    tols: np.ndarray,
    cand: np.ndarray,
) -> int:
    """Raw seven-joint branches (joint ``k`` at ``value``) of world target ``T`` into ``cand``.

    The held joint's axis turns the axes after it (module docstring); the six are solved
    by :func:`optik.analytic.pair_wrist.pair_wrist_candidates`, directly or read
    backwards. ``ref`` (7,) gives the free angles' references; ``cand`` (>= 8, 7).
    Returns the number of rows written.
    """
    R = rotation((z7[k, 0], z7[k, 1], z7[k, 2]), value)
    c = (p7[k, 0], p7[k, 1], p7[k, 2])
    z = np.empty((6, 3))
    p = np.empty((6, 3))
    r6 = np.empty(6)
    M = np.empty((4, 4))
    j = 0
    for i in range(7):
        if i == k:
            continue
        r6[j] = ref[i]
        if i < k:
            for a in range(3):
                z[j, a] = z7[i, a]
                p[j, a] = p7[i, a]
        else:
            for a in range(3):
                z[j, a] = R[3 * a] * z7[i, 0] + R[3 * a + 1] * z7[i, 1] + R[3 * a + 2] * z7[i, 2]
                p[j, a] = (
                    R[3 * a] * (p7[i, 0] - c[0])
                    + R[3 * a + 1] * (p7[i, 1] - c[1])
                    + R[3 * a + 2] * (p7[i, 2] - c[2])
                    + c[a]
                )
        j += 1
    for a in range(3):
        for b in range(4):
            M[a, b] = R[3 * a] * tool[0, b] + R[3 * a + 1] * tool[1, b] + R[3 * a + 2] * tool[2, b]
        M[a, 3] += c[a] - (R[3 * a] * c[0] + R[3 * a + 1] * c[1] + R[3 * a + 2] * c[2])
    M[3, 0] = M[3, 1] = M[3, 2] = 0.0
    M[3, 3] = 1.0
    out = np.empty((cand.shape[0], 6))
    if not reverse:
        n = pair_wrist_candidates(z, p, M, T, r6, tols, out)
    else:
        # Read backwards: axes seen from the tool at q = 0, reversed, in reverse order;
        # target T^-1, home M^-1.
        Mi = _inverse(M)
        zr = np.empty((6, 3))
        pr = np.empty((6, 3))
        rr = np.empty(6)
        for i in range(6):
            src = 5 - i
            rr[i] = r6[src]
            for a in range(3):
                zr[i, a] = -(Mi[a, 0] * z[src, 0] + Mi[a, 1] * z[src, 1] + Mi[a, 2] * z[src, 2])
                pr[i, a] = (
                    Mi[a, 0] * p[src, 0] + Mi[a, 1] * p[src, 1] + Mi[a, 2] * p[src, 2] + Mi[a, 3]
                )
        n = pair_wrist_candidates(zr, pr, Mi, _inverse(T), rr, tols, out)
        for r in range(n):
            for i in range(3):
                out[r, i], out[r, 5 - i] = out[r, 5 - i], out[r, i]
    for r in range(n):
        j = 0
        for i in range(7):
            if i == k:
                cand[r, i] = value
            else:
                cand[r, i] = out[r, j]
                j += 1
    return n


@_jit
def _inverse(T: np.ndarray) -> np.ndarray:
    """Inverse of a rigid transform (4, 4): ``[R^T, -R^T t]``."""
    out = np.zeros((4, 4))
    for a in range(3):
        for b in range(3):
            out[a, b] = T[b, a]
        out[a, 3] = -(T[0, a] * T[0, 3] + T[1, a] * T[1, 3] + T[2, a] * T[2, 3])
    out[3, 3] = 1.0
    return out


__all__ = ["FREE_DOF", "FreeJointPlan", "free_joint_candidates", "free_joint_plan"]
