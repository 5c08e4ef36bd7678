"""Campaigns whose output is removed or replaced mid-run, oversized chunk counts, resumes.

Each test replays a fault found by a hostile tester: a run that wrote (or re-created) a
folder that another run had taken over, a map that died of a raw ``KeyError`` there, a
resume that accepted part files of two runs, a million chunks accepted before any work,
``rolls`` accepted in position mode, a seed bound its check did not allow, and a rate that
counted resumed work. The in-process runs here solve one chunk at a time (the pool of
chunk threads patched to one thread), so a progress callback sees the folder exactly
between two chunks.
"""

from __future__ import annotations

import re
import shutil
import signal
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow.parquet as pq
import pytest
import zarr
from conftest import robot_of, two_link_robot

import optik
from optik.campaign import capability_map, engine, open_engine, open_map, solve_batch
from optik.campaign.batch import SETTINGS_FILE, PartStore
from optik.campaign.sampling import orientations
from optik.errors import OptikError
from optik.ik import MAX_SEED


class Interrupted(Exception):
    """Raised from a progress callback to stop a run as Ctrl-C would."""


@pytest.fixture
def one_chunk_at_a_time(monkeypatch: pytest.MonkeyPatch) -> None:
    """In-process runs solve their chunks one after another, on the calling thread."""
    monkeypatch.setattr(engine.Engine, "pool_size", property(lambda self: 1))


def _targets(n: int, seed: int = 5) -> np.ndarray:
    robot = robot_of("puma560")
    rng = np.random.default_rng(seed)
    q = rng.uniform(robot.lower, robot.upper, (n, robot.dof)) * 0.5
    return np.asarray(robot.fk(q))


def _parts(folder: Path) -> list[str]:
    return sorted(f.name for f in folder.glob("part-*.parquet"))


def _take_over(folder: Path) -> None:
    """Another run at ``folder``: the old folder removed, a new one with its own token."""
    shutil.rmtree(folder)
    folder.mkdir()
    (folder / SETTINGS_FILE).write_text('{"robot": "another run"}', encoding="utf-8")
    PartStore.for_run(folder)


# ---------------------------------------------------------------------------- batches
@pytest.mark.usefixtures("one_chunk_at_a_time")
def test_a_batch_stops_when_its_folder_is_taken_over_by_another_run(tmp_path: Path) -> None:
    robot, T = robot_of("puma560"), _targets(40)
    out = tmp_path / "res.parquet"

    def take_over_after_two(done: int, total: int) -> None:
        if done == 2:
            _take_over(out)

    with pytest.raises(OptikError, match=r"replaced by another run"):
        solve_batch(robot, T, restarts=1, chunk=5, out=out, progress=take_over_after_two)
    assert _parts(out) == []  # the new run's folder holds none of the old run's parts
    assert (out / SETTINGS_FILE).read_text(encoding="utf-8") == '{"robot": "another run"}'


@pytest.mark.usefixtures("one_chunk_at_a_time")
def test_a_batch_whose_folder_is_removed_stops_without_creating_it_again(tmp_path: Path) -> None:
    robot, T = robot_of("puma560"), _targets(40)
    out = tmp_path / "res.parquet"

    def remove_after_two(done: int, total: int) -> None:
        if done == 2:
            shutil.rmtree(out)

    with pytest.raises(OptikError, match=r"res\.parquet: the output folder was removed"):
        solve_batch(robot, T, restarts=1, chunk=5, out=out, progress=remove_after_two)
    assert not out.exists()


