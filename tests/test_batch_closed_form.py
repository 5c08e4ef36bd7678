"""``solve_ik_batch`` takes the closed form where the robot has one, as ``solve_ik`` does."""

from __future__ import annotations

import numpy as np
import pytest

import optik
from optik.problems import load_problem

PUMA = load_problem("puma560").robot
UR5 = load_problem("ur5").robot


def _configurations(robot: optik.Robot, n: int, seed: int) -> np.ndarray:
    return np.random.default_rng(seed).uniform(robot.lower, robot.upper, (n, robot.dof))


@pytest.mark.parametrize("robot", [PUMA, UR5], ids=["puma560", "ur5"])
@pytest.mark.parametrize("q0_form", ["none", "shared", "per_row"])
def test_each_row_is_solve_ik_s_branch(robot: optik.Robot, q0_form: str) -> None:
    Q = _configurations(robot, 60, 1)
    T = robot.fk(Q)
    q0 = {
        "none": None,
        "shared": robot.mid_limits + 0.1,
        "per_row": np.clip(Q + 0.3, robot.lower, robot.upper),
    }[q0_form]
    batch = optik.solve_ik_batch(robot, T, q0=q0)
    assert batch.success.all()
    assert np.all(batch.iterations == 0) and np.all(batch.restarts == 0)
    for k in range(len(T)):
        row_q0 = q0[k] if q0_form == "per_row" else q0  # type: ignore[index]
        single = optik.solve_ik(robot, T[k], q0=row_q0)
        assert single.solver == "analytic"
        np.testing.assert_array_equal(batch.q[k], single.q)


def test_a_target_the_search_misses_is_answered() -> None:
    # One attempt of one iteration from the middle of the limits: the search alone
    # converges on almost none of these targets; every one has a branch in the limits.
    Q = _configurations(UR5, 200, 2)
    T = UR5.fk(Q)
    batch = optik.solve_ik_batch(UR5, T, restarts=0, max_iter=1)
    assert batch.success.all()
    assert np.all(batch.position_error <= 1e-9) and np.all(batch.orientation_error <= 1e-9)
    assert np.all(UR5.within_limits(batch.q))


def test_a_tol_tighter_than_the_closed_form_s_is_searched_from_the_branch() -> None:
    Q = _configurations(PUMA, 40, 3)
    T = PUMA.fk(Q)
    batch = optik.solve_ik_batch(PUMA, T, tol=1e-13)
    single = [optik.solve_ik(PUMA, T[k], tol=1e-13) for k in range(len(T))]
    assert batch.success.tolist() == [s.success for s in single]
    assert batch.success.mean() >= 0.9
    ok = batch.success
    assert np.all(batch.position_error[ok] <= 1e-13)
    assert np.all(batch.orientation_error[ok] <= 1e-13)


def test_a_frozen_joint_is_held_exactly_by_the_branch() -> None:
    Q = _configurations(PUMA, 40, 4)
    T = PUMA.fk(Q)
    name = PUMA.joint_names[5]
    for k in range(0, len(T), 10):
        batch = optik.solve_ik_batch(PUMA, T[k : k + 1], frozen={name: float(Q[k, 5])})
        single = optik.solve_ik(PUMA, T[k], frozen={name: float(Q[k, 5])})
        assert batch.success[0] and single.solver == "analytic"
        assert batch.q[0, 5] == Q[k, 5] and batch.iterations[0] == 0
        np.testing.assert_array_equal(batch.q[0], single.q)


def test_graded_weights_take_the_exact_branch() -> None:
    Q = _configurations(UR5, 30, 5)
    T = UR5.fk(Q)
    weights = [1.0, 1.0, 1.0, 0.2, 0.2, 0.2]
    batch = optik.solve_ik_batch(UR5, T, weights=weights, restarts=0, max_iter=1)
    assert batch.success.all() and np.all(batch.iterations == 0)
    np.testing.assert_allclose(UR5.fk(batch.q), T, atol=1e-9)


def test_a_python_closed_form_answers_the_rows_the_search_missed() -> None:
    # The DOBOT's closed form runs in Python: the search runs first (faster there), the
    # closed form only for the targets it missed.
    dobot = load_problem("dobot_magician").robot
    Q = _configurations(dobot, 200, 6)
    points = dobot.fk(Q)[:, :3, 3]
    searched = optik.solve_ik_batch(dobot, points, mode="position", restarts=0, max_iter=1)
    assert searched.success.all()
    assert np.all(searched.position_error <= 1e-9)


