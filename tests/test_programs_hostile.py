"""Edge cases of the step programs: far postures, tiny tasks, bad arguments, messages.

Every answer is checked against an independent reference (numpy ``pinv``/``lstsq``,
``scipy.linalg.null_space``, ``scipy.optimize.lsq_linear``), never against optik itself.
"""

from __future__ import annotations

import math
import warnings
from typing import Any

import numpy as np
import pytest
from scipy.linalg import null_space
from scipy.optimize import lsq_linear

import optik
from optik.diffik import diff_ik, polish_least_norm, polish_least_squares
from optik.errors import JointLimitError, OptikError
from optik.programs.diff_qp import build_program, build_qp, equilibration_scale
from optik.solvers import available_solvers

TWIST = np.array([0.1, 0.0, 0.05, 0.0, 0.2, 0.0])  # m/s, rad/s


@pytest.fixture(scope="module")
def panda() -> optik.Robot:
    return optik.load_problem("panda").robot


def _step_solvers(*names: str) -> list[str]:
    installed = set(available_solvers(kind="step"))
    return [name for name in names if name in installed]


def _reference_least_norm(J: np.ndarray, v: np.ndarray, d: np.ndarray) -> np.ndarray:
    """``d + pinv(J) (v - J d)``: the least-norm step with offset, bounds inactive."""
    return d + np.linalg.pinv(J) @ (v - J @ d)


# ---------------------------------------------------------------- F1: far posture
@pytest.mark.parametrize("solver", _step_solvers("qp:proxqp", "qp:osqp", "casadi:qrqp"))
def test_far_posture_keeps_the_task_exact(panda: optik.Robot, solver: str) -> None:
    """A posture 1e8 away must not loosen ``J dq = v`` (the step missed it by 100 %)."""
    q = panda.mid_limits
    dq = diff_ik(panda, q, TWIST, dt=0.01, posture=np.full(7, 1e8), solver=solver)
    J, v = panda.jacobian(q), TWIST * 0.01
    assert np.abs(J @ dq - v).max() <= 1e-7 * np.abs(v).max()
    # The optimum moves along the one null-space direction n of J from pinv(J) v as far
    # as the cost asks, inside the bounds: t = n . (d - dq0), clipped to the box.
    n = null_space(J)[:, 0]
    dq0 = np.linalg.pinv(J) @ v
    d = 0.1 * (np.full(7, 1e8) - q)
    moving = np.abs(n) > 1e-12
    ends = np.stack([(panda.lower - q - dq0)[moving], (panda.upper - q - dq0)[moving]])
    ends = ends / n[moving]
    t = np.clip(n @ (d - dq0), ends.min(axis=0).max(), ends.max(axis=0).min())
    # n . d sums terms of 1e7: its rounding (1e-9) bounds the agreement.
    assert np.abs(dq - (dq0 + t * n)).max() <= 1e-8


@pytest.mark.parametrize(
    "solver", _step_solvers("qp:proxqp", "qp:osqp", "qp:clarabel", "casadi:qrqp")
)
def test_posture_with_a_slow_twist_meets_the_task(panda: optik.Robot, solver: str) -> None:
    """posture = upper limits, |v| = 2e-9: the task held to 1e-7 of |v|, not of |d|."""
    q = panda.mid_limits + 0.1
    twist = TWIST * 1e-7
    dq = diff_ik(panda, q, twist, dt=0.01, posture=panda.upper, solver=solver)
    J, v = panda.jacobian(q), twist * 0.01
    assert np.abs(J @ dq - v).max() <= 1e-7 * np.abs(v).max()
    ref = _reference_least_norm(J, v, 0.1 * (panda.upper - q))
    assert np.all(ref > panda.lower - q) and np.all(ref < panda.upper - q)  # bounds idle
    assert np.abs(dq - ref).max() <= 1e-9 * np.abs(ref).max()


