"""Capability maps: where a robot reaches a tool pose, and from how many orientations.

The map of Zacharias et al. (2007) on a voxel grid. At every voxel centre inside the
robot's reach sphere (:attr:`optik.Robot.reach_sphere`) the tool is asked to be there
with each of ``M`` sampled orientations (:mod:`optik.campaign.sampling`), and every
sample is solved by :func:`optik.solve_ik_batch` and verified by forward kinematics and
the limits. A voxel centre outside the sphere is unreachable by proof and never solved.
Per voxel the map holds:

- ``reachability``: the reachability index, the fraction of the ``M`` samples reached
  (no unit, 0 to 1);
- ``manipulability``: the best Yoshikawa measure ``sqrt(det(J J^T))`` over the reached
  samples (the product of the singular values of the 6-row Jacobian, of its 3 position
  rows in position mode; m and rad per rad as the rows mix), NaN where none is reached;
- ``limit_margin``: the mean over the reached samples of the smallest normalised joint
  margin ``min_i 2 min(q_i - lo_i, hi_i - q_i) / (hi_i - lo_i)`` over the joints with
  finite limits (no unit: 0 at a limit, 1 with every joint mid-range), NaN where none is
  reached;
- ``reached`` (per sample) and ``inside`` (centre inside the reach sphere);
- ``q`` (per sample, NaN where not reached) when ``keep_q=True``.

Seeds: sample ``m`` of voxel ``g`` (the voxel's flat index in the ``(x, y, z)`` grid, C
order) is solved with the restart stream ``seed + g * M + m``, whatever the chunk, the
worker or the engine, so a map is identical bit for bit in-process, on one worker or
many, and for every chunk size.

:func:`optik.reachability` answers the same question for a list of points and one
orientation; a map is its voxel-grid, many-orientation form, built on the same batch
solver and the same reach-sphere proof.
"""

from __future__ import annotations

import functools
import math
import shutil
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from optik._checks import (
    FloatArray,
    check_bool,
    check_choice,
    check_int,
    check_progress,
    check_real,
)
from optik._files import check_folder, output_path
from optik._interrupts import surfaces_interrupts
from optik.campaign._deps import require, require_zarr
from optik.campaign._map_store import (
    DONE_MARKER,
    MapStore,
    MapWriter,
    MemoryMapStore,
    map_layout,
    missing_arrays,
    read_markers,
)
from optik.campaign.engine import (
    MAX_CHUNKS,
    Engine,
    ProgressOption,
    check_chunk_count,
    open_engine,
    refuse_reimported_script,
    run_chunks_with_progress,
)
from optik.campaign.provenance import robot_fingerprint, versions
from optik.campaign.sampling import AXES, lattice
from optik.campaign.sampling import orientations as sample_orientations
from optik.errors import OptikError, OutputFileError
from optik.ik import MAX_BATCH_RESTARTS, MAX_ITERATIONS, solve_ik_batch
from optik.model import Robot

MAP_MODES = ("pose", "axis", "position")
DEFAULT_CHUNK = 4
"""Default ``chunk``: a chunk holds ``chunk x chunk`` columns of voxels along z."""
MAX_SEED = 2**40
"""Largest ``seed`` of a map (sample streams run up to ``seed`` + number of samples)."""


