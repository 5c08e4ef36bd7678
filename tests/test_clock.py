import subprocess
import sys
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numba
import numpy as np
import pytest
from conftest import FakeClock

from optik._clock import budget_clock, excluded_seconds


def test_compilation_is_counted_and_excluded_from_the_budget_clock(fake_clock: FakeClock) -> None:
    # Time passes only inside numba's compile events, 5 s at each start (a listener
    # registered after optik's, so inside its window), on a clock no load moves between
    # the readings: the budget clock's only difference from it is the compilation.
    from numba.core import event

    class Slow(event.Listener):
        def on_start(self, ev: object) -> None:
            fake_clock.advance(5.0)

        def on_end(self, ev: object) -> None:
            pass

    @numba.njit(cache=False)
    def fresh(x: float) -> float:  # a function of this test only: it must compile
        return x * 2.0 + 1.0

    compiled_before, wall_before, budget_before = (
        excluded_seconds(),
        fake_clock.now,
        budget_clock(),
    )
    slow = Slow()
    event.register("numba:compile", slow)
    try:
        assert fresh(1.5) == 4.0
    finally:
        event.unregister("numba:compile", slow)
    compiled = excluded_seconds() - compiled_before
    wall = fake_clock.now - wall_before
    budget = budget_clock() - budget_before
    assert compiled >= 5.0  # it compiled, and that was counted
    assert compiled == pytest.approx(wall, abs=1e-9)  # every second of it
    assert budget == pytest.approx(0.0, abs=1e-9)

    # A second call compiles nothing: the compile counter stays where it was.
    after = excluded_seconds()
    assert fresh(2.0) == 5.0
    assert excluded_seconds() == after


def test_a_timeout_does_not_count_compilation(fake_clock: FakeClock) -> None:
    # A solver whose every attempt "compiles" for 0.6 s (a numba compile event around a
    # sleep, and 0.6 s of the budget's clock, which moves at nothing else): with
    # timeout_s=0.5 all four attempts still run, since compile time is not the caller's;
    # a deadline on the wall clock would stop after the first.
    from numba.core import event

    import optik
    from optik.problems import load_problem
    from optik.solvers import IKSolver, SolverOutput, register_solver, unregister_solver

    class Compiling(IKSolver):
        name = "test:compiling"

        def solve(self, query, q0, max_iter, deadline):  # type: ignore[no-untyped-def]
            with event.trigger_event("numba:compile"):
                fake_clock.advance(0.6)
                time.sleep(0.6)  # for the wall time the result reports
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


def test_one_time_setup_is_excluded_and_is_not_compiling(fake_clock: FakeClock) -> None:
    from optik._clock import compiling, one_time_setup

    wall_before, budget_before, excluded_before = (
        fake_clock.now,
        budget_clock(),
        excluded_seconds(),
    )
    with one_time_setup():
        assert not compiling()  # setup is not compilation (the test helpers tell them apart)
        fake_clock.advance(0.2)
    assert fake_clock.now - wall_before == pytest.approx(0.2, abs=1e-9)
    assert excluded_seconds() - excluded_before == pytest.approx(0.2, abs=1e-9)
    assert budget_clock() - budget_before == pytest.approx(0.0, abs=1e-9)


def test_a_robots_derived_data_is_built_as_one_time_setup(fake_clock: FakeClock) -> None:
    from optik.problems import load_problem

    robot = load_problem("planar_2r").robot
    builds: list[object] = []

    def slow_build(r: object) -> int:
        builds.append(r)
        fake_clock.advance(0.2)
        return 7

    before = excluded_seconds()
    assert robot.cached(slow_build) == 7
    assert excluded_seconds() - before == pytest.approx(0.2, abs=1e-9)
    again = excluded_seconds()
    assert robot.cached(slow_build) == 7  # kept: built once
    assert len(builds) == 1 and excluded_seconds() == again


def test_loading_a_kernel_from_numbas_cache_is_excluded(
    tmp_path: Path, fake_clock: FakeClock, monkeypatch: pytest.MonkeyPatch
) -> None:
    # A kernel compiled (and cached) by another process is loaded here: the load is
    # outside numba's compile events, and the budget clock does not count it either.
    # Loading "takes" 1 s of the test's clock (wrapped around numba's own loading), so
    # that no load on the machine can blur the measure.
    import subprocess
    import sys
    import textwrap

    from numba.core import caching

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

    # The same cache as this process's (NUMBA_CACHE_DIR too, when it is set).
    env = {**os.environ, "PYTHONPATH": str(tmp_path)}
    subprocess.run(
        [sys.executable, "-c", "from loaded_kernel import cube; cube(2.0)"], env=env, check=True
    )
    load = caching.Cache._load_overload

    def slow_load(self: Any, *args: Any) -> Any:
        loaded = load(self, *args)
        fake_clock.advance(1.0)
        return loaded

    monkeypatch.setattr(caching.Cache, "_load_overload", slow_load)
    sys.path.insert(0, str(tmp_path))
    try:
        from loaded_kernel import cube  # type: ignore[import-not-found]

        wall_before, budget_before = fake_clock.now, budget_clock()
        assert cube(3.0) == 27.0
        wall = fake_clock.now - wall_before
        budget = budget_clock() - budget_before
        assert sum(cube.stats.cache_hits.values()) == 1  # loaded, not compiled
        assert wall >= 1.0  # the load took its second
        assert budget == pytest.approx(0.0, abs=1e-9)  # and none of it was charged
    finally:
        sys.path.remove(str(tmp_path))
        sys.modules.pop("loaded_kernel", None)