def test_polish_least_norm_projects_onto_the_task(panda: optik.Robot) -> None:
    """A point off the task is moved onto the least-norm optimum (bounds idle)."""
    q = panda.mid_limits
    v = TWIST * 1e-3
    program = build_program(panda, q, v)
    pinv = np.linalg.pinv(panda.jacobian(q))
    ref = pinv @ v
    off = ref + pinv @ (1e-6 * np.arange(6))  # off the task, in the row space
    polished = polish_least_norm(program, off, 1e-12)
    assert polished is not None
    assert np.abs(polished - ref).max() <= 1e-12 * np.abs(ref).max()
    # resolve=True keeps only the active set: any point off in the null space too.
    resolved = polish_least_norm(program, ref + 1e-6 * np.arange(7), 1e-12, resolve=True)
    assert resolved is not None
    assert np.abs(resolved - ref).max() <= 1e-12 * np.abs(ref).max()


# ---------------------------------------------------------------- F7: subnormal task
def test_subnormal_task_gives_a_tiny_exact_step(panda: optik.Robot) -> None:
    """dt = 1e-309: a valid (subnormal) task, no warning, ``dq`` = pinv(J) v."""
    q = panda.mid_limits
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        dq = diff_ik(panda, q, TWIST, dt=1e-309)
    v = TWIST * 1e-309
    J = panda.jacobian(q)
    # pinv(J) v computed with v scaled up exactly by 2**1030, then back.
    ref = np.ldexp(np.linalg.pinv(J) @ np.ldexp(v, 1030), -1030)
    assert np.all(np.isfinite(dq)) and np.abs(dq).max() < 1e-300
    assert np.abs(dq - ref).max() <= 1e-6 * np.abs(ref).max()


@pytest.mark.parametrize("dt", [1e-312, 1e-315, 1e-318, 1e-320])
def test_a_deeper_subnormal_task_is_met_to_the_subnormal_grid(dt: float) -> None:
    # Below 1e-312 the task's relative tolerance underflowed to 0 and every backend's
    # step was refused ("|J dq - v| = 1e-317 > 0"); rounding there is absolute.
    ur5 = optik.load_problem("ur5").robot
    q = ur5.mid_limits + 0.3
    twist = np.array([0.01, 0.0, 0.0, 0.0, 0.0, 0.0])
    dq = diff_ik(ur5, q, twist, dt=dt)
    ref = np.ldexp(np.linalg.pinv(ur5.jacobian(q)) @ np.ldexp(twist * dt, 1060), -1060)
    assert np.abs(dq - ref).max() <= 1e-6 * np.abs(ref).max() + 16 * 2.0**-1074


@pytest.mark.parametrize("size", [1e-309, 5e-324, 1e-3, 3.0, 1e9])
def test_equilibration_scale_stays_finite(size: float) -> None:
    """1 / size where that is at most 2**1000; the cap (not inf) below."""
    s = equilibration_scale(size)
    assert math.isfinite(s) and 0.0 < s <= 2.0**1000
    if size >= 2.0**-1000:
        assert s == 1.0 / size
    else:
        assert s == 2.0**1000


# ---------------------------------------------------------------- F6: held on the bound
def test_polish_least_squares_holds_an_active_joint_on_its_bound(panda: optik.Robot) -> None:
    """A joint left 9.2e-8 short of its bound is held on the bound, as BVLS puts it."""
    q = panda.mid_limits.copy()
    q[3] = panda.upper[3] - 1e-3
    J = panda.jacobian(q)
    twist = J[:, 3] * 0.5  # pushes joint 3 out through its upper limit
    program = build_program(panda, q, twist * 0.05, objective="least_squares")
    A = np.vstack([J, 1e-3 * np.eye(7)])
    b = np.concatenate([twist * 0.05, np.zeros(7)])
    ref = lsq_linear(A, b, bounds=(program.lower, program.upper), method="bvls", tol=1e-15).x
    assert ref[3] == program.upper[3]  # the case binds
    short = ref.copy()
    short[3] -= 9.2e-8
    active = np.zeros(7, dtype=bool)
    active[3] = True
    held = polish_least_squares(program, short, active)
    assert held is not None and held[3] == program.upper[3]
    assert np.abs(held - ref).max() <= 1e-12


