"""The CasADi forms: conic (QP) step programs and the nonlinear IK program.

Conic plugins are checked like the qpsolvers backends (closed forms to 1e-8 with the limits
inactive, KKT with multipliers computed here when active). The NLP's symbolic FK must equal
``Robot.fk``; ipopt and sqpmethod must reach FK targets from nearby warm starts.
"""

from __future__ import annotations

import gc
import time
import weakref

import casadi
import numpy as np
import pytest
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
from conftest import PROBLEM_NAMES, SEED, assert_close, random_q, robot_of

from optik.errors import InvalidRotationError, OptikError, ShapeError, UnknownSolverError
from optik.model import DHJoint, Robot
from optik.programs import nlp as nlp_module
from optik.programs.casadi_qp import build_conic
from optik.programs.diff_qp import DiffIKProgram, QPSolution
from optik.programs.nlp import build_nlp, symbolic_fk
from optik.solvers import IKQuery, available_solvers, casadi_conic, casadi_nlp, get_solver
from optik.solvers.casadi_conic import (
    CONIC_OPTIONS,
    EXCLUDED_PLUGINS,
    casadi_conic_plugins,
    solve_conic,
)
from optik.solvers.casadi_nlp import nlp_backend
from optik.spatial import rotation_angle
from optik.task import make_task

PLUGINS = casadi_conic_plugins()


def conic(plugin: str):
    def solve(prog: DiffIKProgram) -> QPSolution:
        return solve_conic(prog, plugin)

    return solve


# ---------------------------------------------------------------------- conic plugins
def test_working_plugins_found() -> None:
    assert {"qrqp", "osqp"} <= set(PLUGINS)
    assert not set(PLUGINS) & set(EXCLUDED_PLUGINS)
    assert set(PLUGINS) <= set(CONIC_OPTIONS)
    assert casadi_conic_plugins() is PLUGINS  # probed once per process


@pytest.mark.parametrize("plugin", PLUGINS)
@pytest.mark.parametrize("name", PROBLEM_NAMES)
def test_conic_least_norm_matches_closed_form(name: str, plugin: str) -> None:
    for case in inactive_cases(name):
        check_least_norm(conic(plugin), case)


@pytest.mark.parametrize("plugin", PLUGINS)
@pytest.mark.parametrize("name", PROBLEM_NAMES)
def test_conic_least_squares_matches_closed_form(name: str, plugin: str) -> None:
    for case in inactive_cases(name):
        check_least_squares(conic(plugin), case)


@pytest.mark.parametrize("plugin", PLUGINS)
def test_conic_dobot_least_squares_steps_match_closed_form(plugin: str) -> None:
    check_dobot_least_squares(conic(plugin), 60)


@pytest.mark.parametrize("plugin", PLUGINS)
@pytest.mark.parametrize("objective", ["least_norm", "least_squares"])
@pytest.mark.parametrize("name", KKT_ROBOTS)
def test_conic_active_limits_kkt(name: str, objective: str, plugin: str) -> None:
    check_active(conic(plugin), name, objective)


def test_conic_program_is_inspectable_and_solver_reused() -> None:
    case = inactive_cases("puma560", 1)[0]
    prog = least_norm_program(case)
    first = build_conic(prog, "qrqp")
    eq = prog.equilibrated()
    assert_close(first.args["h"], eq.P)
    assert_close(first.args["a"], prog.J)
    assert_close(first.args["lba"], first.args["uba"])
    assert_close(first.args["lba"] / first.scale, prog.v, atol=1e-18)
    second = build_conic(least_norm_program(inactive_cases("puma560", 2)[1]), "qrqp")
    assert first.shape == second.shape == (6, 6)
    # One conic solver per (plugin, dof, rows), built by the backend, not the program.
    solver = casadi_conic._solver("qrqp", *first.shape)
    assert isinstance(solver, casadi.Function)
    assert casadi_conic._solver("qrqp", *second.shape) is solver


def test_unknown_conic_plugin() -> None:
    with pytest.raises(UnknownSolverError) as info:
        get_solver("casadi:no_such_plugin", kind="step")
    assert "casadi:qrqp" in str(info.value)


# ---------------------------------------------------------------------- symbolic FK
@pytest.mark.parametrize("name", PROBLEM_NAMES)
def test_symbolic_fk_equals_robot_fk(name: str) -> None:
    robot = robot_of(name)
    fk = symbolic_fk(robot)
    rng = np.random.default_rng(SEED)
    for q in random_q(robot, rng, 20):
        assert_close(np.asarray(fk(q)), robot.fk(q), atol=1e-12, what=f"{name} FK")