@dataclass(frozen=True)
class MapSpec:
    """Everything a chunk of a map needs (picklable: it travels to Dask workers).

    Attributes:
        robot: the robot.
        mode: ``"pose"``, ``"axis"`` or ``"position"``.
        axis: the tool axis (``"x"``, ``"y"``, ``"z"``).
        tol: IK tolerance (m, rad).
        restarts: attempts after the first, per sample.
        max_iter: iterations per attempt.
        seed: base seed of the sample streams.
        rotations: (M, 3, 3) target rotations sampled at every voxel.
        x, y, z: voxel centre coordinates (m).
        centre: (3,) reach sphere centre (m).
        radius: reach sphere radius (m).
        chunk: columns per chunk along x and y.
        keep_q: also return every reached sample's configuration.
        threads: threads of :func:`optik.solve_ik_batch` (``None``: numba's count).
    """

    robot: Robot
    mode: str
    axis: str
    tol: float
    restarts: int
    max_iter: int
    seed: int
    rotations: FloatArray
    x: FloatArray
    y: FloatArray
    z: FloatArray
    centre: FloatArray
    radius: float
    chunk: int
    keep_q: bool
    threads: int | None = None

    @property
    def shape(self) -> tuple[int, int, int]:
        """Voxels along x, y and z."""
        return len(self.x), len(self.y), len(self.z)

    @property
    def samples(self) -> int:
        """Samples (orientations) per voxel, M."""
        return len(self.rotations)

    @property
    def blocks(self) -> list[tuple[int, int, int, int]]:
        """Every chunk as ``(ix0, ix1, iy0, iy1)``, x-major (chunk ``i`` at position ``i``)."""
        nx, ny, _ = self.shape
        c = self.chunk
        return [
            (ix, min(ix + c, nx), iy, min(iy + c, ny))
            for ix in range(0, nx, c)
            for iy in range(0, ny, c)
        ]

    @property
    def block_grid(self) -> tuple[int, int]:
        """Chunks along x and y."""
        nx, ny, _ = self.shape
        return math.ceil(nx / self.chunk), math.ceil(ny / self.chunk)


def _margins(robot: Robot, Q: FloatArray) -> FloatArray:
    """(N,) smallest normalised joint margin of each row (see the module); NaN if no limits."""
    finite = np.isfinite(robot.lower) & np.isfinite(robot.upper)
    if not np.any(finite):
        return np.full(len(Q), math.nan)
    lo, hi = robot.lower[finite], robot.upper[finite]
    span = np.where(hi > lo, hi - lo, math.inf)  # a joint fixed by its limits has no margin
    part = Q[:, finite]
    margin = 2.0 * np.minimum(part - lo, hi - part) / span
    return np.clip(np.min(margin, axis=1), 0.0, 1.0)


def manipulability(robot: Robot, Q: FloatArray, mode: str) -> FloatArray:
    """(N,) ``sqrt(det(J J^T))`` of each row: the product of the Jacobian's singular values.

    The 6-row geometric Jacobian (its 3 position rows in position mode); with fewer
    joints than rows, ``sqrt(det(J^T J))``, the product of the ``dof`` singular values.
    """
    if len(Q) == 0:
        return np.empty(0)
    J = robot.jacobian(Q)
    rows = J[:, :3, :] if mode == "position" else J
    T = np.swapaxes(rows, 1, 2)
    gram = rows @ T if rows.shape[1] <= rows.shape[2] else T @ rows
    return np.sqrt(np.maximum(np.linalg.det(gram), 0.0))


