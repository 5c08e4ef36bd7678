"""Campaign entry points under hostile input: clear OptikErrors, nothing half-written.

Each test feeds one input found by a hostile-input search (numpy scalar options, empty or
damaged files, overflowing grids, NUL bytes in paths) and checks the error type, a
fragment of its message and, where a folder is involved, that none is left behind.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from conftest import robot_of, two_link_robot

from optik.campaign import batch, capability_map
from optik.campaign.batch import SETTINGS_FILE, solve_batch
from optik.campaign.capability import open_map
from optik.campaign.placement import BasePlacements, base_placement, planar_candidates
from optik.campaign.sampling import MAX_SAMPLES, MAX_VOXELS, lattice, orientations
from optik.errors import OptikError, OutputFileError
from optik.model import Robot


def _targets(n: int = 3) -> tuple[Robot, np.ndarray]:
    robot = robot_of("puma560")
    q = np.linspace(robot.lower, robot.upper, n + 2)[1:-1] * 0.5
    return robot, robot.fk(q)


@pytest.fixture(scope="module")
def coarse_map() -> Any:
    box = [[-2.0, 2.0], [-2.0, 2.0], [0.0, 0.0]]
    return capability_map(
        two_link_robot(), voxel=0.5, bounds=box, mode="position", restarts=0, progress=False
    )


# ---------------------------------------------------------------------------- batches
def test_numpy_scalar_options_are_stored_as_plain_numbers(tmp_path: Path) -> None:
    robot, T = _targets()
    out = tmp_path / "res.parquet"
    options: dict[str, Any] = {"tol": np.float32(1e-6), "seed": np.int64(3), "restarts": 0}
    table = solve_batch(robot, T, out=out, progress=False, **options)
    assert table.num_rows == len(T)
    stored = json.loads((out / SETTINGS_FILE).read_text(encoding="utf-8"))
    assert type(stored["tol"]) is float and stored["seed"] == 3
    resumed = solve_batch(robot, T, out=out, resume=True, progress=False, **options)
    assert resumed.equals(table)


def test_resume_without_out_is_an_error() -> None:
    # It was ignored: the whole run computed again, in memory, without a word.
    robot, T = _targets()
    with pytest.raises(OptikError, match="resume: finishes a stored run; give its folder"):
        solve_batch(robot, T, resume=True, progress=False)
    with pytest.raises(OptikError, match="resume: finishes a stored map; give its folder"):
        capability_map(robot, voxel=0.5, resume=True, progress=False)


def test_a_bad_engine_option_leaves_no_output_folder(tmp_path: Path) -> None:
    robot, T = _targets()
    out = tmp_path / "res.parquet"
    with pytest.raises(OptikError, match="workers"):
        solve_batch(robot, T, out=out, workers=0, progress=False)
    assert not out.exists()


def test_an_output_in_a_missing_folder_is_refused_by_batches_as_by_maps(tmp_path: Path) -> None:
    # A batch created every missing folder of a mistyped path; a map refused it.
    robot, T = _targets()
    out = tmp_path / "typo" / "deeper" / "res.parquet"
    with pytest.raises(OutputFileError, match="typo/deeper does not exist"):
        solve_batch(robot, T, out=out, progress=False)
    with pytest.raises(OutputFileError, match="typo does not exist"):
        capability_map(robot, voxel=0.5, out=tmp_path / "typo" / "m.zarr", progress=False)
    assert not (tmp_path / "typo").exists()


def test_an_axis_a_mode_does_not_read_is_not_a_setting(tmp_path: Path) -> None:
    # It was stored as given, so a resume that left it out was refused over "other
    # settings" that change nothing.
    robot, T = _targets()
    out = tmp_path / "res.parquet"
    first = solve_batch(robot, T, out=out, mode="pose", axis="x", restarts=0, progress=False)
    assert json.loads((out / SETTINGS_FILE).read_text(encoding="utf-8"))["axis"] == "z"
    again = solve_batch(robot, T, out=out, mode="pose", resume=True, restarts=0, progress=False)
    assert again.equals(first)
    with pytest.raises(OptikError, match="other settings"):
        solve_batch(robot, T, out=out, mode="axis", axis="x", resume=True, restarts=0)
    ds = capability_map(robot, voxel=0.4, mode="position", axis="x", progress=False)
    assert ds.attrs["settings"]["axis"] == "z"


def test_a_failed_settings_write_leaves_no_output_folder(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    def refuse(path: Any, data: Any) -> Path:
        raise OutputFileError(str(path), "disk full")

    monkeypatch.setattr(batch, "write_atomic", refuse)
    robot, T = _targets()
    out = tmp_path / "res.parquet"
    with pytest.raises(OutputFileError, match="disk full"):
        solve_batch(robot, T, out=out, progress=False)
    assert not out.exists()


def test_an_empty_npy_targets_file_is_an_error_naming_it(tmp_path: Path) -> None:
    path = tmp_path / "targets.npy"
    path.write_bytes(b"")
    with pytest.raises(OptikError, match=r"targets\.npy: not a NumPy \.npy array"):
        solve_batch(robot_of("puma560"), path, progress=False)


@pytest.mark.parametrize("call", ["batch", "map"])
def test_a_nul_byte_in_the_output_path_is_an_error_naming_it(call: str) -> None:
    robot, T = _targets(1)
    with pytest.raises(OutputFileError, match="NUL character"):
        if call == "batch":
            solve_batch(robot, T, out="res\x00.parquet", progress=False)
        else:
            capability_map(robot, voxel=0.5, orientations=2, restarts=0, out="m\x00.zarr")


def test_a_damaged_part_file_on_resume_is_an_error_naming_it(tmp_path: Path) -> None:
    robot, T = _targets(4)
    out = tmp_path / "res.parquet"
    options: dict[str, Any] = {"chunk": 2, "restarts": 0, "progress": False}
    table = solve_batch(robot, T, out=out, **options)
    part = out / "part-000001.parquet"
    part.write_bytes(part.read_bytes()[:20])
    with pytest.raises(OptikError, match=r"part-000001\.parquet: a damaged part file.*delete it"):
        solve_batch(robot, T, out=out, resume=True, **options)
    part.unlink()  # the recovery the message gives
    assert solve_batch(robot, T, out=out, resume=True, **options).equals(table)


def test_stored_settings_that_are_not_an_object_are_an_error_naming_the_file(
    tmp_path: Path,
) -> None:
    robot, T = _targets(1)
    out = tmp_path / "res.parquet"
    solve_batch(robot, T, out=out, restarts=0, progress=False)
    (out / SETTINGS_FILE).write_text("[1, 2]", encoding="utf-8")
    with pytest.raises(OptikError, match=r"_optik\.json: unreadable settings \(a JSON list"):
        solve_batch(robot, T, out=out, restarts=0, resume=True, progress=False)


# ---------------------------------------------------------------------------- maps
@pytest.mark.parametrize(
    ("voxel", "bounds", "fragment"),
    [
        (1e-300, None, f"more than {MAX_VOXELS}"),
        (1e-12, None, f"more than {MAX_VOXELS}"),
        (1e-3, [[-1e308, 1e308]] * 3, "bounds"),
        (0.5, [[-1e300, 1e300], [0, 0], [0, 0]], "bounds"),
    ],
)
def test_a_lattice_beyond_the_cap_is_refused_before_allocating(
    voxel: float, bounds: Any, fragment: str
) -> None:
    with pytest.raises(OptikError, match=fragment):
        lattice(np.zeros(3), 2.0, voxel, bounds)


def test_orientations_times_rolls_is_capped() -> None:
    with pytest.raises(OptikError, match=f"samples per voxel, more than {MAX_SAMPLES}"):
        orientations("pose", 1000, 1000, "z")
    assert orientations("pose", 1000, MAX_SAMPLES // 1000, "z").shape == (MAX_SAMPLES, 3, 3)


# ---------------------------------------------------------------------------- placement
def test_base_placement_of_a_non_robot_is_an_error(coarse_map: Any) -> None:
    with pytest.raises(OptikError, match=r"robot: expected an optik\.Robot, got NoneType"):
        base_placement(None, [[1.0, 0.0, 0.0]], map=coarse_map)  # type: ignore[arg-type]


@pytest.mark.parametrize(
    ("region", "step"),
    [([[-1e12, 1e12], [0.0, 0.0]], 1e-3), ([[0.0, 1.0], [0.0, 1.0]], 1e-300)],
)
def test_too_many_planar_candidates_are_refused_before_allocating(region: Any, step: float) -> None:
    with pytest.raises(OptikError, match="at most 10,000,000"):
        planar_candidates(region, step, 1)


def test_a_planar_grid_far_from_the_origin_keeps_its_one_position() -> None:
    # 1e9 + 1e-11 rounds to 1e9: numpy's arange alone gives no position at all.
    bases = planar_candidates([[1e9, 1e9], [0.0, 0.0]], 0.01, 2)
    assert bases.shape == (2, 4, 4) and bases[0, 0, 3] == 1e9


def test_a_task_pose_beyond_the_length_limit_is_an_error(coarse_map: Any) -> None:
    with pytest.raises(OptikError, match=r"task_poses translation\[0, 0\].*1e\+09 m"):
        base_placement(two_link_robot(), [[1e300, 0.0, 0.0]], map=coarse_map, step=0.5, yaws=1)


def test_one_task_pose_or_candidate_is_a_batch_of_one(coarse_map: Any) -> None:
    # A (4, 4) pose was an IndexError past the pose check (as_pose keeps its shape).
    robot = two_link_robot()
    task = np.eye(4)
    task[:3, 3] = [0.5, 0.2, 0.0]
    base = np.eye(4)
    base[:3, 3] = [0.1, -0.1, 0.0]
    for single, batch_of_one in (
        (
            {"task_poses": task, "step": 0.5, "yaws": 2},
            {"task_poses": task[None], "step": 0.5, "yaws": 2},
        ),
        (
            {"task_poses": task[None], "candidates": base},
            {"task_poses": task[None], "candidates": base[None]},
        ),
    ):
        one = base_placement(robot, map=coarse_map, top=0, **single)
        reference = base_placement(robot, map=coarse_map, top=0, **batch_of_one)
        assert len(one.placements) == len(reference.placements) > 0
        assert [p.coverage for p in one.placements] == [p.coverage for p in reference.placements]
        np.testing.assert_array_equal(one.task_poses, reference.task_poses)


def test_positions_with_a_map_of_poses_are_an_error(coarse_map: Any) -> None:
    # (P, 3) points became identity-rotation poses and were ranked without a word.
    settings = dict(coarse_map.attrs["settings"], mode="pose")
    pose_map = coarse_map.copy()
    pose_map.attrs = dict(coarse_map.attrs, settings=settings)
    with pytest.raises(OptikError, match=r"positions are for a position map.*'pose'"):
        base_placement(two_link_robot(), [[0.5, 0.2, 0.0]], map=pose_map, step=0.5, yaws=1)


@pytest.mark.parametrize("value", [None, 5, {}])
def test_a_map_that_is_neither_a_dataset_nor_a_path_is_an_error(value: Any) -> None:
    # It was read as a relative path: "None: not a capability map (.../None does not exist)".
    name = type(value).__name__
    with pytest.raises(OptikError, match=rf"map: expected a capability map .* got {name}"):
        base_placement(two_link_robot(), [[0.5, 0.2, 0.0]], map=value, step=0.5, yaws=1)
    with pytest.raises(OptikError, match=rf"map: expected a capability map .* got {name}"):
        open_map(value)


def test_the_best_of_an_empty_ranking_is_an_error() -> None:
    empty = BasePlacements([], np.empty((0, 4, 4)), "position")
    with pytest.raises(OptikError, match="ranking is empty"):
        _ = empty.best


def test_an_in_memory_map_beyond_its_size_cap_is_refused_before_allocating() -> None:
    """Voxels and samples are each within their caps, their product is not: 8e6 voxels
    of 1,000 samples ask for 8 GB of ``reached`` alone (the map was allocated first)."""
    from optik.campaign.capability import MAX_MEMORY_BYTES

    robot = two_link_robot()
    radius = robot.reach_sphere[1]
    with pytest.raises(OptikError, match=r"GiB in memory, more than 4 GiB: give out="):
        capability_map(robot, voxel=radius / 100, orientations=1000, restarts=0)
    assert MAX_MEMORY_BYTES == 4 * 2**30


@pytest.mark.parametrize(
    ("option", "message"),
    [({"tol": -1.0}, "tol"), ({"restarts": -1}, "restarts"), ({"mode": "sideways"}, "mode")],
)
def test_base_placement_checks_its_reverification_options_first(
    coarse_map: Any, option: dict[str, Any], message: str
) -> None:
    """Checked before the ranking, also when nothing is re-verified (``top=0``)."""
    with pytest.raises(OptikError, match=message):
        base_placement(
            two_link_robot(), [[0.5, 0.0, 0.0]], map=coarse_map, step=0.5, yaws=1, top=0, **option
        )
