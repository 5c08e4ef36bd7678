"""Limit-aware preprocessing of Cartesian paths: a continuous joint path, or exact flags.

:func:`plan_path` collects, at every waypoint, every candidate configuration inside the
limits (all closed-form branches when the robot has a family; in ``mode="axis"`` the
roll's closed form, :mod:`optik.analytic.roll`, nearest each previous candidate;
otherwise numeric solutions seeded from the previous waypoint's candidates and from
seeded restarts), then chooses one candidate per waypoint by dynamic programming over the
whole sequence: it minimises the number of steps whose largest single-joint motion
exceeds ``max_joint_step`` (branch switches), then the path's cost

    sum_k ||q_k - q_k-1||  +  MARGIN_WEIGHT * sum_k d(q_k)

(rad, m), where ``d(q)`` is the Euclidean distance of ``q`` to the *comfort box*, the
limits shrunk by :data:`~optik.plan_choice.MARGIN_BAND` (10 %) of each finite range. A branch switch
therefore happens only where no continuous path through the candidates exists, and it
is flagged. With a closed form the candidates are every branch, so a flag is a proof;
numeric candidates (a redundant task, a robot without a family) sample a continuum, and
a flagged step may have a continuous way round that they missed (a step spent near a
wrist singularity, say). The
candidates prefer margin too: a numeric candidate continuing ``q`` (without a path
``posture``) is the answer nearest ``q`` moved towards the comfort box by at most half
of ``max_joint_step`` per joint (:func:`optik.posture.refine_posture`), and a fresh
restart's the answer nearest mid-limits; an axis task's closed-form candidates are the
answers nearest those same references. Every input waypoint appears in the output.

Reachability of many points at once is :mod:`optik.reachability`.
"""

from __future__ import annotations

import csv
import json
import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from optik._checks import (
    FloatArray,
    as_float_array,
    check_bool,
    check_choice,
    check_int,
    check_length_array,
    check_progress,
    check_real,
)
from optik._files import output_path, write_atomic_with
from optik._ik_options import CROSS_CHECK_RESTARTS, query_bounds
from optik._interrupts import surfaces_interrupts
from optik.analytic import analytic_ik, family_of, wrap_into_limits
from optik.analytic.roll import axis_branches, solves_axis_task
from optik.diffik import clip_into_limits
from optik.errors import OptikError, ShapeError
from optik.ik import solve_ik
from optik.model import Robot
from optik.plan_choice import Comfort, choose
from optik.posture import check_posture
from optik.solvers._base import IKQuery, within_reach_of_tolerance
from optik.spatial import as_pose
from optik.task import AXES, MODES, Task, make_task, task_rows
from optik.verify import beyond_reach_task

if TYPE_CHECKING:
    from optik.trajectory import Trajectory

PLAN_STATUSES = (
    "ok",
    "unreachable",
    "outside_limits",
    "not_found",
    "near_singular",
    "discontinuity",
)
"""Per-waypoint flags. ``unreachable`` and ``outside_limits`` are proved (the reach
sphere, a closed form); ``not_found`` is a failure without proof: no answer was found,
even with the limits lifted, but none is proved impossible (raise ``restarts``)."""
SEED_CANDIDATES = 2
"""Closed-form answers of an axis task kept per previous candidate (the nearest ones)."""


_DUPLICATE = 1e-7