def solve_block(spec: MapSpec, block: tuple[int, int, int, int]) -> dict[str, np.ndarray]:
    """Solve one chunk of a map: every sample of the voxels of ``block`` in the sphere.

    Args:
        spec: the map.
        block: ``(ix0, ix1, iy0, iy1)``: the columns ``x[ix0:ix1] x y[iy0:iy1]`` (all z).

    Returns:
        Arrays over the block, ``(bx, by, nz)`` per voxel and ``(bx, by, nz, M)`` per
        sample: ``reachability``, ``manipulability``, ``limit_margin``, ``inside``,
        ``reached`` and (``keep_q``) ``q`` ``(bx, by, nz, M, dof)``.
    """
    ix0, ix1, iy0, iy1 = block
    _, ny, nz = spec.shape
    M, dof = spec.samples, spec.robot.dof
    bx, by = ix1 - ix0, iy1 - iy0
    reached = np.zeros((bx, by, nz, M), dtype=bool)
    best = np.full((bx, by, nz), math.nan)
    margin = np.full((bx, by, nz), math.nan)
    inside = np.zeros((bx, by, nz), dtype=bool)
    Q = np.full((bx, by, nz, M, dof), math.nan) if spec.keep_q else None
    d_y = spec.y[iy0:iy1] - spec.centre[1]
    d_z = spec.z - spec.centre[2]
    # Where a voxel outside the sphere sits inside a run: solve_ik_batch rejects a target
    # this far from the centre by the reach sphere alone (no iteration, no stream used).
    far = spec.centre + np.array([4.0 * spec.radius + 1.0, 0.0, 0.0])
    for a in range(bx):
        ix = ix0 + a
        d_x = spec.x[ix] - spec.centre[0]
        row = d_x * d_x + d_y[:, None] ** 2 + d_z[None, :] ** 2 <= spec.radius**2  # (by, nz)
        inside[a] = row
        cells = np.flatnonzero(row)
        if cells.size == 0:
            continue
        # One call per row of the block: voxels (ix, iy0..iy1, all z) are consecutive in
        # the grid's flat order, so sample streams stay the global ones (seed + index).
        v0, v1 = int(cells[0]), int(cells[-1]) + 1
        n = v1 - v0
        local = np.arange(v0, v1)
        b_of, k_of = local // nz, local % nz
        positions = np.column_stack([np.full(n, spec.x[ix]), spec.y[iy0 + b_of], spec.z[k_of]])
        positions[~row[b_of, k_of]] = far
        poses = np.zeros((n, M, 4, 4))
        poses[:, :, :3, :3] = spec.rotations
        poses[:, :, :3, 3] = positions[:, None, :]
        poses[:, :, 3, 3] = 1.0
        first = ((ix * ny + iy0) * nz + v0) * M  # global index of the call's first sample
        result = solve_ik_batch(
            spec.robot,
            poses.reshape(n * M, 4, 4),
            mode=spec.mode,
            axis=spec.axis,
            tol=spec.tol,
            restarts=spec.restarts,
            max_iter=spec.max_iter,
            seed=spec.seed + first,
            threads=spec.threads,
            proofs=False,  # a map counts successes: no proof of a miss is needed
        )
        ok = result.success.reshape(n, M)
        reached[a, b_of, k_of] = ok
        hits = np.flatnonzero(result.success)
        if hits.size == 0:
            continue
        good = result.q[hits]
        voxel = hits // M
        counts = ok.sum(axis=1)
        hit = counts > 0
        top = np.full(n, -math.inf)
        np.maximum.at(top, voxel, manipulability(spec.robot, good, spec.mode))
        total = np.bincount(voxel, weights=_margins(spec.robot, good), minlength=n)
        with np.errstate(invalid="ignore", divide="ignore"):
            mean = total / counts
        best[a, b_of[hit], k_of[hit]] = top[hit]
        margin[a, b_of[hit], k_of[hit]] = mean[hit]
        if Q is not None:
            Q[a, b_of[voxel], k_of[voxel], hits % M] = good
    out = {
        "reachability": reached.mean(axis=3),
        "manipulability": best,
        "limit_margin": margin,
        "inside": inside,
        "reached": reached,
    }
    if Q is not None:
        out["q"] = Q
    return out


# ---------------------------------------------------------------------------- memory
MAX_MEMORY_BYTES = 4 * 2**30
"""Largest map held in memory (``out=None``), bytes: a larger one is written to Zarr."""


def _check_memory(spec: MapSpec) -> None:
    """Refuse an in-memory map larger than :data:`MAX_MEMORY_BYTES` before allocating it.

    The voxels and the samples per voxel are each capped, but their product (the
    ``reached`` array, and ``q`` with ``keep_q``) could still ask for terabytes.
    """
    size = 0.0
    for var, shape in map_layout(spec).values():
        size += math.prod(float(n) for n in shape) * np.dtype(var.dtype).itemsize
    if size > MAX_MEMORY_BYTES:
        raise OptikError(
            f"the map would take {size / 2**30:.3g} GiB in memory, more than "
            f"{MAX_MEMORY_BYTES / 2**30:g} GiB: give out= (a Zarr store, written chunk by "
            "chunk), a larger voxel, or fewer orientations"
        )


def _check_chunk_memory(spec: MapSpec) -> None:
    """Refuse a chunk larger than :data:`MAX_MEMORY_BYTES` to solve, before solving any.

    A chunk holds ``chunk x chunk`` columns of voxels, every sample of each (``reached``,
    and ``q`` with ``keep_q``), and one row of them at a time as poses and answers.
    """
    nx, ny, nz = spec.shape
    bx, by = min(spec.chunk, nx), min(spec.chunk, ny)
    dof = spec.robot.dof
    per_sample = 1 + (8 * dof if spec.keep_q else 0)
    per_row_sample = 16 * 8 + 3 * 8 * dof  # a pose, and the batch's answers
    size = float(bx * by * nz * spec.samples) * per_sample
    size += float(by * nz * spec.samples) * per_row_sample
    if size > MAX_MEMORY_BYTES:
        raise OptikError(
            f"one chunk of {bx} x {by} columns would take {size / 2**30:.3g} GiB in memory, "
            f"more than {MAX_MEMORY_BYTES / 2**30:g} GiB: give a smaller chunk, a larger "
            "voxel, or fewer orientations"
        )


