"""How a capability map is stored: NumPy arrays in memory, or a Zarr folder chunk by chunk.

Both stores follow one layout (:func:`_layout`): per voxel ``reachability``,
``manipulability``, ``limit_margin`` and ``inside``, per sample ``reached`` (and ``q``),
each chunked as the map is. A Zarr map marks chunk ``(bx, by)`` done in ``chunk_done``
once its data are written, and ``chunk_done`` carries the token of the run writing the
map: a worker, or the client, writes a chunk only into a map that still carries its run's
token (see :class:`MapWriter` and :meth:`MapStore.write`).
"""

from __future__ import annotations

import asyncio
import contextlib
import math
import uuid
from collections.abc import Container, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from optik.campaign._deps import require, require_zarr
from optik.campaign.provenance import check_same_run
from optik.errors import OptikError

if TYPE_CHECKING:  # the spec's module imports this one
    from optik.campaign.capability import MapSpec

DONE_MARKER = "chunk_done"
"""The map's array of chunk markers (1: the chunk's block is written whole)."""
_RUN = "run"  # chunk_done's attribute: the token of the run writing the map


@dataclass(frozen=True)
class _Variable:
    """One array of a stored map: its dims, type, fill and whether it is chunked."""

    dims: tuple[str, ...]
    dtype: str
    fill: Any
    chunked: bool = True  # chunked as the map (x and y in blocks of ``chunk``)


def map_layout(spec: MapSpec) -> dict[str, tuple[_Variable, tuple[int, ...]]]:
    """Every stored array of a map with its shape (the one table both stores follow)."""
    nx, ny, nz = spec.shape
    M, dof = spec.samples, spec.robot.dof
    voxel = ("x", "y", "z")
    table = {
        "reachability": (_Variable(voxel, "f8", 0.0), (nx, ny, nz)),
        "manipulability": (_Variable(voxel, "f8", math.nan), (nx, ny, nz)),
        "limit_margin": (_Variable(voxel, "f8", math.nan), (nx, ny, nz)),
        "inside": (_Variable(voxel, "bool", False), (nx, ny, nz)),
        "reached": (_Variable((*voxel, "orientation"), "bool", False), (nx, ny, nz, M)),
    }
    if spec.keep_q:
        dims = (*voxel, "orientation", "joint")
        table["q"] = (_Variable(dims, "f8", math.nan), (nx, ny, nz, M, dof))
    return table


STORED_ALWAYS = ("reachability", "manipulability", "limit_margin", "inside", "reached")
"""The arrays of :func:`map_layout` that every map stores (``q`` only with ``keep_q``)."""


def missing_arrays(present: Container[str], keep_q: bool) -> list[str]:
    """The arrays (chunk markers first) a map stores that ``present`` lacks.

    Args:
        present: the names of a stored map's arrays (a Zarr group, an xarray Dataset).
        keep_q: whether the map's settings say it keeps ``q``.
    """
    needed = (DONE_MARKER, *STORED_ALWAYS, *(("q",) if keep_q else ()))
    return [name for name in needed if name not in present]


def _statics(spec: MapSpec) -> dict[str, tuple[tuple[str, ...], np.ndarray]]:
    """The arrays known before solving: coordinates and the sampled rotations."""
    return {
        "x": (("x",), spec.x),
        "y": (("y",), spec.y),
        "z": (("z",), spec.z),
        "rotation": (("orientation", "row", "col"), spec.rotations),
    }


class MemoryMapStore:
    """A map in NumPy arrays (no ``out``): the same layout as :class:`MapStore`."""

    def __init__(self, spec: MapSpec) -> None:
        self.spec = spec
        self.arrays = {
            name: np.full(shape, var.fill, dtype=var.dtype)
            for name, (var, shape) in map_layout(spec).items()
        }
        self.done: set[int] = set()

    def finished(self) -> set[int]:
        """Chunks written so far."""
        return set(self.done)

    def write(self, index: int, result: dict[str, np.ndarray]) -> None:
        """Copy chunk ``index``'s arrays in."""
        ix0, ix1, iy0, iy1 = self.spec.blocks[index]
        for name, values in result.items():
            self.arrays[name][ix0:ix1, iy0:iy1] = values
        self.done.add(index)

    def writer(self) -> None:
        """None: the chunks travel back to this process."""
        return None

    def dataset(self, attrs: dict[str, Any]) -> Any:
        """The map as an :class:`xarray.Dataset`."""
        xr = require("xarray", "a capability map")
        layout = map_layout(self.spec)
        statics = _statics(self.spec)
        data = {name: (layout[name][0].dims, array) for name, array in self.arrays.items()}
        data["rotation"] = statics.pop("rotation")
        return xr.Dataset(data, coords=statics, attrs=attrs)


