"""Command-line options that were silently ignored or misread (a hostile-input search).

Each case was an exit 0 with the option without effect, or a result read with the wrong
tolerance; now each either takes effect (checked by its outcome) or is an error (exit 2)
naming the option. The robot is the planar 2R arm (1 m links, reach 2 m).
"""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path

import numpy as np
import pytest
from conftest import run_cli

import optik
from optik.errors import ArgumentError
from optik.paths import PathFileError, read_path

EDGE_PROBLEM = """\
[robot]
name = "planar_2r"
source = "a test"
convention = "dh"
length_unit = "m"
angle_unit = "deg"
analytic = "planar_2r"
[[robot.joints]]
name = "shoulder"
a = 1.0
lower = -180
upper = 180
[[robot.joints]]
name = "elbow"
a = 1.0
lower = -180
upper = 180
[[targets]]
name = "edge"
position = [2.005, 0.0, 0.0]
tolerance = 0.01
[[paths]]
name = "edgepath"
positions = [[2.005, 0.0, 0.0], [2.005, 0.001, 0.0]]
tolerance = 0.01
"""

LINE = ["--line", "1.5", "-0.5", "0", "1.5", "0.5", "0"]


def test_plan_position_mode_refuses_an_orientation(tmp_path: Path) -> None:
    code, err = run_cli(
        ["plan", "planar_2r", *LINE, "--rpy-deg", "0", "0", "90", "--mode", "position",
         "--out", str(tmp_path / "o")]
    )  # fmt: skip
    assert code == 2 and "--mode position ignores the orientation: drop --rpy-deg" in err


def test_plan_step_samples_a_line_only(tmp_path: Path) -> None:
    path = tmp_path / "path.csv"
    path.write_text("x,y,z\n1.5,-0.5,0\n1.5,0.5,0\n")
    code, err = run_cli(
        ["plan", "planar_2r", "--path", str(path), "--step", "0.05", "--out", str(tmp_path / "o")]
    )
    assert code == 2 and "--step samples --line only" in err
    assert not (tmp_path / "o").exists()  # a refused run makes no folder