@dataclass
class PathPlan:
    """A joint path for a Cartesian path, with a status for every waypoint.

    Attributes:
        poses: (N, 4, 4) input waypoints (world frame, m).
        mode: the task's mode: ``"pose"``, ``"position"``, ``"orientation"`` or
            ``"axis"`` (:mod:`optik.task`).
        q: (N, dof) chosen configurations; NaN rows where unsolved.
        status: N entries from :data:`PLAN_STATUSES`.
        limit_margin: (N, dof) distance of each joint to its nearer limit (rad or m).
        manipulability: (N,) ``sqrt(det(J J^T))`` of the task rows, over the joints that
            are not frozen (NaN where unsolved).
        step: (N,) largest single-joint step from the previous solved waypoint, or for the
            first from ``q_start`` (NaN for the first of a stretch and where unsolved).
        candidates: (N,) number of candidate configurations found at each waypoint.
        max_joint_step: the bound on a continuous step (rad or m).
        greedy: whether the choice was greedy (nearest to the previous) instead of optimal.
        weights: (6,) the task's weights on ``[x, y, z, rx, ry, rz]`` in each waypoint's
            frame (0: a free axis); ``axis``: the tool axis of ``mode="axis"`` (0 x, 1 y,
            2 z), else -1.
    """

    poses: FloatArray
    mode: str
    q: FloatArray
    status: list[str]
    limit_margin: FloatArray
    manipulability: FloatArray
    step: FloatArray
    candidates: np.ndarray
    max_joint_step: float
    greedy: bool = False
    joint_names: tuple[str, ...] = field(default_factory=tuple)
    weights: FloatArray = field(default_factory=lambda: np.ones(6))
    axis: int = -1

    @property
    def solved(self) -> np.ndarray:
        """(N,) mask of waypoints with a configuration."""
        return ~np.isnan(self.q[:, 0])

    @property
    def largest_step(self) -> float:
        """Largest single-joint step along the plan (rad or m); 0 for one waypoint."""
        finite = self.step[np.isfinite(self.step)]
        return float(finite.max()) if finite.size else 0.0

    def summary(self) -> dict[str, Any]:
        """Counts per status, waypoints solved and the largest step."""
        counts = {s: self.status.count(s) for s in PLAN_STATUSES}
        return {
            "waypoints": len(self.status),
            "solved": int(self.solved.sum()),
            "flagged": len(self.status) - counts["ok"],
            "largest_step": self.largest_step,
            "max_joint_step": self.max_joint_step,
            **counts,
        }

    def save(self, path: str | Path) -> Path:
        """Write the plan as ``.csv``, ``.npz`` or ``.json`` (whole or not at all).

        Args:
            path: the file to write; its suffix (``.csv``, ``.npz``, ``.json``) picks the format.
        """
        target = output_path(path)
        suffix = target.suffix.lower()
        if suffix == ".npz":
            return _atomic_write(target, self._write_npz, binary=True)
        if suffix == ".csv":
            return _atomic_write(target, self._write_csv)
        if suffix == ".json":
            return _atomic_write(target, self._write_json)
        raise OptikError(f"{target}: unknown plan format {suffix!r} (expected .csv, .npz, .json)")

    def _write_npz(self, handle: Any) -> None:
        np.savez(
            handle,
            poses=self.poses,
            q=self.q,
            status=np.array(self.status),
            limit_margin=self.limit_margin,
            manipulability=self.manipulability,
            step=self.step,
            candidates=self.candidates,
        )

    def _write_csv(self, handle: Any) -> None:
        names = self.joint_names or tuple(f"q{i}" for i in range(self.q.shape[1]))
        header = ["index", "status", "x", "y", "z", *names, "step", "manipulability"]
        # Quoted where needed: a URDF joint name may hold a comma.
        csv.writer(handle, lineterminator="\n").writerow(header)
        for k in range(len(self.status)):
            cells = [str(k), self.status[k], *(f"{v:.9g}" for v in self.poses[k, :3, 3])]
            cells += [f"{v:.12g}" for v in self.q[k]]
            cells += [f"{self.step[k]:.9g}", f"{self.manipulability[k]:.9g}"]
            handle.write(",".join(cells) + "\n")

    def _write_json(self, handle: Any) -> None:
        def clean(a: FloatArray) -> Any:
            return (
                [None if not math.isfinite(v) else v for v in a.tolist()]
                if a.ndim == 1
                else [clean(row) for row in a]
            )

        json.dump(
            {
                "summary": self.summary(),
                "mode": self.mode,
                "joint_names": list(self.joint_names),
                "status": self.status,
                "q": clean(self.q),
                "step": clean(self.step),
                "manipulability": clean(self.manipulability),
                "positions": self.poses[:, :3, 3].tolist(),
            },
            handle,
            indent=1,
        )

    def plot(self, path: str | Path, robot: Robot | None = None) -> Path:
        """Joint trajectories with limit bands and flagged waypoints, saved as an image.

        Args:
            path: the image file to write (PNG, SVG or PDF, by suffix).
            robot: the robot the plan was made for: adds its limit bands and the arm along the
                path (default: joint panels only).

        Raises:
            OptikError: the plan has no waypoint (an empty path plans to nothing).
        """
        from optik.plots import plot_plan

        target = output_path(path)
        if len(self.q) == 0:
            raise OptikError("the plan has no waypoint to draw (its path was empty)")
        return plot_plan(self, target, robot)

    def to_trajectory(
        self,
        velocity_limits: Any = None,
        acceleration_limits: Any = None,
        *,
        robot: Robot | None = None,
        dt: float = 0.01,
        grid: int = 200,
        path_tolerance: float | None = None,
    ) -> Trajectory:
        """The time-optimal trajectory (TOPP-RA) along this joint path, in segments.

        Unsolved waypoints and discontinuities split it; see
        :func:`optik.trajectory.plan_trajectory` for the path, the default limits and the
        guarantees.

        Args:
            velocity_limits: joint speed limits, one value or one per joint (rad/s or m/s);
                default: the robot's.
            acceleration_limits: joint acceleration limits, one value or one per joint (rad/s² or
                m/s²); default: the robot's.
            robot: the robot the plan was made for: the source of default limits, and of the
                measured departure from the Cartesian path.
            dt: sampling step (s) of the returned arrays.
            grid: least number of TOPP-RA grid intervals per segment; no unit.
            path_tolerance: largest accepted departure (m for position, rad for orientation)
                of the tool from the Cartesian path between waypoints; needs ``robot``.
        """
        from optik.trajectory import plan_trajectory

        return plan_trajectory(
            self,
            velocity_limits,
            acceleration_limits,
            robot=robot,
            dt=dt,
            grid=grid,
            path_tolerance=path_tolerance,
        )


