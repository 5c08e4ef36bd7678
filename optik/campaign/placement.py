"""Base placement by inverse reachability (Reuleaux: Makhal & Goins 2017), re-verified.

A capability map says, in the robot's own frame, which tool poses the robot reaches and
how well (:mod:`optik.campaign.capability`). Put the robot's frame at a candidate base
pose ``B`` in the cell: a task pose ``T`` (cell frame) is then the tool pose ``B^-1 T``
in the robot's frame. Its map cell is the voxel holding that position and, at that voxel,
the sample orientation nearest it (the nearest tool-axis direction in ``axis`` mode, the
nearest rotation in ``pose`` mode). Scoring every candidate this way over every task
pose is Reuleaux's inverse-reachability vote, read from the candidates' side:

- ``coverage``: the fraction of task poses whose map cell was reached;
- ``score``: the mean over task poses of the voxel's reachability index where the cell
  was reached (0 where not).

Candidates are ranked by ``(coverage, score)``; the ``top`` first are re-verified by
solving every task pose from them with :func:`optik.solve_ik` (closed forms where the
robot has one), so a chosen placement never rests on the map's discretisation alone.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from optik._checks import (
    FloatArray,
    as_float_array,
    check_int,
    check_length_array,
    check_real,
)
from optik._interrupts import surfaces_interrupts
from optik.campaign.capability import open_map, read_variable
from optik.campaign.engine import open_engine
from optik.campaign.sampling import AXES
from optik.errors import OptikError, ShapeError
from optik.ik import solve_ik
from optik.model import Robot
from optik.planning import MAX_RESTARTS
from optik.spatial import as_pose, invert_transform, rot_z
from optik.task import make_task

MAX_CANDIDATES = 10_000_000
"""Largest number of base poses :func:`planar_candidates` makes (640 bytes each)."""


@dataclass
class Placement:
    """One candidate base pose and how well it serves the task poses.

    Attributes:
        T_cell_base: (4, 4) the robot's frame in the cell frame (m).
        coverage: fraction of task poses whose map cell is reached (no unit).
        score: mean reachability index over the task poses, 0 where not covered.
        verified: fraction of task poses solved from this base by :func:`optik.solve_ik`,
            or ``None`` when not re-verified (outside the ``top``).
        q: (P, dof) the solutions (rad, m; NaN where unsolved), or ``None``.
        status: the P statuses of those solves, or ``None``.
    """

    T_cell_base: FloatArray
    coverage: float
    score: float
    verified: float | None = None
    q: FloatArray | None = None
    status: list[str] | None = None


@dataclass
class BasePlacements:
    """Ranked base placements: the re-verified ones first (best verified first).

    Attributes:
        placements: every candidate, re-verified ones first by ``(verified, coverage,
            score)``, then the rest by ``(coverage, score)``.
        task_poses: (P, 4, 4) the task poses (cell frame, m).
        mode: the task mode used to re-verify.
        verified_count: how many placements (the first ones) were re-verified.
    """

    placements: list[Placement]
    task_poses: FloatArray
    mode: str
    verified_count: int = field(default=0)

    @property
    def best(self) -> Placement:
        """The first placement (the best re-verified one).

        Raises:
            OptikError: the ranking holds no placement.
        """
        if not self.placements:
            raise OptikError("base placements: the ranking is empty (no candidate base pose)")
        return self.placements[0]


def _grid(lo: float, hi: float, step: float) -> FloatArray:
    """Positions from ``lo`` every ``step`` up to ``hi`` (m); at least ``lo`` itself.

    Far from the origin ``hi + 1e-9 * step`` may round to ``hi == lo``, and the range
    would then be empty.
    """
    values = np.arange(lo, hi + 1e-9 * step, step)
    return values if len(values) else np.array([lo])


def planar_candidates(region: Any, step: Any, yaws: Any, height: Any = 0.0) -> FloatArray:
    """(K, 4, 4) base poses on a grid of the floor: positions every ``step`` m, ``yaws`` turns.

    Args:
        region: ``[[xmin, xmax], [ymin, ymax]]`` (m) of the base origin.
        step: grid spacing (m), > 0.
        yaws: rotations about the vertical per position, ``2 pi j / yaws``.
        height: z of the base origin (m).

    Raises:
        OptikError: a malformed or inverted region, a non-positive step, more than
            :data:`MAX_CANDIDATES` poses.
    """
    box = as_float_array("region", region)
    if box.shape != (2, 2) or not np.all(np.isfinite(box)):
        raise ShapeError("region", "finite (2, 2): [[xmin, xmax], [ymin, ymax]]", box.shape)
    if np.any(box[:, 0] > box[:, 1]):
        raise OptikError(f"region: a minimum is above its maximum ({box.tolist()})")
    h = check_real("step", step, positive=True)
    n = check_int("yaws", yaws, minimum=1, maximum=3600)
    z = check_real("height", height)
    # The count first, in floating point (inf when a huge region or tiny step overflows
    # it), so that no grid axis is allocated beyond the cap.
    spans = (float(box[0, 1]) - float(box[0, 0]), float(box[1, 1]) - float(box[1, 0]))
    estimate = math.prod(float(np.floor(span / h + 1e-9)) + 1.0 for span in spans) * n
    if not estimate <= MAX_CANDIDATES:
        shown = f"{estimate:.3g}" if math.isfinite(estimate) else "too many"
        raise OptikError(
            f"region, step and yaws give {shown} candidates: at most {MAX_CANDIDATES:,}"
        )
    xs = _grid(float(box[0, 0]), float(box[0, 1]), h)
    ys = _grid(float(box[1, 0]), float(box[1, 1]), h)
    count = len(xs) * len(ys) * n
    if count > MAX_CANDIDATES:  # the estimate's rounding, at the very edge of the cap
        raise OptikError(
            f"region, step and yaws give {count} candidates: at most {MAX_CANDIDATES:,}"
        )
    out = np.empty((len(xs), len(ys), n, 4, 4))
    out[...] = np.eye(4)
    for j in range(n):
        out[:, :, j, :3, :3] = rot_z(2.0 * math.pi * j / n)
    out[..., 0, 3] = xs[:, None, None]
    out[..., 1, 3] = ys[None, :, None]
    out[..., 2, 3] = z
    return out.reshape(-1, 4, 4)


LOOKUP_ENTRIES = 2**22
"""Most (pose, sample orientation) pairs compared at once in a map lookup: 32 MB of
scores, whatever the number of candidates, task poses and orientations."""


@dataclass(frozen=True)
class MapGrids:
    """The arrays of a capability map that a lookup reads, loaded once.

    Attributes:
        voxel: the voxel edge (m).
        mode: the map's task mode.
        axis: the tool axis of an ``axis`` map.
        coords: the voxel centres along x, y and z (m).
        samples: (S, 3, 3) the sampled orientations.
        reached: (nx, ny, nz, S) whether each sample was reached.
        index: (nx, ny, nz) the reachability index of each voxel.
    """

    voxel: float
    mode: str
    axis: str
    coords: tuple[np.ndarray, np.ndarray, np.ndarray]
    samples: np.ndarray
    reached: np.ndarray
    index: np.ndarray


def map_grids(ds: Any, where: str = "the map") -> MapGrids:
    """:class:`MapGrids` of a capability map (an :class:`xarray.Dataset`).

    Raises:
        OptikError: a chunk of the map cannot be read (a damaged stored map).
    """
    settings = ds.attrs["settings"]
    x, y, z = (read_variable(ds, a, where) for a in ("x", "y", "z"))
    return MapGrids(
        float(settings["voxel_m"]),
        settings["mode"],
        settings.get("axis", "z"),
        (x, y, z),
        read_variable(ds, "rotation", where),
        read_variable(ds, "reached", where),
        read_variable(ds, "reachability", where),
    )


def map_cells(ds: Any, T_robot_tool: FloatArray) -> tuple[np.ndarray, np.ndarray]:
    """The map cell of each tool pose (robot frame): reached? and the voxel's index.

    Args:
        ds: a capability map, or its :class:`MapGrids`.
        T_robot_tool: (..., 4, 4) tool poses in the robot's frame (m).

    Returns:
        ``(reached, index)``, each of shape ``(...)``: whether the nearest sample was
        reached, and the voxel's reachability index (0 outside the grid).
    """
    grids = ds if isinstance(ds, MapGrids) else map_grids(ds)
    shape = T_robot_tool.shape[:-2]
    T = T_robot_tool.reshape(-1, 4, 4)
    reached = np.empty(len(T), dtype=bool)
    index = np.empty(len(T))
    rows = max(1, LOOKUP_ENTRIES // max(len(grids.samples), 1))
    for start in range(0, len(T), rows):
        part = slice(start, start + rows)
        reached[part], index[part] = _cells(grids, T[part])
    return reached.reshape(shape), index.reshape(shape)


def _cells(grids: MapGrids, T: FloatArray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`map_cells` of (N, 4, 4) poses, at once."""
    coords = grids.coords
    P = T[:, :3, 3]
    idx = [np.rint((P[:, i] - coords[i][0]) / grids.voxel).astype(np.int64) for i in range(3)]
    inside = np.ones(len(P), dtype=bool)
    for i in range(3):
        inside &= (idx[i] >= 0) & (idx[i] < len(coords[i]))
        idx[i] = np.clip(idx[i], 0, len(coords[i]) - 1)
    R = T[:, :3, :3]
    samples = grids.samples
    if grids.mode == "position":
        nearest = np.zeros(len(P), dtype=np.int64)
    elif grids.mode == "axis":
        k = AXES.index(grids.axis)
        nearest = np.argmax(R[:, :, k] @ samples[:, :, k].T, axis=1)
    else:  # the smallest relative angle: the largest trace(R_s^T R)
        nearest = np.argmax(np.einsum("nij,sij->ns", R, samples), axis=1)
    reached = grids.reached[idx[0], idx[1], idx[2], nearest] & inside
    index = np.where(inside, grids.index[idx[0], idx[1], idx[2]], 0.0)
    return reached, index