def test_symbolic_fk_with_mimic_coupling_and_tool() -> None:
    """A chain whose variables differ from q (a mimic joint) and with base and tool."""
    robot = Robot.from_dh(
        [
            {"a": 0.3, "alpha": 0.4, "d": 0.1, "name": "a", "role": "arm"},
            {"a": 0.2, "theta": 0.3, "name": "b", "mimic": {"joint": "a", "multiplier": -2.0}},
            {"d": 0.5, "type": "prismatic", "lower": 0.0, "upper": 1.0, "name": "c"},
        ],
        base=np.array([[0, -1, 0, 0.1], [1, 0, 0, 0.2], [0, 0, 1, 0.3], [0, 0, 0, 1.0]]),
        tool=np.array([[1, 0, 0, 0.05], [0, 0, -1, 0], [0, 1, 0, 0.1], [0, 0, 0, 1.0]]),
    )
    assert robot.dof == 2
    fk = symbolic_fk(robot)
    for q in np.random.default_rng(SEED).uniform([-2.0, 0.0], [2.0, 1.0], (10, 2)):
        assert_close(np.asarray(fk(q)), robot.fk(q), atol=1e-12)


# ---------------------------------------------------------------------- the NLP program
def test_nlp_is_inspectable() -> None:
    robot = robot_of("puma560")
    prog = build_nlp(robot, "pose")
    q = random_q(robot, np.random.default_rng(SEED))
    T = robot.fk(q)
    params = prog.parameter_vector(T, weights=[1, 1, 1, 2, 2, 2], mu=0.5, q_ref=q + 0.1)
    f = casadi.Function("f", [prog.q, prog.parameters], [prog.objective])
    # At the target's own q: only the regularisation remains, mu * |q - q_ref|^2.
    assert float(f(q, params)) == pytest.approx(0.5 * 6 * 0.01, rel=1e-12)
    # With unit weights the rotation rows give 3 - trace(R*^T R) = 2 (1 - cos(angle)).
    unit = prog.parameter_vector(T)
    m = casadi.Function("m", [prog.q, prog.parameters], [prog.orientation_measure])
    q2 = q + 0.05
    angle = rotation_angle(T[:3, :3].T @ robot.fk(q2)[:3, :3])
    assert float(m(q2, unit)) == pytest.approx(2.0 * (1.0 - np.cos(angle)), rel=1e-9)
    # Only the weights' ratios count (the task divides them by the largest): rotation
    # weights of 2 beside position weights of 1 keep the rotation rows' measure and
    # halve the position rows'.
    assert float(m(q2, params)) == pytest.approx(2.0 * (1.0 - np.cos(angle)), rel=1e-9)
    half = prog.parameter_vector(T, weights=[1, 1, 1, 0.5, 0.5, 0.5])
    assert float(m(q2, half)) == pytest.approx(1.0 * (1.0 - np.cos(angle)), rel=1e-2)
    assert prog.dof == 6
    assert prog.shape == ("pose", -1)
    assert_close(prog.lbx, robot.lower)
    assert_close(prog.ubx, robot.upper)


def test_nlp_hessian_is_gauss_newton() -> None:
    """The program's Hessian is 2 (J_r^T J_r + (damping + mu) I), J_r by finite differences."""
    robot = robot_of("panda")
    prog = build_nlp(robot, "axis")
    rng = np.random.default_rng(SEED)
    q = random_q(robot, rng)
    params = prog.parameter_vector(robot.fk(random_q(robot, rng)), weights=[1, 2, 0.5, 3, 1, 0])
    r = casadi.Function("r", [prog.q, prog.parameters], [prog.residual])
    H = casadi.Function("H", [prog.q, prog.parameters], [prog.hessian])
    h = 1e-6
    J = np.column_stack(
        [
            (np.asarray(r(q + h * e, params)) - np.asarray(r(q - h * e, params))).ravel() / (2 * h)
            for e in np.eye(robot.dof)
        ]
    )
    expected = 2.0 * (J.T @ J + nlp_module.GN_DAMPING * np.eye(robot.dof))
    assert_close(np.asarray(H(q, params)), expected, atol=1e-7)


