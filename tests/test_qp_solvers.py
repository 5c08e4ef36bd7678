"""The qpsolvers backends on the step programs, and the ``qp:<backend>`` IK solvers.

Every installed backend, every robot in problems/: with the limits inactive the answers
equal the closed forms (optik.linalg and numpy.linalg.pinv) to 1e-8; with limits active
the bounds hold and the KKT conditions hold with multipliers computed here from the active
set. The helpers (tests/_step_programs.py) are shared with tests/test_casadi.py.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pytest
import qpsolvers
from _step_programs import (
    KKT_ROBOTS,
    check_active,
    check_dobot_least_squares,
    check_least_norm,
    check_least_squares,
    inactive_cases,
    least_norm_program,
    reach,
)
from conftest import PROBLEM_NAMES, robot_of

from optik.errors import UnknownSolverError
from optik.programs.diff_qp import DiffIKProgram, QPSolution, build_program
from optik.solvers._base import (
    IKQuery,
    available_solvers,
    budget_now,
    get_solver,
    registered_solvers,
)
from optik.solvers.qp import (
    BACKEND_OPTIONS,
    QPStepSolver,
    installed_backends,
    qpsolvers_backends,
    solve_program,
)
from optik.solvers.qp_direct import DirectBackend, direct_backend

BACKENDS = installed_backends()


def qp_solve(backend: str) -> Callable[[DiffIKProgram], QPSolution]:
    return lambda prog: solve_program(prog, backend)


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("name", PROBLEM_NAMES)
def test_least_norm_matches_closed_form(name: str, backend: str) -> None:
    for case in inactive_cases(name):
        check_least_norm(qp_solve(backend), case)


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("name", PROBLEM_NAMES)
def test_least_squares_matches_closed_form(name: str, backend: str) -> None:
    for case in inactive_cases(name):
        check_least_squares(qp_solve(backend), case)


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("objective", ["least_norm", "least_squares"])
@pytest.mark.parametrize("name", KKT_ROBOTS)
def test_active_limits_kkt(name: str, objective: str, backend: str) -> None:
    check_active(qp_solve(backend), name, objective)


@pytest.mark.parametrize("backend", BACKENDS)
def test_dobot_least_squares_steps_match_closed_form(backend: str) -> None:
    # 4 joints, 6-D twists: Clarabel once stopped 1.3e-8 from the closed form here.
    check_dobot_least_squares(qp_solve(backend), 60)


def test_at_least_osqp_and_proxqp_installed() -> None:
    assert {"osqp", "proxqp"} <= set(BACKENDS)


# ---------------------------------------------------------------------- failures stay reports
def test_backend_exception_becomes_a_report() -> None:
    case = inactive_cases("puma560", 1)[0]
    prog = least_norm_program(case)
    result = solve_program(prog, "proxqp", options={"backend": "no-such-backend"})
    assert not result.found and result.x is None
    assert "no-such-backend" in result.status


def test_infeasible_program_is_reported_not_raised() -> None:
    robot = robot_of("puma560")
    q = robot.mid_limits + 0.3
    prog = build_program(robot, q, 1.0 * robot.jacobian(q)[:, 0])  # 1 rad of joint 0...
    blocked = build_program(robot, q, prog.v, velocity_limits=np.zeros(6), dt=1.0)  # ...frozen
    for backend in BACKENDS:
        result = solve_program(blocked, backend)
        ok = result.x is not None and np.max(np.abs(blocked.task_residual(result.x))) < 1e-6
        assert not (result.found and ok), backend


@pytest.mark.parametrize("backend", BACKENDS)
def test_variables_fixed_by_their_bounds_keep_their_value(backend: str) -> None:
    # lb == ub away from 0 (a zero-width box): the answer against the KKT system of the
    # same program with each fixed variable written as an equality row instead.
    rng = np.random.default_rng(5)
    n, m = 6, 2
    M = rng.normal(size=(n, n))
    P = M @ M.T + np.eye(n)
    c, A, b = rng.normal(size=n), rng.normal(size=(m, n)), rng.normal(size=m)
    lb, ub = np.full(n, -50.0), np.full(n, 50.0)
    fixed = np.array([1, 4])
    lb[fixed] = ub[fixed] = [0.3, -0.2]
    rows = np.vstack([A, np.eye(n)[fixed]])
    kkt = np.block([[P, rows.T], [rows, np.zeros((len(rows), len(rows)))]])
    expected = np.linalg.solve(kkt, np.concatenate([-c, b, lb[fixed]]))[:n]
    assert np.all(np.abs(expected) < 40.0)  # the other bounds inactive
    solver = direct_backend(backend, n, m)
    x, _, status, _ = solver.solve(P, c, A, b, lb, ub)
    assert x is not None, (backend, status)
    assert np.allclose(x, expected, rtol=1e-7, atol=1e-8), (backend, x - expected)
    if type(solver) is DirectBackend:  # through qpsolvers: substituted out, so exact
        assert np.all(x[fixed] == lb[fixed])


@pytest.mark.parametrize("backend", BACKENDS)
def test_every_variable_fixed_by_its_bounds_is_the_box_itself(backend: str) -> None:
    n = 3
    box = np.array([0.1, -0.2, 0.0])
    solver = direct_backend(backend, n, 0)
    x, found, _, _ = solver.solve(
        np.eye(n), np.ones(n), np.zeros((0, n)), np.zeros(0), box, box.copy()
    )
    assert found and x is not None
    if type(solver) is DirectBackend:  # through qpsolvers: substituted out, so exact
        assert np.array_equal(x, box)
    else:  # the backend's own API, to its tolerance
        assert np.allclose(x, box, rtol=0.0, atol=1e-9), (backend, x - box)


# ---------------------------------------------------------------------- the registry
def test_every_qpsolvers_backend_is_registered() -> None:
    names = set(registered_solvers())
    assert {f"qp:{b}" for b in qpsolvers_backends()} <= names
    assert set(qpsolvers.available_solvers) <= set(qpsolvers_backends())
    installed = set(available_solvers())
    assert {f"qp:{b}" for b in BACKENDS} <= installed
    missing = [b for b in qpsolvers_backends() if b not in BACKENDS]
    assert not {f"qp:{b}" for b in missing} & installed


def test_uninstalled_backend_gives_install_hint(monkeypatch: pytest.MonkeyPatch) -> None:
    # Availability is read from qpsolvers at call time: hide one installed backend so the
    # test runs whatever this machine has installed.
    hidden = "quadprog"
    monkeypatch.setattr(
        qpsolvers, "available_solvers", [b for b in qpsolvers.available_solvers if b != hidden]
    )
    with pytest.raises(UnknownSolverError) as info:
        get_solver(f"qp:{hidden}")
    assert f"qpsolvers[{hidden}]" in str(info.value)
    assert "qp:proxqp" in info.value.available
    assert f"qp:{hidden}" not in available_solvers()


def test_backend_options_are_known_backends() -> None:
    assert set(BACKEND_OPTIONS) <= set(qpsolvers_backends())


# ---------------------------------------------------------------------- qp:<backend> IK
@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize(
    ("name", "mode"), [("puma560", "pose"), ("panda", "pose"), ("ur5", "position")]
)
def test_qp_solver_reaches_targets(backend: str, name: str, mode: str) -> None:
    reach(f"qp:{backend}", name, mode, count=3)


def test_qp_solver_stops_at_max_iter_and_deadline() -> None:
    robot = robot_of("puma560")
    solver = get_solver("qp:proxqp")
    assert isinstance(solver, QPStepSolver)
    T = robot.fk(robot.mid_limits + 0.5)
    query = IKQuery(robot, T, "pose", 1e-6)
    # Deadlines are on the budget clock (compilation not counted).
    out = solver.solve(query, robot.mid_limits, 1, budget_now() + 30)
    assert out.iterations == 1 and not out.converged and out.message == "max_iter"
    out = solver.solve(query, robot.mid_limits, 100, budget_now() - 1.0)
    assert out.iterations == 0 and out.message == "timeout"


def test_a_stalled_proxqp_step_is_capped(monkeypatch: pytest.MonkeyPatch) -> None:
    # A kilometre UR5 stretched: one ProxQP step used to run 15 million iterations (its
    # default inner loop of 1,500 under 10,000 outer ones), 30-60 s past any timeout_s.
    from dataclasses import replace

    import optik
    from optik.solvers import qp_direct

    iterations: list[int] = []
    solve = qp_direct._Proxqp._solve

    def counted(self: qp_direct._Proxqp, qp: object, warm: bool) -> qp_direct.DirectAnswer:
        answer = solve(self, qp, warm)  # type: ignore[arg-type]
        iterations.append(int(self._qp.results.info.iter))
        return answer

    monkeypatch.setattr(qp_direct._Proxqp, "_solve", counted)
    # The search in metres from the start where this step stalled (the seed table's
    # third start then; the balanced search of a kilometre arm, and the table ranked in
    # its size, no longer meet it): the cap is the backend's, whatever the search.
    monkeypatch.setattr(QPStepSolver, "balanced", False)
    base = robot_of("ur5")
    robot = optik.Robot.from_dh([replace(r, a=r.a * 1e3, d=r.d * 1e3) for r in base.dh])
    q = np.array([-5.03394836, -0.62097304, -6.42976063e-09, 1.51138766, 0.0504474737, 5.49581603])
    stalling = np.array([1.35049037, 5.37033694, -5.34863878, 1.10188208, 5.29667167, 6.21427729])
    result = optik.solve_ik(
        robot, robot.fk(q), solver="qp:proxqp", warm_start="q0", q0=stalling, restarts=0,
        max_iter=40,
    )  # fmt: skip
    cap = qp_direct.BACKEND_OPTIONS["proxqp"]["max_iter"] * qp_direct.PROXQP_MAX_ITER_IN
    # It stalls: about 90,000 iterations in one step (15 million before the cap).
    assert iterations and 10_000 < max(iterations) <= cap == 100_000
    if result.success:  # whatever the outcome, an honest one
        np.testing.assert_allclose(robot.fk(result.q), robot.fk(q), atol=1e-6)