def _atomic_write(target: Path, writer: Callable[[Any], None], binary: bool = False) -> Path:
    """Write through a temporary file in the same folder, then rename over ``target``."""
    return write_atomic_with(target, writer, binary=binary)


def _as_path(path: Any, mode: str | None) -> tuple[FloatArray, str]:
    array = as_float_array("path", path)
    if array.ndim == 2 and array.shape[1] == 3:
        if mode in ("orientation", "axis"):
            raise ShapeError(f"path (mode {mode!r})", "(N, 4, 4) poses", array.shape)
        poses = np.broadcast_to(np.eye(4), (len(array), 4, 4)).copy()
        poses[:, :3, 3] = array
        if not np.all(np.isfinite(array)):
            raise OptikError("path: positions must be finite")
        return poses, mode or "position"
    if array.ndim == 3 and array.shape[1:] == (4, 4):
        return as_pose("path", array, batch=True), mode or "pose"
    raise ShapeError("path", "(N, 3) positions or (N, 4, 4) poses", array.shape)


def _dedupe(rows: FloatArray, limit: int) -> list[FloatArray]:
    """Distinct rows of ``rows`` (k, dof) in their order, at most ``limit``.

    Rows equal after rounding to ``_DUPLICATE`` count as one (two rows straddling a
    rounding boundary may both stay: harmless, one extra candidate).
    """
    if len(rows) == 0:
        return []
    keys = np.round(rows / _DUPLICATE)
    _, first = np.unique(keys, axis=0, return_index=True)
    return list(rows[np.sort(first)[:limit]])


