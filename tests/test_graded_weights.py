"""Graded task weights: the search on the binary twin, the compromise on the weights.

Positive weights far apart (1e-6 of each other) used to slow the numeric search until
most reachable targets ended in ``max_iter``; they now search with ``Task.search`` and
keep the graded weights for the compromise of an unreachable target, which must be a
KKT point of the weighted cost (checked by finite differences, independently of optik's
residual code).
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

import optik
from optik.spatial import rot_x
from optik.task import make_task

HEAVY_POSITION = [1.0, 1.0, 1.0, 1e-3, 1e-3, 1e-3]
HEAVY_ROTATION = [1e-3, 1e-3, 1e-3, 1.0, 1.0, 1.0]


def test_search_twin_has_unit_weights_and_the_same_success() -> None:
    task = make_task(weights=[2.0, 1.0, 1.0, 1e-6, 1e-6, 0.0], tol=(1e-5, 1e-4))
    twin = task.search
    assert task.is_graded and not twin.is_graded
    assert twin.mode == task.mode == "axis" and twin.axis == task.axis == 2
    np.testing.assert_array_equal(twin.weights, [1, 1, 1, 1, 1, 0])
    assert (twin.position_tol, twin.orientation_tol) == (1e-5, 1e-4)
    assert task.search is twin  # made once
    plain = make_task("position")
    assert not plain.is_graded and plain.search is plain
    # Graded position weights on every axis: the twin is the plain point (any frame).
    point = make_task("position", weights=[3.0, 1.0, 1.0, 0.0, 0.0, 0.0]).search
    assert point.is_pose_or_position and point.mode == "position"


def _poses(robot: optik.Robot, n: int, seed: int) -> list[np.ndarray]:
    rng = np.random.default_rng(seed)
    return [robot.fk(rng.uniform(robot.lower, robot.upper)) for _ in range(n)]


@pytest.mark.parametrize("ratio", [1e-6, 1e-8])
@pytest.mark.parametrize("light", ["rotation", "position"])
def test_reachable_targets_with_weights_far_apart_are_solved(ratio: float, light: str) -> None:
    # Before: 3 of 20 (1e-6) and 0 of 20 (1e-8) random Panda poses with light position
    # rows ended in max_iter.
    panda = optik.load_problem("panda").robot
    weights = [1, 1, 1, ratio, ratio, ratio] if light == "rotation" else [ratio] * 3 + [1] * 3
    targets = _poses(panda, 10, seed=3)
    for T in targets:
        result = optik.solve_ik(panda, T, weights=weights)
        assert result.success, (result.status, result.position_error, result.orientation_error)
        F = panda.fk(result.q)
        assert np.linalg.norm(F[:3, 3] - T[:3, 3]) <= 1e-6
        assert Rotation.from_matrix(T[:3, :3].T @ F[:3, :3]).magnitude() <= 1e-6
    batch = optik.solve_ik_batch(panda, np.array(targets), weights=weights)
    assert batch.success.all(), batch.status


def test_closed_form_answers_graded_full_pose_weights() -> None:
    ur5 = optik.load_problem("ur5").robot
    for T in _poses(ur5, 5, seed=4):
        result = optik.solve_ik(ur5, T, weights=[1, 1, 1, 1e-8, 1e-8, 1e-8])
        assert result.success and result.solver == "analytic"
        np.testing.assert_allclose(ur5.fk(result.q), T, atol=1e-9)


def _weighted_cost(robot: optik.Robot, q: np.ndarray, T: np.ndarray, w: list[float]) -> float:
    """0.5 sum w_i e_i^2, e = [R*^T (p - p*); rotvec(R*^T R)] (target frame)."""
    F = robot.fk(q)
    d = T[:3, :3].T @ (F[:3, 3] - T[:3, 3])
    r = Rotation.from_matrix(T[:3, :3].T @ F[:3, :3]).as_rotvec()
    e = np.concatenate([d, r])
    return 0.5 * float(np.sum(np.asarray(w) * e * e))


def _kkt_violation(robot: optik.Robot, q: np.ndarray, T: np.ndarray, w: list[float]) -> float:
    """Largest projected gradient of the weighted cost inside the box (central differences)."""
    h = 1e-6
    steps = np.eye(len(q)) * h
    g = np.array(
        [
            (_weighted_cost(robot, q + s, T, w) - _weighted_cost(robot, q - s, T, w)) / (2 * h)
            for s in steps
        ]
    )
    at_lower = q <= robot.lower + 1e-9
    at_upper = q >= robot.upper - 1e-9
    projected = np.where(at_lower, np.minimum(g, 0.0), np.where(at_upper, np.maximum(g, 0.0), g))
    return float(np.max(np.abs(projected)))


@pytest.mark.parametrize("name", ["ur5", "panda"])
def test_unreachable_target_gets_the_weighted_compromise(name: str) -> None:
    base = optik.load_problem(name).robot
    centre = base.mid_limits + 0.2
    robot = base.with_limits(centre - 0.3, centre + 0.3)
    T = robot.fk(centre)
    T[:3, :3] = T[:3, :3] @ rot_x(1.2)  # a turn the narrowed wrist cannot make
    results = {}
    for label, weights in (("position", HEAVY_POSITION), ("rotation", HEAVY_ROTATION)):
        single = optik.solve_ik(robot, T, weights=weights)
        batch = optik.solve_ik_batch(robot, T[None], weights=weights)
        assert not single.success and not batch.success[0]
        assert robot.within_limits(single.q) and robot.within_limits(batch.q[0])
        # A stationary point of the weighted cost (an unweighted answer is not: its
        # projected gradient is 0.1 to 0.16 here).
        assert _kkt_violation(robot, single.q, T, weights) <= 1e-4
        assert _kkt_violation(robot, batch.q[0], T, weights) <= 1e-4
        results[label] = single
    assert results["position"].position_error < 0.1 * results["rotation"].position_error
    assert results["rotation"].orientation_error < results["position"].orientation_error


def test_graded_path_uses_every_waypoint() -> None:
    ur5 = optik.load_problem("ur5").robot
    start = np.array([0.3, -1.2, 1.5, -0.9, 1.1, 0.4])
    waypoints = np.array([ur5.fk(start + 0.02 * k) for k in range(5)])
    path = optik.plan_path(ur5, waypoints, weights=[1, 1, 1, 1e-7, 1e-7, 1e-7])
    assert path.status == ["ok"] * 5
    for q, T in zip(path.q, waypoints, strict=True):
        np.testing.assert_allclose(ur5.fk(q), T, atol=1e-6)


def _narrowed_panda_target() -> tuple[optik.Robot, np.ndarray]:
    base = optik.load_problem("panda").robot
    centre = base.mid_limits + 0.2
    robot = base.with_limits(centre - 0.3, centre + 0.3)
    T = robot.fk(centre)
    T[:3, :3] = T[:3, :3] @ rot_x(1.2)
    return robot, T


@pytest.mark.parametrize("solver", ["dls", "qp:daqp"])
def test_the_compromise_survives_a_timeout(solver: str) -> None:
    # With timeout_s the restarts run to the deadline; the compromise used to be skipped
    # then (a position error of 0.31 m against 3.8 mm, weights ignored).
    robot, T = _narrowed_panda_target()
    result = optik.solve_ik(robot, T, weights=HEAVY_POSITION, solver=solver, timeout_s=0.1)
    assert result.status == "timeout"
    assert _kkt_violation(robot, result.q, T, HEAVY_POSITION) <= 1e-4
    assert result.position_error < 0.01


def test_a_target_beyond_reach_gets_the_compromise() -> None:
    panda = optik.load_problem("panda").robot
    T = panda.fk(panda.mid_limits + 0.3)
    T[:3, 3] *= 3.0  # beyond the reach sphere: proved unreachable at once
    result = optik.solve_ik(panda, T, weights=HEAVY_ROTATION)
    assert result.status == "unreachable"
    assert not np.allclose(result.q, panda.mid_limits)  # no longer the start
    assert _kkt_violation(panda, result.q, T, HEAVY_ROTATION) <= 1e-4


def test_posture_keeps_what_a_tiny_weight_constrains() -> None:
    # A weight of 1e-100 still constrains its axis: the posture's refinement used the
    # graded task, on which that row weighs nothing, and lost a verified answer.
    panda = optik.load_problem("panda").robot
    rng = np.random.default_rng(5)
    q0 = [panda.lower + (panda.upper - panda.lower) * rng.uniform(0.1, 0.9, 7) for _ in range(3)][2]
    T = panda.fk(q0 + 0.01)
    weights = [1, 1, 1, 1e-100, 1, 1]
    result = optik.solve_ik(
        panda, T, weights=weights, solver="dls", warm_start="q0", q0=q0, restarts=0, posture=q0
    )
    assert result.success
    assert Rotation.from_matrix(T[:3, :3].T @ panda.fk(result.q)[:3, :3]).magnitude() <= 1e-6
    path = np.array([panda.fk(q0 + 0.01 * t) for t in range(10)])
    plan = optik.plan_path(panda, path, weights=[1, 1e-8, 1, 1e-100, 1e-50, 1])
    assert plan.status == ["ok"] * 10 and float(np.nanmax(plan.step)) < 0.05


def test_unequal_rotational_weights_reach_the_weighted_minimum() -> None:
    # The rotation rows used the tool's angular velocity, the rotation vector's
    # derivative only at zero error: with weights differing between the rotation rows the
    # compromise stopped 5 % above the minimum (L-BFGS-B moved it 0.13 rad further).
    ur5 = optik.load_problem("ur5").robot
    rng = np.random.default_rng(3)
    rng.uniform(0.3, 0.7, 6)
    centre = ur5.lower + (ur5.upper - ur5.lower) * rng.uniform(0.3, 0.7, 6)
    robot = ur5.with_limits(centre - 0.3, centre + 0.3)
    T = robot.fk(centre)
    T[:3, :3] = T[:3, :3] @ rot_x(1.2)
    weights = [1, 1, 1, 1, 1e-2, 1e-4]
    for solver in ("auto", "dls"):
        result = optik.solve_ik(robot, T, weights=weights, solver=solver)
        assert not result.success
        assert _kkt_violation(robot, result.q, T, weights) <= 1e-5


def _left_to_descend(robot: optik.Robot, q: np.ndarray, T: np.ndarray, w: list[float]) -> float:
    """Relative weighted cost that scipy's bounded least squares (TRF) still removes from q."""

    def residual(x: np.ndarray) -> np.ndarray:
        F = robot.fk(x)
        d = T[:3, :3].T @ (F[:3, 3] - T[:3, 3])
        r = Rotation.from_matrix(T[:3, :3].T @ F[:3, :3]).as_rotvec()
        return np.sqrt(np.asarray(w)) * np.concatenate([d, r])

    found = least_squares(
        residual, q, bounds=(robot.lower, robot.upper), xtol=1e-15, ftol=1e-15, gtol=1e-15,
        max_nfev=500,
    )  # fmt: skip
    before = float(residual(q) @ residual(q))
    return (before - float(found.fun @ found.fun)) / before


