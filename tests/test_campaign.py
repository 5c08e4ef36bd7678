"""Campaigns: the engine seam, seeds by global index, batches to Parquet, Dask runs.

One local cluster (2 worker processes, 1 thread each, no dashboard, 127.0.0.1) serves the
Dask tests of this module; its results are compared with in-process runs element for
element.
"""

from __future__ import annotations

import math
import os
import signal
import warnings
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
import xarray as xr
from conftest import random_q, robot_of, time_limit

import optik
from optik.campaign import capability, capability_map, open_engine, run_chunks
from optik.campaign.batch import (
    RUN_FILE,
    BatchSpec,
    PartStore,
    PartWriter,
    read_targets,
    result_columns,
    solve_batch,
    solve_chunk,
)
from optik.campaign.engine import QUIET_CLUSTER, Engine, Written, compute_and_write
from optik.errors import OptikError, OutputFileError

RESTARTS = 20


class Interrupted(Exception):
    """Raised from a progress callback to stop a run as Ctrl-C would."""


def _warm() -> None:
    """Load the compiled batch kernel in a worker (so a test does not time the cache)."""
    robot = optik.load_problem("ur5").robot
    optik.solve_ik_batch(robot, robot.fk(robot.mid_limits)[None], restarts=0, threads=1)


@pytest.fixture(scope="module")
def client() -> Iterator[Any]:
    """The client of the local cluster optik starts for ``workers=2``."""
    with open_engine(workers=2) as engine:
        assert engine.description == "2 local worker processes"
        engine.client.run(_warm)
        yield engine.client


def _dask_settings(names: tuple[str, ...]) -> tuple[Any, ...]:
    """Dask settings as a worker process sees them (run there by ``client.run``)."""
    import dask

    return tuple(dask.config.get(name) for name in names)


