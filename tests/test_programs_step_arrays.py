"""The step programs in preallocated arrays: filled like build_program, checked like the proof.

:class:`optik.programs.step_arrays.StepArrays` must hold the very program
:func:`optik.programs.diff_qp.build_program` builds (matrices, bounds, equilibration), for
every robot, objective, row set and bound option; its cheap check must accept the
closed-form and KKT answers and reject what the full proof rejects; the direct backends
must give the closed forms warm or cold; the polish must return the exact minimizer.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from _step_programs import active_case, inactive_cases, least_norm_program, well_conditioned_q
from conftest import PROBLEM_NAMES, SEED, assert_close, robot_of

import optik
from optik.diffik import FEASIBILITY_ATOL, FEASIBILITY_RTOL, KKT_RTOL, verify_step
from optik.linalg import least_squares, min_norm
from optik.programs import step_arrays as sa
from optik.programs.diff_qp import (
    ALL_ROWS,
    DEFAULT_DAMPING,
    POSITION_ROWS,
    QPSolution,
    build_program,
)
from optik.solvers.qp import direct_backend, installed_backends, polish

TWIST = np.array([0.05, -0.02, 0.03, 0.1, -0.2, 0.05])
DT = 0.01


def _arrays(robot: optik.Robot, rows: tuple[int, ...], objective: str) -> sa.StepArrays:
    return sa.StepArrays(robot, rows, objective)  # type: ignore[arg-type]


def _check(arrays: sa.StepArrays, dq: np.ndarray) -> tuple[int, float, int]:
    return arrays.check(dq * arrays.scale[1], FEASIBILITY_RTOL, FEASIBILITY_ATOL, KKT_RTOL)


@pytest.mark.parametrize("name", PROBLEM_NAMES)
@pytest.mark.parametrize("objective", ["least_norm", "least_squares"])
@pytest.mark.parametrize(
    "options",
    [{}, {"limit_gain": 0.5}, {"velocity_limits": "half"}, {"limits": False}],
)
def test_fill_equals_build_program(name: str, objective: str, options: dict[str, Any]) -> None:
    robot = robot_of(name)
    rng = np.random.default_rng(SEED)
    rows = POSITION_ROWS if robot.dof < 6 else ALL_ROWS
    damping = 0.02 if objective == "least_squares" else None
    kwargs = dict(options)
    if kwargs.get("velocity_limits") == "half":
        kwargs["velocity_limits"] = np.full(robot.dof, 0.5)
    for _ in range(3):
        q = robot.mid_limits + 0.3 * rng.normal(size=robot.dof)
        q = np.clip(q, robot.lower, robot.upper)
        twist = rng.normal(size=6)
        prog = build_program(
            robot, q, twist * DT, objective=objective, dt=DT, damping=damping, rows=rows, **kwargs
        )
        arrays = _arrays(robot, rows, objective)
        code = arrays.fill(
            q,
            twist,
            DT,
            limits=kwargs.get("limits", True),
            limit_gain=kwargs.get("limit_gain", 1.0),
            velocity_limits=kwargs.get("velocity_limits"),
            damping=0.0 if damping is None else damping,
        )
        assert code == sa.FILL_OK
        assert_close(arrays.J, prog.J, atol=1e-15, what="J")
        assert_close(arrays.v, prog.v, atol=1e-17, what="v")
        assert np.array_equal(arrays.lb, prog.lower) and np.array_equal(arrays.ub, prog.upper)
        assert_close(arrays.P, prog.P, atol=1e-14, what="P")
        assert_close(arrays.c, prog.c, atol=1e-17, what="c")
        eq = prog.equilibrated()
        assert_close(arrays.Ps, eq.P, atol=1e-14, what="scaled P")
        assert_close(arrays.cs, eq.c, atol=1e-14, what="scaled c")
        assert arrays.scale[1] == eq.scale
        if objective == "least_norm":
            assert eq.b is not None
            assert_close(arrays.bs, eq.b, atol=1e-15, what="scaled b")
            n, m = robot.dof, len(rows)
            assert np.array_equal(arrays.lower_stack[n:], arrays.bs)
            assert np.array_equal(arrays.upper_stack[: n + m][n:], arrays.bs)
        lbs = np.full(robot.dof, -np.inf) if eq.lb is None else eq.lb
        assert np.array_equal(arrays.lbs, lbs)
        again = arrays.program()
        assert_close(again.P, prog.P, atol=1e-14, what="program() P")
        assert (again.qp.lb is None) == (prog.qp.lb is None)


def test_fill_reports_bad_input_by_code() -> None:
    robot = robot_of("puma560")
    arrays = _arrays(robot, (0, 1, 2, 3, 4, 5), "least_norm")
    q = robot.mid_limits.copy()
    bad_q = q.copy()
    bad_q[2] = np.nan
    assert arrays.fill(bad_q, TWIST, DT) == sa.FILL_BAD_Q
    outside = q.copy()
    outside[0] = robot.upper[0] + 1e-3
    assert arrays.fill(outside, TWIST, DT) == sa.FILL_Q_OUTSIDE
    assert arrays.fill(outside, TWIST, DT, limits=False) == sa.FILL_OK
    hair = q.copy()
    hair[0] = robot.upper[0] + 1e-7  # within Q_CLIP_TOLERANCE: clipped onto the limit
    assert arrays.fill(hair, TWIST, DT) == sa.FILL_OK
    assert arrays.q[0] == robot.upper[0]
    assert arrays.fill(q, np.array([0, 0, np.inf, 0, 0, 0.0]), DT) == sa.FILL_BAD_TWIST
    assert arrays.fill(q, np.full(6, 1e8), 100.0) == sa.FILL_STEP_TOO_LONG
    blocked = q.copy()
    blocked[0] = robot.upper[0]
    code = arrays.fill(blocked, TWIST, DT, velocity_limits=np.zeros(6), limit_gain=0.5)
    assert code == sa.FILL_OK  # zero speed: lb = ub = 0 is consistent
    assert arrays.fill(q, TWIST, DT, velocity_limits=np.full(6, -1.0)) == sa.FILL_INCONSISTENT


@pytest.mark.parametrize("name", ["puma560", "panda", "ur5", "dobot_magician"])
def test_cheap_check_accepts_closed_forms(name: str) -> None:
    for case in inactive_cases(name):
        prog = least_norm_program(case)
        arrays = _arrays(case.robot, prog.rows, "least_norm")
        assert arrays.fill(case.q, case.v6, 1.0) == sa.FILL_OK
        assert _check(arrays, min_norm(prog.J, prog.v))[0] == sa.CHECK_OK
        ls = _arrays(case.robot, ALL_ROWS, "least_squares")
        assert ls.fill(case.q, case.v6, 1.0, damping=DEFAULT_DAMPING) == sa.FILL_OK
        answer = least_squares(ls.J, ls.v, damping=DEFAULT_DAMPING)
        assert _check(ls, answer)[0] == sa.CHECK_OK


def test_cheap_check_rejects_what_the_proof_rejects() -> None:
    robot = robot_of("panda")
    q = robot.mid_limits + 0.2
    arrays = _arrays(robot, (0, 1, 2, 3, 4, 5), "least_norm")
    arrays.fill(q, TWIST, DT)
    prog = arrays.program()
    best = min_norm(prog.J, prog.v)
    null = np.linalg.svd(prog.J)[2][-1]
    not_minimal = best + 1e-3 * null  # feasible, J dq = v, but not the least norm
    code, value, _ = _check(arrays, not_minimal)
    assert code == sa.CHECK_KKT and value > 1e-5
    _, reason = verify_step(prog, QPSolution(not_minimal, True, "solved", "test"))
    assert "not optimal" in reason
    assert _check(arrays, best + 1e-6)[0] == sa.CHECK_TASK
    far = best.copy()
    far[0] = prog.upper[0] + 1e-3
    assert _check(arrays, far)[0] == sa.CHECK_BOUNDS
    assert _check(arrays, np.full(7, np.nan))[0] == sa.CHECK_NOT_FINITE


@pytest.mark.parametrize("objective", ["least_norm", "least_squares"])
@pytest.mark.parametrize("name", ["puma560", "panda", "ur5"])
def test_cheap_check_with_active_bounds_agrees_with_the_proof(name: str, objective: str) -> None:
    prog, k = active_case(name, objective)
    rows = prog.rows
    arrays = _arrays(robot_of(name), rows, objective)
    twist = np.zeros(6)
    twist[list(rows)] = prog.v
    arrays.fill(prog.q, twist, 1.0, damping=prog.damping)
    assert_close(arrays.P, prog.P, atol=1e-14, what="P")
    answer = direct_backend("daqp", prog.dof, 0 if objective == "least_squares" else len(rows))
    x, found, status, _ = answer.solve(
        arrays.Ps, arrays.cs, arrays.A_eq, arrays.b_eq, arrays.lbs, arrays.ubs
    )
    assert found and x is not None, status
    code, *_ = arrays.check(x, FEASIBILITY_RTOL, FEASIBILITY_ATOL, KKT_RTOL)
    assert code == sa.CHECK_OK
    assert abs(arrays.dq[k] - prog.upper[k]) <= 1e-12  # the bound is active
    dq, reason = verify_step(prog, QPSolution(arrays.dq.copy(), True, "", "qp:daqp"))
    assert reason == "" and dq is not None


@pytest.mark.parametrize("backend", installed_backends())
def test_direct_backends_warm_and_cold_give_the_closed_form(backend: str) -> None:
    robot = robot_of("ur5")
    rng = np.random.default_rng(SEED)
    for objective in ("least_norm", "least_squares"):
        arrays = _arrays(robot, (0, 1, 2, 3, 4, 5), objective)
        m = 0 if objective == "least_squares" else 6
        solver = direct_backend(backend, robot.dof, m)
        for warm in (False, True, True, False):
            q = well_conditioned_q(robot, None, rng)
            arrays.fill(q, TWIST, DT, damping=DEFAULT_DAMPING)
            x, found, status, _ = solver.solve(
                arrays.Ps, arrays.cs, arrays.A_eq, arrays.b_eq, arrays.lbs, arrays.ubs, warm
            )
            assert found and x is not None, status
            if objective == "least_norm":
                expected = min_norm(arrays.J, arrays.v)
            else:
                expected = least_squares(arrays.J, arrays.v, damping=DEFAULT_DAMPING)
            assert_close(x / arrays.scale[1], expected, atol=1e-9, what=f"{backend} {warm}")


def test_polish_returns_the_exact_minimizer_or_nothing() -> None:
    # min 1/2 |x - t|^2 s.t. x1 <= 0.5, x0 + x1 + x2 = 1: t = (1, 2, 0) -> (0.75, 0.5, -0.25)
    P = np.eye(3)
    c = -np.array([1.0, 2.0, 0.0])
    A = np.ones((1, 3))
    b = np.ones(1)
    lb = np.full(3, -np.inf)
    ub = np.array([np.inf, 0.5, np.inf])
    exact = np.array([0.75, 0.5, -0.25])
    near = exact + np.array([3e-9, -2e-9, 1e-9])
    polished = polish(P, c, A, b, lb, ub, near)
    assert polished is not None
    assert_close(polished, exact, atol=1e-15, what="polished")
    # A point far from the active bound frees it: the unconstrained answer violates it.
    assert polish(P, c, A, b, lb, ub, np.array([0.0, 0.0, 1.0])) is None


def test_diff_ik_full_proof_on_request_and_on_a_cheap_rejection(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    robot = robot_of("panda")
    q = robot.mid_limits + 0.2
    fast = optik.diff_ik(robot, q, TWIST, dt=DT, solver="qp:daqp")
    proved = optik.diff_ik(robot, q, TWIST, dt=DT, solver="qp:daqp", kkt_proof=True)
    expected = min_norm(robot.jacobian(q), TWIST * DT)
    assert_close(fast, expected, atol=1e-12, what="fast path")
    assert_close(proved, expected, atol=1e-12, what="proved")
    calls: list[str] = []
    original = verify_step

    def counting(program: Any, solution: Any) -> Any:
        calls.append(solution.backend)
        return original(program, solution)

    monkeypatch.setattr(optik.diffik, "verify_step", counting)
    optik.diff_ik(robot, q, TWIST, dt=DT, solver="qp:daqp")
    assert calls == []  # the cheap check accepted it
    optik.diff_ik(robot, q, TWIST, dt=DT, solver="qp:daqp", kkt_proof=True)
    assert calls == ["qp:daqp"]
    # A cheap check that rejects hands the answer to the full proof, which accepts it.
    monkeypatch.setattr(sa.StepArrays, "check", lambda self, *a: (sa.CHECK_KKT, 1.0, 0))
    again = optik.diff_ik(robot, q, TWIST, dt=DT, solver="qp:daqp")
    assert_close(again, expected, atol=1e-12, what="after the full proof")
    assert calls == ["qp:daqp", "qp:daqp"]