@dataclass(frozen=True)
class _PathTask:
    """The task of every waypoint and the keywords that hand it to :func:`solve_ik`."""

    task: Task
    posture: FloatArray | None
    joint_weights: FloatArray | None
    frozen: np.ndarray  # (dof,) bool: joints held by the limits of the robots used

    @property
    def analytic_ok(self) -> bool:
        """Whether a closed form gives the candidates: a plain (or graded) task, no joint held."""
        return self.task.search.is_pose_or_position and not self.frozen.any()

    def target(self, T: FloatArray) -> FloatArray:
        if self.task.mode == "position" and not self.task.needs_target_frame:
            return T[:3, 3]
        return T

    def keywords(self, posture: bool) -> dict[str, Any]:
        """The task keywords of :func:`solve_ik` (frozen joints are in the robot's limits)."""
        task = self.task
        axis = AXES[task.axis] if task.mode == "axis" else "z"
        # The mode's own weights and one tolerance go as make_task's plain arguments,
        # which it caches (one solve per candidate and waypoint).
        plain = np.array_equal(task.weights, make_task(task.mode, axis=axis).weights)
        ptol, rtol = task.position_tol, task.orientation_tol
        keywords: dict[str, Any] = {
            "mode": task.mode,
            "axis": axis,
            "weights": None if plain else task.weights,
            "tol": ptol if ptol == rtol else (ptol, rtol),
        }
        if posture and self.posture is not None:
            keywords["posture"] = self.posture
            keywords["joint_weights"] = self.joint_weights
        return keywords