def test_a_folder_holding_parts_of_two_runs_is_refused_on_resume(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from optik.cli import main

    robot = robot_of("puma560")
    first, second = tmp_path / "a.parquet", tmp_path / "b.parquet"
    solve_batch(robot, _targets(30, seed=1), restarts=1, chunk=10, out=first)
    solve_batch(robot, _targets(30, seed=2), restarts=1, chunk=10, out=second)
    shutil.copyfile(first / "part-000001.parquet", second / "part-000001.parquet")
    with pytest.raises(OptikError, match=r"part-000001\.parquet: a part file of another run"):
        solve_batch(robot, _targets(30, seed=2), restarts=1, chunk=10, out=second, resume=True)
    np.save(tmp_path / "t.npy", _targets(30, seed=2))
    args = ["batch", "puma560", str(tmp_path / "t.npy"), "--out", str(second)]
    assert main([*args, "--restarts", "1", "--chunk", "10", "--resume"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "a part file of another run" in err
    # Deleting the foreign part and resuming computes it again, for this run.
    (second / "part-000001.parquet").unlink()
    table = solve_batch(robot, _targets(30, seed=2), restarts=1, chunk=10, out=second, resume=True)
    assert table.equals(solve_batch(robot, _targets(30, seed=2), restarts=1, chunk=10))


# ---------------------------------------------------------------------------- maps
MAP: dict[str, Any] = {
    "voxel": 0.5,
    "bounds": [[-2.0, 2.0], [-2.0, 2.0], [0.0, 0.0]],
    "mode": "position",
    "restarts": 0,
    "chunk": 2,
}


@pytest.mark.usefixtures("one_chunk_at_a_time")
def test_a_map_whose_folder_is_removed_is_a_clear_error(tmp_path: Path) -> None:
    out = tmp_path / "m.zarr"

    def remove_after_one(done: int, total: int) -> None:
        if done == 1:
            shutil.rmtree(out)

    with pytest.raises(OptikError, match=r"m\.zarr: the map was removed"):
        capability_map(two_link_robot(), out=out, progress=remove_after_one, **MAP)
    assert not out.exists()


@pytest.mark.usefixtures("one_chunk_at_a_time")
def test_a_map_stops_when_its_folder_is_taken_over_by_another_run(tmp_path: Path) -> None:
    robot = two_link_robot()
    other = tmp_path / "other.zarr"
    capability_map(robot, out=other, **{**MAP, "restarts": 1})  # the new run's map
    before = {str(f.relative_to(other)): f.read_bytes() for f in other.rglob("*") if f.is_file()}
    out = tmp_path / "m.zarr"

    def take_over_after_one(done: int, total: int) -> None:
        if done == 1:
            shutil.rmtree(out)
            shutil.copytree(other, out)

    with pytest.raises(OptikError, match=r"m\.zarr: the map was removed or replaced"):
        capability_map(robot, out=out, progress=take_over_after_one, **MAP)
    after = {str(f.relative_to(out)): f.read_bytes() for f in out.rglob("*") if f.is_file()}
    assert after == before  # not one byte of the old run in the new run's map


def test_cli_map_whose_folder_is_removed_exits_2_with_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    from optik.cli import main

    monkeypatch.setattr(engine.Engine, "pool_size", property(lambda self: 1))
    out = tmp_path / "m.zarr"
    real = engine.run_chunks

    def run_then_remove(*args: Any, progress: Any = None, **kwargs: Any) -> int:
        def remove_after_one(done: int, total: int) -> None:
            if done == 1:
                shutil.rmtree(out)
            if progress is not None:
                progress(done, total)

        return real(*args, progress=remove_after_one, **kwargs)

    monkeypatch.setattr(engine, "run_chunks", run_then_remove)
    args = ["map", "puma560", "--voxel", "0.3", "--orientations", "2", "--chunk", "2"]
    assert main([*args, "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "the map was removed" in err and "Traceback" not in err


# ---------------------------------------------------------------------------- chunk counts
def test_a_batch_of_too_many_chunks_is_refused_before_any_work(tmp_path: Path) -> None:
    robot = robot_of("puma560")
    T = np.broadcast_to(_targets(1)[0], (engine.MAX_CHUNKS + 1, 4, 4))

    def no_work(done: int, total: int) -> None:
        raise AssertionError(f"started a run of {total} chunks")

    out = tmp_path / "res.parquet"
    with pytest.raises(OptikError, match=r"chunk: .*100001 chunks, more than 100000.*chunk=2"):
        solve_batch(robot, T, chunk=1, out=out, progress=no_work)
    assert not out.exists()


def test_a_map_of_too_many_chunks_is_refused_before_any_work(tmp_path: Path) -> None:
    """UR5, a 501 x 501 slab of voxel columns: 251,001 chunks of one column."""
    robot = optik.load_problem("ur5").robot
    c, _ = robot.reach_sphere
    box = [[c[0] - 1, c[0] + 1], [c[1] - 1, c[1] + 1], [c[2], c[2]]]

    def no_work(done: int, total: int) -> None:
        raise AssertionError(f"started a run of {total} chunks")

    options: dict[str, Any] = {"voxel": 0.004, "bounds": box, "mode": "position"}
    out = tmp_path / "slab.zarr"
    with pytest.raises(OptikError, match=r"chunk: .*251001 chunks.*chunk=2"):
        capability_map(robot, chunk=1, out=out, progress=no_work, **options)
    assert not out.exists()


# ---------------------------------------------------------------------------- options
def test_rolls_other_than_1_is_refused_in_position_mode(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from optik.cli import main

    with pytest.raises(OptikError, match="rolls"):
        orientations("position", 1, 2, "z")
    with pytest.raises(OptikError, match="rolls"):
        capability_map(two_link_robot(), **{**MAP, "chunk": 4}, rolls=2, progress=False)
    args = ["map", "puma560", "--voxel", "0.3", "--mode", "position", "--rolls", "2"]
    assert main([*args, "--out", str(tmp_path / "m.zarr")]) == 2
    assert "rolls" in capsys.readouterr().err
    assert not (tmp_path / "m.zarr").exists()


def test_the_batch_seed_bound_in_the_message_is_the_one_checked() -> None:
    robot = robot_of("puma560")
    T = np.asarray(robot.fk(robot.mid_limits))[None]
    with pytest.raises(OptikError, match="seed must be at most") as refused:
        optik.solve_ik_batch(robot, T, seed=MAX_SEED)
    bound = int(re.findall(r"\((\d+)\)", str(refused.value))[0])
    assert optik.solve_ik_batch(robot, T, seed=bound, restarts=0).q.shape == (1, robot.dof)
    with pytest.raises(OptikError, match="seed must be at most"):
        optik.solve_ik_batch(robot, T, seed=bound + 1)


# ---------------------------------------------------------------------------- resumed runs
@pytest.mark.usefixtures("one_chunk_at_a_time")
def test_cli_batch_resume_counts_only_the_targets_it_solved(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from optik.cli import main

    T = _targets(50)
    out = tmp_path / "res.parquet"

    def stop_after_two(done: int, total: int) -> None:
        if done == 2:
            raise Interrupted

    robot = robot_of("puma560")
    with pytest.raises(Interrupted):
        solve_batch(robot, T, restarts=1, chunk=10, out=out, progress=stop_after_two)
    # One chunk at a time: the run stopped with exactly its first two chunks written (on
    # a pool, the chunks in flight would be finished too, up to all five of them).
    resumed = sum(pq.read_table(out / name).num_rows for name in _parts(out))
    assert resumed == 20
    np.save(tmp_path / "t.npy", T)
    args = ["batch", "puma560", str(tmp_path / "t.npy"), "--out", str(out), "--restarts", "1"]
    assert main([*args, "--chunk", "10", "--resume"]) == 0
    text = capsys.readouterr().out
    assert f"{50 - resumed} computed in " in text and f"{resumed} resumed" in text
    assert main([*args, "--chunk", "10", "--resume"]) == 0  # nothing left to solve
    text = capsys.readouterr().out
    assert "0 computed in " in text and "50 resumed" in text


def test_cli_map_resume_counts_only_the_samples_it_solved(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from optik.cli import main

    out = tmp_path / "m.zarr"
    args = ["map", "puma560", "--voxel", "0.3", "--orientations", "2", "--chunk", "2"]
    assert main([*args, "--out", str(out)]) == 0
    capsys.readouterr()
    ds = open_map(out)
    samples = int(ds.inside.values.sum()) * 2
    marker = zarr.open_array(store=str(out), path="chunk_done", mode="r+")
    marker[1, 1] = 0  # as if the run had stopped before this chunk
    first = int(ds.inside.values[2:4, 2:4].sum()) * 2
    assert first > 0
    assert main([*args, "--out", str(out), "--resume"]) == 0
    text = capsys.readouterr().out
    assert f"  {first} IK samples in " in text and f"{samples - first} resumed" in text


# ---------------------------------------------------------------------------- Ctrl-C
def _sigint_handler() -> str:
    """How this process handles SIGINT (run in a worker by ``client.run``)."""
    return str(signal.getsignal(signal.SIGINT))


@pytest.mark.slow
def test_local_cluster_workers_leave_ctrl_c_to_the_client() -> None:
    """A terminal's Ctrl-C reaches every process of its group: the workers must not die
    of it (each printed a traceback); the client stops the run and closes the cluster."""
    with open_engine(workers=1) as local:
        handlers = local.client.run(_sigint_handler)
    assert list(handlers.values()) == [str(signal.SIG_IGN)]