def _votes(grids: MapGrids, bases: FloatArray, tasks: FloatArray) -> tuple[np.ndarray, np.ndarray]:
    """Each candidate's ``(coverage, score)`` (K,) over the task poses, block by block.

    A block of candidates holds about :data:`LOOKUP_ENTRIES` (pose, orientation) pairs,
    so memory stays bounded for any number of candidates and task poses.
    """
    K, n_tasks = len(bases), len(tasks)
    coverage = np.empty(K)
    score = np.empty(K)
    inverse = invert_transform(bases)
    block = max(1, LOOKUP_ENTRIES // (n_tasks * max(len(grids.samples), 1)))
    for start in range(0, K, block):
        part = slice(start, start + block)
        # (k, P, 4, 4): every task pose seen from each candidate, in the robot's frame.
        local = np.einsum("kij,pjl->kpil", inverse[part], tasks)
        reached, index = map_cells(grids, local)
        coverage[part] = reached.mean(axis=1)
        score[part] = np.where(reached, index, 0.0).mean(axis=1)
    return coverage, score


@dataclass(frozen=True)
class _VerifySpec:
    robot: Robot
    task_poses: FloatArray
    mode: str
    axis: str
    tol: float
    restarts: int


def _verify(spec: _VerifySpec, T_cell_base: FloatArray) -> tuple[FloatArray, list[str]]:
    """Solve every task pose from one base: (P, dof) answers (NaN unsolved), statuses."""
    T_base_cell = invert_transform(T_cell_base)
    Q = np.full((len(spec.task_poses), spec.robot.dof), math.nan)
    status = []
    for i, T in enumerate(spec.task_poses):
        local = T_base_cell @ T
        target = local[:3, 3] if spec.mode == "position" else local
        result = solve_ik(
            spec.robot, target, mode=spec.mode, axis=spec.axis, tol=spec.tol,
            restarts=spec.restarts, seed=i,
        )  # fmt: skip
        if result.success:
            Q[i] = result.q
        status.append(result.status)
    return Q, status


@surfaces_interrupts
def base_placement(
    robot: Robot,
    task_poses: Any,
    *,
    map: Any,
    candidates: Any = None,
    region: Any = None,
    step: float | None = None,
    yaws: int = 8,
    height: float = 0.0,
    top: int = 10,
    mode: str | None = None,
    tol: float = 1e-6,
    restarts: int = 20,
    client: Any = None,
    workers: int | None = None,
    scheduler: str | None = None,
) -> BasePlacements:
    """Rank candidate base poses for a set of task poses; re-verify the best by IK.

    Args:
        robot: the robot the map was made for.
        task_poses: (P, 4, 4) task poses in the cell frame (m), or one (4, 4); (P, 3)
            positions for a position map (a map of another mode refuses them).
        map: a capability map (:func:`optik.capability_map`) or the path of a stored one.
        candidates: (K, 4, 4) base poses in the cell frame, or one (4, 4); by default a
            floor grid (:func:`planar_candidates`) over ``region``.
        region: ``[[xmin, xmax], [ymin, ymax]]`` of the base origin (m); default: the task
            poses' extent grown by the map's reach radius.
        step: grid spacing of ``region`` (m); default: the map's voxel.
        yaws: turns about the vertical per grid position.
        height: z of the base origin on the grid (m).
        top: how many of the best-ranked candidates to re-verify.
        mode: the task mode of the re-verification (default: the map's).
        tol: IK tolerance of the re-verification (m, rad).
        restarts: numeric restarts per task pose when re-verifying.
        client: a :class:`distributed.Client` for the re-verification.
        workers: re-verify on a local cluster of this many processes.
        scheduler: re-verify on the Dask scheduler at this address.

    Returns:
        :class:`BasePlacements`, best first.

    Raises:
        OptikError: a map of another robot, malformed task poses or candidates, options
            out of range.
    """
    from optik.campaign.provenance import robot_fingerprint

    if not isinstance(robot, Robot):
        raise OptikError(f"robot: expected an optik.Robot, got {type(robot).__name__}")
    ds = open_map(map) if not hasattr(map, "attrs") else map
    settings = ds.attrs.get("settings", {})
    if settings.get("robot_fingerprint") != robot_fingerprint(robot):
        raise OptikError(
            f"map: made for robot {settings.get('robot')!r}, not this {robot.name!r} "
            "(its kinematics or limits differ)"
        )
    map_mode = settings["mode"]
    mode = map_mode if mode is None else mode
    top = check_int("top", top, minimum=0, maximum=100_000)
    # The re-verification's options, checked now rather than after the ranking (or never,
    # with top=0).
    make_task(mode, tol=tol)
    restarts = check_int("restarts", restarts, minimum=0, maximum=MAX_RESTARTS)
    tasks = _task_poses(task_poses, map_mode)
    if candidates is None:
        radius = float(settings["reach_radius_m"])
        if region is None:
            lo = tasks[:, :2, 3].min(axis=0) - radius
            hi = tasks[:, :2, 3].max(axis=0) + radius
            region = np.column_stack([lo, hi])
        step = float(settings["voxel_m"]) if step is None else step
        bases = planar_candidates(region, step, yaws, height)
    else:
        bases = as_pose("candidates", candidates, batch=True).reshape(-1, 4, 4)
        if len(bases) == 0:
            raise OptikError("candidates: give at least one base pose")
        check_length_array("candidates translation", bases[:, :3, 3])
    where = str(map) if isinstance(map, (str, Path)) else "map"
    coverage, score = _votes(map_grids(ds, where), bases, tasks)
    order = np.lexsort((-score, -coverage))
    placements = [Placement(bases[k], float(coverage[k]), float(score[k])) for k in order]
    chosen = placements[:top]
    spec = _VerifySpec(robot, tasks, mode, settings.get("axis", "z"), tol, restarts)
    with open_engine(client=client, workers=workers, scheduler=scheduler) as engine:
        work = functools.partial(_verify, spec)
        for i, (Q, status) in engine.map_unordered(work, [p.T_cell_base for p in chosen]):
            solved = ~np.isnan(Q[:, 0])
            chosen[i].q, chosen[i].status = Q, status
            chosen[i].verified = float(solved.mean())
    chosen.sort(key=lambda p: (-(p.verified or 0.0), -p.coverage, -p.score))
    return BasePlacements(chosen + placements[top:], tasks, mode, len(chosen))


def _task_poses(task_poses: Any, map_mode: str) -> FloatArray:
    """The task poses (P, 4, 4): one pose, or points of a position map, as poses."""
    array = as_float_array("task_poses", task_poses)
    if array.ndim == 2 and array.shape[1] == 3:
        if map_mode != "position":
            raise OptikError(
                f"task_poses: (P, 3) positions are for a position map; this map's mode is "
                f"{map_mode!r}: give (P, 4, 4) poses"
            )
        poses = np.broadcast_to(np.eye(4), (len(array), 4, 4)).copy()
        poses[:, :3, 3] = array
        array = poses
    poses = as_pose("task_poses", array, batch=True).reshape(-1, 4, 4)
    if len(poses) == 0:
        raise OptikError("task_poses: give at least one task pose")
    # Beyond MAX_LENGTH_M the map lookup loses all precision (and no map reaches there).
    check_length_array("task_poses translation", poses[:, :3, 3])
    return poses


__all__ = [
    "LOOKUP_ENTRIES",
    "MAX_CANDIDATES",
    "BasePlacements",
    "MapGrids",
    "Placement",
    "base_placement",
    "map_cells",
    "map_grids",
    "planar_candidates",
]