def open_map(path: str | Path) -> Any:
    """A stored capability map as a lazily loaded :class:`xarray.Dataset`.

    Args:
        path: the map's Zarr folder.

    Raises:
        OptikError: ``path`` is not a finished map, its chunk markers or one of its
            arrays are missing, the markers cannot be read (a damaged map), or the
            cluster extra is missing. The data are read lazily: a damaged data chunk
            raises when it is read (:func:`read_variable` says which, as an OptikError).
    """
    if not isinstance(path, (str, Path)):
        raise OptikError(
            "map: expected a capability map (an xarray.Dataset) or the path of a stored "
            f"one, got {type(path).__name__}"
        )
    xr = require("xarray", "a capability map")
    try:
        ds = xr.open_zarr(str(path), consolidated=False)
    except Exception as exc:
        raise OptikError(f"{path}: not a capability map ({exc})") from None
    if DONE_MARKER not in ds:
        raise OptikError(
            f"{path}: no chunk markers ({DONE_MARKER}): not a map written by "
            "capability_map(out=...), or a damaged one"
        )
    # Read by zarr at once, not through a dask graph (60 ms of the client's CPU).
    zarr = require_zarr("a capability map")
    marker = zarr.open_array(store=str(path), path=DONE_MARKER, mode="r")
    if not bool(np.all(read_markers(marker, str(path)))):
        raise OptikError(f"{path}: the map is unfinished (resume the run to finish it)")
    settings = ds.attrs.get("settings", {})
    missing = missing_arrays(ds, bool(settings.get("keep_q")))
    if missing:
        raise OptikError(
            f"{path}: damaged capability map, no {', '.join(missing)} array; delete the map "
            "and compute it again"
        )
    return ds.drop_vars(DONE_MARKER)


def read_variable(ds: Any, name: str, where: str) -> np.ndarray:
    """``ds[name]`` of a map, loaded (a stored map is read lazily, chunk by chunk).

    Raises:
        OptikError: a chunk of it cannot be read (a damaged map), naming ``where``.
    """
    try:
        return np.asarray(ds[name].values)
    except Exception as exc:  # zarr's codecs raise what they raise (Zstd: RuntimeError)
        raise OptikError(
            f"{where}: damaged capability map, {name!r} cannot be read ({exc}); delete the "
            "map and compute it again"
        ) from None


# ---------------------------------------------------------------------------- the API
def _settings(spec: MapSpec, voxel: float, orientations_n: int, rolls: int) -> dict[str, Any]:
    return {
        "robot": spec.robot.name,
        "robot_fingerprint": robot_fingerprint(spec.robot),
        "dof": spec.robot.dof,
        "mode": spec.mode,
        "axis": spec.axis,
        "voxel_m": voxel,
        "bounds_m": [[float(a[0]), float(a[-1])] for a in (spec.x, spec.y, spec.z)],
        "shape": list(spec.shape),
        "orientations": orientations_n,
        "rolls": rolls,
        "samples_per_voxel": spec.samples,
        "tol": spec.tol,
        "restarts": spec.restarts,
        "max_iter": spec.max_iter,
        "seed": spec.seed,
        "chunk": spec.chunk,
        "keep_q": spec.keep_q,
        "reach_centre_m": [float(v) for v in spec.centre],
        "reach_radius_m": spec.radius,
        "seed_rule": "sample m of voxel g (flat C-order index) uses stream seed + g * M + m",
        "optik": versions()["optik"],
    }


