"""Capability maps: verified samples, the reach-sphere proof, a known annulus, resume."""

from __future__ import annotations

import math
import shutil
import sys
import threading
import types
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import zarr
from conftest import reference_fk, robot_of, two_link_robot

import optik
from optik.campaign import (
    _map_store,
    base_placement,
    capability,
    capability_map,
    open_map,
    plot_map,
)
from optik.campaign.engine import Engine
from optik.campaign.sampling import fibonacci_sphere, frames_with_axis, lattice, orientations
from optik.errors import OptikError, OutputFileError
from optik.model import Robot

PUMA: dict[str, Any] = {"voxel": 0.25, "orientations": 6, "restarts": 2}


class Interrupted(Exception):
    """Raised from a progress callback to stop a run as Ctrl-C would."""


@pytest.fixture(scope="module")
def puma_map() -> Any:
    return capability_map(robot_of("puma560"), mode="pose", rolls=2, keep_q=True, **PUMA)


def _same_data(a: Any, b: Any) -> None:
    assert set(a.data_vars) == set(b.data_vars)
    for name in a.data_vars:
        assert np.array_equal(a[name].values, b[name].values, equal_nan=True), name


def _marker_files(out: Path) -> dict[str, tuple[int, int]]:
    """``(inode, mtime in ns)`` of each chunk's marker file in a map's Zarr folder (one
    file per chunk, written when the chunk is done; written again, it gets a new inode)."""
    files = [f for f in (out / "chunk_done").rglob("*") if f.is_file() and f.name != "zarr.json"]
    return {str(f.relative_to(out)): (f.stat().st_ino, f.stat().st_mtime_ns) for f in files}


@pytest.fixture(scope="module")
def two_link_map() -> Any:
    box = [[-2.0, 2.0], [-2.0, 2.0], [-0.01, 0.01]]
    return capability_map(two_link_robot(), voxel=0.05, bounds=box, mode="position", restarts=10)


# ---------------------------------------------------------------------------- sampling
def test_fibonacci_sphere_is_unit_and_balanced() -> None:
    d = fibonacci_sphere(500)
    assert np.max(np.abs(np.linalg.norm(d, axis=1) - 1.0)) < 1e-12
    assert np.linalg.norm(d.mean(axis=0)) < 5e-3  # centred: no side favoured
    # Even: every point's nearest neighbour is at about the mean spacing sqrt(4 pi / n).
    gaps = np.sort(np.linalg.norm(d[:, None] - d[None], axis=2), axis=1)[:, 1]
    spacing = math.sqrt(4 * math.pi / 500)
    assert 0.6 * spacing < gaps.min() and gaps.max() < 1.3 * spacing


@pytest.mark.parametrize("axis", [0, 1, 2])
def test_frames_put_the_tool_axis_on_the_direction(axis: int) -> None:
    d = fibonacci_sphere(50)
    R = frames_with_axis(d, axis)
    assert np.max(np.abs(np.swapaxes(R, 1, 2) @ R - np.eye(3))) < 1e-12
    assert np.max(np.abs(np.linalg.det(R) - 1.0)) < 1e-12
    assert np.max(np.abs(R[:, :, axis] - d)) < 1e-15


def test_pose_orientations_turn_about_the_tool_axis() -> None:
    R = orientations("pose", 5, 4, "z").reshape(5, 4, 3, 3)
    for j in range(4):  # same tool axis, the other axes turned by 2 pi j / 4
        assert np.max(np.abs(R[:, j, :, 2] - R[:, 0, :, 2])) < 1e-12
        cos = np.sum(R[:, j, :, 0] * R[:, 0, :, 0], axis=1)
        assert np.max(np.abs(cos - math.cos(2 * math.pi * j / 4))) < 1e-12
    assert orientations("position", 7, 1, "z").shape == (1, 3, 3)
    with pytest.raises(OptikError, match="rolls"):
        orientations("axis", 5, 2, "z")


