"""The compiled (numba) machinery: cache entries, borrowed views, the LM stopping rules."""

from __future__ import annotations

import importlib
import pkgutil

import numba as nb
import numpy as np
from numba.core.registry import CPUDispatcher

import optik
from optik import solve_ik_batch
from optik._nrt import borrowed
from optik.model import Robot
from optik.problems import load_problem
from optik.solvers._lm_kernel import (
    QUICK_RATIO,
    QUICK_WINDOW,
    STALL_RATIO,
    STALL_WINDOW,
    lm_attempt,
    lm_solve_restarts,
    workspace,
)
from optik.solvers._seeds import seed_table
from optik.solvers._starts import table_order
from optik.solvers.iterative import DLSSolver
from optik.task import make_task


def _dispatchers() -> dict[int, tuple[str, CPUDispatcher]]:
    found: dict[int, tuple[str, CPUDispatcher]] = {}
    for info in pkgutil.walk_packages(optik.__path__, "optik."):
        module = importlib.import_module(info.name)
        for name, value in vars(module).items():
            if isinstance(value, CPUDispatcher):
                found.setdefault(id(value), (f"{info.name}.{name}", value))
    return found


def test_no_two_kernels_share_a_cache_entry() -> None:
    # numba's disk cache is keyed by the Python function's file, name and first line, not
    # by options such as `parallel`: one function jitted twice would share one entry, and
    # a parallel kernel could silently load its serial twin (or the reverse).
    owners: dict[tuple[str, int, str], str] = {}
    dispatchers = _dispatchers()
    assert len(dispatchers) > 20  # the walk found optik's kernels
    for name, dispatcher in dispatchers.values():
        code = dispatcher.py_func.__code__
        key = (code.co_filename, code.co_firstlineno, dispatcher.py_func.__qualname__)
        assert key not in owners, f"{name} and {owners[key]} compile the same function"
        owners[key] = name


def test_borrowed_view_shares_data_without_an_owner() -> None:
    @nb.njit
    def double_through_view(x: np.ndarray) -> float:
        view = borrowed(x)
        total = 0.0
        for i in range(view.shape[0]):
            view[i] *= 2.0
            total += view[i]
        return total

    x = np.arange(5.0)
    assert double_through_view(x) == 20.0
    assert np.array_equal(x, 2.0 * np.arange(5.0))  # written through to the owner


def _attempt(
    robot: Robot,
    target: np.ndarray,
    q0: np.ndarray,
    window: int,
    ratio: float,
    tol: float,
    pose: bool = True,
) -> tuple[int, bool]:
    q = np.array(q0, dtype=float)
    scratch = workspace(robot.chain.n, robot.dof)
    task = make_task("pose" if pose else "position", tol=tol)
    it, ok, _, _ = lm_attempt(
        robot.chain.kernel_args(), target, task.packed, q, 100, DLSSolver.w_bias, window, ratio,
        scratch,
    )  # fmt: skip
    return it, ok


def test_stall_rule_stops_an_attempt() -> None:
    panda = load_problem("panda").robot
    target = panda.fk(panda.lower + 0.8 * (panda.upper - panda.lower))
    start = panda.mid_limits
    # A cut to 0 is impossible: the attempt stops as soon as the window has passed.
    assert _attempt(panda, target, start, 2, 0.0, 1e-9) == (2, False)
    assert _attempt(panda, target, start, 5, 0.0, 1e-9) == (5, False)
    # Any error counts as a cut when ratio is huge: only convergence or max_iter stops it.
    it, ok = _attempt(panda, target, start, STALL_WINDOW, 1e300, 1e-9)
    assert ok and it > 5
    assert _attempt(panda, target, start, STALL_WINDOW, STALL_RATIO, 1e-9)[1]


def test_no_stall_stop_below_the_floor() -> None:
    panda = load_problem("panda").robot
    q_star = panda.lower + 0.3 * (panda.upper - panda.lower)
    target = panda.fk(q_star)
    # Start 1e-6 rad away: e'e is far below STALL_FLOOR, so even an impossible cut (ratio
    # 0, window 1) does not stop the attempt; it converges to a tolerance of 1e-13.
    start = q_star + 1e-6
    assert np.linalg.norm(panda.fk(start)[:3, 3] - target[:3, 3]) < 1e-5
    it, ok = _attempt(panda, target, start, 1, 0.0, 1e-13)
    assert ok and it >= 1
    # From far away the same rule stops at once.
    assert _attempt(panda, target, panda.mid_limits, 1, 0.0, 1e-13) == (1, False)


def test_first_attempts_use_the_quick_stall_rule() -> None:
    panda = load_problem("panda").robot
    table = seed_table(panda)
    rng = np.random.default_rng(5)
    differs = 0
    for _ in range(40):
        target = panda.fk(rng.uniform(panda.lower, panda.upper))
        task = make_task("pose", tol=1e-6)
        order = table_order(table.features, table.centroids, table.offsets, target, task.features)
        start = table.q[order[0]]
        _, total, ran, ok, _, _ = lm_solve_restarts(
            panda.chain.kernel_args(), target, task.packed, np.empty((0, panda.dof)),
            table.kernel_args(), 100, DLSSolver.w_bias, 0, 0, 0,
        )  # fmt: skip
        quick = _attempt(panda, target, start, QUICK_WINDOW, QUICK_RATIO, 1e-6)
        patient = _attempt(panda, target, start, STALL_WINDOW, STALL_RATIO, 1e-6)
        assert ran == 1 and (total, ok) == quick
        differs += quick != patient
    assert differs > 0  # the two rules do part ways on these targets


def test_gauss_newton_steps_next_to_a_folded_elbow() -> None:
    # The planar 2R with q2 0.0003 rad from pi: sigma_min(J) ~ 1e-4 at the answer. The
    # damping must be able to fall below sigma_min^2; with Marquardt's scale floored at
    # 1e-3 (damping >= 1e-6) this attempt crawled and was still short at 100 iterations.
    planar = load_problem("planar_2r").robot
    q_star = np.array([-2.82293589, 3.14129826])
    target = planar.fk(q_star)
    start = np.clip(q_star + np.array([0.01, -0.01]), planar.lower, planar.upper)
    it, ok = _attempt(planar, target, start, STALL_WINDOW, STALL_RATIO, 1e-9, pose=False)
    assert ok and it <= 40


def test_batch_solves_next_to_a_folded_elbow() -> None:
    # End to end, the same target under the random stream (seed 3860: row 3860 of a batch
    # seeded 0) with which it once failed after 100 restarts.
    planar = load_problem("planar_2r").robot
    target = planar.fk(np.array([-2.82293589, 3.14129826]))[:3, 3]
    result = solve_ik_batch(planar, target[None], mode="position", seed=3860)
    assert result.success[0] and result.position_error[0] <= 1e-6


def test_target_layout_reuses_the_compiled_solver() -> None:
    # The kernels are specialised on layout and writability: a Fortran-ordered, read-only
    # target must reach them as the usual C-ordered array, not compile them again.
    panda = load_problem("panda").robot
    T = panda.fk(panda.mid_limits + 0.1)
    assert optik.solve_ik(panda, T, solver="dls", restarts=1).success
    compiled = len(lm_solve_restarts.signatures)
    odd = np.asfortranarray(T)
    odd.flags.writeable = False
    assert optik.solve_ik(panda, odd, solver="dls", restarts=1).success
    assert len(lm_solve_restarts.signatures) == compiled