# A narrowed Puma whose compromise rests on a bound (a hostile search's case).
PUMA_CENTRE = [0.81018222, 0.41577736, -1.45446491, 0.54638816, 0.77773137, -0.77291055]
# A Panda target beyond the reach sphere (the same search).
PANDA_FAR = [
    [0.23529298386330305, 0.679060534245923, 0.6953517114197278, 0.5478757108097195],
    [-0.9232583830054841, 0.379713998998636, -0.05840579743965935, 1.0698481889378508],
    [-0.3036958510661648, -0.6282468223509812, 0.7162923706497876, 0.3794743055061174],
    [0.0, 0.0, 0.0, 1.0],
]


def test_a_compromise_on_a_bound_is_the_constrained_minimum() -> None:
    # The LM held a joint on its bound when its weakly damped step pointed outward,
    # although the cost's gradient pointed inward: the compromise stopped 0.4 % above the
    # minimum (scipy moved it 0.055 rad), its gradient 4.7e-5 into the box.
    puma = optik.load_problem("puma560").robot
    centre = np.array(PUMA_CENTRE)
    robot = puma.with_limits(
        np.maximum(centre - 0.3, puma.lower), np.minimum(centre + 0.3, puma.upper)
    )
    T = robot.fk(centre)
    T[:3, :3] = T[:3, :3] @ rot_x(1.2)
    result = optik.solve_ik(robot, T, weights=HEAVY_POSITION)
    assert result.status == "outside_limits"
    assert np.any(result.q <= robot.lower + 1e-12) or np.any(result.q >= robot.upper - 1e-12)
    assert _left_to_descend(robot, result.q, T, HEAVY_POSITION) <= 1e-9