def _targets(n: int, seed: int = 3) -> np.ndarray:
    """UR5 poses: half reached from FK, half with their position pulled in (many unreachable)."""
    robot = robot_of("ur5")
    T = robot.fk(random_q(robot, np.random.default_rng(seed), n))
    T[n // 2 :, :3, 3] *= 0.25
    return T


def _files(folder: Path, pattern: str) -> dict[str, tuple[int, int]]:
    """``(inode, mtime in ns)`` of every file matching ``pattern`` under ``folder``: a file
    written again (a temporary file renamed over it) gets a new inode."""
    return {
        str(f.relative_to(folder)): (f.stat().st_ino, f.stat().st_mtime_ns)
        for f in folder.glob(pattern)
    }


def _same_tables(a: pa.Table, b: pa.Table) -> None:
    assert a.column_names == b.column_names
    assert a.num_rows == b.num_rows
    for name in a.column_names:
        x, y = a.column(name).to_numpy(), b.column(name).to_numpy()
        if x.dtype.kind == "f":
            assert np.array_equal(x, y, equal_nan=True), name
        else:
            assert np.array_equal(x, y), name


# ---------------------------------------------------------------------------- seeds
def test_batch_seed_offset_gives_the_same_rows_as_one_call() -> None:
    """solve_ik_batch gives target k the stream seed + k: a slice with seed + start agrees."""
    robot = robot_of("ur5")
    T = _targets(300)
    whole = optik.solve_ik_batch(robot, T, restarts=RESTARTS, seed=11)
    for start, stop in ((0, 120), (120, 121), (121, 300)):
        part = optik.solve_ik_batch(robot, T[start:stop], restarts=RESTARTS, seed=11 + start)
        assert np.array_equal(part.q, whole.q[start:stop], equal_nan=True)
        assert np.array_equal(part.iterations, whole.iterations[start:stop])
        assert np.array_equal(part.restarts, whole.restarts[start:stop])
    # And the seed matters (else the test above would prove nothing).
    other = optik.solve_ik_batch(robot, T, restarts=RESTARTS, seed=12)
    assert not np.array_equal(other.iterations, whole.iterations)


def test_batch_is_the_same_for_every_chunk_size() -> None:
    robot = robot_of("ur5")
    T = _targets(200)
    reference = optik.solve_ik_batch(robot, T, restarts=RESTARTS, seed=5)
    tables = [solve_batch(robot, T, restarts=RESTARTS, seed=5, chunk=c) for c in (7, 64, 1000)]
    for table in tables[1:]:
        _same_tables(tables[0], table)
    table = tables[0]
    assert table.column_names == result_columns(robot)
    assert np.array_equal(table.column("index").to_numpy(), np.arange(200))
    Q = np.column_stack([table.column(f"q_{n}").to_numpy() for n in robot.joint_names])
    assert np.array_equal(Q, reference.q, equal_nan=True)
    assert table.column("status").to_pylist() == list(reference.status)
    assert np.array_equal(table.column("success").to_numpy(), reference.success)
    assert 0 < reference.success.sum() < 200  # both outcomes are present


def test_batch_rows_verify_from_fk() -> None:
    """Each successful row reaches its target within tol (FK), inside the limits."""
    robot = robot_of("ur5")
    T = _targets(60)
    table = solve_batch(robot, T, restarts=RESTARTS, chunk=16)
    Q = np.column_stack([table.column(f"q_{n}").to_numpy() for n in robot.joint_names])
    ok = table.column("success").to_numpy()
    assert ok.sum() >= 30
    reached = robot.fk(Q[ok])
    assert np.max(np.linalg.norm(reached[:, :3, 3] - T[ok, :3, 3], axis=1)) <= 1e-6
    assert np.all(Q[ok] >= robot.lower - 1e-12) and np.all(Q[ok] <= robot.upper + 1e-12)


# ---------------------------------------------------------------------------- files
def test_targets_files_npy_and_parquet(tmp_path: Path) -> None:
    robot = robot_of("ur5")
    T = _targets(10)
    np.save(tmp_path / "t.npy", T)
    assert np.array_equal(read_targets(tmp_path / "t.npy"), T)
    quat = optik.to_quat_wxyz(T)
    columns = {"x": T[:, 0, 3], "y": T[:, 1, 3], "z": T[:, 2, 3]}
    columns |= {k: quat[:, i] for i, k in enumerate(("qw", "qx", "qy", "qz"))}
    pq.write_table(pa.table(columns), tmp_path / "t.parquet")
    assert np.max(np.abs(read_targets(tmp_path / "t.parquet") - T)) < 1e-12
    a = solve_batch(robot, tmp_path / "t.npy", restarts=2)
    b = solve_batch(robot, T, restarts=2)
    _same_tables(a, b)
    pq.write_table(pa.table({k: columns[k] for k in "xyz"}), tmp_path / "p.parquet")
    with pytest.raises(OptikError, match="positions only"):
        solve_batch(robot, tmp_path / "p.parquet")
    positions = solve_batch(robot, tmp_path / "p.parquet", mode="position", restarts=2)
    assert positions.column("orientation_error").to_numpy().max() == 0.0
    np.save(tmp_path / "bad.npy", np.zeros((4, 5)))
    with pytest.raises(OptikError, match=r"\(N, 4, 4\)"):
        read_targets(tmp_path / "bad.npy")
    pq.write_table(pa.table({"x": [0.1], "y": [0.2]}), tmp_path / "short.parquet")
    with pytest.raises(OptikError, match="missing column"):
        read_targets(tmp_path / "short.parquet")
    with pytest.raises(OptikError, match="not found"):
        read_targets(tmp_path / "none.npy")


def test_batch_interrupted_then_resumed_writes_every_chunk_once(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    # Two chunk threads whatever the machine: at most four chunks in flight when the
    # run stops, so some are left for the resume.
    monkeypatch.setattr(Engine, "pool_size", property(lambda self: 2))
    robot = robot_of("ur5")
    T = _targets(90)
    out = tmp_path / "results.parquet"
    reference = solve_batch(robot, T, restarts=RESTARTS, chunk=10)

    def stop_after_three(done: int, total: int) -> None:
        if done == 3:
            raise Interrupted

    with pytest.raises(Interrupted):
        solve_batch(robot, T, restarts=RESTARTS, chunk=10, out=out, progress=stop_after_three)
    # Chunks finish in any order on the thread pool, and the threads write their own: the
    # chunks already running when the run stopped were finished and written whole.
    written = PartStore(out).finished()
    assert 3 <= len(written) < 9 and written <= set(range(9))
    before = _files(out, "part-*.parquet")
    assert len(before) == len(written)
    # A temporary file left by a killed write is not a part.
    (out / ".part-000004.parquet.0123456789ab.tmp").write_bytes(b"half a file")
    (out / "..optik-run.0123456789ab.tmp").write_bytes(b"")  # and of the run's token
    with pytest.raises(OutputFileError, match="exists"):
        solve_batch(robot, T, restarts=RESTARTS, chunk=10, out=out)
    with pytest.raises(OptikError, match="other settings"):
        solve_batch(robot, T, restarts=RESTARTS, chunk=9, out=out, resume=True)
    calls: list[int] = []
    table = solve_batch(
        robot,
        T,
        restarts=RESTARTS,
        chunk=10,
        out=out,
        resume=True,
        progress=lambda done, total: calls.append(done),
    )
    assert calls == list(range(len(written), 10))  # the unfinished chunks, each once
    assert PartStore(out).finished() == set(range(9))
    assert not list(out.glob(".*.tmp"))  # the resume removed the killed write's leftover
    after = _files(out, "part-*.parquet")
    assert {name: after[name] for name in before} == before  # finished parts not rewritten
    _same_tables(table, reference)
    on_disk = pq.read_table(out).sort_by("index")  # a reader of the folder, not optik's
    assert np.array_equal(on_disk.column("index").to_numpy(), np.arange(90))
    _same_tables(on_disk, reference)


# ---------------------------------------------------------------------------- engine
def test_engine_options_are_checked() -> None:
    with pytest.raises(OptikError, match="at most one"):
        open_engine(workers=2, scheduler="tcp://127.0.0.1:1")
    with pytest.raises(OptikError, match="workers"):
        open_engine(workers=0)
    with pytest.raises(OptikError, match="client"):
        open_engine(client="tcp://127.0.0.1:1")
    with open_engine() as engine:
        assert not engine.distributed and engine.threads_for(10**6) == 1
        assert engine.threads_for(1) is None  # one chunk: numba's threads inside it
        assert sorted(engine.map_unordered(abs, [-3, 1, -2])) == [(0, 3), (1, 1), (2, 2)]


def test_a_local_cluster_starts_quietly_when_dasks_default_port_is_taken() -> None:
    """The scheduler's HTTP server takes a free port of 127.0.0.1, not 8787: another
    cluster on 8787 gave a warning on stderr before every message of the run."""
    import socket

    holder = socket.socket()
    try:
        holder.bind(("127.0.0.1", 8787))
        holder.listen()
    except OSError:
        pass  # taken already: the case under test
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            with open_engine(workers=1) as engine:
                http = engine.client.cluster.scheduler.http_server
                assert http.address == "127.0.0.1" and http.port != 8787
    finally:
        holder.close()
    assert not [w for w in caught if "in use" in str(w.message)]


def test_a_script_starting_a_cluster_without_the_main_guard_is_told_so(tmp_path: Path) -> None:
    """Dask's workers import the script again: unguarded, each started a cluster in turn,
    and the run ended in a dozen tracebacks and "Nanny failed to start"."""
    import subprocess
    import sys

    script = tmp_path / "unguarded.py"
    script.write_text(
        "from optik.campaign import open_engine\n"
        "with open_engine(workers=1) as engine:\n"
        "    print('started')\n"
    )
    env = {k: v for k, v in os.environ.items() if k != "PYTHONSTARTUP"}
    done = subprocess.run(
        [sys.executable, str(script)], capture_output=True, text=True, timeout=120, env=env,
        cwd=tmp_path,
    )  # fmt: skip
    assert done.returncode == 1 and "started" not in done.stdout
    guard = 'under `if __name__ == "__main__":`'
    assert guard in done.stderr.splitlines()[-1]  # the last line says what to do
    assert "a local cluster was started while a worker process imports this script" in (done.stderr)


def test_unreachable_scheduler_is_a_clear_error_within_seconds(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    # Within seconds because Dask is given the connect timeout: checked on the call
    # rather than on a stopwatch (a loaded machine takes longer to import and start).
    import distributed

    real = distributed.Client
    timeouts: list[object] = []

    def client(*args: Any, **kwargs: Any) -> Any:
        timeouts.append(kwargs.get("timeout"))
        return real(*args, **kwargs)

    monkeypatch.setattr(distributed, "Client", client)
    with time_limit(20.0), pytest.raises(OptikError, match="no Dask scheduler answered"):
        open_engine(scheduler="tcp://127.0.0.1:9", connect_timeout_s=1.0)
    assert timeouts == [1.0]


def test_run_chunks_skips_finished_chunks() -> None:
    class Store:
        def __init__(self) -> None:
            self.rows: dict[int, int] = {1: 10}

        def finished(self) -> set[int]:
            return set(self.rows)

        def write(self, index: int, result: int) -> None:
            assert index not in self.rows
            self.rows[index] = result

    store = Store()
    computed = run_chunks(open_engine(), lambda x: 10 * x, [0, 1, 2, 3], store)
    assert computed == 3
    assert store.rows == {0: 0, 1: 10, 2: 20, 3: 30}


def test_run_chunks_takes_receipts_from_a_store_whose_workers_write() -> None:
    """A writer that wrote a chunk sends a receipt; one that could not, the answer."""
    on_workers: dict[int, int] = {}

    def writer(index: int, result: int) -> bool:
        if index % 2:  # as a worker that does not see the store
            return False
        on_workers[index] = result
        return True

    class Store:
        def __init__(self) -> None:
            self.rows: dict[int, int] = {}

        def finished(self) -> set[int]:
            return set(self.rows) | set(on_workers)

        def write(self, index: int, result: int) -> None:
            self.rows[index] = result

        def writer(self) -> Any:
            return writer

    store = Store()
    done: list[int] = []
    computed = run_chunks(
        open_engine(), lambda x: 10 * x, list(range(7)), store, progress=lambda d, t: done.append(d)
    )
    assert computed == 7 and done == list(range(8))
    assert on_workers == {0: 0, 2: 20, 4: 40, 6: 60}
    assert store.rows == {1: 10, 3: 30, 5: 50}
    assert compute_and_write(lambda x: x + 1, writer, (2, 5)) == Written(2)
    assert compute_and_write(lambda x: x + 1, writer, (3, 5)) == 6
    assert compute_and_write(lambda x: x + 1, None, (2, 5)) == 6


def test_a_part_writer_writes_only_into_its_own_run(tmp_path: Path) -> None:
    robot = robot_of("ur5")
    T = _targets(20)
    out = tmp_path / "results.parquet"
    solve_batch(robot, T, restarts=RESTARTS, chunk=10, out=out)
    rows = solve_chunk(BatchSpec(robot, "pose", "z", 1e-6, RESTARTS, 100, 0, 1), (0, T[:10]))
    first = PartStore.for_run(out)
    writer = first.writer()
    assert writer is not None and writer.folder == str(out.resolve())
    before = _files(out, "*")
    resumed = PartStore.for_run(out)  # a later run of the folder (a resume) stamps it anew
    assert resumed.run != first.run
    assert not writer(5, rows)  # the earlier run's writer leaves the folder alone
    assert not (out / PartStore.part_name(5)).exists()
    again = resumed.writer()
    assert again is not None and again(5, rows)
    assert pq.read_table(out / PartStore.part_name(5)).column("index").to_pylist() == list(
        range(10)
    )
    assert {k: v for k, v in _files(out, "*").items() if k in before and k != RUN_FILE} == {
        k: v for k, v in before.items() if k != RUN_FILE
    }
    elsewhere = PartWriter(str(tmp_path / "not-here"), resumed.run)  # another machine's disk
    assert not elsewhere(0, rows) and not (tmp_path / "not-here").exists()
    assert PartStore(None).writer() is None


def test_a_batch_written_by_the_client_alone_is_the_same(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """When no worker can write the folder, the answers come back and the client writes."""
    robot = robot_of("ur5")
    T = _targets(60)
    reference = solve_batch(robot, T, restarts=RESTARTS, chunk=7)
    monkeypatch.setattr(PartWriter, "__call__", lambda self, index, result: False)
    table = solve_batch(robot, T, restarts=RESTARTS, chunk=7, out=tmp_path / "r.parquet")
    _same_tables(table, reference)
    assert PartStore(tmp_path / "r.parquet").finished() == set(range(9))


# ---------------------------------------------------------------------------- on Dask
# The cluster takes 10-30 s to start on a loaded machine: these are slow tests.
def _client_never_writes(self: Any, index: int, result: Any) -> None:
    """Stands in for a store's ``write`` in the client: the workers must write every chunk."""
    raise AssertionError(f"chunk {index} came back to the client to be written")


@pytest.mark.slow
def test_batch_on_a_local_cluster_equals_in_process(
    client: Any, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    robot = robot_of("ur5")
    T = _targets(240)
    here = solve_batch(robot, T, restarts=RESTARTS, chunk=50)
    there = solve_batch(robot, T, restarts=RESTARTS, chunk=17, client=client)  # rows come back
    _same_tables(here, there)
    monkeypatch.setattr(PartStore, "write", _client_never_writes)
    out = tmp_path / "results.parquet"
    written = solve_batch(robot, T, restarts=RESTARTS, chunk=17, client=client, out=out)
    _same_tables(here, written)
    assert PartStore(out).finished() == set(range(math.ceil(240 / 17)))


@pytest.mark.slow
def test_map_on_a_local_cluster_equals_in_process(
    client: Any, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    robot = robot_of("puma560")
    options: dict[str, Any] = {"voxel": 0.3, "orientations": 6, "mode": "axis", "keep_q": True}
    here = capability_map(robot, chunk=4, **options)
    there = capability_map(robot, chunk=2, client=client, **options)  # the arrays come back
    assert set(here.data_vars) == set(there.data_vars)
    for name in here.data_vars:
        assert np.array_equal(here[name].values, there[name].values, equal_nan=True), name
    xr.testing.assert_equal(here, there)
    assert float(here.reachability.max()) > 0.0
    monkeypatch.setattr(capability.MapStore, "write", _client_never_writes)
    out = tmp_path / "map.zarr"
    written = capability_map(robot, chunk=3, client=client, out=out, **options)
    xr.testing.assert_equal(here, written.load())


def _kill_a_worker_once(client: Any, before: set[int], killed: list[int]) -> Any:
    """A progress callback that kills one worker process once the first chunk is in."""

    def kill_one(done: int, total: int) -> None:
        if done >= 1 and not killed:  # answers are arriving: the workers are busy
            pid = sorted(before)[0]
            os.kill(pid, signal.SIGKILL)
            killed.append(done)

    return kill_one


@pytest.mark.slow
def test_a_worker_killed_mid_run_changes_nothing(client: Any, tmp_path: Path) -> None:
    robot = robot_of("ur5")
    T = _targets(2000, seed=8)
    reference = solve_batch(robot, T, restarts=RESTARTS, chunk=50)
    before = set(client.run(os.getpid).values())
    killed: list[int] = []
    out = tmp_path / "results.parquet"  # the workers write the parts
    with time_limit(120.0):
        table = solve_batch(
            robot,
            T,
            restarts=RESTARTS,
            chunk=50,
            client=client,
            out=out,
            progress=_kill_a_worker_once(client, before, killed),
        )
    assert killed and killed[0] < math.ceil(2000 / 50)  # killed before the end
    _same_tables(table, reference)
    on_disk = pq.read_table(out)
    assert np.array_equal(np.sort(on_disk.column("index").to_numpy()), np.arange(2000))
    client.wait_for_workers(2, timeout=60)
    assert set(client.run(os.getpid).values()) != before  # a new worker took its place
    # The new worker runs with the quiet settings of the cluster too.
    names = tuple(QUIET_CLUSTER)
    quiet = tuple(QUIET_CLUSTER.values())
    assert list(client.run(_dask_settings, names).values()) == [quiet, quiet]
    assert _dask_settings(names) != quiet  # this process keeps Dask's defaults


@pytest.mark.slow
def test_a_worker_killed_while_writing_a_map_changes_nothing(client: Any, tmp_path: Path) -> None:
    robot = robot_of("ur5")
    options: dict[str, Any] = {"voxel": 0.15, "orientations": 8, "mode": "pose", "chunk": 1}
    reference = capability_map(robot, **options)
    client.wait_for_workers(2, timeout=60)
    before = set(client.run(os.getpid).values())
    killed: list[int] = []
    out = tmp_path / "map.zarr"
    with time_limit(120.0):
        ds = capability_map(
            robot, client=client, out=out, progress=_kill_a_worker_once(client, before, killed),
            **options,
        )  # fmt: skip
    total = ds.sizes["x"] * ds.sizes["y"]
    assert killed and killed[0] < total  # killed before the end
    xr.testing.assert_equal(reference, ds.load())
    client.wait_for_workers(2, timeout=60)
    assert set(client.run(os.getpid).values()) != before


# ---------------------------------------------------------------------------- the CLI
def test_cli_batch_writes_a_row_per_target(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from optik.cli import main

    robot = robot_of("ur5")
    T = _targets(40)
    np.save(tmp_path / "t.npy", T)
    out = tmp_path / "results.parquet"
    args = ["batch", "ur5", str(tmp_path / "t.npy"), "--out", str(out), "--restarts", "5"]
    assert main([*args, "--chunk", "16"]) == 0
    text = capsys.readouterr().out
    table = pq.read_table(out).sort_by("index")
    _same_tables(table, solve_batch(robot, T, restarts=5))
    assert f"{table.column('success').to_numpy().sum()} converged" in text
    assert main(args) == 2  # exists without --resume
    assert "exists" in capsys.readouterr().err
    assert main([*args, "--chunk", "16", "--resume"]) == 0  # nothing left to do
    assert pq.read_table(out).num_rows == 40
    np.save(tmp_path / "p.npy", T[:, :3, 3])
    assert main(["batch", "ur5", str(tmp_path / "p.npy"), "--out", str(tmp_path / "p")]) == 2
    assert "positions only" in capsys.readouterr().err
    assert main([*args[:3], "--out", str(tmp_path / "x"), "--scheduler", "tcp://127.0.0.1:9"]) == 2
    assert "no Dask scheduler answered" in capsys.readouterr().err


def test_cli_map_writes_zarr_and_plots(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from optik.campaign import open_map
    from optik.cli import main

    out = tmp_path / "map.zarr"
    args = ["map", "puma560", "--voxel", "0.3", "--orientations", "4", "--mode", "axis"]
    assert main([*args, "--out", str(out), "--plots", str(tmp_path / "plots")]) == 0
    assert "reached" in capsys.readouterr().out
    ds = open_map(out)
    reference = capability_map(robot_of("puma560"), voxel=0.3, orientations=4, mode="axis")
    assert np.array_equal(ds.reachability.values, reference.reachability.values)
    assert sorted(p.name for p in (tmp_path / "plots").iterdir()) == [
        "manipulability.png",
        "map3d.png",
        "reachability.png",
    ]
    with pytest.raises(SystemExit) as usage:  # argparse refuses it: a usage error
        main([*args, "--out", str(tmp_path / "other.zarr"), "--voxel", "0"])
    assert usage.value.code == 2 and "--voxel" in capsys.readouterr().err
    for bad, message in (
        (["--voxel", "40"], "reach radius"),
        (["--bounds", "1", "0", "-1", "1", "-1", "1"], "above"),
        ([], "exists"),
    ):
        assert main([*args, "--out", str(out), *bad]) == 2
        assert message in capsys.readouterr().err
