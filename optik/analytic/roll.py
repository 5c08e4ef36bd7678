"""Closed forms for the tool-axis task: the free roll as a one-parameter family of poses.

In ``mode="axis"`` the target fixes the tool point and one tool axis ``a`` (the column
``k`` of the target's rotation); the roll about ``a`` is free. Every answer of the axis
task is a full-pose answer of one of the poses ``T(θ) = T* · Rot_k(θ)``, θ in [-π, π):
all of them have the tool point at ``p*`` and the tool axis along ``a``. A closed-form
family therefore solves the axis task one roll at a time.

:func:`axis_branches` samples the roll on a grid (:data:`ROLL_GRID` rolls, one batched
compiled call of :func:`optik.analytic.analytic_ik_batch`), links the samples of
neighbouring rolls into continuations of the branches (nearest configuration, angles
compared modulo 2π), and refines every local minimum of ``||q(θ) − q_ref||²`` along its
continuation by a bracketed one-dimensional search over θ (parabolic steps safeguarded
by golden sections as in Brent's method, and golden sections alone where the distance
jumps: a continuation that ends at a wrist singularity; batched over all minima). Where
the number of branches changes between two grid rolls (a fold, where a pair of branches
is born or dies), the interval is sampled :data:`FOLD_SAMPLES` times finer and its
sample nearest each reference is refined too: a branch living on less than a grid step
is searched as well. The rolled poses skip the polish
:func:`optik.analytic.analytic_ik_batch` gives a pose without a branch
(:func:`optik.analytic.checked_batch`): a roll out of reach has none.

What is guaranteed: every configuration returned is a closed-form branch of one rolled
pose, verified by forward kinematics there (:data:`optik.analytic.VERIFY_TOLERANCE`), so it
is exact in the axis task, and it lies inside the given bounds. What is not: the nearest
answer is the nearest over the grid, refined locally (a minimum of a continuation between
two grid rolls, or one the grid does not resolve, can be missed: a pair of branches born
and dying between two grid rolls of equal branch counts); and an empty grid is no
proof that the task has no answer (a stretch of roll narrower than the grid step can be
missed), so callers fall back to a numeric search instead of reporting ``unreachable``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from optik._checks import FloatArray
from optik.analytic import checked_batch, family_of, wrap_into_limits
from optik.analytic._base import DUPLICATE_TOLERANCE, AnalyticFamily
from optik.errors import AnalyticIKError
from optik.model import Robot
from optik.task import Task

ROLL_GRID = 48
"""Rolls sampled over [-π, π) (a step of 7.5°)."""

ROLL_TOLERANCE = 1e-7
"""A refinement stops when its roll bracket is this narrow or its parabolic step this
short (rad). Near a minimum the distance changes by about the square of the roll's
error, so the answer's distance is within ~1e-14 of the continuation's minimum."""

FOLD_SAMPLES = 8
"""Sub-intervals a grid interval is cut into where the number of branches changes from one
grid roll to the next (a fold of the closed form, where a pair of branches is born or
dies): a branch that lives on a stretch of roll shorter than the grid step is sampled
there (:func:`_fold_starts`)."""

MAX_REFINE_ROUNDS = 60
"""Most rounds of the bracketed search (each one batched call over the open minima)."""

_GOLDEN = 0.5 * (3.0 - math.sqrt(5.0))  # 0.381966...


@dataclass(frozen=True)
class RollBranches:
    """The axis task's closed-form answers for one reference configuration.

    Attributes:
        nearest: the refined local minima of ``||q − q_ref||`` along each continuation of
            a branch over the roll, nearest ``q_ref`` first (each (dof,), inside the
            bounds, exact in the axis task).
        samples: (M, dof) the grid's branches inside the bounds, nearest ``q_ref`` first.
        outside: (K, dof) the grid's branches outside the bounds (starting points for a
            numeric search when ``nearest`` is empty).
    """

    nearest: list[FloatArray]
    samples: FloatArray
    outside: FloatArray


def solves_axis_task(family: AnalyticFamily, task: Task) -> bool:
    """Whether ``task`` is a free roll that ``family``'s full-pose closed form solves.

    ``mode="axis"`` with every position axis constrained (any positive weights: the set of
    exact answers is the same): its answers are the full-pose answers of the target
    turned about its axis.
    """
    return task.mode == "axis" and task.constrains_position and "pose" in family.modes


def roll_grid(grid: int = ROLL_GRID) -> FloatArray:
    """(grid,) the rolls sampled over [-π, π): ``-π + 2π k / grid`` (rad)."""
    return -math.pi + (2.0 * math.pi / grid) * np.arange(grid, dtype=np.float64)


def rolled_poses(T_target: FloatArray, axis: int, rolls: FloatArray) -> FloatArray:
    """(N, 4, 4) the poses ``T_target · Rot_axis(θ)`` for the rolls θ (N,) (rad).

    ``axis`` is the index (0 x, 1 y, 2 z) of the target-frame axis turned about; that
    column of the rotation and the translation stay those of ``T_target``.
    """
    c, s = np.cos(rolls), np.sin(rolls)
    i, j = (axis + 1) % 3, (axis + 2) % 3
    R = np.zeros((len(rolls), 3, 3))
    R[:, axis, axis] = 1.0
    R[:, i, i] = c
    R[:, j, j] = c
    R[:, j, i] = s
    R[:, i, j] = -s
    poses = np.broadcast_to(T_target, (len(rolls), 4, 4)).copy()
    poses[:, :3, :3] = T_target[:3, :3] @ R
    return poses


class _Roll:
    """The rolled-pose family of one target on one robot, inside the bounds given."""

    def __init__(
        self, robot: Robot, T_target: FloatArray, axis: int, lower: FloatArray, upper: FloatArray
    ) -> None:
        self.robot, self.T, self.axis = robot, T_target, axis
        self.family = _pose_family(robot)
        self.lower, self.upper = lower, upper
        self.revolute = np.array([j.kind == "revolute" for j in robot.joints])

    def branches(self, rolls: FloatArray, refs: FloatArray | None) -> FloatArray:
        """Every branch (N, B, dof) at each roll (NaN rows past a roll's count).

        With ``refs`` (N, dof) the branches of roll ``n`` are wrapped and sorted nearest
        ``refs[n]`` (so ``[:, 0]`` continues ``refs``); limits are not applied here.
        """
        poses = rolled_poses(self.T, self.axis, rolls)
        return _pose_branches(self.robot, self.family, poses, refs)

    def inside(self, Q: FloatArray) -> np.ndarray:
        """Whether each configuration (..., dof) is finite and inside the bounds."""
        with np.errstate(invalid="ignore"):
            return np.all((self.lower <= Q) & (self.upper >= Q), axis=-1)

    def cost(self, Q: FloatArray, refs: FloatArray) -> tuple[FloatArray, FloatArray]:
        """``Q`` wrapped nearest ``refs`` and its squared distance to them (inf outside)."""
        V = wrap_into_limits(Q, self.robot, refs)
        d2 = np.sum((V - refs) ** 2, axis=-1)
        return V, np.where(self.inside(V), d2, math.inf)

    def link_distance(self, A: FloatArray, B: FloatArray) -> FloatArray:
        """Largest joint difference of ``A`` and ``B`` (..., dof), angles modulo 2π."""
        D = A - B
        D = np.where(self.revolute, np.remainder(D + math.pi, 2.0 * math.pi) - math.pi, D)
        with np.errstate(invalid="ignore"):
            return np.max(np.abs(D), axis=-1)


def _pose_family(robot: Robot) -> AnalyticFamily:
    """The robot's closed-form family, which must solve full poses.

    Raises:
        AnalyticIKError: the robot has no family, or its family does not solve poses.
    """
    family = family_of(robot)
    if family is None or "pose" not in family.modes:
        raise AnalyticIKError(
            f"robot {robot.name!r}: the roll's closed form needs a family that solves "
            f"full poses, found {family.name if family else 'none'!r}"
        )
    return family


def _pose_branches(
    robot: Robot, family: AnalyticFamily, poses: FloatArray, refs: FloatArray | None
) -> FloatArray:
    """Every branch (N, B, dof) of the rolled ``poses`` (N, 4, 4), limits not applied.

    :func:`optik.analytic.analytic_ik_batch` without its arguments' checks (the poses
    are a validated target turned) and without the polish of poses that have no
    branch (:func:`optik.analytic.checked_batch`): the roll is sampled, and where it
    has no branch (a roll out of reach) the polish would search in vain. With ``refs``
    (1 or N, dof) each pose's branches are wrapped and sorted nearest its reference.
    """
    return checked_batch(robot, family, poses, "pose", refs, False, polish=False).q


def _links(roll: _Roll, Q: FloatArray) -> tuple[np.ndarray, np.ndarray]:
    """The links of the grid samples (N, B) along the roll.

    For each sample: the sample that continues it at the next roll and the one at the
    previous roll (the nearest, -1 where that roll has none).
    """
    following = np.roll(Q, -1, axis=0)  # roll n + 1 (cyclic: the roll is periodic)
    D = roll.link_distance(Q[:, :, None, :], following[:, None, :, :])  # (N, B, B)
    D = np.where(np.isnan(D), math.inf, D)
    nxt = np.argmin(D, axis=2)
    nxt = np.where(np.isfinite(np.min(D, axis=2)), nxt, -1)
    # Previous: the nearest sample at roll n - 1, i.e. the transpose of the pairs above.
    Dp = np.swapaxes(np.roll(D, 1, axis=0), 1, 2)  # Dp[n, b, b'] = D[n-1, b', b]
    prv = np.argmin(Dp, axis=2)
    prv = np.where(np.isfinite(np.min(Dp, axis=2)), prv, -1)
    return nxt, prv


def _neighbour_cost(F: FloatArray, link: np.ndarray, shift: int) -> FloatArray:
    """``F`` (S, N, B) of the linked sample at roll ``n + shift`` (inf where none)."""
    N = F.shape[1]
    rows = (np.arange(N) + shift) % N
    picked = F[:, rows[:, None], np.maximum(link, 0)]  # (S, N, B)
    return np.where(link[None] >= 0, picked, math.inf)


def _refine(
    roll: _Roll,
    refs: FloatArray,
    x: FloatArray,
    qx: FloatArray,
    fx: FloatArray,
    fa: FloatArray,
    fb: FloatArray,
    h: float | FloatArray,
) -> tuple[FloatArray, FloatArray]:
    """Minimise ``||q(θ) − ref||²`` along each continuation, in [x − h, x + h].

    Each minimum ``m`` starts at the grid roll ``x[m]`` (configuration ``qx[m]``, cost
    ``fx[m]``) with the costs ``fa``, ``fb`` of its neighbours at ``x ∓ h``; ``q(θ)`` is
    the branch at roll θ nearest the current best (its continuation). Returns the refined
    configurations (M, dof) and costs (M,): never worse than the starting ones.
    """
    a, b = x - h, x + h
    x, qx, fx = x.copy(), qx.copy(), fx.copy()
    fa, fb = fa.copy(), fb.copy()
    # Brent's safeguard: a parabolic step must be shorter than half the step before the
    # last one, else a golden section, which shrinks the bracket by 0.618 at the least.
    last = np.broadcast_to(np.asarray(h, dtype=np.float64), x.shape).copy()
    before_last = 2.0 * last
    open_ = np.ones(len(x), dtype=bool)
    for _ in range(MAX_REFINE_ROUNDS):
        open_ &= b - a > ROLL_TOLERANCE
        active = np.flatnonzero(open_)
        if active.size == 0:
            break
        A, X, Bv = a[active], x[active], b[active]
        FA, FX, FB = fa[active], fx[active], fb[active]
        # A parabola through the bracket's three points, where it is one.
        with np.errstate(invalid="ignore", divide="ignore"):
            r = (X - A) * (FX - FB)
            p = (X - Bv) * (FX - FA)
            u = X - 0.5 * ((X - A) * r - (X - Bv) * p) / (r - p)
        right = Bv - X > X - A
        golden = np.where(right, X + _GOLDEN * (Bv - X), X - _GOLDEN * (X - A))
        room = 0.01 * (Bv - A)
        usable = np.isfinite(u) & (u > A + room) & (u < Bv - room)
        usable &= np.abs(u - X) < 0.5 * before_last[active]
        # Nor where the two sides' curvatures differ a hundredfold: the cost jumps there
        # (a continuation ends at a wrist singularity, falling steeply towards it), and a
        # parabola through the jump creeps towards it; golden sections find it.
        with np.errstate(invalid="ignore", over="ignore"):
            left_curv = (FA - FX) * (Bv - X) ** 2
            right_curv = (FB - FX) * (X - A) ** 2
        usable &= (left_curv <= 100.0 * right_curv) & (right_curv <= 100.0 * left_curv)
        # A parabolic step shorter than the tolerance: the minimum is found.
        settled = usable & (np.abs(u - X) < ROLL_TOLERANCE)
        open_[active[settled]] = False
        before_last[active] = np.where(usable, last[active], np.where(right, Bv - X, X - A))
        u = np.where(usable, u, golden)
        last[active] = np.abs(u - X)
        Q = roll.branches(u, qx[active])
        qu, fu = roll.cost(Q[:, 0], refs[active])
        better = fu < FX
        left = u < X
        # The bracket keeps the best point inside it (the classic update).
        a[active] = np.where(better, np.where(left, A, X), np.where(left, u, A))
        fa[active] = np.where(better, np.where(left, FA, FX), np.where(left, fu, FA))
        b[active] = np.where(better, np.where(left, X, Bv), np.where(left, Bv, u))
        fb[active] = np.where(better, np.where(left, FX, FB), np.where(left, FB, fu))
        x[active] = np.where(better, u, X)
        fx[active] = np.where(better, fu, FX)
        qx[active] = np.where(better[:, None], qu, qx[active])
    return qx, fx


def _distinct_rows(Q: FloatArray) -> list[FloatArray]:
    """The rows of ``Q`` (M, dof) in order, without repeats (max-abs below 1e-9).

    Two minima of one continuation can meet at a bracket's end.
    """
    if len(Q) == 0:
        return []
    D = np.max(np.abs(Q[:, None, :] - Q[None, :, :]), axis=2)
    repeat = np.any(np.tril(D < DUPLICATE_TOLERANCE, k=-1), axis=1)
    return list(Q[~repeat])


def _fold_starts(
    roll: _Roll, rolls: FloatArray, Q: FloatArray, refs: FloatArray, h: float
) -> tuple[np.ndarray, FloatArray, FloatArray, FloatArray]:
    """Starts of the search inside the grid intervals where the branch count changes.

    ``Q`` (N, B, dof) the branches at the grid ``rolls`` (N,), step ``h``; ``refs`` (S,
    dof). Each such interval is sampled at :data:`FOLD_SAMPLES` - 1 inner rolls; for each
    reference, its in-bound sample nearest the reference is a start. Returns ``(owner,
    x, q, f)``: the reference index (E,), roll (E,), wrapped configuration (E, dof) and
    squared distance (E,) of each start.
    """
    counts = np.sum(np.all(np.isfinite(Q), axis=-1), axis=1)
    changed = np.flatnonzero(counts != np.roll(counts, -1))  # interval n .. n + 1
    dof = Q.shape[-1]
    if changed.size == 0:
        return np.zeros(0, dtype=int), np.zeros(0), np.zeros((0, dof)), np.zeros(0)
    inner = FOLD_SAMPLES - 1
    sub = rolls[changed][:, None] + h * np.arange(1, FOLD_SAMPLES) / FOLD_SAMPLES
    Qs = roll.branches(sub.ravel(), None)  # (C * inner, B', dof)
    V, F = roll.cost(Qs[None], refs[:, None, None, :])
    S, C, width = len(refs), len(changed), Qs.shape[1]
    F = F.reshape(S, C, inner * width)
    V = V.reshape(S, C, inner * width, dof)
    best = np.argmin(F, axis=2)  # (S, C)
    f = np.take_along_axis(F, best[..., None], axis=2)[..., 0]
    owner, interval = np.nonzero(np.isfinite(f))
    j = best[owner, interval]
    return owner, sub[interval, j // width], V[owner, interval, j], f[owner, interval]


def axis_branches(
    robot: Robot,
    T_target: FloatArray,
    axis: int,
    q_refs: FloatArray,
    lower: FloatArray | None = None,
    upper: FloatArray | None = None,
    *,
    grid: int = ROLL_GRID,
    per_ref: int | None = None,
) -> list[RollBranches]:
    """The closed-form answers of the axis task nearest each reference.

    Args:
        robot: a robot whose closed-form family solves full poses.
        T_target: (4, 4) validated world target; its column ``axis`` is the tool axis's
            direction and its translation the tool point (m).
        axis: index of the tool axis (0 x, 1 y, 2 z).
        q_refs: (S, dof) reference configurations (rad, m).
        lower: (dof,) lower bounds of the answers (default: the robot's limits).
        upper: (dof,) upper bounds of the answers (default: the robot's limits).
        grid: rolls sampled over [-π, π).
        per_ref: refine at most this many local minima per reference, the lowest on
            the grid first (default: all).

    Returns:
        One :class:`RollBranches` per reference (see the module for what is guaranteed).

    Raises:
        AnalyticIKError: the robot has no closed-form family that solves full poses.
    """
    lower = robot.lower if lower is None else lower
    upper = robot.upper if upper is None else upper
    roll = _Roll(robot, T_target, axis, lower, upper)
    dof = robot.dof
    h = 2.0 * math.pi / grid
    rolls = roll_grid(grid)
    refs = np.asarray(q_refs, dtype=float).reshape(-1, dof)
    S = len(refs)
    # With one reference, a joint left free at a singular roll (an aligned wrist's turn)
    # takes the reference's value, as a pose's closed form does from its q_ref: from
    # mid-limits the answers at a singular waypoint would all hold it there.
    Q = roll.branches(rolls, refs if S == 1 else None)  # (N, B, dof)
    B = Q.shape[1]
    nxt, prv = _links(roll, Q)
    V, F = roll.cost(Q[None], refs[:, None, None, :])  # (S, N, B, dof), (S, N, B)
    f_next = _neighbour_cost(F, nxt, 1)
    f_prev = _neighbour_cost(F, prv, -1)
    minimum = np.isfinite(F) & (f_next >= F) & (f_prev >= F)
    chosen: list[np.ndarray] = []
    for s in range(S):
        flat = np.flatnonzero(minimum[s].ravel())
        flat = flat[np.argsort(F[s].ravel()[flat], kind="stable")]
        chosen.append(flat if per_ref is None else flat[:per_ref])
    owner = np.concatenate([np.full(len(c), s) for s, c in enumerate(chosen)]).astype(int)
    flat = np.concatenate(chosen).astype(int) if chosen else np.zeros(0, dtype=int)
    n_idx, b_idx = np.divmod(flat, B)
    # Folds between grid rolls: their nearest samples start searches of their own, in
    # one sub-interval each (no neighbour on a continuation: golden sections).
    e_owner, e_x, e_q, e_f = _fold_starts(roll, rolls, Q, refs, h)
    if per_ref is not None:
        order = np.lexsort((e_f, e_owner))
        rank = np.arange(len(order)) - np.searchsorted(e_owner[order], e_owner[order])
        e_owner, e_x, e_q, e_f = (v[order][rank < per_ref] for v in (e_owner, e_x, e_q, e_f))
    infinite = np.full(len(e_owner), math.inf)
    qx, fx = _refine(
        roll,
        refs[np.concatenate([owner, e_owner])],
        np.concatenate([rolls[n_idx], e_x]),
        np.concatenate([V[owner, n_idx, b_idx], e_q]),
        np.concatenate([F[owner, n_idx, b_idx], e_f]),
        np.concatenate([f_prev[owner, n_idx, b_idx], infinite]),
        np.concatenate([f_next[owner, n_idx, b_idx], infinite]),
        np.concatenate([np.full(len(flat), h), np.full(len(e_owner), h / FOLD_SAMPLES)]),
    )
    owner = np.concatenate([owner, e_owner])
    finite = np.all(np.isfinite(Q), axis=-1)
    results = []
    for s in range(S):
        mine = np.flatnonzero(owner == s)
        mine = mine[np.argsort(fx[mine], kind="stable")]
        nearest = _distinct_rows(qx[mine])
        keep = np.isfinite(F[s])
        order = np.argsort(F[s][keep], kind="stable")
        results.append(
            RollBranches(nearest, V[s][keep][order], V[s][finite & ~keep].reshape(-1, dof))
        )
    return results


def grid_branches(
    robot: Robot,
    T_target: FloatArray,
    axis: int,
    q_ref: FloatArray,
    lower: FloatArray | None = None,
    upper: FloatArray | None = None,
    *,
    grid: int = ROLL_GRID,
    keep: int = 8,
) -> RollBranches:
    """The grid's closed-form answers nearest ``q_ref``, without refining the roll.

    What :func:`axis_branches` starts from, for a caller that wants an exact answer fast
    rather than the nearest one (``solve_ik(..., select="first")``): one batched
    closed-form call over the grid; ``nearest`` holds the ``keep`` distinct in-bound
    branches nearest ``q_ref`` (each exact in the axis task, verified by FK), ``samples``
    all of them, ``outside`` the rest. The arguments are :func:`axis_branches`'s.

    Raises:
        AnalyticIKError: the robot has no closed-form family that solves full poses.
    """
    dof = robot.dof
    rolls = roll_grid(grid)
    poses = rolled_poses(T_target, axis, rolls)
    ref = np.broadcast_to(np.asarray(q_ref, dtype=float).reshape(dof), (grid, dof))
    # The compiled pipeline wraps every branch into the limits nearest the reference.
    Q = _pose_branches(robot, _pose_family(robot), poses, ref)
    Q = Q.reshape(-1, dof)
    Q = Q[np.all(np.isfinite(Q), axis=1)]
    lo = robot.lower if lower is None else lower
    hi = robot.upper if upper is None else upper
    inside = np.all((lo <= Q) & (hi >= Q), axis=1)
    V = Q[inside]
    samples = V[np.argsort(np.sum((V - ref[0]) ** 2, axis=1), kind="stable")]
    return RollBranches(_distinct_rows(samples[:keep]), samples, Q[~inside])