def test_plan_trajectory_without_toppra_fails_before_the_work(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setitem(sys.modules, "toppra", None)  # as if the extra were not installed

    def no_planning(*args: object, **kwargs: object) -> None:
        raise AssertionError("the path was planned before the missing extra was named")

    monkeypatch.setattr("optik.cli._plan.plan_path", no_planning)
    limits = ["--velocity-limits", "1", "--acceleration-limits", "2"]
    out = tmp_path / "out"
    code, err = run_cli(["plan", "planar_2r", *LINE, "--trajectory", *limits, "--out", str(out)])
    assert code == 2 and "pip install 'optik[trajectory]'" in err, err
    assert not out.exists()


def test_a_reused_plan_folder_keeps_no_stale_trajectory(tmp_path: Path) -> None:
    out = tmp_path / "out"
    limits = ["--velocity-limits", "1", "--acceleration-limits", "2"]
    assert run_cli(["plan", "planar_2r", *LINE, "--trajectory", *limits, "--out", str(out)])[0] == 0
    assert (out / "trajectory.csv").exists()
    other = ["--line", "0.5", "-0.5", "0", "0.5", "0.5", "0"]
    assert run_cli(["plan", "planar_2r", *other, "--out", str(out)])[0] == 0
    assert not (out / "trajectory.csv").exists() and not (out / "trajectory.json").exists()
    first = (out / "plan.csv").read_text().splitlines()[1].split(",")
    assert float(first[2]) == pytest.approx(0.5)  # x of the new line's first waypoint


def test_an_npz_path_reads_its_rpy_and_refuses_arrays_it_does_not_read(tmp_path: Path) -> None:
    positions = np.array([[1.5, -0.5, 0.0], [1.5, 0.5, 0.0]])
    rpy = np.array([[0.0, 0.0, 0.3], [0.0, 0.0, 0.4]])
    np.savez(tmp_path / "rpy.npz", positions=positions, rpy=rpy)
    poses, mode = read_path(tmp_path / "rpy.npz")
    assert mode == "pose"
    for T, (_, _, yaw) in zip(poses, rpy, strict=True):
        assert np.allclose(T[:3, :3], [[math.cos(yaw), -math.sin(yaw), 0],
                                       [math.sin(yaw), math.cos(yaw), 0], [0, 0, 1]])  # fmt: skip
    np.savez(tmp_path / "both.npz", positions=positions, poses=poses)
    with pytest.raises(PathFileError, match="'positions' is not read beside 'poses'"):
        read_path(tmp_path / "both.npz")
    np.savez(tmp_path / "short.npz", positions=positions, rpy=rpy[:1])
    with pytest.raises(PathFileError, match="'rpy' holds 1 rows for 2 positions"):
        read_path(tmp_path / "short.npz")
    # a saved plan is a path (its poses), its results beside them
    robot = optik.load_problem("planar_2r").robot
    plan = optik.plan_path(robot, positions, mode="position")
    plan.save(tmp_path / "plan.npz")
    again, again_mode = read_path(tmp_path / "plan.npz")
    assert again_mode == "pose" and np.array_equal(again, plan.poses)


def test_solve_and_plan_take_the_problems_own_tolerance(tmp_path: Path) -> None:
    problem = tmp_path / "edge.toml"
    problem.write_text(EDGE_PROBLEM)
    # 5 mm beyond the 2 m reach, with a tolerance of 1 cm: solved with it, not with 1e-6
    assert run_cli(["solve", str(problem), "--target", "edge"])[0] == 0
    assert run_cli(["solve", str(problem), "--target", "edge", "--tol", "1e-6"])[0] == 1
    code, _ = run_cli(
        ["plan", str(problem), "--problem-path", "edgepath", "--out", str(tmp_path / "o")]
    )
    assert code == 0
    plan = json.loads((tmp_path / "o" / "plan.json").read_text())
    assert len(plan["status"]) == 2
    assert not set(plan["status"]) & {"unreachable", "outside_limits", "not_found"}


def test_plan_tol_overrides_the_default_and_the_paths_own(tmp_path: Path) -> None:
    problem = tmp_path / "edge.toml"
    problem.write_text(EDGE_PROBLEM)
    line = ["--line", "2.005", "0", "0", "2.005", "0.001", "0", "--step", "0.001"]

    def bad(args: list[str], out: str) -> set[str]:
        code, _ = run_cli(["plan", str(problem), *args, "--out", str(tmp_path / out)])
        status = json.loads((tmp_path / out / "plan.json").read_text())["status"]
        assert len(status) == 2
        unsolved = set(status) & {"unreachable", "outside_limits", "not_found"}
        assert code == (1 if unsolved else 0)  # an unsolved waypoint: exit 1, files written
        return unsolved

    # 5 mm beyond the reach: met with --tol 1 cm, not with the default 1e-6 ...
    assert bad(line, "default")
    assert not bad([*line, "--tol", "0.01"], "loose")
    # ... and a path's own 1 cm gives way to --tol
    assert bad(["--problem-path", "edgepath", "--tol", "1e-6"], "strict")


def test_batch_refuses_an_axis_without_axis_mode(tmp_path: Path) -> None:
    targets = tmp_path / "t.npy"
    np.save(targets, optik.pose(np.array([[1.0, 1.0, 0.0]]), rpy=np.array([[0.0, 0.0, 1.0]]),
                                rpy_convention="urdf"))  # fmt: skip
    code, err = run_cli(
        ["batch", "planar_2r", str(targets), "--mode", "pose", "--axis", "x",
         "--out", str(tmp_path / "o")]
    )  # fmt: skip
    assert code == 2 and "--axis x does not apply to --mode pose" in err
    # a map's pose samples turn about the tool axis: there --axis applies to pose too
    code, err = run_cli(
        ["map", "planar_2r", "--voxel", "0.5", "--mode", "position", "--axis", "x",
         "--out", str(tmp_path / "m.zarr")]
    )  # fmt: skip
    assert code == 2 and "--axis x does not apply to --mode position" in err


@pytest.mark.parametrize("batch", [None, 0, 1, "yes"])
def test_as_target_pose_takes_a_boolean_batch(batch: object) -> None:
    with pytest.raises(ArgumentError, match="batch"):
        optik.as_target_pose(np.eye(4), "pose", batch=batch)  # type: ignore[arg-type]