def test_the_compromise_is_not_cut_by_the_searchs_iterations() -> None:
    # The compromise ran at most the search's max_iter (100): 1.3 % above the minimum,
    # which this redundant arm reaches after about 425 iterations.
    panda = optik.load_problem("panda").robot
    T = np.array(PANDA_FAR)
    result = optik.solve_ik(panda, T, weights=HEAVY_POSITION)
    assert result.status == "unreachable" and result.iterations > 100
    assert _left_to_descend(panda, result.q, T, HEAVY_POSITION) <= 1e-9


def test_the_batch_takes_the_compromise_beyond_the_reach_sphere_too() -> None:
    # The batch left q NaN (position error inf) on a row beyond the reach sphere, where
    # solve_ik returns the weighted compromise from q0.
    panda = optik.load_problem("panda").robot
    far = np.array(PANDA_FAR)
    further = far.copy()
    further[:3, 3] += 0.3
    T = np.stack([far, further])
    per_row = np.stack([panda.mid_limits + 0.2, panda.mid_limits - 0.1])
    for q0 in (None, panda.mid_limits + 0.2, per_row):
        batch = optik.solve_ik_batch(panda, T, weights=HEAVY_POSITION, q0=q0)
        assert batch.status.tolist() == ["unreachable", "unreachable"]
        for k in range(2):
            row_q0 = per_row[k] if q0 is per_row else q0
            single = optik.solve_ik(panda, T[k], weights=HEAVY_POSITION, q0=row_q0)
            assert np.allclose(batch.q[k], single.q, rtol=0.0, atol=1e-9)
            assert batch.position_error[k] == pytest.approx(single.position_error, abs=1e-9)
            assert _left_to_descend(panda, batch.q[k], T[k], HEAVY_POSITION) <= 1e-6