def test_nlp_is_cached_per_robot_and_released_with_it() -> None:
    robot = Robot.from_dh([DHJoint(a=0.5, role="arm"), DHJoint(a=0.4, role="arm")], name="2r")
    first = build_nlp(robot, "position")
    assert build_nlp(robot, "position") is first
    assert build_nlp(robot, "pose") is not first
    solver = nlp_backend(robot, "position", plugin="sqpmethod")
    assert solver.program is first
    assert nlp_backend(robot, "position", plugin="sqpmethod") is solver
    assert nlp_backend(robot, "position", plugin="ipopt") is not solver
    ref = weakref.ref(robot)
    del robot
    gc.collect()
    assert ref() is None  # both caches hold the robot weakly
    assert all(r.name != "2r" for r in nlp_module._CACHE)
    assert all(r.name != "2r" for r in casadi_nlp._BACKENDS)


def test_nlp_position_mode_accepts_a_point() -> None:
    robot = robot_of("puma560")
    backend = nlp_backend(robot, "position")
    q = random_q(robot, np.random.default_rng(SEED))
    p = robot.fk(q)[:3, 3]
    sol = backend.solve(p, np.clip(q + 0.05, robot.lower, robot.upper))
    assert np.linalg.norm(robot.fk(sol.q)[:3, 3] - p) < 1e-8, sol.status


@pytest.mark.parametrize(
    "task",
    [
        {"mode": "pose"},
        {"mode": "position", "tol": (2e-3, 1e-9)},
        {"mode": "orientation"},
        {"mode": "axis", "axis": "x"},
        {"weights": [2.0, 0.3, 0.0, 1.0, 0.5, 4.0], "tol": (1e-3, 3e-3)},
        {"mode": "axis", "axis": "z", "weights": [1.0, 1.0, 1.0, 0.2, 3.0, 0.0]},
    ],
)
def test_stop_objective_bounds_the_judged_errors(task: dict) -> None:
    """Below ``stop_objective`` both judged errors are within sqrt(STOP_FRACTION) tol.

    Configurations near a target's own, at distances from 1e-6 to 1e-1 rad; the errors
    are computed here with numpy (position over the constrained target axes, the angle
    of ``R*^T R`` or between the tool axis and the target's), the objective by the
    program's CasADi function.
    """
    robot = robot_of("panda")
    spec = make_task(**{"tol": 1e-3, **task})
    prog = build_nlp(robot, spec)
    f = casadi.Function("f", [prog.q, prog.parameters], [prog.objective])
    threshold = casadi_nlp.stop_objective(spec)
    bound = np.sqrt(casadi_nlp.STOP_FRACTION)
    rng = np.random.default_rng(SEED + 9)
    w = spec.weights
    below = 0
    for _ in range(400):
        q_true = random_q(robot, rng)
        T = robot.fk(q_true)
        q = q_true + 10.0 ** rng.uniform(-6.0, -1.0) * rng.normal(size=robot.dof)
        if float(f(q, prog.parameter_vector(T, weights=spec))) > threshold:
            continue
        below += 1
        T_q = robot.fk(q)
        d = T[:3, :3].T @ (T_q[:3, 3] - T[:3, 3])
        assert np.linalg.norm(d[w[:3] > 0.0]) <= bound * spec.position_tol
        if np.all(w[3:] > 0.0):
            angle = rotation_angle(T[:3, :3].T @ T_q[:3, :3])
            assert angle <= bound * spec.orientation_tol
        elif np.any(w[3:] > 0.0):
            k = int(np.flatnonzero(w[3:] == 0.0)[0])
            a, b = T_q[:3, k], T[:3, k]
            angle = np.arctan2(np.linalg.norm(np.cross(a, b)), a @ b)
            assert angle <= bound * spec.orientation_tol
    assert below >= 40  # the implication was put to the test


@pytest.mark.parametrize(
    ("kwargs", "error"),
    [
        ({"target": np.eye(3)}, ShapeError),
        ({"target": np.diag([1.0, 1.0, -1.0, 1.0])}, InvalidRotationError),
        ({"weights": [1, 1, 1, -1, 1, 1]}, OptikError),
        ({"weights": [1, 1, 1, 1, 1, 0]}, OptikError),  # an axis task, not this program's
        ({"mu": np.nan}, OptikError),
        ({"mu": -1.0}, OptikError),
        ({"q_ref": np.zeros(5)}, ShapeError),
    ],
)
def test_nlp_bad_parameters(kwargs: dict, error: type[Exception]) -> None:
    prog = build_nlp(robot_of("puma560"), "pose")
    target = kwargs.pop("target", np.eye(4))
    with pytest.raises(error):
        prog.parameter_vector(target, **kwargs)