@surfaces_interrupts
def capability_map(
    robot: Robot,
    *,
    voxel: float = 0.02,
    bounds: Any = None,
    orientations: int = 100,
    rolls: int = 1,
    mode: str = "pose",
    axis: str = "z",
    tol: float = 1e-6,
    restarts: int = 3,
    max_iter: int = 100,
    seed: int = 0,
    chunk: int = DEFAULT_CHUNK,
    keep_q: bool = False,
    client: Any = None,
    workers: int | None = None,
    scheduler: str | None = None,
    out: str | Path | None = None,
    resume: bool = False,
    progress: ProgressOption = None,
) -> Any:
    """The capability map of a robot on a voxel grid (see the module for its contents).

    Args:
        robot: the robot.
        voxel: voxel edge (m), > 0 and at most the reach radius.
        bounds: ``[[xmin, xmax], [ymin, ymax], [zmin, zmax]]`` (m): keep voxel centres
            in this box (default: the reach sphere's bounding box).
        orientations: tool-axis directions per voxel, on the Fibonacci sphere.
        rolls: rotations about the tool axis per direction (pose mode only); a voxel has
            ``orientations * rolls`` samples (1 in position mode).
        mode: ``"pose"`` (full orientation), ``"axis"`` (the tool axis ``axis`` along the
            direction, the rotation about it free) or ``"position"`` (the point alone).
        axis: the tool axis, ``"x"``, ``"y"`` or ``"z"`` (pose and axis modes; in
            position mode it is not read, and stored as ``"z"``).
        tol: IK tolerance of every sample (m, rad).
        restarts: attempts after the first per sample (:func:`optik.solve_ik_batch`); a
            sample not found within them counts as not reached (no proof).
        max_iter: iterations per attempt.
        seed: base seed of the sample streams, 0 to 2**40.
        chunk: columns of voxels per chunk along x and along y (a chunk is ``chunk x
            chunk`` columns of all z); the map does not depend on it. A map of more than
            :data:`~optik.campaign.engine.MAX_CHUNKS` (100,000) chunks is refused.
        keep_q: also store ``q`` (x, y, z, orientation, joint), every reached sample's
            configuration (NaN elsewhere): 8 * dof bytes per sample.
        client: a :class:`distributed.Client` to run on.
        workers: run on a local cluster of this many worker processes.
        scheduler: run on the Dask scheduler at this address.
        out: a folder to write the map to as Zarr, chunk by chunk (default: in memory).
        resume: finish the map already at ``out`` (its settings must match); finished
            chunks are not computed again.
        progress: draw a progress bar (default: when stderr is a terminal), or a
            callable ``progress(done, total)`` (chunks) called before the first chunk and
            after each chunk is written.

    Returns:
        An :class:`xarray.Dataset` with dims ``x, y, z, orientation`` (and ``joint``),
        coordinates in m, the run's settings in ``attrs["settings"]`` and the versions in
        ``attrs["versions"]``; read lazily from ``out`` when given.
        ``attrs["resumed_samples"]`` counts the samples this call resumed from ``out``
        rather than solved (0 for a new map).

    Raises:
        OptikError: an option out of range (``voxel`` <= 0 or larger than the reach,
            inverted ``bounds``, ``rolls`` other than 1 outside pose mode, ...); more than
            :data:`~optik.campaign.engine.MAX_CHUNKS` chunks (give a larger ``chunk``);
            ``out`` exists and ``resume`` is false, or is a place that cannot be written;
            a stored map with other settings on ``resume``; ``out`` removed or replaced
            by another run while this one writes it (the run stops); an unreachable
            ``scheduler``; the cluster extra not installed.
    """
    if not isinstance(robot, Robot):
        raise OptikError(f"robot: expected an optik.Robot, got {type(robot).__name__}")
    refuse_reimported_script(workers)  # before its output is checked or created
    require("xarray", "a capability map")
    require_zarr("a capability map")
    check_choice("mode", mode, MAP_MODES)
    check_choice("axis", axis, AXES)
    if mode == "position":
        axis = "z"  # not read: the stored settings must not differ over it on a resume
    tol = check_real("tol", tol, positive=True)
    restarts = check_int("restarts", restarts, minimum=0, maximum=MAX_BATCH_RESTARTS)
    max_iter = check_int("max_iter", max_iter, minimum=1, maximum=MAX_ITERATIONS)
    seed = check_int("seed", seed, minimum=0, maximum=MAX_SEED)
    chunk = check_int("chunk", chunk, minimum=1, maximum=100_000)
    keep_q = check_bool("keep_q", keep_q)
    resume = check_bool("resume", resume)
    progress = check_progress(progress)
    centre, radius = robot.reach_sphere
    x, y, z = lattice(centre, radius, voxel, bounds)
    rotations = sample_orientations(mode, orientations, rolls, axis)
    target = None if out is None else output_path(out)
    if resume and target is None:
        raise OptikError("resume: finishes a stored map; give its folder as out=")
    if target is not None and target.exists() and not resume:
        raise OutputFileError(str(target), "it exists (resume=True, or --resume, finishes it)")
    if target is not None:
        check_folder(target)  # before the engine starts, not when the store is created
    spec = MapSpec(
        robot, mode, axis, tol, restarts, max_iter, seed, rotations, x, y, z, centre,
        float(radius), chunk, keep_q,
    )  # fmt: skip
    _check_chunk_count(spec)
    if target is None:
        _check_memory(spec)
    _check_chunk_memory(spec)
    with open_engine(client=client, workers=workers, scheduler=scheduler) as engine:
        spec = replace(spec, threads=engine.threads_for(len(spec.blocks)))
        settings = _settings(spec, float(voxel), int(orientations), int(rolls))
        attrs = {"settings": settings, "versions": versions(), "engine": engine.description}
        if target is None:
            memory = MemoryMapStore(spec)
            _run(engine, spec, memory, progress, set())
            return memory.dataset({**attrs, "resumed_samples": 0})
        store = _open_store(target, spec, settings, attrs, resume)
        done = store.finished()
        _run(engine, spec, store, progress, done)
    store.check_own()  # not another run's map: the folder may have been replaced since
    ds = open_map(target)
    inside = read_variable(ds, "inside", str(target)) if done else None  # read if needed
    ds.attrs["resumed_samples"] = 0 if inside is None else _samples_in(spec, done, inside)
    return ds


