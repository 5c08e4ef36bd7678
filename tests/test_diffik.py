"""optik.diffik.diff_ik: one differential-IK step, verified, inside the limits."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from typing import Any

import numpy as np
import pytest
from conftest import SEED, assert_close, robot_of

import optik
from optik.diffik import diff_ik, diff_ik_solvers, verify_step
from optik.errors import (
    JointLimitError,
    NonFiniteError,
    NoSolutionError,
    OptikError,
    ShapeError,
    SolverError,
    UnknownSolverError,
)
from optik.linalg import least_squares, min_norm
from optik.programs.diff_qp import DEFAULT_DAMPING, DiffIKProgram, QPSolution, build_program
from optik.solvers import StepBackend, register_solver, registered_solvers, unregister_solver
from optik.solvers.casadi_conic import casadi_conic_plugins
from optik.solvers.qp import installed_backends, qpsolvers_backends

Q_PUMA = np.array([0.1, 0.5, -1.0, 0.3, 0.6, 0.2])
TWIST = np.array([0.1, -0.05, 0.08, 0.2, -0.1, 0.3])  # m/s then rad/s
DT = 0.01
SOLVERS = ["qp:proxqp", "qp:osqp", "qp:daqp", "casadi:qrqp", "casadi:osqp"]


def near_limit_push(name: str = "puma560") -> tuple:
    """q with joint 0 1e-4 below its upper limit and a twist that drives joint 0 up."""
    robot = robot_of(name)
    q = Q_PUMA.copy() if name == "puma560" else robot.mid_limits + 0.2
    q[0] = robot.upper[0] - 1e-4
    twist = robot.jacobian(q)[:, 0] * 1.0  # 1 rad/s of joint 0: 1e-2 rad in one step
    return robot, q, twist


# ---------------------------------------------------------------------- answers
@pytest.mark.parametrize("solver", SOLVERS)
def test_least_norm_equals_closed_form(solver: str) -> None:
    robot = robot_of("puma560")
    dq = diff_ik(robot, Q_PUMA, TWIST, dt=DT, solver=solver)
    J = robot.jacobian(Q_PUMA)
    assert_close(dq, min_norm(J, TWIST * DT), atol=1e-10)
    assert_close(J @ dq, TWIST * DT, atol=1e-12)


@pytest.mark.parametrize("solver", SOLVERS)
def test_least_squares_equals_damped_closed_form(solver: str) -> None:
    robot = robot_of("panda")
    q = robot.mid_limits + 0.2
    dq = diff_ik(robot, q, TWIST, dt=DT, objective="least_squares", solver=solver)
    J = robot.jacobian(q)
    assert_close(dq, least_squares(J, TWIST * DT, damping=DEFAULT_DAMPING), atol=1e-9)


def test_redundant_least_norm_and_rows() -> None:
    robot = robot_of("panda")
    q = robot.mid_limits + 0.2
    dq = diff_ik(robot, q, TWIST, dt=DT)
    assert_close(dq, np.linalg.pinv(robot.jacobian(q)) @ (TWIST * DT), atol=1e-10)
    dq3 = diff_ik(robot, q, TWIST, dt=DT, rows=(0, 1, 2))
    J3 = robot.jacobian(q)[:3]
    assert_close(dq3, min_norm(J3, TWIST[:3] * DT), atol=1e-10)


def test_velocity_limits_hold() -> None:
    robot = robot_of("panda")
    q = robot.mid_limits + 0.2
    vmax = np.full(7, 0.5)
    dq = diff_ik(robot, q, 5.0 * TWIST, dt=DT, objective="least_squares", velocity_limits=vmax)
    assert np.all(np.abs(dq) <= vmax * DT + 1e-15)
    assert np.any(np.isclose(np.abs(dq), vmax * DT, rtol=0, atol=1e-12))  # some at the cap


# ---------------------------------------------------------------------- limits
@pytest.mark.parametrize("solver", SOLVERS)
def test_infeasible_least_norm_raises_with_program(solver: str) -> None:
    robot, q, twist = near_limit_push()
    with pytest.raises(NoSolutionError) as info:
        diff_ik(robot, q, twist, dt=DT, solver=solver)
    program = info.value.program
    assert isinstance(program, DiffIKProgram)
    assert program.objective == "least_norm"
    assert program.min_task_violation() > 1e-3
    assert "limits block it" in str(info.value)
    # The caller switches to least squares and gets a bounded step.
    dq = diff_ik(robot, q, twist, dt=DT, objective="least_squares", solver=solver)
    assert robot.within_limits(q + dq, tol=0.0)
    assert dq[0] == pytest.approx(1e-4, abs=1e-9)  # joint 0 stops at its limit
    # It is the bounded optimum: KKT with sign-correct multipliers.
    prog = build_program(robot, q, twist * DT, objective="least_squares")
    report = prog.kkt(dq, active_tol=1e-9)
    assert report.active_upper[0] and report.z_upper[0] > 0
    assert report.stationarity <= 1e-6 * report.scale


def test_redundant_arm_works_around_a_blocked_joint() -> None:
    """Least norm stays feasible when one of seven joints is stopped (limit or speed 0)."""
    robot = robot_of("panda")
    q = robot.mid_limits + 0.2
    q[0] = robot.upper[0] - 1e-4
    twist = robot.jacobian(q)[:, 0] * 1.0
    dq = diff_ik(robot, q, twist, dt=DT)
    assert dq[0] == pytest.approx(1e-4, abs=1e-9)  # at the limit
    assert robot.within_limits(q + dq, tol=0.0)
    assert_close(robot.jacobian(q) @ dq, twist * DT, atol=1e-12)
    frozen = np.array([0.0, 9, 9, 9, 9, 9, 9])
    dq = diff_ik(robot, robot.mid_limits + 0.2, TWIST, dt=DT, velocity_limits=frozen)
    assert dq[0] == 0.0
    assert_close(robot.jacobian(robot.mid_limits + 0.2) @ dq, TWIST * DT, atol=1e-12)


def test_twist_outside_range_of_j() -> None:
    """A planar arm cannot produce a generic 6D twist, limits or not."""
    robot = robot_of("planar_2r")
    with pytest.raises(NoSolutionError) as info:
        diff_ik(robot, np.array([0.3, 0.6]), TWIST, dt=DT, limits=False)
    assert "outside the range of J" in str(info.value)
    assert info.value.program.qp.lb is None  # no limits: no bounds in the program


def test_limits_false_ignores_the_limit() -> None:
    robot, q, twist = near_limit_push()
    dq = diff_ik(robot, q, twist, dt=DT, limits=False)
    assert dq[0] == pytest.approx(1e-2, rel=1e-6)
    assert not robot.within_limits(q + dq)


def test_limit_gain_scales_the_reach() -> None:
    robot, q, twist = near_limit_push()
    dq = diff_ik(robot, q, twist, dt=DT, objective="least_squares", limit_gain=0.5)
    assert dq[0] == pytest.approx(0.5e-4, abs=1e-9)


def test_inconsistent_bounds_raise_no_solution() -> None:
    robot = robot_of("puma560")
    q = Q_PUMA.copy()
    q[0] = robot.upper[0] + 0.1  # outside, and the speed limit cannot bring it back
    program = build_program(
        robot, q, TWIST * DT, objective="least_squares", dt=DT, velocity_limits=np.ones(6)
    )
    assert not program.bounds_consistent
    # diff_ik itself refuses a q this far outside (beyond Q_CLIP_TOLERANCE) by name
    with pytest.raises(JointLimitError, match=robot.joints[0].name):
        diff_ik(robot, q, TWIST, dt=DT, objective="least_squares", velocity_limits=np.ones(6))


# ---------------------------------------------------------------------- verification
class _FakeStep(StepBackend):
    """A step backend that answers with a fixed rule (registered for one test only)."""

    def __init__(self, name: str, rule: Callable[[DiffIKProgram], QPSolution]) -> None:
        self.name = name
        self.rule = rule

    def solve(self, program: DiffIKProgram, initvals: np.ndarray | None = None) -> QPSolution:
        return self.rule(program)


@pytest.fixture
def fake_step() -> Iterator[Callable[[Callable[[DiffIKProgram], QPSolution]], str]]:
    name = "test:fake-step"

    def install(rule: Callable[[DiffIKProgram], QPSolution]) -> str:
        register_solver(name, lambda: _FakeStep(name, rule), lambda: True, kind="step")
        return name

    yield install
    unregister_solver(name, kind="step")
    assert name not in registered_solvers(kind="step")


def test_a_backend_answer_is_checked_not_trusted(fake_step: Any) -> None:
    """A backend claiming success at a wrong point gives SolverError, not a wrong step."""
    robot = robot_of("panda")
    q = robot.mid_limits + 0.2

    def liar(program: DiffIKProgram) -> QPSolution:
        x = np.linalg.pinv(program.J) @ program.v
        null = np.linalg.svd(program.J)[2][-1]
        return QPSolution(x + 1e-3 * null, True, "solved", "test")  # feasible, not minimal

    name = fake_step(liar)
    with pytest.raises(SolverError) as info:
        diff_ik(robot, q, TWIST, dt=DT, solver=name)
    assert "not optimal" in str(info.value)
    assert info.value.solver == name


def test_a_failed_backend_on_a_feasible_program(fake_step: Any) -> None:
    def broken(program: DiffIKProgram) -> QPSolution:
        return QPSolution(None, False, "ValueError: boom", "test")

    name = fake_step(broken)
    with pytest.raises(SolverError, match="boom"):
        diff_ik(robot_of("puma560"), Q_PUMA, TWIST, dt=DT, solver=name)


def test_bare_backend_name_is_deprecated() -> None:
    robot = robot_of("puma560")
    with pytest.warns(DeprecationWarning, match="qp:osqp"):
        dq = diff_ik(robot, Q_PUMA, TWIST, dt=DT, solver="osqp")
    assert_close(dq, diff_ik(robot, Q_PUMA, TWIST, dt=DT, solver="qp:osqp"), atol=1e-9)


def test_step_solvers_come_from_the_registry() -> None:
    names = diff_ik_solvers()
    assert names == optik.available_solvers(kind="step")
    assert "qp:proxqp" in names and "casadi:qrqp" in names
    assert "dls" not in names and "casadi:ipopt" not in names  # whole-IK solvers only
    with pytest.raises(UnknownSolverError, match="whole-IK solver"):
        diff_ik(robot_of("puma560"), Q_PUMA, TWIST, dt=DT, solver="dls")


def test_verify_step_accepts_an_unclaimed_but_correct_point() -> None:
    robot = robot_of("puma560")
    prog = build_program(robot, Q_PUMA, TWIST * DT)
    x = np.linalg.solve(prog.J, prog.v)
    dq, reason = verify_step(prog, QPSolution(x, False, "solved inaccurate", "qp:x"))
    assert reason == "" and dq is not None
    # A point off the task is projected back onto J dq = v (here the square J's solution).
    dq, reason = verify_step(prog, QPSolution(x + 1e-6, True, "solved", "qp:x"))
    assert reason == "" and dq is not None
    assert np.abs(dq - x).max() <= 1e-12 * np.abs(x).max()
    _, reason = verify_step(prog, QPSolution(np.full(6, np.nan), True, "solved", "qp:x"))
    assert "non-finite" in reason


# ---------------------------------------------------------------------- bad inputs
@pytest.mark.parametrize(
    ("kwargs", "error"),
    [
        ({"dt": 0.0}, OptikError),
        ({"dt": -0.1}, OptikError),
        ({"dt": np.nan}, NonFiniteError),
        ({"dt": "soon"}, OptikError),
        ({"twist": np.zeros(5)}, ShapeError),
        ({"twist": np.array([0, 0, np.nan, 0, 0, 0])}, NonFiniteError),
        ({"q": np.zeros(7)}, ShapeError),
        ({"q": np.array([0, 0, np.inf, 0, 0, 0])}, NonFiniteError),
        ({"limit_gain": 0.0}, OptikError),
        ({"limit_gain": 2.0}, OptikError),
        ({"damping": 0.1}, OptikError),  # least norm takes no damping
        ({"objective": "least_squares", "damping": -1.0}, OptikError),
        ({"objective": "minimum_effort"}, OptikError),
        ({"velocity_limits": -np.ones(6)}, OptikError),
        ({"velocity_limits": np.ones(3)}, ShapeError),
    ],
)
def test_bad_inputs(kwargs: dict, error: type[Exception]) -> None:
    args = {"q": Q_PUMA, "twist": TWIST, "dt": DT}
    args.update({k: kwargs.pop(k) for k in ("q", "twist", "dt") if k in kwargs})
    with pytest.raises(error):
        diff_ik(robot_of("puma560"), args["q"], args["twist"], dt=args["dt"], **kwargs)


def test_every_error_is_an_optik_error_and_a_value_error() -> None:
    with pytest.raises(ValueError):
        diff_ik(robot_of("puma560"), Q_PUMA, TWIST, dt=0.0)


# ---------------------------------------------------------------------- solver names
def test_unknown_solver_lists_installed() -> None:
    with pytest.raises(UnknownSolverError) as info:
        diff_ik(robot_of("puma560"), Q_PUMA, TWIST, dt=DT, solver="qp:nonexistent")
    message = str(info.value)
    for name in diff_ik_solvers():
        assert name in message
    assert info.value.available == diff_ik_solvers()


def test_solver_names() -> None:
    names = diff_ik_solvers()
    assert {f"qp:{b}" for b in installed_backends()} <= set(names)
    assert {f"casadi:{p}" for p in casadi_conic_plugins()} <= set(names)
    with pytest.raises(UnknownSolverError, match="conic"):
        diff_ik(robot_of("puma560"), Q_PUMA, TWIST, dt=DT, solver="casadi:ipopt")
    missing = [b for b in qpsolvers_backends() if b not in installed_backends()]
    if missing:  # a bare backend name: deprecated, and this one is not installed
        with (
            pytest.warns(DeprecationWarning, match=rf"write solver='qp:{missing[0]}'"),
            pytest.raises(UnknownSolverError, match=rf"qpsolvers\[{missing[0]}\]"),
        ):
            diff_ik(robot_of("puma560"), Q_PUMA, TWIST, dt=DT, solver=missing[0])


@pytest.mark.parametrize("solver", [f"qp:{b}" for b in installed_backends()])
def test_every_installed_backend_by_both_names(solver: str) -> None:
    robot = robot_of("ur5")
    rng = np.random.default_rng(SEED)
    q = robot.mid_limits + 0.3 * rng.normal(size=6)
    expected = min_norm(robot.jacobian(q), TWIST * DT)
    assert_close(diff_ik(robot, q, TWIST, dt=DT, solver=solver), expected, atol=1e-9)
    plain = solver.split(":", 1)[1]
    with pytest.warns(DeprecationWarning):
        assert_close(diff_ik(robot, q, TWIST, dt=DT, solver=plain), expected, atol=1e-9)


def test_a_non_finite_velocity_limit_is_named_by_plain_index() -> None:
    """The index of a NaN prints as ``(0,)``, not numpy's ``(np.int64(0),)``."""
    robot = robot_of("ur5")
    limits = np.ones(6)
    limits[2] = np.nan
    with pytest.raises(NonFiniteError, match=r"velocity_limits: .* at index \(2,\)$") as caught:
        diff_ik(robot, robot.mid_limits, TWIST, dt=DT, velocity_limits=limits)
    assert caught.value.index == (2,) and type(caught.value.index[0]) is int
