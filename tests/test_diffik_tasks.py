"""diff_ik's task keywords: weights, joint_weights and posture against numpy closed forms."""

from __future__ import annotations

import numpy as np
import pytest

import optik
from optik.errors import OptikError, SolverError
from optik.problems import builtin_problems

DT = 0.01  # s
STEP_BACKENDS = optik.available_solvers(kind="step")
ROBOTS = {path.stem: optik.load_problem(path).robot for path in builtin_problems()}
# Every backend with every robot: 8 robots x 11 backends run in a few seconds.
CASES = [(name, solver) for name in ROBOTS for solver in STEP_BACKENDS]


def _setup(name: str, seed: int) -> tuple[optik.Robot, np.ndarray, np.ndarray]:
    """A configuration near mid-limits (limits inactive) and a small twist (m/s, rad/s)."""
    robot = ROBOTS[name]
    rng = np.random.default_rng(seed)
    mid = 0.5 * (robot.lower + robot.upper)
    # Off mid-limits a little: exactly there the Puma's wrist is singular.
    q = mid + 0.1 * (robot.upper - robot.lower) * rng.uniform(-1.0, 1.0, robot.dof)
    twist = 0.05 * rng.standard_normal(6)
    return robot, q, twist


def _independent_rows(J6: np.ndarray, at_most: int) -> list[int]:
    """Rows of J6 picked greedily while they raise its rank (numpy's SVD), at most ``at_most``."""
    picked: list[int] = []
    for row in range(6):
        if len(picked) == at_most:
            break
        trial = [*picked, row]
        if np.linalg.matrix_rank(J6[trial], tol=1e-3) == len(trial):
            picked = trial
    return picked


def _rel(dq: np.ndarray, ref: np.ndarray) -> float:
    return float(np.linalg.norm(dq - ref) / np.linalg.norm(ref))


def _least_norm(J: np.ndarray, v: np.ndarray, w: np.ndarray, d: np.ndarray) -> np.ndarray:
    """``d + W^-1 J^T (J W^-1 J^T)^-1 (v - J d)`` with ``W = diag(w)``."""
    w_inv = 1.0 / w
    A = (J * w_inv) @ J.T
    return d + w_inv * (J.T @ np.linalg.solve(A, v - J @ d))


def _least_squares(
    J: np.ndarray, v: np.ndarray, wt: np.ndarray, w: np.ndarray, lam: float, d: np.ndarray
) -> np.ndarray:
    """``argmin ||J dq - v||^2_Wt + lam^2 ||dq - d||^2_W`` as a stacked ``lstsq``."""
    A = np.vstack([np.sqrt(wt)[:, None] * J, lam * np.diag(np.sqrt(w))])
    b = np.concatenate([np.sqrt(wt) * v, lam * np.sqrt(w) * d])
    x, *_ = np.linalg.lstsq(A, b, rcond=None)
    return x


@pytest.mark.parametrize(("name", "solver"), CASES)
def test_weighted_steps_equal_closed_forms(name: str, solver: str) -> None:
    robot, q, twist = _setup(name, seed=len(name))
    rng = np.random.default_rng(7)
    J6 = robot.jacobian(q)
    rows = _independent_rows(J6, robot.dof)
    jw = rng.uniform(0.3, 3.0, robot.dof)
    v = twist * DT
    # Least norm: zero weights free the other rows; positive ones do not matter.
    weights = np.zeros(6)
    weights[rows] = rng.uniform(0.5, 2.0, len(rows))
    dq = optik.diff_ik(robot, q, twist, dt=DT, solver=solver, weights=weights, joint_weights=jw)
    ref = _least_norm(J6[rows], v[rows], jw, np.zeros(robot.dof))
    assert _rel(dq, ref) <= 1e-8
    # Least squares over all six rows, some of them weighted zero.
    wt = rng.uniform(0.2, 5.0, 6)
    wt[rng.integers(0, 6)] = 0.0
    lam = 0.05
    dq = optik.diff_ik(
        robot, q, twist, dt=DT, solver=solver, objective="least_squares", damping=lam,
        weights=wt, joint_weights=jw,
    )  # fmt: skip
    ref = _least_squares(J6, v, wt, jw, lam, np.zeros(robot.dof))
    assert _rel(dq, ref) <= 1e-8