def _open_store(
    target: Path,
    spec: MapSpec,
    settings: dict[str, Any],
    attrs: dict[str, Any],
    resume: bool,
) -> MapStore:
    if target.exists():
        return MapStore.reopen(target, spec, settings)
    if not target.parent.exists():
        raise OutputFileError(str(target), f"its folder {target.parent} does not exist")
    try:
        return MapStore.create(str(target), spec, attrs)
    except OSError as exc:
        shutil.rmtree(target, ignore_errors=True)
        raise OutputFileError(str(target), exc.strerror or str(exc)) from exc


def _run(
    engine: Engine,
    spec: MapSpec,
    store: MapStore | MemoryMapStore,
    progress: ProgressOption,
    done: set[int],
) -> int:
    work = functools.partial(solve_block, spec)
    note = f"map {spec.robot.name}"
    return run_chunks_with_progress(engine, work, spec.blocks, store, progress, note, done)


def _check_chunk_count(spec: MapSpec) -> None:
    """Refuse a map of more than :data:`~optik.campaign.engine.MAX_CHUNKS` chunks."""
    nx, ny, _ = spec.shape
    nbx, nby = spec.block_grid
    smallest = max(1, math.ceil(math.sqrt(nx * ny / MAX_CHUNKS)))
    while math.ceil(nx / smallest) * math.ceil(ny / smallest) > MAX_CHUNKS:
        smallest += 1
    c = spec.chunk
    what = f"{nx} x {ny} voxel columns in chunks of {c} x {c} make"
    check_chunk_count(nbx * nby, what, smallest)


def _samples_in(spec: MapSpec, chunks: set[int], inside: np.ndarray) -> int:
    """Samples of the voxels inside the reach sphere in ``chunks`` (indices of blocks)."""
    nx, ny, _ = spec.shape
    starts_x, starts_y = np.arange(0, nx, spec.chunk), np.arange(0, ny, spec.chunk)
    columns = inside.sum(axis=2)
    per_block = np.add.reduceat(np.add.reduceat(columns, starts_x, axis=0), starts_y, axis=1)
    picked = [i for i in chunks if i < per_block.size]
    return int(per_block.ravel()[picked].sum()) * spec.samples


__all__ = [
    "MAP_MODES",
    "MAX_MEMORY_BYTES",
    "MapSpec",
    "MapStore",
    "MapWriter",
    "capability_map",
    "manipulability",
    "open_map",
    "read_variable",
    "solve_block",
]