class _CandidateFinder:
    """Candidate configurations at one waypoint, inside the (margin-shrunk) limits.

    ``robot`` has the joint limits with the frozen joints held (``lower = upper``);
    ``work`` is the same shrunk by the margin (frozen joints exempt).
    """

    def __init__(
        self,
        robot: Robot,
        work: Robot,
        path_task: _PathTask,
        restarts: int,
        seed: int,
        limit: int,
        max_step: float,
    ) -> None:
        self.robot, self.work, self.path_task = robot, work, path_task
        self.mode = path_task.task.mode
        self.max_step = max_step
        self.restarts, self.seed, self.limit = restarts, seed, limit
        self.comfort = Comfort.of(robot)
        # Whether the margin narrows the box: only then is an answer inside the limits
        # (and not inside the margin) a reason for "outside_limits".
        self.narrowed = not (
            np.array_equal(work.lower, robot.lower) and np.array_equal(work.upper, robot.upper)
        )
        family = family_of(robot)
        self.analytic = family is not None and path_task.analytic_ok and self.mode in family.modes
        # Whether an empty branch set is a proof (not for the numerical general_6r).
        self.proves = self.analytic and family is not None and family.proves_unreachable
        # The free roll of an axis task, solved by the full-pose closed form: a fast one
        # (the roll's search solves it hundreds of times a waypoint; general_6r's 2 ms
        # each made 2 to 6 s a waypoint, where the numeric search takes milliseconds).
        self.roll = (
            family is not None
            and family.fast
            and not path_task.frozen.any()
            and solves_axis_task(family, path_task.task)
        )

    def _reference(self, seed: FloatArray) -> FloatArray:
        """Where a candidate continuing ``seed`` should be.

        ``seed`` moved out of the limit band, by at most half a continuous step per
        waypoint (so the path stays continuous while it leaves the band).
        """
        return self.comfort.towards(seed, 0.5 * self.max_step)

    def _solve(self, robot: Robot, T: FloatArray, with_posture: bool, **options: Any) -> Any:
        settings = {"solver": "dls", "warm_start": "q0", **options}
        return solve_ik(
            robot, self.path_task.target(T), **self.path_task.keywords(with_posture), **settings
        )

    def _continuing(self, target: Any, seed: FloatArray) -> FloatArray:
        """The closed form's branches from ``seed`` that continue it: (m, dof).

        At a singularity the closed form holds its free joint (an aligned wrist's turn,
        a shoulder over its axis) at the reference: from mid-limits a branch may not
        continue ``seed`` although one on the same continuum does.
        """
        branches = analytic_ik(self.work, target, self.mode, q_ref=seed)
        rows = np.array(branches).reshape(-1, seed.shape[0])
        return rows[np.max(np.abs(rows - seed), axis=1) <= self.max_step]

    def find(self, T: FloatArray, seeds: list[FloatArray], k: int) -> list[FloatArray]:
        target = self.path_task.target(T)
        branches = analytic_ik(self.work, target, self.mode) if self.analytic else []
        if branches:
            # Joints with more than 2 pi of range have several representatives of each
            # branch. Those that continue a previous candidate (within one step of it)
            # come first; for where the path must jump, each branch's representative
            # nearest a previous candidate follows (not one a turn away), then the
            # branches themselves.
            B = np.array(branches)
            parts = []
            if seeds:
                refs = np.array(seeds)[:, None, :]
                V = wrap_into_limits(B[None], self.work, refs)
                near = np.max(np.abs(V - refs), axis=2) <= self.max_step
                parts.append(V[near])
                for seed, continued in zip(seeds, near.any(axis=1).tolist(), strict=True):
                    if not continued:
                        parts.append(self._continuing(target, seed))
                parts.append(V[~near])
            parts.append(B)
            return _dedupe(np.concatenate(parts), self.limit)
        # No branch inside the limits proves nothing yet: at a singularity the closed form
        # holds its free joint at the reference (the DOBOT's flange over its base axis)
        # and rounds there by up to 1e-7, so the numeric search follows, as in solve_ik.
        if self.roll:
            found = self._on_roll(T, seeds)
            if found:
                return found
            # The grid of rolls proves nothing: the numeric search follows.
        rows = []
        own = self.path_task.posture is not None
        for q0 in seeds:
            # Without a posture of the path's own, the candidate continuing q0 is the
            # answer nearest q0 moved out of the limit band (optik.posture's refinement).
            steer = {} if own else {"posture": self._reference(q0)}
            result = self._solve(self.work, T, True, q0=q0, restarts=0, **steer)
            if result.success:
                rows.append(result.q)
        if not rows or self.restarts > 0:
            # A fresh start: the answer nearest mid-limits, the middle of the comfort box.
            steer = {} if own else {"posture": self.work.mid_limits}
            result = self._solve(
                self.work,
                T,
                True,
                restarts=self.restarts if rows else max(self.restarts, 20),
                seed=self.seed + k,
                **steer,
            )
            if result.success:
                rows.append(result.q)
        if not rows and not own:
            # The steered searches can fail where solve_ik's own policy does not (its
            # closed forms and their cross-check; an axis task with joints on their
            # limits): any answer beats none.
            result = self._solve(
                self.work, T, False, solver="auto", warm_start="analytic", seed=self.seed + k
            )
            if result.success:
                rows.append(result.q)
        return _dedupe(np.array(rows), self.limit) if rows else []

    def _on_roll(self, T: FloatArray, seeds: list[FloatArray]) -> list[FloatArray]:
        """Closed-form candidates of an axis task (:mod:`optik.analytic.roll`).

        For every previous candidate, the answer nearest it moved out of the limit band
        (the continuation of the path) and the next nearest; then, for where the path
        must jump, every refined local minimum of the distance to the first (or to
        mid-limits at the start).
        """
        if seeds:
            refs = np.array([self._reference(q) for q in seeds])
        else:
            refs = self.work.mid_limits[None]
        task = self.path_task.task
        per_seed = axis_branches(self.work, T, task.axis, refs, per_ref=SEED_CANDIDATES)
        rows = [q for found in per_seed for q in found.nearest[:SEED_CANDIDATES]]
        if len(refs) > 1:
            rows += axis_branches(self.work, T, task.axis, refs[:1])[0].nearest
        else:
            rows += per_seed[0].nearest
        return _dedupe(np.array(rows), self.limit) if rows else []

    def _near_within_tol(self, T: FloatArray, branches: list[FloatArray]) -> str:
        """Whether an answer within the task's ``tol`` lies near ``T`` inside the limits.

        ``"found"``: one was found; ``"maybe"``: one may lie there (no proof then);
        ``"no"``: none does. The closed form proves no *exact* answer. As
        :func:`solve_ik`'s proofs: a short search (:data:`~optik.ik.CROSS_CHECK_RESTARTS`)
        from the first branch clipped into the limits, or from mid-limits, and the task's
        minimum from its best attempt must miss the target by more than any answer within
        ``tol`` could (:func:`optik.solvers._base.within_reach_of_tolerance`).
        """
        robot, task = self.robot, self.path_task.task
        start = np.clip(branches[0], robot.lower, robot.upper) if branches else robot.mid_limits
        run = self._solve(robot, T, False, q0=start, restarts=CROSS_CHECK_RESTARTS)
        if run.success:
            return "found"
        pose = np.ascontiguousarray(T, dtype=np.float64)
        query = IKQuery(robot, pose, task.mode, task.position_tol, task, None)
        return "maybe" if within_reach_of_tolerance(query, run.q)[0] else "no"

    def why_unsolved(self, T: FloatArray) -> str:
        """Why a waypoint has no candidate: a proved status, or ``"not_found"``.

        ``unreachable`` beyond the reach sphere (the line or plane of a task's free
        position axes missing it: :func:`optik.verify.beyond_reach_task`) or when the
        closed form has no branch even outside the limits;
        ``outside_limits`` when an answer exists with the limits lifted (frozen joints
        stay held), or inside the limits but not inside the margin; otherwise
        ``not_found``: the numeric search failed, which proves nothing.
        """
        target = self.path_task.target(T)
        task = self.path_task.task
        if beyond_reach_task(self.robot, T, task):
            return "unreachable"
        if self.proves:
            loose = analytic_ik(self.robot, target, self.mode, within_limits=False)
            near = self._near_within_tol(T, loose)
            if near == "found" and self.narrowed:
                return "outside_limits"  # reachable inside the limits, not inside the margin
            if near != "no":
                return "not_found"  # an answer within tol may lie near the target
            return "outside_limits" if loose else "unreachable"
        if self.narrowed:
            inside = self._solve(self.robot, T, False, restarts=20)
            if inside.success:
                return "outside_limits"  # reachable inside the limits, not inside the margin
        prismatic = np.array([j.kind == "prismatic" for j in self.robot.joints])
        keep = prismatic | self.path_task.frozen
        free = self.robot.with_limits(
            np.where(keep, self.robot.lower, -2 * math.pi),
            np.where(keep, self.robot.upper, 2 * math.pi),
        )
        lifted = self._solve(free, T, False, restarts=20)
        return "outside_limits" if lifted.success else "not_found"