def _create_array(
    group: Any,
    name: str,
    *,
    shape: tuple[int, ...],
    chunks: tuple[int, ...],
    dtype: str,
    dims: tuple[str, ...],
    fill_value: Any = None,
) -> Any:
    """A Zarr (format 3) array with named dimensions, as xarray reads them."""
    return group.create_array(
        name, shape=shape, chunks=chunks, dtype=dtype, fill_value=fill_value,
        dimension_names=list(dims),
    )  # fmt: skip


def _write_block(arrays: Mapping[str, Any], chunk: int, nby: int, index: int, result: Any) -> None:
    """Write chunk ``index``'s arrays into a map's Zarr ``arrays``, then its marker.

    Chunk ``index`` is block ``(bx, by) = divmod(index, nby)`` of ``chunk x chunk``
    columns: exactly one Zarr chunk of every variable, each written whole (zarr writes a
    temporary file and renames it). The marker ``chunk_done[bx, by]`` goes last, so a
    chunk interrupted halfway has none and is computed again on ``resume``.
    """
    bx, by = divmod(index, nby)
    ix0, iy0 = bx * chunk, by * chunk
    for name, values in result.items():
        arrays[name][ix0 : ix0 + values.shape[0], iy0 : iy0 + values.shape[1]] = values
    arrays[DONE_MARKER][bx, by] = 1


_OPEN: dict[tuple[str, str], dict[str, Any]] = {}
"""The arrays of the maps this process writes chunks into, by (path, run token)."""


def _arrays_for_writing(path: str, run: str) -> dict[str, Any] | None:
    """The Zarr arrays of the map at ``path`` if it is run ``run``'s from here, else None.

    The marker array is opened afresh every time, so a map replaced since (another run
    at the same path) is never written into; the data arrays are opened once.
    """
    zarr = require_zarr("a capability map")
    try:
        marker = zarr.open_array(store=path, path=DONE_MARKER, mode="r+")
    except Exception:  # no such map from here (another machine's disk): the client writes
        return None
    if marker.attrs.get(_RUN) != run:
        return None
    arrays = _OPEN.get((path, run))
    if arrays is None:
        group = zarr.open_group(store=path, mode="r+")
        arrays = {name: group[name] for name in group.array_keys() if name != DONE_MARKER}
        if len(_OPEN) >= 8:  # a long-lived worker that served many maps
            _OPEN.clear()
        _OPEN[(path, run)] = arrays
    return {**arrays, DONE_MARKER: marker}


@dataclass(frozen=True)
class MapWriter:
    """Writes a map's chunk where it was computed.

    A :class:`~optik.campaign.engine.ChunkWriter`: it writes only into a map stamped with
    its run's token.

    Attributes:
        path: the map's Zarr folder, absolute.
        run: the token of the run that writes it (``chunk_done``'s attribute ``run``).
        chunk: columns per chunk along x and y.
        nby: chunks along y.
    """

    path: str
    run: str
    chunk: int
    nby: int

    def __call__(self, index: int, result: dict[str, np.ndarray]) -> bool:
        """Write chunk ``index`` whole (True), or leave it unmarked (False).

        False when the map is not this run's from here (another machine's disk, or a map
        since replaced) or cannot be written from here: the client then writes it.
        """
        arrays = _arrays_for_writing(self.path, self.run)
        if arrays is None:
            return False
        try:
            _write_block(arrays, self.chunk, self.nby, index, result)
        except OSError:  # a disk this worker cannot write: the client tries, or says why
            return False
        return True