def test_lattice_is_anchored_at_the_centre_and_respects_bounds() -> None:
    c = np.array([0.1, -0.2, 0.3])
    x, _, _ = lattice(c, 1.0, 0.25)
    assert np.allclose(np.diff(x), 0.25) and 0.1 in x.tolist() and len(x) == 9
    x, _, _ = lattice(c, 1.0, 0.25, [[0.0, 0.5], [-1, 1], [-1, 1]])
    assert x.tolist() == pytest.approx([0.1, 0.35])
    with pytest.raises(OptikError, match="voxel"):
        lattice(c, 1.0, 0.0)
    with pytest.raises(OptikError, match="voxel"):
        lattice(c, 1.0, -0.1)
    with pytest.raises(OptikError, match="reach radius"):
        lattice(c, 1.0, 1.5)
    with pytest.raises(OptikError, match="above"):
        lattice(c, 1.0, 0.1, [[0.5, 0.0], [-1, 1], [-1, 1]])
    with pytest.raises(OptikError, match="no voxel centre"):
        lattice(c, 1.0, 0.25, [[0.12, 0.13], [-1, 1], [-1, 1]])


# ---------------------------------------------------------------------------- the map
def test_every_reached_sample_is_verified_from_fk_and_limits(puma_map: Any) -> None:
    """Independent DH product (conftest) at each stored q against the sampled pose."""
    robot = robot_of("puma560")
    ds = puma_map
    reached = ds.reached.values
    Q = ds.q.values
    assert reached.sum() > 20
    assert np.all(np.isnan(Q[~reached])) and not np.any(np.isnan(Q[reached]))
    R = ds.rotation.values
    for ix, iy, iz, m in zip(*np.nonzero(reached), strict=True):
        q = Q[ix, iy, iz, m]
        T = reference_fk(robot, q)
        p = np.array([ds.x.values[ix], ds.y.values[iy], ds.z.values[iz]])
        assert np.linalg.norm(T[:3, 3] - p) <= 1e-6
        angle = np.arccos(np.clip((np.trace(R[m].T @ T[:3, :3]) - 1) / 2, -1, 1))
        assert angle <= 1e-5  # arccos loses digits near 0: 1e-6 rad is ~1e-5 through it
        assert np.all(q >= robot.lower - 1e-12) and np.all(q <= robot.upper + 1e-12)
    # The per-voxel numbers follow from the samples.
    assert np.array_equal(ds.reachability.values, reached.mean(axis=3))
    hit = reached.any(axis=3)
    assert np.all(np.isfinite(ds.manipulability.values[hit]))
    assert np.all(np.isnan(ds.manipulability.values[~hit]))
    margin = ds.limit_margin.values[hit]
    assert np.all((margin >= 0) & (margin <= 1))


def test_manipulability_is_the_best_yoshikawa_measure(puma_map: Any) -> None:
    robot = robot_of("puma560")
    ds = puma_map
    ix, iy, iz = (int(v[0]) for v in np.nonzero(ds.reached.values.any(axis=3)))
    rows = ds.q.values[ix, iy, iz][ds.reached.values[ix, iy, iz]]
    best = max(math.sqrt(np.linalg.det(J @ J.T)) for J in (robot.jacobian(q) for q in rows))
    assert ds.manipulability.values[ix, iy, iz] == pytest.approx(best, rel=1e-9)


