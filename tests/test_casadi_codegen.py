"""The nonlinear program's functions compiled to C: same answers, cached on disk, fallback.

Each test builds its programs on a fresh robot (the program cache is per robot) and with
its own cache directory, so what is compiled, found on disk or refused is known.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from conftest import SEED, assert_close

import optik
from optik.programs.nlp_codegen import cache_dir, find_compiler
from optik.solvers.casadi_nlp import nlp_backend


def _fresh_robot() -> optik.Robot:
    return optik.load_problem("puma560").robot


def test_compiled_solver_gives_the_sx_answers(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("OPTIK_CACHE_DIR", str(tmp_path))
    robot = _fresh_robot()
    rng = np.random.default_rng(SEED)
    for plugin in ("sqpmethod", "ipopt"):
        compiled = nlp_backend(robot, "pose", plugin=plugin)
        plain = nlp_backend(robot, "pose", plugin=plugin, codegen=False)
        assert compiled is not plain
        report = compiled.compile_report
        # Compiled whenever this machine has a C compiler (CI images do).
        assert report.compiled == (find_compiler() is not None), report.detail
        assert not plain.compile_report.compiled
        if report.compiled:
            assert Path(report.detail).parent == cache_dir() and report.seconds > 0.0
        for _ in range(3):
            q_true = rng.uniform(robot.lower, robot.upper)
            q0 = np.clip(q_true + 0.05 * rng.normal(size=6), robot.lower, robot.upper)
            target = robot.fk(q_true)
            a = compiled.solve(target, q0)
            b = plain.solve(target, q0)
            assert a.iterations == b.iterations
            assert_close(a.q, b.q, atol=1e-12, what=f"{plugin} compiled vs SX")


def test_library_is_found_on_disk_by_the_next_build(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    if find_compiler() is None:
        pytest.fail("no C compiler: the codegen path cannot be tested here")
    monkeypatch.setenv("OPTIK_CACHE_DIR", str(tmp_path))
    first = nlp_backend(_fresh_robot(), "position", plugin="sqpmethod").compile_report
    second = nlp_backend(_fresh_robot(), "position", plugin="sqpmethod").compile_report
    assert first.compiled and not first.cached
    assert second.compiled and second.cached and second.detail == first.detail
    assert len(list((tmp_path / "casadi").glob("*.so"))) == 1
    assert not list((tmp_path / "casadi").glob(".*"))  # no temporary file left behind


def test_without_a_compiler_the_sx_solver_is_used(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("OPTIK_CACHE_DIR", str(tmp_path))
    monkeypatch.setenv("CC", "no-such-compiler-optik")
    robot = _fresh_robot()
    program = nlp_backend(robot, "pose", plugin="sqpmethod")
    assert not program.compile_report.compiled
    assert "no C compiler" in program.compile_report.detail
    q_true = robot.mid_limits + 0.2
    result = program.solve(robot.fk(q_true), robot.mid_limits + 0.15)
    assert np.linalg.norm(robot.fk(result.q)[:3, 3] - robot.fk(q_true)[:3, 3]) < 1e-8


def test_a_failing_compiler_falls_back(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("OPTIK_CACHE_DIR", str(tmp_path))
    monkeypatch.setenv("CC", "false")  # exists, always fails
    program = nlp_backend(_fresh_robot(), "pose", plugin="sqpmethod")
    assert not program.compile_report.compiled
    assert "code generation failed" in program.compile_report.detail
    assert not list((tmp_path / "casadi").glob("*"))


def test_solve_ik_casadi_runs_compiled(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("OPTIK_CACHE_DIR", str(tmp_path))
    robot = _fresh_robot()
    target = robot.fk(robot.mid_limits + 0.3)
    result = optik.solve_ik(robot, target, solver="casadi:sqpmethod", warm_start="q0")
    assert result.status == "converged"
    assert len(list((tmp_path / "casadi").glob("*.so"))) == (find_compiler() is not None)


def test_compiled_task_programs_give_the_sx_answers(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """An axis task with weights and narrowed bounds: one library per task shape."""
    monkeypatch.setenv("OPTIK_CACHE_DIR", str(tmp_path))
    robot = _fresh_robot()
    rng = np.random.default_rng(SEED + 1)
    weights = [1.0, 0.5, 2.0, 1.0, 3.0, 0.0]  # the tool's z axis, roll free
    lower, upper = robot.lower + 0.1, robot.upper - 0.1
    for plugin in ("sqpmethod", "ipopt"):
        compiled = nlp_backend(robot, "axis", plugin=plugin)
        plain = nlp_backend(robot, "axis", plugin=plugin, codegen=False)
        assert compiled.gauss_newton and plain.gauss_newton
        assert compiled.compile_report.compiled == (find_compiler() is not None)
        for _ in range(2):
            q_true = rng.uniform(lower, upper)
            q0 = np.clip(q_true + 0.05 * rng.normal(size=6), lower, upper)
            target = robot.fk(q_true)
            a = compiled.solve(target, q0, weights=weights, bounds=(lower, upper))
            b = plain.solve(target, q0, weights=weights, bounds=(lower, upper))
            assert a.iterations == b.iterations
            assert_close(a.q, b.q, atol=1e-10, what=f"{plugin} compiled vs SX")
            axis, goal = robot.fk(a.q)[:3, 2], target[:3, 2]
            angle = np.arctan2(np.linalg.norm(np.cross(axis, goal)), float(axis @ goal))
            assert angle < 1e-6
    if find_compiler() is not None:
        assert len(list((tmp_path / "casadi").glob("*.so"))) == 2
