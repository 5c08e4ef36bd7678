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
from optik.diffik import diff_ik
from optik.programs.diff_qp import DEFAULT_DAMPING
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


def _reference(robot: optik.Robot, q: np.ndarray, twist: np.ndarray) -> np.ndarray:
    """BVLS on ``[J; lambda I]``, checked to be a KKT point with an active bound."""
    J = robot.jacobian(q)
    lam = DEFAULT_DAMPING
    A = np.vstack([J, lam * np.eye(robot.dof)])
    b = np.concatenate([twist * DT, np.zeros(robot.dof)])
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
