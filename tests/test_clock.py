import time

import numba

from optik._clock import budget_clock, compile_seconds


def test_compilation_is_counted_and_excluded_from_the_budget_clock() -> None:
    @numba.njit(cache=False)
    def fresh(x: float) -> float:  # a function of this test only: it must compile
        return x * 2.0 + 1.0

    compiled_before, wall_before, budget_before = (
        compile_seconds(),
        time.perf_counter(),
        budget_clock(),
    )
    assert fresh(1.5) == 4.0
    compiled = compile_seconds() - compiled_before
    wall = time.perf_counter() - wall_before
    budget = budget_clock() - budget_before
    assert compiled > 0.0
    assert 0.0 <= budget < wall
    assert abs((wall - budget) - compiled) < 1e-3  # the clock's only difference is the compile

    # A second call compiles nothing: the compile counter stays where it was.
    after = compile_seconds()
    assert fresh(2.0) == 5.0
    assert compile_seconds() == after


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