@pytest.mark.parametrize("name", ["ur5", "puma560"])
def test_rows_weighted_1e_minus_12_still_reach_their_compromise(name: str) -> None:
    # The damping's bias (1e-3, a search's) swamped rows weighted 1e-12: the UR5's
    # compromises stopped 0.3 to 0.8 % above the weighted minimum (the Puma's 6e-8).
    robot = optik.load_problem(name).robot
    centre, radius = robot.reach_sphere
    rng = np.random.default_rng(11)
    weights = [1e-12, 1e-12, 1e-12, 1.0, 1.0, 1.0]
    for _ in range(3):
        T = robot.fk(robot.lower + (robot.upper - robot.lower) * rng.uniform(0.2, 0.8, 6))
        direction = rng.normal(size=3)
        T[:3, 3] = centre + 1.5 * radius * direction / np.linalg.norm(direction)
        result = optik.solve_ik(robot, T, weights=weights)
        assert result.status == "unreachable"
        assert _left_to_descend(robot, result.q, T, weights) <= 1e-6


@pytest.mark.parametrize("solver", ["casadi:ipopt", "casadi:sqpmethod"])
def test_an_nlps_own_convergence_claim_does_not_skip_the_compromise(solver: str) -> None:
    # An NLP "solved to an acceptable level" short of the task counted as converged, so
    # the compromise was skipped: 1.2 % above the weighted minimum (a hostile search's).
    rng = np.random.default_rng(5)
    ur5 = optik.load_problem("ur5").robot
    centre = rng.uniform(np.maximum(ur5.lower, -2.5) + 0.4, np.minimum(ur5.upper, 2.5) - 0.4)
    robot = ur5.with_limits(centre - 0.3, centre + 0.3)
    T = robot.fk(centre)
    T[:3, :3] = T[:3, :3] @ Rotation.from_rotvec(rng.normal(size=3)).as_matrix()
    T[:3, 3] += rng.normal(size=3) * 0.1
    weights = [2.0, 1.0, 1.0, 0.0, 0.0, 0.0]
    result = optik.solve_ik(robot, T, weights=weights, solver=solver, seed=0)
    assert not result.success
    assert _left_to_descend(robot, result.q, T, weights) <= 1e-9