@pytest.mark.parametrize(("name", "solver"), CASES)
def test_posture_keeps_task_and_nears_reference(name: str, solver: str) -> None:
    robot, q, twist = _setup(name, seed=3 * len(name))
    rng = np.random.default_rng(11)
    J6 = robot.jacobian(q)
    # Leave a null space: at most dof - 1 task rows (all six for a 7-dof arm).
    rows = _independent_rows(J6, min(6, robot.dof - 1))
    jw = rng.uniform(0.5, 2.0, robot.dof)
    q_ref = robot.lower + (robot.upper - robot.lower) * rng.uniform(0.3, 0.7, robot.dof)
    gain = 0.2
    v = (twist * DT)[rows]
    J = J6[rows]
    common = {"dt": DT, "solver": solver, "rows": tuple(rows), "joint_weights": jw}
    dq = optik.diff_ik(robot, q, twist, posture=q_ref, posture_gain=gain, **common)
    dq0 = optik.diff_ik(robot, q, twist, **common)
    assert np.max(np.abs(J @ dq - v)) <= 1e-10
    d = gain * (q_ref - q)
    assert _rel(dq, _least_norm(J, v, jw, d)) <= 1e-8

    def dist(step: np.ndarray) -> float:
        e = q + step - q_ref
        return float(e @ (jw * e))

    assert dist(dq) < dist(dq0)
    # Least squares with the posture term: its own closed form.
    lam = 0.1
    dq = optik.diff_ik(
        robot, q, twist, objective="least_squares", damping=lam, posture=q_ref,
        posture_gain=gain, **common,
    )  # fmt: skip
    ref = _least_squares(J, v, np.ones(len(rows)), jw, lam, d)
    assert _rel(dq, ref) <= 1e-8


def test_positive_weights_leave_least_norm_unchanged() -> None:
    robot, q, twist = _setup("panda", seed=1)
    plain = optik.diff_ik(robot, q, twist, dt=DT, solver="qp:daqp")
    weighted = optik.diff_ik(
        robot, q, twist, dt=DT, solver="qp:daqp", weights=[5.0, 0.1, 1.0, 2.0, 3.0, 0.5]
    )
    assert _rel(weighted, plain) <= 1e-9
    # Consistent rows and weights: zeros outside rows are accepted.
    position = optik.diff_ik(robot, q, twist, dt=DT, solver="qp:daqp", rows=(0, 1, 2))
    both = optik.diff_ik(
        robot, q, twist, dt=DT, solver="qp:daqp", rows=(0, 1, 2), weights=[1, 1, 1, 0, 0, 0]
    )
    assert _rel(both, position) <= 1e-9


def test_posture_with_active_bounds_is_verified() -> None:
    """Near a limit the posture pull is clipped by the bound; the answer still holds J dq = v."""
    robot = ROBOTS["panda"]
    q = 0.5 * (robot.lower + robot.upper)
    q[0] = robot.upper[0] - 1e-4
    q_ref = q.copy()
    q_ref[0] = robot.upper[0] + 1.0  # pulls joint 0 beyond its limit
    twist = np.array([0.01, 0.0, 0.0, 0.0, 0.0, 0.0])
    dq = optik.diff_ik(robot, q, twist, dt=DT, solver="qp:proxqp", posture=q_ref, posture_gain=1.0)
    assert q[0] + dq[0] <= robot.upper[0] + 1e-12
    J = robot.jacobian(q)
    assert np.max(np.abs(J @ dq - twist * DT)) <= 1e-10


BAD = [
    ({"weights": [1, 1, 1, 1, 1]}, "weights"),
    ({"weights": [1, 1, np.nan, 1, 1, 1]}, "weights"),
    ({"weights": [1, 1, -1, 1, 1, 1]}, "weights"),
    ({"weights": [0, 0, 0, 0, 0, 0]}, "weights"),
    ({"weights": [1, 1, 1, 1, 0, 0], "rows": (0, 1, 2)}, "weights"),
    ({"joint_weights": np.ones(6)}, "joint_weights"),
    ({"joint_weights": [1, 1, 0, 1, 1, 1, 1]}, "joint_weights"),
    ({"joint_weights": [1, 1, -2, 1, 1, 1, 1]}, "joint_weights"),
    ({"joint_weights": [1, 1, np.nan, 1, 1, 1, 1]}, "joint_weights"),
    ({"joint_weights": [1, 1, 1e300, 1, 1, 1, 1]}, r"joint_weights must lie within"),
    ({"joint_weights": [1, 1, 1e-300, 1, 1, 1, 1]}, r"joint_weights must lie within"),
    ({"posture": np.zeros(6)}, "posture"),
    ({"posture": np.full(7, 1e200)}, "posture"),
    ({"posture": [0, 0, np.nan, 0, 0, 0, 0]}, "posture"),
    ({"posture": [0, 0, np.inf, 0, 0, 0, 0]}, "posture"),
    ({"posture": np.zeros(7), "posture_gain": 0.0}, "posture_gain"),
    ({"posture": np.zeros(7), "posture_gain": 1.5}, "posture_gain"),
    ({"posture": np.zeros(7), "posture_gain": np.nan}, "posture_gain"),
    ({"posture_gain": 2.0}, "posture_gain"),
]


