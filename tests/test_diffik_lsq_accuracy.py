"""Least-squares steps with active joint limits, against scipy's bounded least squares.

The reference is ``scipy.optimize.lsq_linear`` (BVLS, ``tol=1e-15``) on the stacked rows
``[J; lambda I] dq ~ [v; 0]`` with the step bounds ``lower - q <= dq <= upper - q``, from
the robot's own Jacobian: it shares nothing with optik's programs or its backends. On
these programs a backend that solves the QP ``P = J^T J + lambda^2 I`` (whose condition
number is the square of the rows') stopped up to 2e-4 (relative) from the optimum on the
default path, and the cheap check accepted it.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import lsq_linear

import optik
from optik.diffik import diff_ik, verify_step
from optik.programs.diff_qp import DEFAULT_DAMPING, QPSolution, build_program
from optik.solvers import available_solvers

DT = 0.05  # s
# (robot, q, twist): joints 1e-3 from a limit, the twist pushing two of them out; at the
# optimum at least one bound is active with a multiplier well above the check's tolerance.
CASES = [
    (
        "ur5",
        [-1.4120604325106054, -2.2237908581905037, 6.282185307179586, 3.9752218520341334,
         6.282185307179586, 6.016123346351797],
        [-0.03519371424292496, 0.21947804127492937, 0.177744554989494, -0.5896559627642513,
         -0.8006729957962403, 0.12664232138561848],
    ),
    (
        "ur5",
        [-3.7884949867156137, -1.7199974665017912, 6.282185307179586, -1.934449007953691,
         -6.282185307179586, 0.9215261076594894],
        [0.4248237125588598, -0.32077993692297635, 0.14317262637755002, 0.9773862733470374,
         0.49284438017129284, -0.8554906576703232],
    ),
    (
        "panda",
        [1.8359585913041965, 1.761782544514273, 2.4557654322235543, -0.38955002865395416,
         0.9753404550392393, 0.16895871486479191, -2.896246558310587],
        [-0.019160725651217174, 0.0705588196046482, -0.5007981621542471,
         -1.4322587279953136, 0.5600336827087748, -0.04628358687903742],
    ),
    (
        "panda",
        [2.881181604669802, -1.2104355632358925, 2.896246558310587, -3.07077948351002,
         1.6416234806715497, 3.344474988702584, 2.850880113647169],
        [-0.14715429868223384, 0.33106642752740156, 0.2968950513237228, 1.1763485743659738,
         0.641422787984905, 0.11920071483797937],
    ),
]  # fmt: skip
SOLVERS = [
    name
    for name in ("qp:osqp", "qp:proxqp", "qp:clarabel", "qp:daqp", "qp:quadprog")
    if name in available_solvers(kind="step")
]


def _reference(robot: optik.Robot, q: np.ndarray, twist: np.ndarray, dt: float = DT) -> np.ndarray:
    """BVLS on ``[J; lambda I]``, checked to be a KKT point with an active bound."""
    J = robot.jacobian(q)
    lam = DEFAULT_DAMPING
    A = np.vstack([J, lam * np.eye(robot.dof)])
    b = np.concatenate([twist * dt, np.zeros(robot.dof)])
    lower, upper = robot.lower - q, robot.upper - q
    ref = np.asarray(lsq_linear(A, b, bounds=(lower, upper), method="bvls", tol=1e-15).x)
    g = A.T @ (A @ ref - b)
    at_lower, at_upper = ref - lower <= 1e-14, upper - ref <= 1e-14
    assert np.any(at_lower | at_upper)
    free = ~(at_lower | at_upper)
    size = np.max(np.abs(A.T @ b))
    assert np.max(np.abs(g[free]), initial=0.0) <= 1e-12 * size
    assert np.all(g[at_lower] >= 1e-6 * size) and np.all(g[at_upper] <= -1e-6 * size)
    return ref


@pytest.mark.parametrize("solver", SOLVERS)
@pytest.mark.parametrize("case", range(len(CASES)))
def test_least_squares_with_active_limits_matches_bvls(case: int, solver: str) -> None:
    name, q_list, twist_list = CASES[case]
    robot = optik.load_problem(name).robot
    q, twist = np.array(q_list), np.array(twist_list)
    ref = _reference(robot, q, twist)
    for kkt_proof in (False, True):
        dq = diff_ik(
            robot, q, twist, dt=DT, objective="least_squares", solver=solver, kkt_proof=kkt_proof
        )
        error = np.max(np.abs(dq - ref)) / np.max(np.abs(ref))
        assert error <= 1e-8, (name, solver, kkt_proof, error)
        assert np.all(q + dq >= robot.lower) and np.all(q + dq <= robot.upper)


@pytest.mark.parametrize("solver", SOLVERS)
def test_an_unbounded_step_is_the_damped_closed_form(solver: str) -> None:
    # Without limits the program has no constraint: qpsolvers gives it to SciPy's LSQR
    # rather than Clarabel, whose residual then failed its own 1e-8 check ("unbounded
    # below") on 37 of 40 random UR5 steps at cond(J) near 9.
    ur5 = optik.load_problem("ur5").robot
    rng = np.random.default_rng(3)
    lam = DEFAULT_DAMPING
    for _ in range(10):
        q = rng.uniform(-2.0, 2.0, ur5.dof)
        twist = rng.normal(0.0, 0.05, 6)
        J = ur5.jacobian(q)
        expected = np.linalg.solve(J.T @ J + lam**2 * np.eye(ur5.dof), J.T @ twist)
        dq = diff_ik(ur5, q, twist, dt=1.0, objective="least_squares", solver=solver, limits=False)
        assert np.allclose(dq, expected, rtol=1e-9, atol=1e-12), (solver, q, dq - expected)


# A Panda step (dt = 1 s) where Clarabel stopped 2e-5 (4e-6 of the KKT scale) from
# stationary: the point was refused ("not optimal") although the program has a minimiser.
OFF_STATIONARY_Q = [-0.14181415069294756, 1.4766542362984598, 0.13192342504187504,
                    -2.087376074671621, -0.45866469206648475, 1.692055213484364,
                    0.45475678796761443]  # fmt: skip
OFF_STATIONARY_TWIST = [-0.0753449059467109, -0.6481748467516018, -0.016553984689091875,
                        0.9776829420248081, 1.3476104278195014, -0.14505830071075107]  # fmt: skip


@pytest.mark.parametrize("solver", SOLVERS)
def test_a_step_every_backend_leaves_near_stationary_is_the_bvls_minimiser(solver: str) -> None:
    panda = optik.load_problem("panda").robot
    q, twist = np.array(OFF_STATIONARY_Q), np.array(OFF_STATIONARY_TWIST)
    ref = _reference(panda, q, twist, dt=1.0)
    dq = diff_ik(panda, q, twist, dt=1.0, objective="least_squares", solver=solver)
    assert np.max(np.abs(dq - ref)) <= 1e-8 * np.max(np.abs(ref)), (solver, dq - ref)


def _off_stationary_answer(shift: float) -> tuple[np.ndarray, tuple[np.ndarray | None, str]]:
    """The BVLS minimiser, and :func:`verify_step` of it moved by ``shift`` along a free joint."""
    panda = optik.load_problem("panda").robot
    q, twist = np.array(OFF_STATIONARY_Q), np.array(OFF_STATIONARY_TWIST)
    program = build_program(panda, q, twist, objective="least_squares")
    ref = _reference(panda, q, twist, dt=1.0)
    free = int(np.argmax(np.minimum(ref - program.lower, program.upper - ref)))
    point = ref.copy()
    point[free] += shift
    return ref, verify_step(program, QPSolution(point, True, "test point", "test"))


def test_a_least_squares_point_a_little_off_stationary_is_solved_again() -> None:
    ref, (dq, reason) = _off_stationary_answer(1e-2)  # 2e-3 of the scale from stationary
    assert reason == "" and dq is not None
    assert np.max(np.abs(dq - ref)) <= 1e-9 * np.max(np.abs(ref))


def test_a_least_squares_point_far_from_stationary_is_refused() -> None:
    # Re-solving any feasible point would hide a broken backend: only a near one is.
    _, (dq, reason) = _off_stationary_answer(1.0)  # 0.21 of the scale from stationary
    assert dq is None
    assert reason.startswith("not optimal: KKT stationarity residual")


# A Panda step with two joints at speed 0 (a zero-width box): quadprog, which takes each
# bound as an inequality, returned no point ("no point returned") on it.
ZERO_SPEED_Q = [0.0025932972742159777, -0.2510029224115682, 1.7078691403868618,
                -3.048792921549545, 2.1788336530817247, 0.7249433587663224,
                -2.2902956989297065]  # fmt: skip
ZERO_SPEED_TWIST = [-0.07225345490329442, -0.0846080520711566, 0.0003661039443088937,
                    0.01252726527947324, -0.020333410093396828, 0.019450767858593832]  # fmt: skip
ZERO_SPEED_VMAX = [0.0, 1.9621540699364257, 0.7341961103106678, 1.9498483113054421,
                   0.8686833925950458, 1.342679979911842, 0.0]  # fmt: skip


@pytest.mark.parametrize("solver", SOLVERS)
def test_joints_at_speed_zero_stay_and_the_others_take_the_bvls_step(solver: str) -> None:
    panda = optik.load_problem("panda").robot
    q, twist, vmax = (np.array(a) for a in (ZERO_SPEED_Q, ZERO_SPEED_TWIST, ZERO_SPEED_VMAX))
    dt = 0.1
    free = vmax > 0.0
    J = panda.jacobian(q)[:, free]
    lam = DEFAULT_DAMPING
    A = np.vstack([J, lam * np.eye(J.shape[1])])
    b = np.concatenate([twist * dt, np.zeros(J.shape[1])])
    box = vmax[free] * dt
    ref = lsq_linear(A, b, bounds=(-box, box), method="bvls", tol=1e-15).x
    dq = diff_ik(
        panda, q, twist, dt=dt, objective="least_squares", solver=solver,
        velocity_limits=vmax, limits=False,
    )  # fmt: skip
    assert np.all(dq[~free] == 0.0)
    assert np.max(np.abs(dq[free] - ref)) <= 1e-8 * np.max(np.abs(ref)), (solver, dq[free] - ref)


@pytest.mark.parametrize("solver", SOLVERS)
def test_a_least_norm_step_with_joints_at_speed_zero_is_the_others_pseudoinverse(
    solver: str,
) -> None:
    # One joint at speed 0 (with two, J dq = v has no solution: five joints, six rows).
    panda = optik.load_problem("panda").robot
    q, vmax = np.array(ZERO_SPEED_Q), np.array(ZERO_SPEED_VMAX)
    vmax[0] = 1.0
    twist = 0.01 * np.array(ZERO_SPEED_TWIST)  # small: no speed bound of the free joints acts
    free = vmax > 0.0
    expected = np.linalg.pinv(panda.jacobian(q)[:, free]) @ twist
    dq = diff_ik(panda, q, twist, dt=1.0, solver=solver, velocity_limits=vmax, limits=False)
    assert np.all(dq[~free] == 0.0)
    assert np.allclose(dq[free], expected, rtol=1e-8, atol=1e-13), (solver, dq[free] - expected)