def _axis_residual(x: np.ndarray, robot: optik.Robot, T: np.ndarray, w: list[float]) -> np.ndarray:
    """Weighted residual of a z-axis task, written independently of optik's kernels."""
    F = robot.fk(x)
    d = T[:3, :3].T @ (F[:3, 3] - T[:3, 3])
    a, b = F[:3, 2], T[:3, 2]
    v = np.cross(a, b)
    s = float(np.linalg.norm(v))
    r = v * np.arctan2(s, float(a @ b)) / s if s > 0.0 else np.zeros(3)
    return np.sqrt(np.asarray(w)) * np.concatenate([d, T[:3, :3].T @ r])


@pytest.mark.parametrize("weights", [[1, 1, 1, 1, 3, 0], [1, 1, 1, 1e-2, 1, 0]])
def test_a_tool_axis_with_unequal_weights_reaches_the_weighted_minimum(
    weights: list[float],
) -> None:
    # The tool-axis rows were the tool's angular velocity, the axis error's derivative
    # only where the axes meet: with its two rotation weights unequal the compromise of a
    # narrowed Panda stopped up to 12 % above the minimum (33 of 36 cases in a sweep).
    panda = optik.load_problem("panda").robot
    rng = np.random.default_rng(1)
    for trial in range(4):
        centre = panda.lower + (panda.upper - panda.lower) * rng.uniform(0.3, 0.7, 7)
        robot = panda.with_limits(
            np.maximum(centre - 0.3, panda.lower), np.minimum(centre + 0.3, panda.upper)
        )
        T = robot.fk(centre)
        T[:3, :3] = T[:3, :3] @ (
            rot_x(1.2) if trial % 2 else Rotation.from_rotvec([0, 0.9, 0]).as_matrix()
        )
        solvers = ("auto", "dls", "qp:osqp") if trial == 0 else ("auto",)
        for solver in solvers:
            result = optik.solve_ik(robot, T, weights=weights, solver=solver)
            assert not result.success
            found = least_squares(
                _axis_residual, result.q, bounds=(robot.lower, robot.upper), xtol=1e-15,
                ftol=1e-15, gtol=1e-15, max_nfev=500, args=(robot, T, weights),
            )  # fmt: skip
            start = _axis_residual(result.q, robot, T, weights)
            before = float(start @ start)
            assert (before - float(found.fun @ found.fun)) / before <= 1e-9, (trial, solver)


def _axis_error(turn: np.ndarray, R: np.ndarray, G: np.ndarray) -> np.ndarray:
    """Rotation vector taking the z axis of ``R``, turned by ``turn`` (world), to ``G``'s."""
    a = Rotation.from_rotvec(turn).as_matrix() @ R[:, 2]
    v = np.cross(a, G[:3, 2])
    s = np.linalg.norm(v)
    return v * np.arctan2(s, a @ G[:3, 2]) / s


@pytest.mark.parametrize("angle", [1e-6, 0.3, 2.0, 3.1])
def test_the_tool_axis_rows_are_the_axis_errors_derivative(angle: float) -> None:
    # _axis_derivative_rows against central differences of an independent residual, from
    # aligned axes (its series) to nearly opposite ones.
    from optik.solvers._lm_kernel import _axis_derivative_rows

    rng = np.random.default_rng(int(angle * 1000))
    for _ in range(5):
        R = Rotation.random(random_state=rng).as_matrix()
        turn = rng.normal(size=3)
        turn -= (turn @ R[:, 2]) * R[:, 2]  # perpendicular to the axis: turns it by angle
        G = np.eye(4)
        G[:3, :3] = Rotation.from_rotvec(angle * turn / np.linalg.norm(turn)).as_matrix() @ R
        T = np.eye(4)
        T[:3, :3] = R

        h = 1e-7
        D = np.column_stack(
            [(_axis_error(h * u, R, G) - _axis_error(-h * u, R, G)) / (2 * h) for u in np.eye(3)]
        )
        J = np.zeros((6, 3))
        J[3:6] = np.eye(3)
        _axis_derivative_rows(J, T, G, 2)
        np.testing.assert_allclose(J[3:6], -D, atol=1e-6 * max(1.0, np.abs(D).max()))
