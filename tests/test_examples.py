"""Every example runs, and prints what its docstring promises."""

from __future__ import annotations

import importlib.util
from pathlib import Path
from types import ModuleType

import pytest

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"


def _load(name: str) -> ModuleType:
    spec = importlib.util.spec_from_file_location(name, EXAMPLES / f"{name}.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_every_example_is_covered() -> None:
    names = sorted(p.stem for p in EXAMPLES.glob("[0-9]*.py"))
    assert names == sorted(CASES), "add the new example to this test"


def _planar(tmp_path: Path) -> None:
    out = _load("01_planar_2r").main(tmp_path)
    assert out["error"] < 0.01 and out["precise_error"] < 1e-9
    assert (tmp_path / "planar_2r_trajectory.png").stat().st_size > 10_000


def _spherical(tmp_path: Path) -> None:
    out = _load("02_spherical_arm_branches").main()
    assert out == {"branches": 4, "inside": 1, "pose_branches": 1}


def _dobot(tmp_path: Path) -> None:
    counts = _load("03_dobot_pinv_vs_transpose").main()
    assert set(counts) == {"part1", "part2", "part3"}
    assert all(c["pinv"] <= c["transpose"] for c in counts.values())


def _puma(tmp_path: Path) -> None:
    out = _load("04_puma_branches_qp").main()
    assert out["branches"] == 8 and out["inside"] >= 1 and out["refined"] >= out["inside"]


def _path(tmp_path: Path) -> None:
    out = _load("05_limit_aware_path").main(tmp_path)
    assert out["plan_step"] <= 0.2 < out["greedy_step"]
    assert (tmp_path / "puma_line_plan.csv").is_file()


CASES = {
    "01_planar_2r": _planar,
    "02_spherical_arm_branches": _spherical,
    "03_dobot_pinv_vs_transpose": _dobot,
    "04_puma_branches_qp": _puma,
    "05_limit_aware_path": _path,
}


@pytest.mark.parametrize("name", sorted(CASES))
def test_example_runs(name: str, tmp_path: Path) -> None:
    CASES[name](tmp_path)