MAX_RESTARTS = 10_000
"""Largest ``restarts`` accepted by :func:`plan_path` and :func:`reachability`."""

MAX_CANDIDATES = 10_000
"""Largest ``max_candidates`` accepted by :func:`plan_path`."""

MAX_SEED = 2**32 - 1
"""Largest ``seed`` accepted (seeds are non-negative; ``seed + k`` seeds waypoint ``k``)."""


def _check_robot(robot: Any) -> None:
    if not isinstance(robot, Robot):
        raise OptikError(f"robot: expected an optik.Robot, got {type(robot).__name__}")


def _path_task(
    robot: Robot,
    mode: str,
    axis: Any,
    weights: Any,
    tol: Any,
    frozen: Mapping[str, float] | None,
    posture: Any,
    joint_weights: Any,
) -> _PathTask:
    """The validated task of :func:`plan_path` (the validators of :func:`optik.solve_ik`).

    ``frozen`` must have been validated (:func:`optik._ik_options.query_bounds`).
    """
    task = make_task(mode, axis=axis, weights=weights, tol=tol)
    names = frozen or {}
    held = np.array([name in names for name in robot.joint_names])
    q_ref, w = check_posture(posture, joint_weights, robot.dof)
    return _PathTask(task, q_ref, w, held)


def _task_jacobian(robot: Robot, q: FloatArray, T: FloatArray, path_task: _PathTask) -> FloatArray:
    """The task's unweighted Jacobian rows at ``q`` (positive weights), free joints only."""
    task = path_task.task.search  # graded weights choose a compromise, not a singularity
    J = np.array(robot.jacobian(q), dtype=np.float64, order="C")  # a copy: changed in place
    frame = np.array(T, dtype=np.float64, order="C")
    if task.mode == "position" and not task.needs_target_frame:
        frame[:3, :3] = np.eye(3)  # solve_ik takes the point alone: on the world axes
    n = task_rows(J, frame, task.packed)
    # Plain tasks keep the world-frame rows (6 for a pose, 3 for a point); the others
    # are the weighted target-frame rows, of which the zero-weight ones carry nothing.
    rows = J[:n] if task.is_pose_or_position else J[task.weights > 0.0]
    return rows[:, ~path_task.frozen]