def test_collecting_answers_stops_at_the_deadline(fake_clock: FakeClock) -> None:
    # solve_ik_all with a solver whose every attempt answers (a closed-form branch, a
    # different one each time) and takes 0.15 s of the budget's clock: with timeout_s=0.2
    # the second answer ends past the deadline, and no run starts after it. (Without the
    # check between runs each later run made its one admitted attempt: 8 answers.)
    import optik
    from optik.problems import load_problem
    from optik.solvers import IKSolver, SolverOutput, register_solver, unregister_solver

    puma = load_problem("puma560").robot
    T = puma.fk(puma.mid_limits + 0.2)
    branches = optik.analytic_ik(puma, T)
    calls: list[int] = []

    class Answering(IKSolver):
        name = "test:answering"

        def solve(self, query, q0, max_iter, deadline):  # type: ignore[no-untyped-def]
            fake_clock.advance(0.15)
            calls.append(1)
            return SolverOutput(branches[len(calls) % len(branches)], 1, True, "converged")

    register_solver("test:answering", Answering, lambda: True)
    try:
        found = optik.solve_ik_all(
            puma, T, solver="test:answering", k=8, min_separation=0.0, restarts=20,
            timeout_s=0.2,
        )  # fmt: skip
    finally:
        unregister_solver("test:answering")
    assert len(branches) >= 4
    assert len(found) == 2 and len(calls) == 2


# A listener registered before optik's raises once in an end event: numba skips the
# listeners after it, so optik's timer never hears that compilation end. The budget clock
# stood still from then on, and a solve_ik with timeout_s ran its restarts forever.
RAISING_LISTENER = """
import numpy as np
from numba.core import event

class RaisesOnce(event.Listener):
    raised = False

    def on_start(self, ev):
        pass

    def on_end(self, ev):
        if not self.raised:
            self.raised = True
            raise RuntimeError("a listener that fails")

event.register("numba:compile", RaisesOnce())
import optik

try:
    with event.trigger_event("numba:compile"):
        pass
except RuntimeError:
    pass
panda = optik.load_problem("panda").robot
centre = panda.mid_limits + 0.2
boxed = panda.with_limits(centre - 0.3, centre + 0.3)
T = boxed.fk(centre)
c, s = np.cos(1.2), np.sin(1.2)
T[:3, :3] = T[:3, :3] @ np.array([[1.0, 0, 0], [0, c, -s], [0, s, c]])
print(optik.solve_ik(boxed, T, timeout_s=0.2).status)
"""


def test_a_listener_that_raises_cannot_stop_the_budget_clock_for_good() -> None:
    # The target is out of the boxed Panda's reach by its orientation, with no proof: the
    # restarts run to the deadline (seconds at most, with kernels to load or compile).
    try:
        done = subprocess.run(
            [sys.executable, "-c", RAISING_LISTENER],
            capture_output=True,
            text=True,
            timeout=600,
        )
    except subprocess.TimeoutExpired:
        pytest.fail("solve_ik(timeout_s=0.2) still ran after 600 s: the budget clock stopped")
    assert done.returncode == 0, done.stderr
    assert done.stdout.split() == ["timeout"]


def _in_thread(action: Callable[[], object]) -> object:
    out: list[object] = []
    worker = threading.Thread(target=lambda: out.append(action()))
    worker.start()
    worker.join()
    return out[0]


def test_each_thread_leaves_out_its_own_one_time_work_alone(fake_clock: FakeClock) -> None:
    from optik._clock import _OneTimeTimer

    timer = _OneTimeTimer()
    timer.leave(True)  # an end without its start: ignored
    assert timer.seconds() == 0.0 and timer.idle()

    # Another thread's work does not stop this thread's clock; its own clock leaves it out.
    started, release = threading.Event(), threading.Event()
    seen: list[float] = []

    def compile_in_thread() -> None:
        timer.enter(True)
        started.set()
        release.wait()
        timer.leave(True)
        seen.append(timer.seconds())

    worker = threading.Thread(target=compile_in_thread)
    worker.start()
    started.wait()
    fake_clock.advance(2.0)
    assert timer.seconds() == 0.0 and timer.compiling()
    release.set()
    worker.join()
    assert seen == [pytest.approx(2.0)] and timer.seconds() == 0.0 and timer.idle()

    # A start left open in this thread is not counted, by this thread or any other ...
    timer.enter(True)
    fake_clock.advance(3.0)
    assert timer.seconds() == 0.0 and _in_thread(timer.seconds) == 0.0
    timer.leave(True)  # ... until it ends: then it is counted whole
    assert timer.seconds() == pytest.approx(3.0) and timer.idle()

    # A thread that ended inside its work leaves nothing open.
    _in_thread(lambda: timer.enter(True))
    assert timer.idle() and not timer.compiling()


def test_another_threads_setup_does_not_hold_off_a_deadline() -> None:
    # A second caller building a robot's derived data (here 5 s of "setup") used to stop
    # every thread's budget clock: a warm solve with timeout_s=0.3 then ran until the
    # other thread's setup ended.
    import optik
    from optik._clock import one_time_setup

    panda = optik.load_problem("panda").robot
    centre, radius = panda.reach_sphere
    far = panda.fk(panda.mid_limits)
    far[:3, 3] = centre + np.array([0.97 * radius, 0.0, 0.0])  # in its sphere, out of reach
    assert optik.solve_ik(panda, far, timeout_s=0.1).status == "timeout"  # warm

    started = threading.Event()

    def setup() -> None:
        with one_time_setup():
            started.set()
            time.sleep(5.0)

    other = threading.Thread(target=setup)
    other.start()
    started.wait()
    try:
        result = optik.solve_ik(panda, far, timeout_s=0.3)
    finally:
        other.join()
    assert result.status == "timeout"
    assert result.time_s < 4.0  # 0.3 s and the machine's load; not the other thread's 5 s
