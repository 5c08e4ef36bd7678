"""solve_ik / solve_ik_batch: verified success rates, statuses, warm starts, bad input."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
from conftest import FakeClock

import optik
from optik.compare import planar_2r_example
from optik.errors import (
    InvalidRotationError,
    JointLimitError,
    NonFiniteError,
    OptikError,
    ShapeError,
    UnknownSolverError,
)
from optik.problems import load_problem
from optik.solvers import IKSolver, register_solver, unregister_solver
from optik.spatial import pose_error

SIX_AND_SEVEN_DOF = ["puma560", "ur5", "panda", "stanford_arm", "jumbo_drill_6dof"]


def _random_in_limits(robot: optik.Robot, rng: np.random.Generator, n: int) -> np.ndarray:
    lower = np.where(np.isfinite(robot.lower), robot.lower, -math.pi)
    upper = np.where(np.isfinite(robot.upper), robot.upper, math.pi)
    return rng.uniform(lower, upper, (n, robot.dof))


def _verify(robot: optik.Robot, q: np.ndarray, T: np.ndarray, tol: float) -> bool:
    """Independent check: FK error and limits, recomputed here."""
    position, orientation = pose_error(robot.fk(q), T)
    inside = bool(np.all(q >= robot.lower - 1e-12) and np.all(q <= robot.upper + 1e-12))
    return position <= tol and orientation <= tol and inside


@pytest.mark.parametrize("name", SIX_AND_SEVEN_DOF)
def test_success_rate_on_random_reachable_poses(name: str, rng: np.random.Generator) -> None:
    robot = load_problem(name).robot
    Q = _random_in_limits(robot, rng, 500)
    successes = 0
    for q in Q:
        T = robot.fk(q)
        result = optik.solve_ik(robot, T, tol=1e-6)
        if result.success:
            assert _verify(robot, result.q, T, 1e-6), "reported success does not verify"
            assert result.status == "converged"
            successes += 1
        else:
            assert result.status in optik.ik.STATUSES
    assert successes / len(Q) >= 0.999


@pytest.mark.parametrize("solver", ["dls", "pinv"])
def test_numeric_solvers_without_warm_start(solver: str, rng: np.random.Generator) -> None:
    robot = load_problem("puma560").robot
    for q in _random_in_limits(robot, rng, 20):
        T = robot.fk(q)
        result = optik.solve_ik(
            robot, T, solver=solver, warm_start="q0", q0=q * 0.9 + 0.1 * robot.mid_limits
        )
        assert result.success and _verify(robot, result.q, T, 1e-6)
        assert result.solver == solver
        assert result.backend_converged is True


def test_auto_uses_closed_form_when_available(rng: np.random.Generator) -> None:
    robot = load_problem("ur5").robot
    q = _random_in_limits(robot, rng, 1)[0]
    result = optik.solve_ik(robot, robot.fk(q), q0=q)
    assert result.solver == "analytic" and result.iterations == 0
    assert np.max(np.abs(result.q - q)) < 1e-8


def test_explicit_solver_refines_analytic_branch(rng: np.random.Generator) -> None:
    robot = load_problem("puma560").robot
    q = _random_in_limits(robot, rng, 1)[0]
    T = robot.fk(q)
    result = optik.solve_ik(robot, T, solver="transpose", q0=q)
    assert result.success and result.solver == "transpose"
    assert result.iterations == 0  # the branch is already exact


def test_unreachable_and_outside_limits_statuses() -> None:
    puma = load_problem("puma560").robot
    far = np.eye(4)
    far[:3, 3] = [3.0, 0.0, 0.0]
    result = optik.solve_ik(puma, far)
    assert not result.success and result.status == "unreachable"
    arm = load_problem("jumbo_spherical_arm").robot
    p = arm.fk(np.array([0.2, 0.4, 1.5]))[:3, 3]  # needs a 1.5 m stroke; the boom's is 2-6 m
    result = optik.solve_ik(arm, p, mode="position")
    assert result.status == "outside_limits" and not result.success
    assert result.limit_violation == pytest.approx(0.5, abs=1e-9)
    # q is the branch beyond the limits that reaches the target (conventions.md).
    assert arm.limit_violation(result.q) == pytest.approx(0.5, abs=1e-9)
    assert np.linalg.norm(arm.fk(result.q)[:3, 3] - p) < 1e-9


def test_a_target_beyond_the_reach_sphere_is_unreachable_for_an_arm_with_a_slide() -> None:
    # The closed form's branch with the slide stretched beyond its stroke made such a
    # target "outside_limits" (solve_ik_batch said "unreachable"), with q up to 1.4 km
    # outside the limits; from 1e9 m out its check raised about that q.
    for name, modes in (
        ("jumbo_spherical_arm", ("pose", "position", "axis")),
        ("stanford_arm", ("pose", "position", "axis")),
        ("jumbo_drill_6dof", ("pose", "position", "axis")),
    ):
        robot = load_problem(name).robot
        centre, radius = robot.reach_sphere
        for factor in (1.1, 3.0, 1e3, 1e150, 1e300):
            T = np.eye(4)
            T[:3, 3] = centre + factor * radius * np.array([0.6, 0.0, 0.8])
            for mode in modes:
                with warnings.catch_warnings():
                    warnings.simplefilter("error")  # no overflow on the way
                    result = optik.solve_ik(robot, T, mode=mode)
                    batch = optik.solve_ik_batch(robot, T[None], mode=mode)
                    if factor >= 1e150 and mode == "pose":
                        # A branch beyond the length range (1e9 m) is no configuration.
                        assert optik.analytic_ik(robot, T, within_limits=False) == []
                assert (result.status, result.solver) == ("unreachable", "reach"), (name, mode)
                assert robot.within_limits(result.q)
                assert batch.status[0] == "unreachable"
            graded = optik.solve_ik(robot, T, weights=[1.0, 1.0, 1.0, 0.5, 0.5, 0.5])
            assert graded.status == "unreachable" and robot.within_limits(graded.q)
            assert "beyond its radius" in graded.message and graded.solver == "reach"


def test_numeric_failure_statuses(fake_clock: FakeClock) -> None:
    panda = load_problem("panda").robot
    far = np.eye(4)
    far[:3, 3] = [0.0, 0.0, 1.33]  # inside the reach sphere, beyond the arm: no proof
    result = optik.solve_ik(panda, far, restarts=3)
    assert not result.success and result.status == "max_iter"
    assert result.restarts == 3
    # Each reading of the budget's clock moves it 3 ms, whatever the machine's load: the
    # 20 ms deadline passes at a known check, and the run stops there, in its first
    # attempt (the attempt's check, then the run's: no third check past it).
    fake_clock.checks.clear()
    fake_clock.tick = 0.003
    result = optik.solve_ik(panda, far, timeout_s=0.02, solver="pinv", max_iter=50)
    assert not result.success and result.status == "timeout"
    deadline = fake_clock.checks[0] + 0.02  # the first check sets the deadline
    assert result.restarts == 0 and 0 < result.iterations < 50
    assert sum(t > deadline for t in fake_clock.checks) == 2


class _Exploding(IKSolver):
    name = "test:exploding"

    def solve(self, query, q0, max_iter, deadline):  # type: ignore[no-untyped-def]
        raise RuntimeError("backend crashed")


def test_backend_exception_becomes_solver_failed() -> None:
    register_solver("test:exploding", _Exploding, lambda: True)
    try:
        panda = load_problem("panda").robot
        result = optik.solve_ik(panda, panda.fk(panda.mid_limits + 0.1), solver="test:exploding")
        assert result.status == "solver_failed" and not result.success
        assert "backend crashed" in result.message
    finally:
        unregister_solver("test:exploding")
    assert "test:exploding" not in optik.solvers.registered_solvers()


def test_deterministic_for_a_seed(rng: np.random.Generator) -> None:
    panda = load_problem("panda").robot
    T = panda.fk(_random_in_limits(panda, rng, 1)[0])
    a = optik.solve_ik(panda, T, seed=3)
    b = optik.solve_ik(panda, T, seed=3)
    assert np.array_equal(a.q, b.q) and a.iterations == b.iterations


def test_position_mode(rng: np.random.Generator) -> None:
    panda = load_problem("panda").robot
    for q in _random_in_limits(panda, rng, 20):
        p = panda.fk(q)[:3, 3]
        result = optik.solve_ik(panda, p, mode="position")
        assert result.success and np.linalg.norm(panda.fk(result.q)[:3, 3] - p) <= 1e-6
        assert result.orientation_error == 0.0


def test_batch_matches_independent_verification(rng: np.random.Generator) -> None:
    panda = load_problem("panda").robot
    Q = _random_in_limits(panda, rng, 300)
    T = panda.fk(Q)
    batch = optik.solve_ik_batch(panda, T)
    assert batch.success.mean() >= 0.999
    for k in range(len(Q)):
        assert bool(batch.success[k]) == _verify(panda, batch.q[k], T[k], 1e-6)
    for threads in (1, 2):
        again = optik.solve_ik_batch(panda, T, threads=threads)
        assert np.array_equal(batch.q, again.q)  # seeded, thread-count independent
        assert np.array_equal(batch.iterations, again.iterations)


def test_batch_threads_must_be_a_count() -> None:
    panda = load_problem("panda").robot
    T = panda.fk(panda.mid_limits)[None]
    for bad in (0, -1, 2.0, True, 10**6):
        with pytest.raises(OptikError, match="threads"):
            optik.solve_ik_batch(panda, T, threads=bad)


def test_bad_input_raises_optik_errors() -> None:
    puma = load_problem("puma560").robot
    T = puma.fk(puma.mid_limits)
    nan_target = T.copy()
    nan_target[0, 3] = np.nan
    with pytest.raises(NonFiniteError):
        optik.solve_ik(puma, nan_target)
    skew = T.copy()
    skew[:3, :3] *= 1.01
    with pytest.raises(InvalidRotationError):
        optik.solve_ik(puma, skew)
    with pytest.raises(ShapeError):
        optik.solve_ik(puma, T[:3])
    with pytest.raises(ShapeError):
        optik.solve_ik(puma, np.ones(4), mode="position")
    outside = puma.mid_limits.copy()
    outside[1] = puma.upper[1] + 0.1
    with pytest.raises(JointLimitError) as info:
        optik.solve_ik(puma, T, q0=outside)
    assert info.value.joint == "j2"
    with pytest.raises(UnknownSolverError) as unknown:
        optik.solve_ik(puma, T, solver="nonsense")
    assert "dls" in str(unknown.value) and "installed" in str(unknown.value)
    with pytest.raises(OptikError, match="tol"):
        optik.solve_ik(puma, T, tol=0.0)
    with pytest.raises(OptikError, match="mode"):
        optik.solve_ik(puma, T, mode="twist")
    with pytest.raises(OptikError, match="warm_start"):
        optik.solve_ik(puma, T, warm_start="magic")
    with pytest.raises(TypeError):
        optik.solve_ik(puma, T, "pose")  # type: ignore[misc]  # keyword-only


def test_seed003_two_link_example() -> None:
    """Seed 003: pinv with step 0.001 from (0.5, 0.5) reaches (1.2, 1.3) within 0.01."""
    problem = load_problem("planar_2r")
    robot = problem.robot
    target = problem.targets["seed003"]
    (row,), trajectory = planar_2r_example(problem, steps=(0.001,))
    assert row.backend_converged and row.success
    p = robot.fk(trajectory[-1])[:3, 3]
    assert np.linalg.norm(p - target.position) <= 0.01
    assert row.iterations is not None
    assert 1000 < row.iterations < 5000  # small steps: hundreds of thousandths of the way
    precise = optik.solve_ik(
        robot,
        target.position,
        mode="position",
        solver="dls",
        tol=1e-9,
        warm_start="q0",
        q0=[0.5, 0.5],
    )
    assert precise.success and precise.position_error <= 1e-9


def test_batch_reports_status_and_limit_violation_per_target(rng: np.random.Generator) -> None:
    panda = load_problem("panda").robot
    Q = rng.uniform(panda.lower, panda.upper, (70, panda.dof))
    T = panda.fk(Q)
    T[3, :3, 3] = [1e154, 0.0, 0.0]  # overflows any squared distance: proved unreachable
    T[4, :3, 3] = [5.0, 0.0, 0.0]  # outside the reach sphere
    res = optik.solve_ik_batch(panda, T, threads=2)
    assert list(res.status[3:5]) == ["unreachable", "unreachable"]
    assert not res.success[3] and not res.success[4]
    others = np.delete(np.arange(70), [3, 4])
    assert np.all(res.status[others] == "converged") and res.success[others].all()
    assert np.all(res.limit_violation[others] <= 1e-12)
    assert np.all(res.iterations >= 0) and np.all(res.iterations[others] < 10**6)
    # The same rows, verified here from FK.
    for k in others[:10]:
        p, r = pose_error(panda.fk(res.q[k]), T[k])
        assert p <= 1e-6 and r <= 1e-6


def test_a_bad_row_of_a_batchs_q0_is_named() -> None:
    panda = load_problem("panda").robot
    targets = np.stack([panda.fk(panda.mid_limits)] * 3)
    q0 = np.stack([panda.mid_limits] * 3)
    q0[1, 2] = math.nan  # row 1 (it was reported at "index (2,)", the row unnamed)
    with pytest.raises(OptikError, match=r"q0\[1\]: values must be finite"):
        optik.solve_ik_batch(panda, targets, q0=q0)


def test_batch_of_zero_targets() -> None:
    panda = load_problem("panda").robot
    res = optik.solve_ik_batch(panda, np.empty((0, 4, 4)))
    assert res.q.shape == (0, panda.dof) and res.success.shape == (0,)


@pytest.mark.parametrize(
    "bad",
    [
        {"max_iter": "10"},
        {"max_iter": 0},
        {"max_iter": True},
        {"seed": -1},
        {"seed": 1.5},
        {"seed": True},
        {"timeout_s": "1"},
        {"timeout_s": math.nan},
        {"tol": True},
        {"restarts": 2.5},
        {"solver": ["dls"]},
    ],
)
def test_bad_options_raise_optik_errors(bad: dict[str, object]) -> None:
    puma = load_problem("puma560").robot
    with pytest.raises(OptikError):
        optik.solve_ik(puma, puma.fk(puma.mid_limits), **bad)  # type: ignore[arg-type]


def test_not_a_robot() -> None:
    with pytest.raises(OptikError, match=r"optik\.Robot"):
        optik.solve_ik("panda", np.eye(4))  # type: ignore[arg-type]


def test_the_batch_verification_refuses_a_configuration_outside_the_limits() -> None:
    # solve_ik_batch hands verify only answers inside the limits: its limit term is
    # checked here directly, on a row that reaches its own pose 1e-3 rad past a limit.
    puma = load_problem("puma560").robot
    inside = puma.mid_limits
    outside = puma.mid_limits.copy()
    outside[1] = puma.upper[1] + 1e-3
    Q = np.stack([inside, outside])
    verdict = optik.verify.verify(puma, Q, puma.fk(Q), "pose")
    assert verdict.success.tolist() == [True, False]
    assert verdict.position_error.max() <= 1e-12 and verdict.orientation_error.max() <= 1e-12
    assert verdict.limit_violation == pytest.approx([0.0, 1e-3], abs=1e-12)


def test_a_branch_that_misses_a_tol_below_rounding_says_so() -> None:
    # tol = 1e-300: the branch (4e-16 m off) and the dls polish from every branch miss
    # it; the result said "max_iter" with an empty message and 0 iterations.
    ur5 = load_problem("ur5").robot
    T = ur5.fk(ur5.mid_limits + 0.2)
    result = optik.solve_ik(ur5, T, tol=1e-300, timeout_s=5.0)
    assert not result.success and result.solver == "analytic"
    assert result.status in ("max_iter", "timeout") and result.iterations > 0
    assert result.message.startswith("the closed-form branch reaches the target to ")
    assert "outside tol (1e-300 m, 1e-300 rad)" in result.message
    assert f"{result.position_error:.3g} m" in result.message
