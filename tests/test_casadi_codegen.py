"""The nonlinear program's functions compiled to C: same answers, cached on disk, fallback.

Each test builds its programs on a fresh robot (the program cache is per robot) and with
its own cache directory, so what is compiled, found on disk or refused is known.
"""

from __future__ import annotations

import re
import threading
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

import casadi
import numpy as np
import pytest
from conftest import SEED, FakeClock, assert_close

import optik
from optik.programs.nlp_codegen import INFO_SYMBOL, cache_dir, find_compiler, instrument
from optik.solvers import casadi_nlp
from optik.solvers.casadi_nlp import nlp_backend
from optik.spatial import rotation_angle


def _fresh_robot() -> optik.Robot:
    return optik.load_problem("puma560").robot


def _compiling_into(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Libraries compiled into ``tmp_path`` (a C compiler is required: CI images have one)."""
    if find_compiler() is None:
        pytest.fail("no C compiler: the codegen path cannot be tested here")
    monkeypatch.setenv("OPTIK_CACHE_DIR", str(tmp_path))


def _case(
    robot: optik.Robot, rng: np.random.Generator, spread: float
) -> tuple[np.ndarray, np.ndarray]:
    """A reachable target and a start about ``spread`` rad from its configuration."""
    q_true = rng.uniform(robot.lower, robot.upper)
    q0 = np.clip(q_true + spread * rng.normal(size=robot.dof), robot.lower, robot.upper)
    return robot.fk(q_true), q0


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
            target, q0 = _case(robot, rng, 0.05)
            a = compiled.solve(target, q0)
            b = plain.solve(target, q0)
            assert a.iterations == b.iterations
            assert_close(a.q, b.q, atol=1e-12, what=f"{plugin} compiled vs SX")


def test_library_is_found_on_disk_by_the_next_build(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    _compiling_into(tmp_path, monkeypatch)
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


def test_a_compile_that_overruns_is_stopped_with_the_processes_it_started(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    # The timeout stopped the driver (cc) alone: its cc1 compiled on as an orphan.
    import subprocess
    import time

    from optik.programs import nlp_codegen

    pid_file = tmp_path / "child.pid"
    compiler = tmp_path / "slow-cc"
    compiler.write_text(f"#!/bin/sh\nsleep 60 &\necho $! > {pid_file}\nwait\n")
    compiler.chmod(0o755)
    monkeypatch.setattr(nlp_codegen, "COMPILE_TIMEOUT_S", 1.0)
    source = tmp_path / "x.c"
    source.write_text("int x;\n")
    target = tmp_path / "lib" / "x.so"
    with pytest.raises(subprocess.TimeoutExpired):
        nlp_codegen._compile(source, target, str(compiler), ())
    child = Path(f"/proc/{int(pid_file.read_text())}/stat")

    def running() -> bool:  # a zombie waits for a reaper; it runs no more
        try:
            return child.read_text().rsplit(")", 1)[1].split()[0] != "Z"
        except OSError:
            return False

    deadline = time.monotonic() + 5.0
    while running():  # SIGKILL is delivered at once, the state follows
        assert time.monotonic() < deadline, "the compiler's child still runs"
        time.sleep(0.05)
    assert not list((tmp_path / "lib").glob("*"))  # no temporary library left


def test_a_program_too_large_to_compile_runs_on_the_sx_functions(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    # A 200-joint chain's C code took its compiler past 10 minutes on the first call.
    from optik.programs import nlp_codegen

    monkeypatch.setenv("OPTIK_CACHE_DIR", str(tmp_path))
    monkeypatch.setattr(nlp_codegen, "MAX_CODE_BYTES", 10_000)  # the Puma's is ~0.1 MB
    program = nlp_backend(_fresh_robot(), "pose", plugin="sqpmethod")
    assert not program.compile_report.compiled
    assert re.search(
        r"C code \(0\.\d MB\) is larger than optik compiles", program.compile_report.detail
    )
    assert not list((tmp_path / "casadi").glob("*.so"))
    robot = _fresh_robot()
    q_true = robot.mid_limits + 0.2
    result = program.solve(robot.fk(q_true), robot.mid_limits + 0.15)
    assert np.linalg.norm(robot.fk(result.q)[:3, 3] - robot.fk(q_true)[:3, 3]) < 1e-8


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
    if find_compiler() is not None:  # a library per plugin, and Ipopt's monitor
        assert len(list((tmp_path / "casadi").glob("ik_*.so"))) == 2
        assert len(list((tmp_path / "casadi").glob("optik_monitor_*.so"))) == 1


# ------------------------------------------------------------------ the whole SQP solver in C
_LOOP = """  while (1) {
    du_inf = casadi_norm_inf(7, d->gLag);
    if (iter_count >= 0 && pr_inf < 1e-10 && du_inf < 1e-10) break;
    if (iter_count >= 8) break;
    iter_count++;
  }
"""


def test_instrument_keeps_the_loops_count_and_test() -> None:
    code = instrument(_LOOP)
    assert code is not None
    lines = [line.strip() for line in code.splitlines()]
    at = lines.index("optik_iterations = iter_count;")
    assert (
        lines[at + 1] == "optik_converged = (iter_count >= 0 && pr_inf < 1e-10 && du_inf < 1e-10);"
    )
    assert lines[at + 2] == "if (optik_converged) break;"
    assert lines[at + 3] == "if (iter_count >= 8) break;"  # the rest of the loop untouched
    assert f"long long {INFO_SYMBOL}(void)" in code
    # Not exactly one convergence test: not instrumented (the solver is not compiled whole).
    assert instrument(_LOOP.replace("pr_inf < 1e-10 && ", "")) is None
    assert instrument(_LOOP + _LOOP) is None


_POOL = """int casadi_f4_checkout(void) {
  return casadi_f4_unused_stack[casadi_f4_unused_stack_counter--];
}

void casadi_f4_release(int mem) {
  casadi_f4_unused_stack[++casadi_f4_unused_stack_counter] = mem;
}
"""


def test_instrument_takes_and_gives_back_memory_under_a_lock() -> None:
    """The generated pools' checkout and release run under one mutex per function."""
    code = instrument(_POOL + _LOOP)
    assert code is not None
    assert code.count("static pthread_mutex_t optik_pool_lock_casadi_f4 = ") == 1
    for definition, inner in (
        ("int casadi_f4_checkout(void) {", "got = casadi_f4_checkout_unlocked();"),
        ("void casadi_f4_release(int mem) {", "casadi_f4_release_unlocked(mem);"),
    ):
        body = code.split(definition, 1)[1].split("}", 1)[0].split("\n")
        lines = [line.strip() for line in body if line.strip()]
        at = lines.index(inner)
        assert lines[at - 1] == "pthread_mutex_lock(&optik_pool_lock_casadi_f4);"
        assert lines[at + 1] == "pthread_mutex_unlock(&optik_pool_lock_casadi_f4);"
    # The original bodies follow under the unlocked names, untouched.
    assert "static int casadi_f4_checkout_unlocked(void) {\n  return casadi_f4_unused" in code


def test_every_memory_pool_the_sqp_loop_takes_is_locked() -> None:
    """In the real generated solver, every checkout the loop calls is a locked one.

    The SQP loop checks out its QP solver's memory on every iteration: unlocked, two
    threads took the same memory and the process crashed.
    """
    robot = _fresh_robot()
    backend = nlp_backend(robot, "pose", plugin="sqpmethod", codegen=False)
    generator = casadi.CodeGenerator("locked.c")
    generator.add(backend.solver)
    code = instrument(generator.dump())
    assert code is not None
    called = set(re.findall(r"= (casadi_f\d+)_checkout\(\);", code))
    assert called  # the loop takes its QP solver's memory
    for name in called:
        assert f"pthread_mutex_lock(&optik_pool_lock_{name});" in code


def test_whole_compiled_sqpmethod_reports_what_nlpsol_reports(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Iterations, the claim and the status of the compiled loop equal ``stats()``'s."""
    _compiling_into(tmp_path, monkeypatch)
    robot = _fresh_robot()
    rng = np.random.default_rng(SEED + 2)
    statuses = set()
    for max_iter in (2, 8):
        compiled = nlp_backend(robot, "pose", plugin="sqpmethod", max_iter=max_iter)
        plain = nlp_backend(robot, "pose", plugin="sqpmethod", max_iter=max_iter, codegen=False)
        assert compiled.compiled is not None and plain.compiled is None
        assert compiled.compile_report.compiled
        for _ in range(6):
            target, q0 = _case(robot, rng, 0.3)
            a = compiled.solve(target, q0)
            b = plain.solve(target, q0)
            assert (a.iterations, a.success, a.status) == (b.iterations, b.success, b.status)
            assert_close(a.q, b.q, atol=1e-12, what="compiled whole vs nlpsol")
            statuses.add(a.status)
    assert {"Solve_Succeeded", "Maximum_Iterations_Exceeded"} <= statuses


def test_whole_compiled_solver_from_threads(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Solves from four threads give the answers (and counts) of the same solves in one."""
    monkeypatch.setenv("OPTIK_CACHE_DIR", str(tmp_path))
    robot = _fresh_robot()
    backend = nlp_backend(robot, "pose", plugin="sqpmethod")
    rng = np.random.default_rng(SEED + 4)
    cases = [_case(robot, rng, 0.2) for _ in range(24)]
    expected = [backend.solve(target, q0) for target, q0 in cases]
    with ThreadPoolExecutor(4) as pool:
        got = list(pool.map(lambda case: backend.solve(*case), cases * 4))
    for a, b in zip(got, expected * 4, strict=True):
        assert (a.iterations, a.success, a.status) == (b.iterations, b.success, b.status)
        assert np.array_equal(a.q, b.q)


def test_slot_pool_makes_at_most_its_limit_and_waits() -> None:
    made: list[object] = []

    def make() -> object:
        made.append(object())
        return made[-1]

    pool = casadi_nlp._SlotPool(make, 2)  # type: ignore[arg-type]
    first, second = pool.take(), pool.take()
    got: list[object] = []
    waiter = threading.Thread(target=lambda: got.append(pool.take()))
    waiter.start()
    waiter.join(0.3)
    assert waiter.is_alive() and not got and len(made) == 2  # the third caller waits
    pool.give(first)
    waiter.join(10.0)
    assert got == [first] and len(made) == 2  # and gets the slot given back
    pool.give(second)
    pool.give(got[0])
    assert pool.take() in (first, second)


# ------------------------------------------------------------------ Ipopt's compiled monitor
def test_monitor_counts_ipopts_iterations_and_stops_at_the_tolerance(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Never stopping, the monitor counts ``stats()["iter_count"]`` and changes nothing;
    armed with the task's threshold, Ipopt stops within the task's tolerances, sooner."""
    _compiling_into(tmp_path, monkeypatch)
    robot = _fresh_robot()
    task = optik.task.make_task("pose", tol=1e-6)
    monitored = nlp_backend(robot, task, plugin="ipopt", max_iter=30)
    plain = nlp_backend(robot, task, plugin="ipopt", max_iter=30, codegen=False)
    assert monitored.monitor is not None and plain.monitor is None
    stop = casadi_nlp.stop_objective(task)
    rng = np.random.default_rng(SEED + 5)
    saved = 0
    for _ in range(8):
        target, q0 = _case(robot, rng, 0.2)
        params = monitored.program.parameter_vector(target, weights=task)
        counted = monitored.solve_parameters(params, q0)
        assert monitored.monitor.last_solve() == (counted.iterations, False)
        reference = plain.solve_parameters(params, q0)
        assert (counted.iterations, counted.status) == (reference.iterations, reference.status)
        assert np.array_equal(counted.q, reference.q)
        stopped = monitored.solve_parameters(params, q0, stop=stop)
        if not reference.success:
            continue
        assert stopped.success and stopped.status == casadi_nlp.STOP_STATUS
        assert stopped.iterations <= reference.iterations
        saved += reference.iterations - stopped.iterations
        T = robot.fk(stopped.q)
        limit = np.sqrt(casadi_nlp.STOP_FRACTION) * 1e-6
        assert np.linalg.norm(T[:3, 3] - target[:3, 3]) <= limit
        assert rotation_angle(target[:3, :3].T @ T[:3, :3]) <= limit
    assert saved > 0


@pytest.mark.parametrize("solver", ["casadi:sqpmethod", "casadi:ipopt"])
def test_compiled_solvers_take_every_task_shape(solver: str) -> None:
    """solve_ik on the compiled solvers (the whole SQP, Ipopt with its monitor), verified
    from FK here, for each program shape and weights; the library cache is the default."""
    robot = optik.load_problem("panda").robot  # fresh: its backends are built here
    rng = np.random.default_rng(SEED + 6)
    tasks = [
        {"mode": "pose"},
        {"mode": "position"},
        {"mode": "orientation"},
        {"mode": "axis", "axis": "x"},
        {"weights": [2.0, 1.0, 0.0, 1.0, 3.0, 0.2]},
    ]
    for kw in tasks:
        for _ in range(3):
            q_true = rng.uniform(robot.lower, robot.upper)
            target = robot.fk(q_true)
            result = optik.solve_ik(robot, target, solver=solver, tol=1e-6, **kw)
            assert result.success, (kw, result.status, result.message)
            spec = optik.task.make_task(**kw)
            T = robot.fk(result.q)
            w = spec.weights
            d = target[:3, :3].T @ (T[:3, 3] - target[:3, 3])
            assert np.linalg.norm(d[w[:3] > 0.0]) <= 1e-6
            if np.all(w[3:] > 0.0):
                assert rotation_angle(target[:3, :3].T @ T[:3, :3]) <= 1e-6
            elif np.any(w[3:] > 0.0):
                k = int(np.flatnonzero(w[3:] == 0.0)[0])
                a, b = T[:3, k], target[:3, k]
                assert np.arctan2(np.linalg.norm(np.cross(a, b)), a @ b) <= 1e-6
            assert robot.within_limits(result.q, tol=0.0)
    backend = casadi_nlp.nlp_backend(robot, "pose", plugin=solver.split(":")[1], max_iter=8)
    assert backend.compile_report.compiled == (find_compiler() is not None)


def test_building_the_solver_is_not_charged_to_the_timeout(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, fake_clock: FakeClock
) -> None:
    """A first call compiles its solver (a second or more), yet meets a 0.2 s timeout."""
    _compiling_into(tmp_path, monkeypatch)
    # Each build "takes" 10 s of the budget's clock, which moves at nothing else: the
    # solve itself is not timed (how long it takes on a loaded machine is not the point).
    build = casadi_nlp._new_backend
    builds: list[str] = []

    def slow_build(*args: Any, **kwargs: Any) -> Any:
        builds.append(args[1])
        backend = build(*args, **kwargs)
        fake_clock.advance(10.0)
        return backend

    monkeypatch.setattr(casadi_nlp, "_new_backend", slow_build)
    robot = _fresh_robot()
    target = robot.fk(robot.mid_limits + 0.3)
    for solver in ("casadi:sqpmethod", "casadi:ipopt"):
        result = optik.solve_ik(robot, target, solver=solver, timeout_s=0.2, warm_start="q0")
        assert result.status == "converged", (solver, result.message)
    assert builds == ["sqpmethod", "ipopt"]  # each built in its first call
    assert len(list((tmp_path / "casadi").glob("ik_*.so"))) == 2  # both compiled here
