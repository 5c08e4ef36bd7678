"""``optik solve`` and ``optik plan`` with the task options: --mode, --axis, --weights,
--posture, --freeze.

Exit codes 0 (solved), 1 (no answer) and 2 (bad input); every printed configuration is
checked against forward kinematics here, with targets built independently of the CLI.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from optik.cli import main
from optik.problems import load_problem
from optik.spatial import rot_x, rot_z

PANDA = load_problem("panda").robot
UR5 = load_problem("ur5").robot


def _axis_angle(a: np.ndarray, b: np.ndarray) -> float:
    return math.atan2(float(np.linalg.norm(np.cross(a, b))), float(a @ b))


def _num(v: float) -> str:
    """A number as the command line takes it: fixed point (argparse reads ``-1e-17`` as an
    option), 16 decimals (the values here are below 10 in magnitude)."""
    return f"{float(v):.16f}"


def _target_args(T: np.ndarray) -> list[str]:
    """--position and --quat-xyzw of a pose, at full precision (scipy's quaternion)."""
    quat = Rotation.from_matrix(T[:3, :3]).as_quat()  # x, y, z, w
    return ["--position", *map(_num, T[:3, 3]), "--quat-xyzw", *map(_num, quat)]


def _rolled_target(roll: float = 1.3) -> np.ndarray:
    """A Panda target whose roll about the tool z differs from the FK pose's."""
    T = PANDA.fk(PANDA.mid_limits + 0.3)
    T[:3, :3] = T[:3, :3] @ rot_z(roll)
    return T


def _solve_json(args: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, dict]:
    code = main(["solve", "panda", *args, "--json"])
    return code, json.loads(capsys.readouterr().out)


def test_solve_axis_mode_json(capsys: pytest.CaptureFixture[str]) -> None:
    T = _rolled_target()
    code, out = _solve_json([*_target_args(T), "--mode", "axis"], capsys)
    assert code == 0 and out["success"] and out["mode"] == "axis"
    F = PANDA.fk(np.array(out["q"]))
    assert np.linalg.norm(F[:3, 3] - T[:3, 3]) <= 1e-6
    assert _axis_angle(F[:3, 2], T[:3, 2]) <= 1e-6
    assert out["orientation_error"] == pytest.approx(_axis_angle(F[:3, 2], T[:3, 2]), abs=1e-9)


def test_solve_axis_mode_text_output(capsys: pytest.CaptureFixture[str]) -> None:
    """The printed joint values (6 decimals, rad) reach the target to about 1e-5."""
    T = PANDA.fk(PANDA.mid_limits - 0.2)
    T[:3, :3] = T[:3, :3] @ rot_x(0.9)  # turn the tool about its x: the x axis stays
    code = main(["solve", "panda", *_target_args(T), "--mode", "axis", "--axis", "x"])
    out = capsys.readouterr().out
    assert code == 0 and "tool-axis angle error" in out
    q = [float(line.split()[1]) for line in out.splitlines() if line.strip().startswith("panda_j")]
    F = PANDA.fk(np.array(q))
    assert np.linalg.norm(F[:3, 3] - T[:3, 3]) <= 2e-5
    assert _axis_angle(F[:3, 0], T[:3, 0]) <= 2e-5


def test_solve_weights_free_the_depth(capsys: pytest.CaptureFixture[str]) -> None:
    T = PANDA.fk(PANDA.mid_limits + 0.3)
    T[:3, 3] += 0.03 * T[:3, 2]  # 3 cm deeper along the target's z, which is free
    code, out = _solve_json([*_target_args(T), "--weights", "1", "1", "0", "1", "1", "1"], capsys)
    assert code == 0 and out["success"] and out["mode"] == "pose"
    F = PANDA.fk(np.array(out["q"]))
    d = T[:3, :3].T @ (F[:3, 3] - T[:3, 3])
    assert math.hypot(d[0], d[1]) <= 1e-6
    R = T[:3, :3].T @ F[:3, :3]
    assert math.acos(min(1.0, (np.trace(R) - 1) / 2)) <= 1e-5


def test_solve_weights_choose_the_axis_mode(capsys: pytest.CaptureFixture[str]) -> None:
    T = _rolled_target(2.0)
    code, out = _solve_json([*_target_args(T), "--weights", "1", "1", "1", "1", "1", "0"], capsys)
    assert code == 0 and out["mode"] == "axis"
    F = PANDA.fk(np.array(out["q"]))
    assert np.linalg.norm(F[:3, 3] - T[:3, 3]) <= 1e-6
    assert _axis_angle(F[:3, 2], T[:3, 2]) <= 1e-6


def test_solve_orientation_mode(capsys: pytest.CaptureFixture[str]) -> None:
    T = PANDA.fk(PANDA.mid_limits + 0.4)
    T[:3, 3] = [3.0, 0.0, 0.0]  # beyond the reach: only the rotation counts
    code, out = _solve_json([*_target_args(T), "--mode", "orientation"], capsys)
    assert code == 0 and out["success"] and out["position_error"] == 0.0
    R = T[:3, :3].T @ PANDA.fk(np.array(out["q"]))[:3, :3]
    angle = Rotation.from_matrix(R).magnitude()
    assert angle <= 1e-6


def test_solve_freeze_holds_the_joint(capsys: pytest.CaptureFixture[str]) -> None:
    q = PANDA.mid_limits + 0.25
    T = PANDA.fk(q)
    held = _num(q[2])
    code, out = _solve_json([*_target_args(T), "--freeze", f"panda_joint3={held}"], capsys)
    assert code == 0 and out["success"]
    assert out["q"][2] == float(held)
    F = PANDA.fk(np.array(out["q"]))
    assert np.linalg.norm(F[:3, 3] - T[:3, 3]) <= 1e-6
    assert Rotation.from_matrix(T[:3, :3].T @ F[:3, :3]).magnitude() <= 1e-5


def test_solve_posture_is_nearer_the_reference(capsys: pytest.CaptureFixture[str]) -> None:
    T = _rolled_target(0.0)
    q_ref = PANDA.mid_limits + np.array([0.5, -0.2, -0.6, 0.3, 0.4, -0.3, 0.5])
    reference = [_num(v) for v in q_ref]
    code, plain = _solve_json([*_target_args(T), "--mode", "axis"], capsys)
    assert code == 0
    code, near = _solve_json([*_target_args(T), "--mode", "axis", "--posture", *reference], capsys)
    assert code == 0 and near["success"]
    qn = np.array(near["q"])
    F = PANDA.fk(qn)
    assert np.linalg.norm(F[:3, 3] - T[:3, 3]) <= 1e-6
    assert _axis_angle(F[:3, 2], T[:3, 2]) <= 1e-6
    assert np.linalg.norm(qn - q_ref) < np.linalg.norm(np.array(plain["q"]) - q_ref)


def test_solve_without_an_answer_exits_1(capsys: pytest.CaptureFixture[str]) -> None:
    T = _rolled_target()
    T[:3, 3] = [3.0, 0.0, 0.5]  # beyond the Panda's reach sphere: proved unreachable
    code, out = _solve_json([*_target_args(T), "--mode", "axis"], capsys)
    assert code == 1 and not out["success"] and out["q"] is None
    assert out["status"] == "unreachable"


OK_TARGET = ["--position", "0.4", "0.1", "0.5", "--rpy-deg", "180", "0", "0"]


@pytest.mark.parametrize(
    ("args", "says"),
    [
        (["--position", "0.4", "0.1", "0.5", "--mode", "axis"], "orientation"),
        (["--position", "0.4", "0.1", "0.5", "--mode", "orientation"], "orientation"),
        ([*OK_TARGET, "--mode", "drill"], "--mode"),
        ([*OK_TARGET, "--mode", "axis", "--axis", "w"], "--axis"),
        ([*OK_TARGET, "--axis", "x"], "--axis"),
        ([*OK_TARGET, "--mode", "axis", "--axis", "x", "--weights", *"111110"], "--weights"),
        ([*OK_TARGET, "--weights", "1", "1", "1", "1", "1"], "--weights"),
        ([*OK_TARGET, "--weights", *"11111", "nan"], "--weights"),
        ([*OK_TARGET, "--weights", *"11111", "-1"], "--weights"),
        ([*OK_TARGET, "--weights", *"111100"], "weights"),
        ([*OK_TARGET, "--weights", *"000000"], "weights"),
        (["--position", "0.4", "0.1", "0.5", "--weights", *"111110"], "weights"),
        ([*OK_TARGET, "--freeze", "panda_joint1"], "--freeze"),
        ([*OK_TARGET, "--freeze", "=0.1"], "--freeze"),
        ([*OK_TARGET, "--freeze", "panda_joint1=inf"], "--freeze"),
        ([*OK_TARGET, "--freeze", "elbow=0.1"], "frozen"),
        ([*OK_TARGET, "--freeze", "panda_joint4=0.5"], "panda_joint4"),
        ([*OK_TARGET, "--freeze", "panda_joint1=0.1", "--freeze", "panda_joint1=0.2"], "twice"),
        ([*OK_TARGET, "--posture", "0", "0", "0"], "posture"),
        ([*OK_TARGET, "--posture", *"0000000", "--posture"], "--posture"),
    ],
)
def test_solve_bad_task_input_exits_2(
    args: list[str], says: str, capsys: pytest.CaptureFixture[str]
) -> None:
    with pytest.raises(SystemExit) as raised:  # argparse's usage errors exit directly
        raise SystemExit(main(["solve", "panda", *args]))
    assert raised.value.code == 2
    captured = capsys.readouterr()
    assert captured.out == ""
    assert captured.err.startswith("optik: error:") and says in captured.err
    assert "Traceback" not in captured.err


# ---------------------------------------------------------------------- optik plan
def _plan(args: list[str], tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> np.ndarray:
    code = main(["plan", *args, "--out", str(tmp_path)])
    out = capsys.readouterr().out
    assert code == 0, out
    with np.load(tmp_path / "plan.npz") as data:
        assert list(data["status"]) == ["ok"] * len(data["q"])
        return np.array(data["q"])


def _segment(p0: np.ndarray, p1: np.ndarray, step: float) -> np.ndarray:
    """The sample points of a straight line, ``step`` apart at most (m), ends included."""
    n = math.ceil(np.linalg.norm(p1 - p0) / step - 1e-9) + 1
    return p0 + np.linspace(0.0, 1.0, n)[:, None] * (p1 - p0)


def test_plan_axis_line_on_the_ur5(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A drilling line pointing straight down (rpy 180 0 0: tool z along -z)."""
    p0, p1 = np.array([0.3, 0.2, 0.3]), np.array([0.3, 0.3, 0.3])
    line_args = ["--line", *(str(v) for v in (*p0, *p1)), "--step", "0.02"]
    Q = _plan(["ur5", *line_args, "--rpy-deg", "180", "0", "0", "--mode", "axis"], tmp_path, capsys)
    points = _segment(p0, p1, 0.02)
    assert len(Q) == len(points)
    for q, p in zip(Q, points, strict=True):
        F = UR5.fk(q)
        assert np.linalg.norm(F[:3, 3] - p) <= 1e-6
        assert _axis_angle(F[:3, 2], np.array([0.0, 0.0, -1.0])) <= 1e-6
    plan = json.loads((tmp_path / "plan.json").read_text())
    assert plan["mode"] == "axis"


def test_plan_freeze_and_weights(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    q = PANDA.mid_limits.copy()
    T = PANDA.fk(q)
    p0 = T[:3, 3]
    p1 = p0 + np.array([0.0, 0.1, 0.0])
    quat = Rotation.from_matrix(T[:3, :3]).as_quat()
    args = [
        "panda",
        "--line",
        *(_num(v) for v in (*p0, *p1)),
        "--step",
        "0.025",
        "--quat-xyzw",
        *(_num(v) for v in quat),
        "--weights",
        *"111110",
        "--freeze",
        "panda_joint3=0.0",
        "--q0",
        *(_num(v) for v in q),
    ]
    Q = _plan(args, tmp_path, capsys)
    assert np.all(Q[:, 2] == 0.0)
    for qk, p in zip(Q, _segment(p0, p1, 0.025), strict=True):
        F = PANDA.fk(qk)
        assert np.linalg.norm(F[:3, 3] - p) <= 1e-6
        assert _axis_angle(F[:3, 2], T[:3, 2]) <= 1e-6


@pytest.mark.parametrize(
    ("args", "says"),
    [
        (["--line", "0.3", "0.2", "0.3", "0.3", "0.3", "0.3", "--mode", "axis"], "orientation"),
        (["--line", *"000111", "--rpy", "0", "0", "0", "--mode", "pose", "--axis", "y"], "--axis"),
        (["--line", *"000111", "--freeze", "nope=1"], "frozen"),
        (["--line", *"000111", "--rpy", "0", "0", "0", "--weights", *"110001"], "weights"),
    ],
)
def test_plan_bad_task_input_exits_2(
    args: list[str], says: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["plan", "ur5", *args, "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("optik: error:") and says in err and "Traceback" not in err