def test_no_voxel_outside_the_reach_sphere_is_reached_or_solved(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    robot = robot_of("puma560")
    centre, radius = robot.reach_sphere
    asked: list[tuple[np.ndarray, Any]] = []
    solve = capability.solve_ik_batch

    def spy(robot: Robot, targets: np.ndarray, **kw: Any) -> Any:
        result = solve(robot, targets, **kw)
        asked.append((np.asarray(targets)[:, :3, 3], result))
        return result

    monkeypatch.setattr(capability, "solve_ik_batch", spy)
    ds = capability_map(robot, mode="axis", **PUMA)
    X, Y, Z = np.meshgrid(ds.x.values, ds.y.values, ds.z.values, indexing="ij")
    distance = np.sqrt((X - centre[0]) ** 2 + (Y - centre[1]) ** 2 + (Z - centre[2]) ** 2)
    outside = distance > radius
    assert outside.sum() > 0 and (~outside).sum() > 0
    assert np.array_equal(ds.inside.values, ~outside)
    assert np.all(ds.reachability.values[outside] == 0.0)
    assert not ds.reached.values[outside].any()
    points = np.concatenate([p for p, _ in asked])
    iterations = np.concatenate([r.iterations for _, r in asked])
    q = np.concatenate([r.q for _, r in asked])
    near = np.linalg.norm(points - centre, axis=1) <= radius
    assert near.sum() == (~outside).sum() * ds.sizes["orientation"]  # each inside sample once
    # The rest are placeholders beyond the sphere that the batch rejects unsolved.
    assert np.all(iterations[~near] == 0) and np.all(np.isnan(q[~near]))
    assert np.all(np.linalg.norm(points[~near] - centre, axis=1) > 2 * radius)


def test_planar_2r_map_is_its_annulus(two_link_map: Any) -> None:
    """Links 1.0 and 0.6 m, full turns: reached exactly for 0.4 <= r <= 1.6 in z = 0."""
    l1, l2 = 1.0, 0.6
    voxel = 0.05
    ds = two_link_map
    assert ds.z.values.tolist() == [0.0]
    reached = ds.reachability.values > 0
    z = ds.z.values
    plane = int(np.argmin(np.abs(z)))
    X, Y = np.meshgrid(ds.x.values, ds.y.values, indexing="ij")
    r = np.hypot(X, Y)
    inner, outer = abs(l1 - l2), l1 + l2
    layer = reached[:, :, plane]
    assert layer[(r > inner + voxel) & (r < outer - voxel)].all()
    assert not layer[(r < inner - voxel) | (r > outer + voxel)].any()
    # Manipulability of a 2R point is l1 l2 |sin q2|, q2 from the law of cosines.
    inside = layer & (r > inner + voxel) & (r < outer - voxel)
    c2 = (r[inside] ** 2 - l1**2 - l2**2) / (2 * l1 * l2)
    expected = l1 * l2 * np.sqrt(1 - c2**2)
    assert np.max(np.abs(ds.manipulability.values[:, :, plane][inside] - expected)) < 1e-5


def test_map_is_the_same_for_every_chunk_size(puma_map: Any) -> None:
    robot = robot_of("puma560")
    other = capability_map(robot, mode="pose", rolls=2, keep_q=True, chunk=1, **PUMA)
    _same_data(puma_map, other)  # 81 chunks side by side on the thread pool
    assert other.attrs["settings"]["chunk"] == 1
    whole = capability_map(robot, mode="pose", rolls=2, keep_q=True, chunk=100, **PUMA)
    _same_data(puma_map, whole)  # one chunk, on numba's threads inside it


def test_map_settings_and_versions_are_attributes(puma_map: Any) -> None:
    settings = puma_map.attrs["settings"]
    assert settings["robot"] == "puma560" and settings["voxel_m"] == 0.25
    assert settings["samples_per_voxel"] == 12 and settings["mode"] == "pose"
    assert puma_map.attrs["versions"]["optik"] == optik.__version__
    assert "zarr" in puma_map.attrs["versions"]


def test_map_interrupted_then_resumed_computes_every_chunk_once(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    # Two chunk threads whatever the machine: at most four chunks in flight when the
    # run stops, so some are left for the resume.
    monkeypatch.setattr(Engine, "pool_size", property(lambda self: 2))
    robot = robot_of("puma560")
    options: dict[str, Any] = {"mode": "axis", "chunk": 3, **PUMA}
    reference = capability_map(robot, **options)
    out = tmp_path / "map.zarr"

    def stop_after_two(done: int, total: int) -> None:
        if done == 2:
            raise Interrupted

    with pytest.raises(Interrupted):
        capability_map(robot, out=out, progress=stop_after_two, **options)
    # The threads write their own chunks: those running when the run stopped were
    # finished and written whole, each with its marker.
    markers = _marker_files(out)
    assert len(markers) >= 2
    with pytest.raises(OptikError, match="unfinished"):
        open_map(out)
    with pytest.raises(OutputFileError, match="exists"):
        capability_map(robot, out=out, **options)
    with pytest.raises(OptikError, match="other settings"):
        capability_map(robot, out=out, resume=True, **{**options, "restarts": 3})
    calls: list[tuple[int, int]] = []
    ds = capability_map(
        robot, out=out, resume=True, progress=lambda d, t: calls.append((d, t)), **options
    )
    total = calls[0][1]
    assert len(markers) < total
    assert [d for d, _ in calls] == list(range(len(markers), total + 1))  # the rest, once each
    after = _marker_files(out)
    assert len(after) == total
    assert {name: after[name] for name in markers} == markers  # finished chunks not rewritten
    _same_data(ds, reference)
    _same_data(open_map(out), reference)


def test_a_damaged_marker_file_is_named_on_open_and_on_resume(tmp_path: Path) -> None:
    """A chunk marker that cannot be decoded is an OptikError naming the map, not zarr's."""
    box = [[-2.0, 2.0], [-2.0, 2.0], [-0.01, 0.01]]
    options: dict[str, Any] = {"voxel": 0.2, "bounds": box, "mode": "position", "restarts": 2}
    out = tmp_path / "map.zarr"
    capability_map(two_link_robot(), out=out, **options)
    open_map(out)  # whole, it opens
    damaged = out / next(iter(_marker_files(out)))
    damaged.write_bytes(b"not a zstd frame")
    with pytest.raises(OptikError, match="damaged capability map") as opened:
        open_map(out)
    assert str(out) in str(opened.value)
    with pytest.raises(OptikError, match="damaged capability map"):
        capability_map(two_link_robot(), out=out, resume=True, **options)


def test_a_damaged_marker_is_one_line_on_the_command_line(tmp_path: Path) -> None:
    """zarr reads the markers' chunks as tasks and leaves the others running when one
    fails: at exit each still pending printed a traceback (487 lines after the error)."""
    import subprocess

    args = ["map", "planar_2r", "--voxel", "0.2", "--mode", "position", "--chunk", "2",
            "--restarts", "1", "--out", str(tmp_path / "m.zarr")]  # fmt: skip
    run = [sys.executable, "-m", "optik", *args]
    subprocess.run(run, capture_output=True, check=True, timeout=300, cwd=tmp_path)
    (tmp_path / "m.zarr" / "chunk_done" / "c" / "0" / "0").write_bytes(b"xx")  # the first read
    done = subprocess.run(
        [*run, "--resume"], capture_output=True, text=True, timeout=300, cwd=tmp_path
    )
    assert done.returncode == 2
    assert done.stderr.startswith("optik: error: ") and "damaged capability map" in done.stderr
    assert done.stderr.count("\n") == 1, done.stderr[:2000]


def test_a_deleted_array_is_named_on_open_and_on_resume(tmp_path: Path) -> None:
    """A finished map missing one of its arrays (a folder deleted by hand) is refused
    when it is opened, naming the array, instead of opening and failing at a later read;
    a resume refuses it too. ``q`` is required only of a map that keeps it."""
    from optik.campaign._map_store import STORED_ALWAYS, missing_arrays

    box = [[-2.0, 2.0], [-2.0, 2.0], [-0.01, 0.01]]
    options: dict[str, Any] = {
        "voxel": 0.5, "bounds": box, "mode": "position", "restarts": 1, "keep_q": True,
    }  # fmt: skip
    robot = two_link_robot()
    out = tmp_path / "map.zarr"
    capability_map(robot, out=out, **options)
    stored = {path.name for path in out.iterdir() if path.is_dir()}
    assert set(STORED_ALWAYS) | {"q", "chunk_done"} <= stored
    assert missing_arrays(stored, keep_q=True) == []
    assert set(open_map(out).data_vars) >= {*STORED_ALWAYS, "q"}
    for name in (*STORED_ALWAYS, "q"):
        damaged = tmp_path / f"no_{name}.zarr"
        shutil.copytree(out, damaged)
        shutil.rmtree(damaged / name)
        with pytest.raises(OptikError, match=f"damaged capability map, no {name} array"):
            open_map(damaged)
        with pytest.raises(OptikError, match=f"not a capability map to resume .*no {name}"):
            capability_map(robot, out=damaged, resume=True, **options)
    without_q = tmp_path / "without_q.zarr"
    capability_map(robot, out=without_q, **{**options, "keep_q": False})
    assert "q" not in open_map(without_q)


def test_missing_markers_or_a_damaged_data_chunk_are_named(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A map without its chunk markers is not taken as finished (nor resumed), and a data
    chunk that cannot be decoded is an OptikError naming the map and the variable: on
    the command line (exit 2), through base_placement(map=path), and read_variable."""
    from optik.cli import main

    box = [[-2.0, 2.0], [-2.0, 2.0], [-0.01, 0.01]]
    options: dict[str, Any] = {"voxel": 0.2, "bounds": box, "mode": "position", "restarts": 2}
    robot = two_link_robot()
    out = tmp_path / "map.zarr"
    capability_map(robot, out=out, **options)
    no_markers = tmp_path / "no_markers.zarr"
    shutil.copytree(out, no_markers)
    shutil.rmtree(no_markers / "chunk_done")
    with pytest.raises(OptikError, match="no chunk markers"):
        open_map(no_markers)
    with pytest.raises(OptikError, match=r"not a capability map to resume .*no chunk_done"):
        capability_map(robot, out=no_markers, resume=True, **options)
    _damage_a_chunk(out / "reachability")
    ds = open_map(out)  # the markers are whole: it opens, and reads lazily
    with pytest.raises(OptikError, match="damaged capability map, 'reachability' cannot be read"):
        capability.read_variable(ds, "reachability", str(out))
    with pytest.raises(OptikError, match="damaged capability map") as placed:
        base_placement(robot, np.array([[0.5, 0.5, 0.0]]), map=out, top=0)
    assert str(out) in str(placed.value)
    cli_out = tmp_path / "cli.zarr"
    argv = ["map", "planar_2r", "--voxel", "0.5", "--mode", "position", "--out", str(cli_out)]
    assert main(argv) == 0
    _damage_a_chunk(cli_out / "reachability")
    capsys.readouterr()
    assert main([*argv, "--resume"]) == 2
    assert "damaged capability map, 'reachability' cannot be read" in capsys.readouterr().err


def _damage_a_chunk(variable: Path) -> None:
    chunk = next(f for f in variable.rglob("*") if f.is_file() and f.name != "zarr.json")
    chunk.write_bytes(b"\x00\x01")


def test_a_chunk_too_large_for_memory_is_refused_before_any_file(tmp_path: Path) -> None:
    """The whole map goes to Zarr chunk by chunk, but one chunk is still held in memory:
    (221 x 221 columns x 100 orientations with q) would ask numpy for 48 GiB."""
    out = tmp_path / "big.zarr"
    with pytest.raises(OptikError, match=r"one chunk of .* GiB in memory"):
        capability_map(
            robot_of("ur5"), voxel=0.01, orientations=100, keep_q=True, chunk=300, out=out
        )
    assert not out.exists()


def test_the_threads_write_the_map_and_the_client_only_what_they_cannot(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    # Two chunk threads whatever the machine: with one (a 1-core machine, or
    # NUMBA_NUM_THREADS=1) the chunks run on the calling thread, and a disk that only
    # the worker threads cannot write would never be put to the test.
    monkeypatch.setattr(Engine, "pool_size", property(lambda self: 2))
    robot = robot_of("puma560")
    options: dict[str, Any] = {"mode": "axis", "chunk": 2, "keep_q": True, **PUMA}
    reference = capability_map(robot, **options)  # in memory: the arrays come back
    with monkeypatch.context() as patch:  # the client must write nothing
        patch.setattr(capability.MapStore, "write", _client_never_writes)
        _same_data(capability_map(robot, out=tmp_path / "a.zarr", **options), reference)
    with monkeypatch.context() as patch:  # no worker sees the map: the client writes it all
        patch.setattr(_map_store.MapWriter, "__call__", lambda self, index, result: False)
        _same_data(capability_map(robot, out=tmp_path / "b.zarr", **options), reference)
    with monkeypatch.context() as patch:  # a disk the worker cannot write: the client does
        patch.setattr(_map_store, "_write_block", _fails_off_the_main_thread)
        _same_data(capability_map(robot, out=tmp_path / "c.zarr", **options), reference)


def _client_never_writes(self: Any, index: int, result: Any) -> None:
    raise AssertionError(f"chunk {index} came back to the client to be written")


_write_block = _map_store._write_block


def _fails_off_the_main_thread(*args: Any) -> None:
    if threading.current_thread() is not threading.main_thread():
        raise OSError(28, "No space left on device")
    _write_block(*args)


def test_a_map_writer_writes_only_into_its_own_run(tmp_path: Path) -> None:
    robot = robot_of("puma560")
    options: dict[str, Any] = {"mode": "axis", "chunk": 3, **PUMA}
    out = tmp_path / "map.zarr"

    def stop(done: int, total: int) -> None:
        raise Interrupted

    with pytest.raises(Interrupted):  # the store, created, before any chunk
        capability_map(robot, out=out, progress=stop, **options)
    spec = capability.MapSpec(
        robot, "axis", "z", 1e-6, 2, 100, 0, orientations("axis", 6, 1, "z"),
        *lattice(*robot.reach_sphere, 0.25), *robot.reach_sphere, 3, False, 1,
    )  # fmt: skip
    block = capability.solve_block(spec, spec.blocks[4])
    settings = dict(zarr.open_group(str(out), mode="r").attrs["settings"])
    first = capability.MapStore.reopen(out, spec, settings)
    writer = first.writer()
    assert writer is not None and writer.path == str(out.resolve())
    later = capability.MapStore.reopen(out, spec, settings)  # a resume stamps it anew
    assert later.run != first.run
    assert not writer(4, block) and _marker_files(out) == {}  # the earlier run writes nothing
    elsewhere = capability.MapWriter(str(tmp_path / "none.zarr"), later.run, 3, writer.nby)
    assert not elsewhere(4, block) and not (tmp_path / "none.zarr").exists()
    again = later.writer()
    assert again is not None and again(4, block)
    bx, by = divmod(4, spec.block_grid[1])
    assert list(_marker_files(out)) == [f"chunk_done/c/{bx}/{by}"]
    ix0, ix1, iy0, iy1 = spec.blocks[4]
    written = zarr.open_group(str(out), mode="r")
    for name, values in block.items():
        assert np.array_equal(written[name][ix0:ix1, iy0:iy1], values, equal_nan=True), name
    assert capability.MemoryMapStore(spec).writer() is None


def test_bad_map_options_are_errors(tmp_path: Path) -> None:
    robot = robot_of("puma560")
    for bad in ({"voxel": 0}, {"voxel": -0.1}, {"voxel": 50.0}, {"mode": "twist"}):
        with pytest.raises(OptikError):
            capability_map(robot, **bad)
    with pytest.raises(OptikError, match="above"):
        capability_map(robot, bounds=[[0.5, -0.5], [-1, 1], [-1, 1]])
    with pytest.raises(OptikError, match="no Dask scheduler"):
        capability_map(robot, voxel=0.5, scheduler="tcp://127.0.0.1:9")
    with pytest.raises(OptikError, match="robot"):
        capability_map("puma560")  # type: ignore[arg-type]


def test_map_plots_are_pngs(puma_map: Any, tmp_path: Path) -> None:
    files = plot_map(puma_map, tmp_path / "plots")
    assert [f.name for f in files] == ["reachability.png", "manipulability.png", "map3d.png"]
    for file in files:
        assert file.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and file.stat().st_size > 5000


# ---------------------------------------------------------------------------- placement
def test_base_placement_ranks_and_reverifies_by_the_annulus(two_link_map: Any) -> None:
    """A 2R base serves a point iff 0.4 <= distance <= 1.6 m: the map and IK agree."""
    robot = two_link_robot()
    tasks = np.array([[2.0, 0.5, 0.0], [2.3, -0.4, 0.0], [1.6, -0.2, 0.0]])
    result = base_placement(
        robot, tasks, map=two_link_map, region=[[0.5, 3.5], [-1.5, 1.5]], step=0.1, yaws=1,
        top=15,
    )  # fmt: skip
    assert result.verified_count == 15
    bases = np.array([p.T_cell_base[:3, 3] for p in result.placements])
    distance = np.linalg.norm(bases[:, None, :2] - tasks[None, :, :2], axis=2)
    in_annulus = (distance >= 0.4) & (distance <= 1.6)
    clear = np.all((np.abs(distance - 0.4) > 0.05) & (np.abs(distance - 1.6) > 0.05), axis=1)
    coverage = np.array([p.coverage for p in result.placements])
    assert np.array_equal(coverage[clear], in_annulus[clear].mean(axis=1))  # to one voxel
    for k, placement in enumerate(result.placements[:15]):
        assert placement.verified == pytest.approx(in_annulus[k].mean())
        assert placement.q is not None
        for q, target in zip(placement.q, tasks, strict=True):
            if not np.isnan(q[0]):  # an answer reaches its task pose from this base (FK)
                p = placement.T_cell_base @ reference_fk(robot, q)
                assert np.linalg.norm(p[:3, 3] - target) <= 1e-6
    assert result.best.verified == 1.0 and result.best.coverage == 1.0
    scores = [(p.coverage, p.score) for p in result.placements[15:]]
    assert scores == sorted(scores, reverse=True)


def test_base_placement_in_small_blocks_ranks_as_in_one(
    two_link_map: Any, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Candidates x task poses are looked up block by block (8 million floor candidates
    and 20 task poses asked numpy for 19 GiB at once): blocks of one or a few candidates,
    and rows split inside a block, give the one-block ranking exactly."""
    from optik.campaign import placement

    robot = two_link_robot()
    tasks = np.array([[2.0, 0.5, 0.0], [2.3, -0.4, 0.0], [1.6, -0.2, 0.0]])
    options: dict[str, Any] = {"region": [[0.5, 3.5], [-1.5, 1.5]], "step": 0.2, "yaws": 3}
    whole = base_placement(robot, tasks, map=two_link_map, top=0, **options)
    for entries in (1, 7):  # 1: one row per lookup, one candidate per block
        monkeypatch.setattr(placement, "LOOKUP_ENTRIES", entries)
        blocked = base_placement(robot, tasks, map=two_link_map, top=0, **options)
        assert [(p.coverage, p.score) for p in blocked.placements] == [
            (p.coverage, p.score) for p in whole.placements
        ]
        assert all(
            np.array_equal(a.T_cell_base, b.T_cell_base)
            for a, b in zip(blocked.placements, whole.placements, strict=True)
        )


def test_base_placement_checks_its_map(two_link_map: Any) -> None:
    with pytest.raises(OptikError, match="made for robot"):
        base_placement(robot_of("planar_2r"), [[1.0, 0.0, 0.0]], map=two_link_map)
    with pytest.raises(OptikError, match="region"):
        base_placement(
            two_link_robot(), [[1.0, 0.0, 0.0]], map=two_link_map, region=[[1, 0], [0, 1]]
        )


def test_a_zarr_older_than_3_is_refused_with_the_reason(monkeypatch: pytest.MonkeyPatch) -> None:
    # zarr 2 has another API and writes another format: optik refuses it up front.
    old = types.ModuleType("zarr")
    old.__version__ = "2.18.3"  # type: ignore[attr-defined]
    monkeypatch.setitem(sys.modules, "zarr", old)
    robot = optik.load_problem("planar_2r").robot
    with pytest.raises(OptikError, match=r"zarr >= 3 \(Python >= 3.11\), found zarr 2.18.3"):
        optik.capability_map(robot, voxel=0.5, orientations=2)