@pytest.mark.parametrize(("kwargs", "name"), BAD)
def test_bad_task_keywords_raise(kwargs: dict[str, object], name: str) -> None:
    robot, q, twist = _setup("panda", seed=2)
    with pytest.raises(OptikError, match=name):
        optik.diff_ik(robot, q, twist, dt=DT, solver="qp:daqp", **kwargs)  # type: ignore[arg-type]


def test_joint_weights_far_apart_within_their_range_are_taken() -> None:
    """Joint weights up to 1e100 apart are accepted (their squares stay finite): the
    step is the weighted least-norm one, the heavy joint all but still."""
    robot, q, twist = _setup("panda", seed=2)
    weights = np.ones(7)
    weights[2] = 1e100
    dq = optik.diff_ik(robot, q, twist, dt=DT, solver="qp:daqp", joint_weights=weights)
    assert abs(dq[2]) < 1e-12
    np.testing.assert_allclose(robot.jacobian(q) @ dq, twist * DT, atol=1e-9)


@pytest.mark.parametrize("solver", STEP_BACKENDS)
@pytest.mark.parametrize(
    "weights", [[1e12, 1, 1, 1, 1, 1], [1, 1, 1, 1e-8, 1e-8, 1e-8], [1, 3, 1, 0.5, 2, 1]]
)
@pytest.mark.parametrize("vmax", [None, 0.3])
def test_weighted_least_squares_step_is_the_bounded_optimum(
    solver: str, weights: list[float], vmax: float | None
) -> None:
    """The least-squares step against scipy's bounded least squares (``lsq_linear`` on the
    stacked square-root rows), with and without velocity bounds that bind. One weight
    1e12 times the others put every backend 1e-3 to 3 rad off the optimum (the QP's
    Hessian squares the rows' condition number) and the KKT test, relative to the
    weights, passed it; each step is now solved again on its active set in square-root
    form."""
    from scipy.optimize import lsq_linear

    from optik.programs.diff_qp import DEFAULT_DAMPING

    panda = ROBOTS["panda"]
    q = panda.mid_limits + 0.2
    twist = np.array([0.5, -0.2, 0.3, 1.0, 0.0, -1.0])
    dt = 0.1
    v = twist * dt
    J = panda.jacobian(q)
    w = np.sqrt(np.array(weights))
    A = np.vstack([w[:, None] * J, DEFAULT_DAMPING * np.eye(7)])
    b = np.concatenate([w * v, np.zeros(7)])
    lower = panda.lower - q
    upper = panda.upper - q
    if vmax is not None:
        lower = np.maximum(lower, -vmax * dt)
        upper = np.minimum(upper, vmax * dt)
    reference = lsq_linear(A, b, bounds=(lower, upper), method="bvls", tol=1e-15).x
    if vmax is not None:  # the bounds bind: the unbounded optimum lies outside them
        free, *_ = np.linalg.lstsq(A, b, rcond=None)
        assert np.any(free < lower) or np.any(free > upper)
    velocity = None if vmax is None else np.full(7, vmax)
    try:
        dq = optik.diff_ik(
            panda, q, twist, dt=dt, solver=solver, objective="least_squares", weights=weights,
            velocity_limits=velocity,
        )  # fmt: skip
    except SolverError as exc:
        # A backend may fail the 1e12 weight outright (CasADi's daqp and qrqp with bounds
        # binding): an error that says so, never a step off the optimum.
        assert weights[0] == 1e12 and vmax is not None, exc
        assert "failed" in str(exc), exc
        return
    assert np.max(np.abs(dq - reference)) <= 1e-8 * max(1.0, float(np.max(np.abs(reference))))