# ---------------------------------------------------------------- F8, F9: bad arguments
@pytest.mark.parametrize("max_iter", ["abc", None, math.nan, math.inf, 0, 2.5, True])
def test_nlp_backend_rejects_a_bad_max_iter(panda: optik.Robot, max_iter: Any) -> None:
    from optik.solvers.casadi_nlp import nlp_backend

    with pytest.raises(OptikError, match="max_iter"):
        nlp_backend(panda, max_iter=max_iter)


@pytest.mark.parametrize("options", [{1: 2}, [1, 2], "print_time"])
def test_nlp_backend_rejects_bad_options(panda: optik.Robot, options: Any) -> None:
    from optik.solvers.casadi_nlp import nlp_backend

    with pytest.raises(OptikError, match="options"):
        nlp_backend(panda, options=options)


@pytest.fixture(scope="module")
def nlp(panda: optik.Robot) -> Any:
    from optik.solvers.casadi_nlp import nlp_backend

    return nlp_backend(panda)


@pytest.mark.parametrize(
    "bounds", [5, (["a"] * 7, ["b"] * 7), "ab", ([0.0] * 7,), ([0.0] * 7, [1.0] * 7, [2.0] * 7)]
)
def test_nlp_solve_rejects_bad_bounds(panda: optik.Robot, nlp: Any, bounds: Any) -> None:
    target = panda.fk(panda.mid_limits)
    with pytest.raises(OptikError, match="bounds"):
        nlp.solve(target, panda.mid_limits, bounds=bounds)


@pytest.mark.parametrize("mu", ["1", b"1", True, None, [1.0]])
def test_nlp_solve_rejects_a_mu_that_is_not_a_number(panda: optik.Robot, nlp: Any, mu: Any) -> None:
    with pytest.raises(OptikError, match="mu"):
        nlp.solve(panda.fk(panda.mid_limits), panda.mid_limits, mu=mu)


def test_huge_weight_matrix_is_an_optik_error(panda: optik.Robot) -> None:
    """1e308 everywhere: rank one, not positive definite; no LinAlgError, no warning."""
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(OptikError, match="W"):
            build_qp(panda, panda.mid_limits, TWIST * 0.01, W=np.full((7, 7), 1e308))
        # A huge definite one is accepted: its eigenvalues are 1e308 (numpy agrees).
        W = np.eye(7) * 1e308
        assert np.linalg.eigvalsh(W / 1e308)[0] > 0.0
        assert build_qp(panda, panda.mid_limits, TWIST * 0.01, W=W).P[0, 0] == 1e308


def test_build_conic_rejects_a_non_program() -> None:
    from optik.programs.casadi_qp import build_conic

    with pytest.raises(OptikError, match="program"):
        build_conic(None, "qrqp")  # type: ignore[arg-type]


@pytest.mark.parametrize("dq", [np.ones(3), np.full(7, np.nan), np.full(7, np.inf), "x"])
def test_kkt_rejects_a_bad_point(panda: optik.Robot, dq: Any) -> None:
    program = build_program(panda, panda.mid_limits, TWIST * 0.01)
    with pytest.raises(OptikError, match="dq"):
        program.kkt(dq)


@pytest.mark.parametrize("limits", ["no", None, 1, "False"])
def test_build_qp_checks_limits_as_diff_ik_does(panda: optik.Robot, limits: Any) -> None:
    for call in (
        lambda: build_qp(panda, panda.mid_limits, TWIST * 0.01, limits=limits),
        lambda: diff_ik(panda, panda.mid_limits, TWIST, dt=0.01, limits=limits),
    ):
        with pytest.raises(OptikError, match="limits"):
            call()


# ---------------------------------------------------------------- F11: the message
def test_joint_limit_message_shows_the_violation(panda: optik.Robot) -> None:
    """q = upper + 2e-6 must not print as a value equal to the limit."""
    q = panda.mid_limits.copy()
    q[0] = panda.upper[0] + 2e-6
    with pytest.raises(JointLimitError) as info:
        diff_ik(panda, q, TWIST, dt=0.01)
    text = str(info.value)
    value, upper = text.split("value ")[1].split(" outside its limits [")
    assert float(value) == q[0]
    assert float(upper.split(", ")[1].split("]")[0]) == panda.upper[0]
    assert float(value) > float(upper.split(", ")[1].split("]")[0])
    assert " by 2e-06" in text
