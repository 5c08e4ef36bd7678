import time

import numba

from optik._clock import budget_clock, excluded_seconds


def test_compilation_is_counted_and_excluded_from_the_budget_clock() -> None:
    @numba.njit(cache=False)
    def fresh(x: float) -> float:  # a function of this test only: it must compile
        return x * 2.0 + 1.0

    compiled_before, wall_before, budget_before = (
        excluded_seconds(),
        time.perf_counter(),
        budget_clock(),
    )
    assert fresh(1.5) == 4.0
    compiled = excluded_seconds() - compiled_before
    wall = time.perf_counter() - wall_before
    budget = budget_clock() - budget_before
    assert compiled > 0.0
    assert 0.0 <= budget < wall
    assert abs((wall - budget) - compiled) < 1e-3  # the clock's only difference is the compile

    # A second call compiles nothing: the compile counter stays where it was.
    after = excluded_seconds()
    assert fresh(2.0) == 5.0
    assert excluded_seconds() == after


def test_a_timeout_does_not_count_compilation() -> None:
    # A solver whose every attempt "compiles" for 0.6 s (a numba compile event around a
    # sleep): with timeout_s=0.5 all four attempts still run, since compile time is not
    # the caller's; a deadline on the wall clock would stop after the first.
    from numba.core import event

    import optik
    from optik.problems import load_problem
    from optik.solvers import IKSolver, SolverOutput, register_solver, unregister_solver

    class Compiling(IKSolver):
        name = "test:compiling"

        def solve(self, query, q0, max_iter, deadline):  # type: ignore[no-untyped-def]
            with event.trigger_event("numba:compile"):
                time.sleep(0.6)
            return SolverOutput(q0, 1, False, "not converged")

    register_solver("test:compiling", Compiling, lambda: True)
    try:
        panda = load_problem("panda").robot
        T = panda.fk(panda.mid_limits + 0.2)
        optik.solve_ik(panda, T, restarts=0)  # the seed table (not compilation) built first
        res = optik.solve_ik(panda, T, solver="test:compiling", timeout_s=0.5, restarts=3)
        assert res.restarts == 3 and res.status == "max_iter"
        assert res.time_s >= 2.4  # the wall time, compilation included, is still reported
    finally:
        unregister_solver("test:compiling")


def test_compiling_is_true_exactly_while_numba_compiles() -> None:
    import numba as nb
    from numba.core import event

    from optik._clock import compiling

    seen: list[bool] = []

    class Probe(event.Listener):
        def on_start(self, ev: object) -> None:
            seen.append(compiling())  # optik's listener, registered first, has started

        def on_end(self, ev: object) -> None:
            pass

    probe = Probe()
    event.register("numba:compile", probe)
    try:
        assert not compiling()
        nb.njit(lambda x: x * 3 + 1)(2)  # a fresh function: always compiles
    finally:
        event.unregister("numba:compile", probe)
    assert seen and all(seen)
    assert not compiling()


def test_one_time_setup_is_excluded_and_is_not_compiling() -> None:
    from optik._clock import compiling, one_time_setup

    wall_before, budget_before, excluded_before = (
        time.perf_counter(),
        budget_clock(),
        excluded_seconds(),
    )
    with one_time_setup():
        assert not compiling()  # setup is not compilation (the test helpers tell them apart)
        time.sleep(0.2)
    wall = time.perf_counter() - wall_before
    assert excluded_seconds() - excluded_before >= 0.2
    assert budget_clock() - budget_before < wall - 0.19


def test_a_robots_derived_data_is_built_as_one_time_setup() -> None:
    from optik.problems import load_problem

    robot = load_problem("planar_2r").robot

    def slow_build(r: object) -> int:
        time.sleep(0.2)
        return 7

    before = excluded_seconds()
    assert robot.cached(slow_build) == 7
    assert excluded_seconds() - before >= 0.2
    again = excluded_seconds()
    assert robot.cached(slow_build) == 7  # kept: built once
    assert excluded_seconds() - again < 0.01


def test_loading_a_kernel_from_numbas_cache_is_excluded(tmp_path) -> None:  # type: ignore[no-untyped-def]
    # A kernel compiled (and cached) by another process is loaded here: the load is
    # outside numba's compile events, and the budget clock does not count it either.
    import subprocess
    import sys
    import textwrap

    (tmp_path / "loaded_kernel.py").write_text(
        textwrap.dedent(
            """
            import numba

            @numba.njit(cache=True)
            def cube(x):
                return x * x * x
            """
        )
    )
    import os

    env = {**os.environ, "PYTHONPATH": str(tmp_path)}
    env.pop("NUMBA_CACHE_DIR", None)
    subprocess.run(
        [sys.executable, "-c", "from loaded_kernel import cube; cube(2.0)"], env=env, check=True
    )
    sys.path.insert(0, str(tmp_path))
    try:
        from loaded_kernel import cube  # type: ignore[import-not-found]

        wall_before, budget_before = time.perf_counter(), budget_clock()
        assert cube(3.0) == 27.0
        wall = time.perf_counter() - wall_before
        budget = budget_clock() - budget_before
        assert sum(cube.stats.cache_hits.values()) == 1  # loaded, not compiled
        assert budget < 0.5 * wall
    finally:
        sys.path.remove(str(tmp_path))
        sys.modules.pop("loaded_kernel", None)