class MapStore:
    """A map in a Zarr group, chunk by chunk (a chunk is done once its marker is written).

    Every variable is chunked as the map is, ``(chunk, chunk, nz, ...)``, so a chunk of
    the map is one Zarr chunk per variable, written whole (see :func:`_write_block`); the
    marker ``chunk_done[bx, by]`` is written last. The workers write their own chunks
    (:meth:`writer`) when they see the folder; each opening of the store (a new run or a
    resumed one) stamps ``chunk_done`` with a new run token, which the workers check.
    """

    def __init__(self, group: Any, spec: MapSpec, path: str | None = None) -> None:
        self.group = group
        self.spec = spec
        self.path = path
        self.run = uuid.uuid4().hex  # this run's: the workers check it before writing
        group[DONE_MARKER].attrs.update({_RUN: self.run})

    @classmethod
    def create(cls, store: Any, spec: MapSpec, attrs: dict[str, Any]) -> MapStore:
        """A new, empty map group in ``store``.

        A path (the workers then write their own chunks), or a Zarr store that this
        process alone writes.
        """
        zarr = require_zarr("a capability map")
        group = zarr.open_group(store=store, mode="w-")
        group.attrs.update(attrs)
        for name, (dims, values) in _statics(spec).items():
            array = _create_array(
                group, name, shape=values.shape, chunks=values.shape, dtype="f8", dims=dims
            )
            array[...] = values
        c = spec.chunk
        for name, (var, shape) in map_layout(spec).items():
            chunks = (min(c, shape[0]), min(c, shape[1]), *shape[2:])
            _create_array(
                group, name, shape=shape, chunks=chunks, dtype=var.dtype, dims=var.dims,
                fill_value=var.fill,
            )  # fmt: skip
        _create_array(
            group, DONE_MARKER, shape=spec.block_grid, chunks=(1, 1), dtype="u1",
            dims=("chunk_x", "chunk_y"), fill_value=0,
        )  # fmt: skip
        path = str(Path(store).resolve()) if isinstance(store, str | Path) else None
        return cls(group, spec, path)

    @classmethod
    def reopen(cls, path: Path, spec: MapSpec, settings: dict[str, Any]) -> MapStore:
        """An existing map to resume; its settings must be the ones asked for."""
        zarr = require_zarr("a capability map")
        try:
            group = zarr.open_group(store=str(path), mode="r+")
            stored = dict(group.attrs.get("settings", {}))
            missing = missing_arrays(group, bool(stored.get("keep_q")))
        except Exception as exc:  # not a Zarr group, or a damaged one
            raise OptikError(f"{path}: not a capability map to resume ({exc})") from None
        if missing:
            raise OptikError(
                f"{path}: not a capability map to resume (no {', '.join(missing)}: a damaged "
                "map; delete it and compute it again)"
            )
        check_same_run(str(path), stored, settings)
        return cls(group, spec, str(Path(path).resolve()))

    def finished(self) -> set[int]:
        """Indices (in :attr:`MapSpec.blocks` order) of the chunks with their marker.

        Raises:
            OptikError: a marker file that cannot be read (a damaged map).
        """
        done = read_markers(self.group[DONE_MARKER], self.path or "the map")
        return {int(i) for i in np.flatnonzero(done)}

    def write(self, index: int, result: dict[str, np.ndarray]) -> None:
        """Write chunk ``index``'s arrays, then its marker (here, in the client).

        Into this run's map only: a map at a path is checked for the run's token first.

        Raises:
            OptikError: the map was removed, or replaced by another run, since this run
                stamped it (:meth:`check_own`); nothing is written then.
        """
        if self.path is None:  # a store this process alone writes
            arrays = {name: self.group[name] for name in (*result, DONE_MARKER)}
        else:
            arrays = self._own_arrays()
        _write_block(arrays, self.spec.chunk, self.spec.block_grid[1], index, result)

    def check_own(self) -> None:
        """Raise unless the map at ``path`` still carries this run's token (see :meth:`write`).

        Raises:
            OptikError: the map was removed or now belongs to another run: this run must
                stop rather than write into it.
        """
        if self.path is not None:
            self._own_arrays()

    def _own_arrays(self) -> dict[str, Any]:
        """The arrays of the map at ``path``, opened afresh, if it is still this run's."""
        if self.path is None:  # an in-memory map has no folder to lose
            raise OptikError("a map without a path has no arrays on disk to open")
        arrays = _arrays_for_writing(self.path, self.run)
        if arrays is None:
            raise OptikError(
                f"{self.path}: the map was removed or replaced (by another run at the same "
                "path) while this run was writing it; the run stopped without writing into "
                "it (give each run its own output path)"
            )
        return arrays

    def writer(self) -> MapWriter | None:
        """The workers' writer of this map (``None`` for a store without a folder)."""
        if self.path is None:
            return None
        return MapWriter(self.path, self.run, self.spec.chunk, self.spec.block_grid[1])


def read_markers(marker: Any, where: str) -> np.ndarray:
    """The chunk markers of a stored map, flattened; a damaged file is an OptikError."""
    try:
        return np.asarray(marker[...]).ravel()
    except Exception as exc:  # zarr's codecs raise what they raise (Zstd: RuntimeError)
        _settle_zarr_reads()
        raise OptikError(
            f"{where}: damaged capability map, a chunk marker cannot be read ({exc}); "
            "delete the map and compute it again"
        ) from None


def _settle_zarr_reads(timeout_s: float = 5.0) -> None:
    """Let the other chunk reads of a failed zarr call finish before the error is raised.

    zarr reads a selection's chunks as tasks on its own event loop and gathers them: when
    one fails, the others keep running, and those still pending when the interpreter
    exits print a traceback each ("Task was destroyed but it is pending"), hundreds after
    the one-line error of a damaged map. They are waited for here (at most ``timeout_s``),
    never cancelled, and their outcomes read.
    """
    try:
        from zarr.core.sync import sync
    except ImportError:  # another zarr: nothing known to wait for
        return

    async def settle() -> None:
        current = asyncio.current_task()
        others = [task for task in asyncio.all_tasks() if task is not current]
        if others:
            await asyncio.wait(others, timeout=timeout_s)
        for task in others:
            if task.done() and not task.cancelled():
                task.exception()  # read: no "exception was never retrieved" either

    with contextlib.suppress(Exception):
        sync(settle())


__all__ = ["MapStore", "MapWriter", "MemoryMapStore"]