def test_build_nlp_bad_arguments() -> None:
    robot = robot_of("puma560")
    with pytest.raises(OptikError):
        build_nlp(robot, "orient")
    with pytest.raises(OptikError):
        build_nlp("puma560", "pose")  # type: ignore[arg-type]
    with pytest.raises(OptikError):
        nlp_backend(robot, "pose", max_iter=0)
    with pytest.raises(OptikError):
        nlp_backend(robot, "pose", plugin="no_such_nlpsol")
    backend = nlp_backend(robot, "pose")
    with pytest.raises(OptikError):
        backend.solve(np.eye(4), robot.mid_limits, bounds=(robot.lower - 1.0, robot.upper))


@pytest.mark.parametrize(
    ("name", "plugin"), [("puma560", "ipopt"), ("puma560", "sqpmethod"), ("panda", "sqpmethod")]
)
def test_nlp_reaches_targets_inside_bounds(name: str, plugin: str) -> None:
    """One solve per target from a start 0.05 rad away: the program alone (no restarts)."""
    robot = robot_of(name)
    backend = nlp_backend(robot, "pose", plugin=plugin, max_iter=200)
    rng = np.random.default_rng(SEED + 3)
    for q_true in random_q(robot, rng, 5):
        T = robot.fk(q_true)
        q0 = np.clip(q_true + 0.05 * rng.normal(size=robot.dof), robot.lower, robot.upper)
        sol = backend.solve(T, q0)
        q = np.clip(sol.q, robot.lower, robot.upper)  # Ipopt may relax a bound by 1e-8
        assert np.max(np.abs(q - sol.q)) < 1e-7
        T_out = robot.fk(q)
        assert np.linalg.norm(T_out[:3, 3] - T[:3, 3]) < 1e-6, sol.status
        assert rotation_angle(T[:3, :3].T @ T_out[:3, :3]) < 1e-6, sol.status


# ---------------------------------------------------------------------- casadi:<nlpsol> IK
def test_nlp_solvers_registered() -> None:
    assert {"casadi:ipopt", "casadi:sqpmethod"} <= set(available_solvers())


@pytest.mark.parametrize("solver", ["casadi:ipopt", "casadi:sqpmethod"])
@pytest.mark.parametrize(
    ("name", "mode"), [("puma560", "pose"), ("panda", "pose"), ("panda", "position")]
)
def test_nlp_solver_reaches_targets(solver: str, name: str, mode: str) -> None:
    reach(solver, name, mode, count=4)


def test_nlp_solver_respects_limits_when_target_is_outside() -> None:
    """A target whose nearby branch needs joint 1 beyond its limit: q stays inside."""
    robot = robot_of("puma560")
    q_out = robot.mid_limits.copy()
    q_out[0] = robot.upper[0] + 0.3
    T = robot.fk(q_out)
    for name in ("casadi:ipopt", "casadi:sqpmethod"):
        solver = get_solver(name)
        start = robot.mid_limits.copy()
        start[0] = robot.upper[0] - 0.05
        out = solver.solve(IKQuery(robot, T, "pose", 1e-6), start, 200, time.perf_counter() + 30)
        assert not out.failed, out.message
        assert robot.within_limits(out.q, tol=0.0)


_SQP_UNREACHABLE = """
import optik
panda = optik.load_problem("panda").robot
T = panda.fk(panda.mid_limits)
T[:3, 3] = [0.0, 0.0, 1.15]  # not reachable with this orientation
q0 = [-2.8333352255957767, -1.7627825445142729, -1.359526939253146, -3.0048939556635363,
      -1.3088218347774314, 0.2981103619415135, -2.897246558310587]
result = optik.solve_ik(panda, T, solver="casadi:sqpmethod", q0=q0, restarts=0)
print(result.status, result.success)
"""


def test_sqpmethod_from_a_start_that_broke_its_qp_solver_keeps_the_process_alive() -> None:
    """CasADi's qrqp, sqpmethod's QP solver then, corrupted the C heap from this start
    on an unreachable Panda target: the process aborted (SIGABRT) at a later free, with
    or without code generation. With DAQP the solve ends with its honest status."""
    import os
    import subprocess
    import sys

    env = {**os.environ, "OPTIK_NO_CODEGEN": "1"}  # the same fault, no C compiler run
    done = subprocess.run(
        [sys.executable, "-c", _SQP_UNREACHABLE],
        env=env, capture_output=True, text=True, timeout=300, check=False,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr[-500:]
    assert done.stdout.split() == ["max_iter", "False"]