@surfaces_interrupts
def plan_path(
    robot: Robot,
    path: Any,
    *,
    max_joint_step: float = 0.1,
    limit_margin: float = 0.0,
    mode: str | None = None,
    axis: str = "z",
    weights: Any = None,
    frozen: Mapping[str, float] | None = None,
    posture: Any = None,
    joint_weights: Any = None,
    q_start: Any = None,
    tol: float | tuple[float, float] = 1e-6,
    restarts: int = 2,
    seed: int = 0,
    singular_threshold: float = 1e-3,
    max_candidates: int = 32,
    greedy: bool = False,
    progress: Callable[[int, int], object] | None = None,
) -> PathPlan:
    """Turn a Cartesian path into a continuous joint path inside the limits.

    Args:
        robot: the robot.
        path: (N, 4, 4) world poses, or (N, 3) positions (m).
        max_joint_step: largest single-joint motion (rad or m) between consecutive
            waypoints that counts as continuous; a larger step is a flagged discontinuity.
        limit_margin: keep every joint this far (rad or m) inside its finite limits
            (frozen joints exempt). Hard; beyond it the path's cost prefers margin
            softly (the comfort box of the module docstring).
        mode: the task of every waypoint, as in :func:`optik.solve_ik`: ``"pose"``,
            ``"position"``, ``"orientation"`` or ``"axis"`` (default: ``"position"`` for
            (N, 3) positions, else ``"pose"``; ``"orientation"`` and ``"axis"`` need
            poses). See :mod:`optik.task`.
        axis: ``"x"``, ``"y"`` or ``"z"``, the tool axis of ``mode="axis"``: it points
            along the waypoint's same axis, the rotation about it is free.
        weights: (6,) >= 0 on ``[x, y, z, rx, ry, rz]`` in each waypoint's frame (0 frees
            that axis), as in :func:`optik.solve_ik`; waypoints given as points (N, 3)
            have the world's axes.
        frozen: ``{joint name: value}`` (rad or m): joints held at these values (inside
            their limits) along the whole path.
        posture: ``q_ref`` (dof,): each numeric candidate is the answer nearest it in the
            ``joint_weights`` norm among those its solve finds, refined by
            :func:`optik.posture.refine_posture` (redundant arms and 5-D tasks, where the
            answers form a continuum). Closed-form candidates are isolated branches and
            stay as they are. The choice between candidates is still by continuity.
        joint_weights: (dof,) in [1e-100, 1e100], the norm of ``posture`` (default ones).
        q_start: current configuration (dof,), inside the limits (a hair outside is clipped
            onto them): the move from it to the first waypoint is a step like the others
            (``step[0]``, flagged ``discontinuity`` beyond ``max_joint_step``).
        tol: IK tolerance for both errors, or ``(position_tol_m, orientation_tol_rad)``.
        restarts: numeric restarts per waypoint (robots without a closed form).
        seed: seed of the restarts.
        singular_threshold: smallest singular value of the task Jacobian (its weighted
            rows in the waypoint's frame, over the joints not frozen; m or rad per rad)
            below which a waypoint is flagged ``near_singular``.
        max_candidates: candidates kept per waypoint.
        greedy: choose, at each waypoint, the candidate nearest the previous choice (no
            look-ahead): the naive baseline the optimal plan is compared with.
        progress: called as ``progress(done, total)`` after each waypoint's candidates are
            found (``optik plan`` draws its progress bar with it).

    Returns:
        A :class:`PathPlan` with one row and one status per input waypoint.

    Raises:
        OptikError: an option of the wrong type or out of range (``max_joint_step`` and
            ``tol`` positive and finite, ``limit_margin`` and ``singular_threshold`` >= 0,
            ``restarts`` in [0, MAX_RESTARTS], ``seed`` in [0, MAX_SEED],
            ``max_candidates`` in [1, MAX_CANDIDATES], ``greedy`` a bool), a malformed
            path, coordinates beyond :data:`~optik._checks.MAX_LENGTH_M`, or a task
            :func:`optik.solve_ik` refuses (an unknown ``mode`` or ``axis``, bad
            ``weights`` or ``tol``, a ``frozen`` name that is not a joint or a value
            outside its limits, a ``posture`` or ``joint_weights`` of the wrong length).
    """
    _check_robot(robot)
    if mode is not None:
        check_choice("mode", mode, MODES)
    max_joint_step = check_real("max_joint_step", max_joint_step, positive=True)
    limit_margin = check_real("limit_margin", limit_margin, nonnegative=True)
    restarts = check_int("restarts", restarts, minimum=0, maximum=MAX_RESTARTS)
    seed = check_int("seed", seed, minimum=0, maximum=MAX_SEED)
    singular_threshold = check_real("singular_threshold", singular_threshold, nonnegative=True)
    max_candidates = check_int("max_candidates", max_candidates, minimum=1, maximum=MAX_CANDIDATES)
    greedy = check_bool("greedy", greedy)
    progress = check_progress(progress, flag=False)
    poses, mode = _as_path(path, mode)
    check_length_array("path translation", poses[:, :3, 3])
    held = query_bounds(robot, frozen, 0.0)  # frozen joints: lower = upper = their value
    path_task = _path_task(robot, mode, axis, weights, tol, frozen, posture, joint_weights)
    base = robot if held is None else robot.with_limits(*held)
    finite = np.isfinite(base.lower) & ~path_task.frozen
    lower = np.where(finite, base.lower + limit_margin, base.lower)
    upper = np.where(finite, base.upper - limit_margin, base.upper)
    if np.any(lower > upper):
        raise OptikError(f"limit_margin {limit_margin} leaves no range for some joint")
    work = base.with_limits(lower, upper)
    # Inside the limits (a hair outside is clipped onto them), as solve_ik's q0.
    start = None if q_start is None else clip_into_limits(robot, "q_start", q_start)
    finder = _CandidateFinder(base, work, path_task, restarts, seed, max_candidates, max_joint_step)

    n = len(poses)
    layers: list[list[FloatArray]] = []
    # Seeds inside the box the solves keep (frozen joints at their values, the margin);
    # the move from q_start itself, frozen joints included, is the plan's first step.
    first = [] if start is None else [np.clip(start, work.lower, work.upper)]
    seeds = first
    for k in range(n):
        layer = finder.find(poses[k], seeds, k)
        layers.append(layer)
        seeds = layer if layer else first
        if progress is not None:
            progress(k + 1, n)
    choice = choose(layers, max_joint_step, greedy, start, finder.comfort)

    dof = robot.dof
    Q = np.full((n, dof), np.nan)
    status = ["ok"] * n
    steps = np.full(n, np.nan)
    manip = np.full(n, np.nan)
    # With q_start, the first waypoint's step is the move from it (flagged like any).
    previous: FloatArray | None = start
    for k in range(n):
        if choice[k] < 0:
            status[k] = finder.why_unsolved(poses[k])
            previous = None
            continue
        q = Q[k] = layers[k][choice[k]]
        rows = _task_jacobian(robot, q, poses[k], path_task)
        # Every joint frozen: the tool cannot move at all (manipulability 0; no singular
        # direction to flag, as no joint could ever move along one).
        sv = np.linalg.svd(rows, compute_uv=False) if rows.shape[1] else np.zeros(0)
        manip[k] = float(np.prod(sv[: min(rows.shape)])) if rows.shape[1] else 0.0
        if previous is not None:
            steps[k] = float(np.max(np.abs(q - previous)))
        if steps[k] > max_joint_step:
            status[k] = "discontinuity"
        elif len(sv) and sv[min(rows.shape) - 1] < singular_threshold:
            status[k] = "near_singular"
        previous = q
    margin = np.minimum(Q - robot.lower, robot.upper - Q)
    return PathPlan(
        poses=poses,
        mode=path_task.task.mode,
        q=Q,
        status=status,
        limit_margin=margin,
        manipulability=manip,
        step=steps,
        candidates=np.array([len(layer) for layer in layers]),
        max_joint_step=float(max_joint_step),
        greedy=greedy,
        joint_names=robot.joint_names,
        weights=path_task.task.weights.copy(),
        axis=path_task.task.axis,
    )