def test_targets_without_a_branch_in_the_limits_are_still_searched() -> None:
    # Narrow limits: the branches of the second target lie outside them. The search runs
    # first; not finding an answer, the row is proved outside the limits, as solve_ik
    # proves it. Without the proofs it says max_iter, which claims nothing.
    centre = UR5.mid_limits
    narrow = UR5.with_limits(centre - 0.2, centre + 0.2)
    far = np.clip(centre + 1.0, UR5.lower, UR5.upper)
    T = UR5.fk(np.stack([centre + 0.05, far]))
    batch = optik.solve_ik_batch(narrow, T, restarts=2)
    assert batch.success.tolist() == [True, False]
    assert batch.status.tolist() == ["converged", "outside_limits"]
    assert optik.solve_ik(narrow, T[1]).status == "outside_limits"
    assert batch.iterations[1] > 0
    unproved = optik.solve_ik_batch(narrow, T, restarts=2, proofs=False)
    assert unproved.status.tolist() == ["converged", "max_iter"]
    assert unproved.iterations[1] > 0


def test_the_closed_form_s_slices_on_threads_give_the_rows_of_one_thread() -> None:
    # More than two slices of targets: the closed form runs on worker threads.
    Q = _configurations(UR5, 10_000, 7)
    T = UR5.fk(Q)
    one = optik.solve_ik_batch(UR5, T, threads=1)
    two = optik.solve_ik_batch(UR5, T, threads=2)
    assert one.success.all() and np.all(one.iterations == 0)
    np.testing.assert_array_equal(one.q, two.q)
    np.testing.assert_allclose(UR5.fk(two.q), T, atol=1e-9)


def test_a_branch_a_turn_from_the_margin_s_box_is_turned_into_it() -> None:
    # The UR5's joints span +-2 pi. A branch wrapped nearest q0 can sit in a
    # limit_margin's band next to +-2 pi while the same branch a turn over lies inside the
    # box: it was dropped, and the search answered (150 iterations, farther from q0).
    import itertools

    rng = np.random.default_rng(11)
    margin = 0.05
    lower, upper = UR5.lower + margin, UR5.upper - margin
    turns = np.array(list(itertools.product((-2.0 * np.pi, 0.0, 2.0 * np.pi), repeat=6)))
    for _ in range(8):
        q = rng.uniform(0.5 * UR5.lower, 0.5 * UR5.upper)
        q[5] = rng.choice([-1.0, 1.0]) * (2.0 * np.pi - rng.uniform(0.0, 0.04))  # in the band
        T = UR5.fk(q)
        # Reference: every branch at every turn of every joint, inside the box, nearest q.
        candidates = np.concatenate(
            [b + turns for b in optik.analytic_ik(UR5, T, within_limits=False)]
        )
        inside = np.all((candidates >= lower) & (candidates <= upper), axis=1)
        nearest = np.min(np.linalg.norm(candidates[inside] - q, axis=1))
        single = optik.solve_ik(UR5, T, q0=q, limit_margin=margin)
        assert (single.success, single.solver, single.iterations) == (True, "analytic", 0)
        assert np.linalg.norm(single.q - q) == pytest.approx(nearest, abs=1e-9)
        batch = optik.solve_ik_batch(UR5, T[None], q0=q, limit_margin=margin)
        assert batch.success[0] and batch.iterations[0] == 0
        np.testing.assert_array_equal(batch.q[0], single.q)


def test_a_branch_whose_polish_fails_stays_the_answer() -> None:
    # A tol below rounding: neither the branch nor the search from it meets it (but where
    # rounding gives exact zeros). The row keeps the branch nearest q0, as solve_ik's
    # answer does (the search's last attempt could be another branch, half a turn away).
    Q = _configurations(PUMA, 30, 12)
    T = PUMA.fk(Q)
    q0 = np.clip(Q + 0.01, PUMA.lower, PUMA.upper)
    batch = optik.solve_ik_batch(PUMA, T, q0=q0, tol=1e-18, restarts=1, max_iter=3)
    failed = np.flatnonzero(~batch.success)
    assert len(failed) >= 10
    for k in failed:
        single = optik.solve_ik(PUMA, T[k], q0=q0[k], tol=1e-18, restarts=1, max_iter=3)
        assert not single.success
        np.testing.assert_array_equal(batch.q[k], single.q)
        assert np.max(np.abs(batch.q[k] - Q[k])) < 1e-9  # the source's own branch
