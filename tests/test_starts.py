"""The one start policy: the same starts for every solver, sliced or not, timed or not."""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import FakeClock

import optik
from optik.problems import load_problem
from optik.solvers._seeds import seed_table, start_sequence
from optik.solvers._starts import (
    TABLE_FIRST,
    nearest_entry,
    nearest_table,
    start_into,
    table_order,
    uniform_draw,
)


def test_uniform_draws_are_in_unit_interval_and_uncorrelated() -> None:
    draws = np.array([uniform_draw(7, k, i) for k in range(2000) for i in range(3)])
    assert draws.min() >= 0.0 and draws.max() < 1.0
    assert abs(draws.mean() - 0.5) < 0.02
    assert abs(draws.var() - 1.0 / 12.0) < 0.005
    a = draws.reshape(-1, 3)
    assert abs(np.corrcoef(a[:, 0], a[:, 1])[0, 1]) < 0.08
    assert uniform_draw(7, 3, 1) != uniform_draw(8, 3, 1)  # the seed matters


def test_sequence_order_given_then_table_then_alternating_draws() -> None:
    panda = load_problem("panda").robot
    target = panda.fk(panda.mid_limits + 0.3)
    given = np.stack([panda.mid_limits, panda.mid_limits + 0.1])
    seq = start_sequence(panda, target, "pose", given, seed=3)
    table = seed_table(panda)
    order = table_order(table.features, table.centroids, table.offsets, target, np.ones(12))
    assert np.array_equal(seq.start(0), given[0]) and np.array_equal(seq.start(1), given[1])
    for j in range(TABLE_FIRST):
        assert np.array_equal(seq.start(2 + j), table.q[order[j]])
    draw = seq.start(2 + TABLE_FIRST + 1)  # odd turns after the first table starts draw
    assert not any(np.array_equal(draw, row) for row in table.q)
    assert np.all(draw >= panda.lower) and np.all(draw <= panda.upper)
    assert np.array_equal(seq.start(2 + TABLE_FIRST + 2), table.q[order[TABLE_FIRST + 1]])
    # Start k is a pure function: asking again, or out of order, gives the same vector.
    assert np.array_equal(seq.start(2 + TABLE_FIRST + 1), draw)


def test_continuous_joints_draw_from_minus_pi_to_pi() -> None:
    lower = np.array([-np.inf, -1.0])
    upper = np.array([np.inf, 1.0])
    out = np.empty(2)
    values = []
    for k in range(500):
        empty = (np.empty(0, np.int64), np.empty(0), np.empty(0, np.int64))
        assert start_into(k, np.empty((0, 2)), empty, np.empty((0, 2)), lower, upper, 1, out) == 2
        values.append(out.copy())
    V = np.array(values)
    assert np.all(np.isfinite(V)) and V[:, 0].min() >= -math.pi and V[:, 0].max() <= math.pi
    assert V[:, 0].max() - V[:, 0].min() > 5.0  # spread over the whole circle


@pytest.mark.parametrize("solver", ["dls", "pinv"])
def test_same_answer_with_and_without_timeout(solver: str) -> None:
    # A hard target (the 'far' end of the Panda's range) that needs several restarts.
    panda = load_problem("panda").robot
    rng = np.random.default_rng(11)
    for _ in range(6):
        target = panda.fk(rng.uniform(panda.lower, panda.upper))
        plain = optik.solve_ik(panda, target, solver=solver, restarts=30, seed=5)
        timed = optik.solve_ik(panda, target, solver=solver, restarts=30, seed=5, timeout_s=60.0)
        assert np.array_equal(plain.q, timed.q)
        assert (plain.iterations, plain.restarts, plain.status) == (
            timed.iterations,
            timed.restarts,
            timed.status,
        )


def test_dls_restarts_are_used_and_counted() -> None:
    # An unreachable pose within the reach sphere: every attempt fails; all are run.
    panda = load_problem("panda").robot
    target = panda.fk(panda.mid_limits)
    target[:3, 3] = [0.0, 0.0, 1.33]  # inside the reach sphere, beyond the arm
    res = optik.solve_ik(panda, target, solver="dls", restarts=300, seed=0)
    assert not res.success and res.status == "max_iter" and res.restarts == 300


def test_timeout_inf_means_no_time_limit_with_a_finite_budget() -> None:
    panda = load_problem("panda").robot
    target = panda.fk(panda.mid_limits)
    target[:3, 3] = [0.0, 0.0, 1.33]
    res = optik.solve_ik(panda, target, solver="dls", timeout_s=math.inf, seed=0)
    assert res.status == "max_iter" and res.restarts == optik.ik.DEFAULT_RESTARTS


def test_timeout_stops_an_unlimited_run(fake_clock: FakeClock) -> None:
    panda = load_problem("panda").robot
    target = panda.fk(panda.mid_limits)
    target[:3, 3] = [0.0, 0.0, 1.33]
    # Each reading of the budget's clock moves it 1 ms, whatever the machine's load: the
    # 0.2 s deadline passes after 200 checks (slices of up to 16 attempts between them),
    # not after however many attempts a loaded machine manages in 0.2 s.
    optik.solve_ik(panda, target, solver="dls", restarts=1)  # compile outside the timing
    fake_clock.checks.clear()
    fake_clock.tick = 0.001
    res = optik.solve_ik(panda, target, solver="dls", timeout_s=0.2, seed=0)
    assert res.status == "timeout" and res.restarts > optik.ik.DEFAULT_RESTARTS
    deadline = fake_clock.checks[0] + 0.2  # the first check sets the deadline
    assert sum(t > deadline for t in fake_clock.checks) == 1  # it stops at the first check


def test_lazy_ranking_equals_the_stable_sort_in_any_order_of_asking() -> None:
    panda = load_problem("panda").robot
    table = seed_table(panda)
    rng = np.random.default_rng(11)
    for trial in range(20):
        target = panda.fk(rng.uniform(panda.lower, panda.upper))
        mask = np.ones(12) if trial % 2 else np.r_[np.ones(3), np.zeros(9)]
        order = table_order(table.features, table.centroids, table.offsets, target, mask)
        nearest = nearest_table(table.features, table.centroids, table.offsets, target, mask)
        asked = rng.permutation(order.shape[0] + 3)  # out of order, and past the end
        for entry in asked:
            expected = order[entry] if entry < order.shape[0] else -1
            assert nearest_entry(nearest, int(entry)) == expected


def test_lazy_ranking_keeps_ties_in_table_order() -> None:
    index = np.array([10, 11, 12, 13], dtype=np.int64)
    left = np.array([0.5, 0.25, 0.5, 0.25])
    nearest = (index, left, np.full(4, -1, dtype=np.int64))
    assert [nearest_entry(nearest, e) for e in range(5)] == [11, 13, 10, 12, -1]
