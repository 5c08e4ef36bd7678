"""Hostile values at the Python API: IK, closed forms, differential IK, trig, linalg, poses.

Each case either succeeds with finite results, returns a documented status, or raises an
``OptikError`` — never another exception type, never a NaN in a result, never a hang
(each case runs under :func:`conftest.time_limit`). Part one pins single rules (each test
fails without its rule); part two throws hypothesis-drawn values at every argument.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from conftest import HostileCases, robot_of
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

import optik
from optik.errors import JointLimitError, OptikError
from optik.ik import BATCH_STATUSES, STATUSES
from optik.limits import Q_CLIP_TOLERANCE
from optik.trig import solve_trig_batch

NAN, INF = math.nan, math.inf
TIME_LIMIT_S = 30.0  # a hard stop per case: a hang fails the test instead of blocking it
FUZZ = settings(
    max_examples=max(150, settings().max_examples),  # the optik-long profile asks for more
    deadline=None,  # the per-case alarm bounds each case; a cold compile may take seconds
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)
HOSTILE = HostileCases(TIME_LIMIT_S)

PUMA = robot_of("puma560")  # closed form (compiled spherical wrist)
PANDA = robot_of("panda")  # numeric (7 dof)
PLANAR = robot_of("planar_2r")  # closed form in Python (position mode)
ROBOTS = {"puma": PUMA, "panda": PANDA}
FK_TARGETS = {name: robot.fk(robot.mid_limits) for name, robot in ROBOTS.items()}
"""A reachable target of each robot (the pose of its mid-limits)."""

SCALARS = st.sampled_from(
    [NAN, INF, -INF, 1e300, -1e300, 1e155, 1e10, -0.0, 0.0, 0.5, 1.0, -1, 3, 1j, 1 + 0j,
     True, False, "1.0", "x", "", None, [], [1.0], {}, (), 10**400, np.float64(NAN),
     np.int64(2), np.float32(0.5), 5e-324, 1e-300, np.bool_(True), np.array(0.5),
     np.array([0.5]), np.complex128(1.0)]
)  # fmt: skip
FLOATS = st.sampled_from(
    [NAN, INF, -INF, 1e300, -1e300, 1e155, -1e155, 1e10, -0.0, 0.0, 0.3, -1.2, 5e-324]
)
DTYPES = st.sampled_from([complex, bool, object, str, np.float32, np.int64, np.float16])


def _pose(x: float = 0.0, y: float = 0.0, z: float = 0.0) -> np.ndarray:
    T = np.eye(4)
    T[:3, 3] = (x, y, z)
    return T


def hostile_array(good: np.ndarray) -> st.SearchStrategy[Any]:
    """Arrays meant to look like ``good``: hostile entries, wrong shapes and dtypes, ragged."""
    shape = good.shape
    n = int(good.size)
    filled = st.lists(FLOATS, min_size=n, max_size=n).map(
        lambda v: np.array(v, dtype=float).reshape(shape)
    )
    one_bad = st.tuples(st.integers(0, n - 1), FLOATS).map(
        lambda iv: np.where(np.arange(n).reshape(shape) == iv[0], iv[1], good)
    )
    junk_entry = st.tuples(st.integers(0, n - 1), SCALARS).map(
        lambda iv: [iv[1] if i == iv[0] else float(x) for i, x in enumerate(good.ravel())]
    )
    dtyped = DTYPES.map(lambda d: good.astype(d))
    strided = st.just(np.asfortranarray(good) if good.ndim > 1 else good[::1].copy())
    reshaped = st.sampled_from([(0,), (0, *shape), (*shape, 1), (1, *shape), (n + 1,), ()]).map(
        np.zeros
    )
    ragged = st.just([[0.1] * max(shape[-1], 2), [0.1]])
    return st.one_of(
        st.just(good), filled, one_bad, junk_entry, dtyped, strided, reshaped, ragged, SCALARS
    )


def hostile_pose(good: np.ndarray) -> st.SearchStrategy[Any]:
    """4x4 poses: ``good``, hostile translations, and what :func:`hostile_array` draws."""
    translated = st.tuples(FLOATS, FLOATS, FLOATS).map(lambda p: _pose(*p))
    rotated = st.sampled_from([np.diag([1.0, 1.0, -1.0, 1.0]), np.diag([2.0, 1.0, 1.0, 1.0])])
    return st.one_of(st.just(good), translated, rotated, hostile_array(good))


def _finite(*arrays: Any) -> bool:
    return all(bool(np.all(np.isfinite(np.asarray(a, dtype=float)))) for a in arrays)


@pytest.fixture(scope="module", autouse=True)
def _report_stats() -> Iterator[None]:
    """Print the tally of hostile cases (run with ``-s -p no:xdist`` to see all of it)."""
    yield
    HOSTILE.report()


@pytest.fixture(scope="module")
def warm() -> None:
    """Compile the kernels once, outside the per-example deadline."""
    for robot in (PUMA, PANDA):
        T = robot.fk(robot.mid_limits)
        optik.solve_ik(robot, T)
        optik.solve_ik_batch(robot, np.stack([T, T]), restarts=1)
    optik.analytic_ik(PUMA, PUMA.fk(PUMA.mid_limits))
    optik.analytic_ik_batch(PUMA, PUMA.fk(PUMA.mid_limits)[None])
    optik.diff_ik(PUMA, PUMA.mid_limits, np.zeros(6), dt=0.01)
    # Compiled functions that Python calls directly, compiled here rather than inside a
    # time-limited case (an alarm in the middle of numba's compiler breaks it): the
    # closed forms' polish, the Python solvers' task residual, the timed dls path.
    inside = PUMA.fk(PUMA.mid_limits)
    inside[:3, 3] = PUMA.reach_sphere[0] + [0.0, 0.0, 0.95 * PUMA.reach_sphere[1]]
    optik.analytic_ik(PUMA, inside)
    for robot in (PUMA, PANDA):
        T = robot.fk(robot.mid_limits)
        optik.solve_ik(robot, T, solver="pinv", max_iter=2, restarts=0)
        optik.solve_ik(robot, T, solver="dls", timeout_s=1.0, q0=robot.mid_limits)
        optik.solve_ik(robot, T[:3, 3], mode="position", warm_start="q0")
    solve_trig_batch([1.0], [0.0], [0.5])
    optik.min_norm(np.eye(2, 3), np.ones(2))


def _check_ik(result: optik.IKResult, robot: optik.Robot) -> None:
    assert result.status in STATUSES
    assert result.q.shape == (robot.dof,) and _finite(result.q), result
    assert _finite(result.position_error, result.orientation_error, result.limit_violation)
    if result.success:
        assert result.status == "converged"


def _check_batch(result: optik.IKBatchResult, robot: optik.Robot, n: int) -> None:
    assert result.q.shape == (n, robot.dof)
    solved = result.status != "unreachable"  # unsolved rows are NaN, as documented
    assert set(result.status.tolist()) <= set(BATCH_STATUSES)
    assert _finite(result.q[solved], result.position_error[solved], result.limit_violation)
    assert np.all(result.iterations >= 0) and np.all(result.iterations < 10**9)
    assert not np.any(result.success & ~solved)


# ====================================================================== single rules
def test_huge_targets_are_handled() -> None:
    """A target 1e155 m away: squared distances overflow; it is proved unreachable."""
    far = _pose(1e155, 0.0, 0.0)
    for robot in (PUMA, PANDA):
        result = optik.solve_ik(robot, far)
        assert result.status == "unreachable" and _finite(result.q)
        good = robot.fk(robot.mid_limits)
        batch = optik.solve_ik_batch(robot, np.stack([good, far] * 40), restarts=2)
        assert batch.status[1::2].tolist() == ["unreachable"] * 40
        assert batch.success[0::2].all()
    assert optik.analytic_ik(PUMA, far) == []


@pytest.mark.parametrize("bad", [1e-300, 0.0, -1.0, "x", None, True, 1j, NAN])
def test_linalg_option_values(warm: None, bad: Any) -> None:
    """A tiny damping is no damping; a non-number is an OptikError, never a TypeError."""
    A = np.array([[1.0, 2.0, 0.0], [0.0, 1.0, 1.0]])
    b = np.array([1.0, 2.0])
    exact = A.T @ np.linalg.solve(A @ A.T, b)  # numpy's independent answer
    for fn in (optik.min_norm, optik.least_squares):
        for option in ("damping", "max_condition"):
            kwargs = {option: bad}
            call = (
                (lambda fn=fn, kw=kwargs: fn(A, b, **kw))
                if fn is optik.min_norm
                else (lambda kw=kwargs: optik.least_squares(A.T, A.T @ b, **kw))
            )
            outcome = HOSTILE.attempt(fn.__name__, call)
            if outcome is not None:
                assert option == "damping" and bad in (1e-300, 0.0)
                if fn is optik.min_norm:
                    np.testing.assert_allclose(outcome, exact, atol=1e-12)
    with pytest.raises(OptikError, match="max_condition"):
        optik.generalized_inverse(A, max_condition="x")


def test_linalg_huge_entries_keep_their_answer(warm: None) -> None:
    """Entries whose squares overflow: the damped answer is still ``s / (s^2 + l^2)``."""
    A = np.array([[1e200, 0.0], [0.0, 1e200]])
    for damping in (0.0, 1e-3):
        x = optik.min_norm(A, [1.0, 1.0], damping=damping)
        # 1 / (1e200 + l^2 / 1e200) = 1e-200 to double precision, by hand
        np.testing.assert_allclose(x, [1e-200, 1e-200], rtol=1e-14, atol=0.0)
    x = optik.least_squares(np.array([[1e200], [1.0]]), [1.0, 1.0], damping=1.0)
    np.testing.assert_allclose(x, [1e-200], rtol=1e-14, atol=0.0)


@pytest.mark.parametrize("dtype", [complex, bool, str, np.complex64])
def test_targets_of_other_dtypes_are_rejected_not_cast(dtype: Any) -> None:
    """A complex 4x4 lost its imaginary part (and succeeded); a bool one became 0/1."""
    for robot in (PUMA, PANDA):
        T = robot.fk(robot.mid_limits).astype(dtype)
        with pytest.raises(OptikError, match="target"):
            optik.solve_ik(robot, T)
        with pytest.raises(OptikError, match="target"):
            optik.as_target_pose(T, "pose")
    with pytest.raises(OptikError, match="targets"):
        optik.solve_ik_batch(PUMA, PUMA.fk(PUMA.mid_limits).astype(dtype)[None])


def test_trig_options_are_typed_errors() -> None:
    for bad in ("x", None, True, 1j, [0.1]):
        with pytest.raises(OptikError, match="tol"):
            optik.solve_trig(1.0, 0.0, 0.5, tol=bad)
        with pytest.raises(OptikError, match="tol"):
            solve_trig_batch([1.0], [0.0], [0.5], tol=bad)
    for bad in (True, 1j, "0.5"):
        with pytest.raises(OptikError, match="c: expected"):
            optik.solve_trig(1.0, 0.0, bad)


def test_trig_huge_coefficients() -> None:
    """``a^2 + b^2`` overflows beyond ~1e154: the roots stay those of the scaled equation."""
    roots = optik.solve_trig(1e200, 0.0, 5e199)
    np.testing.assert_allclose(sorted(roots), [-math.pi / 3, math.pi / 3], atol=1e-12)
    tp, tm, valid = solve_trig_batch([1e200], [0.0], [5e199])
    assert valid.all()
    np.testing.assert_allclose([tp[0], tm[0]], [math.pi / 3, -math.pi / 3], atol=1e-12)
    assert optik.solve_trig(1e200, 1e200, 1e201) == ()


def test_analytic_within_limits_must_be_a_bool() -> None:
    T = PUMA.fk(PUMA.mid_limits)
    for bad in ("false", 0, None, 1.0):
        with pytest.raises(OptikError, match="within_limits"):
            optik.analytic_ik(PUMA, T, within_limits=bad)
        with pytest.raises(OptikError, match="within_limits"):
            optik.analytic_ik_batch(PUMA, T[None], within_limits=bad)


@pytest.mark.parametrize("bad", [0, 1.5, True, "2", np.int64(0), None, 10**6])
def test_batch_threads(bad: Any) -> None:
    T = PUMA.fk(PUMA.mid_limits)[None]
    if bad is None:
        assert optik.solve_ik_batch(PUMA, T, threads=bad).success.all()
        return
    with pytest.raises(OptikError, match="threads"):
        optik.solve_ik_batch(PUMA, T, threads=bad)


def test_batch_threads_accept_numpy_integers() -> None:
    T = PUMA.fk(PUMA.mid_limits)[None]
    assert optik.solve_ik_batch(PUMA, T, threads=np.int64(1)).success.all()


def test_diff_ik_options_are_typed_errors() -> None:
    q = PUMA.mid_limits
    for kwargs in (
        {"dt": "x"}, {"dt": True}, {"dt": 1j}, {"limits": "false"}, {"limits": None},
        {"limit_gain": "x"}, {"limit_gain": True}, {"limit_gain": NAN},
        {"damping": "x", "objective": "least_squares"},
        {"damping": True, "objective": "least_squares"}, {"rows": "012"}, {"rows": [0.5]},
        {"rows": [True]}, {"rows": 3}, {"objective": ["least_norm"]}, {"solver": None},
        {"velocity_limits": [1j] * 6}, {"velocity_limits": "x"},
    ):  # fmt: skip
        options: dict[str, Any] = {"dt": 0.01, **kwargs}
        with pytest.raises(OptikError):
            optik.diff_ik(PUMA, q, np.zeros(6), **options)


def test_diff_ik_step_beyond_length_bound() -> None:
    """A twist of 1e300 m/s is a step of 1e298 m: rejected, not handed to a QP backend."""
    twist = np.array([1e300, 0.0, 0.0, 0.0, 0.0, 0.0])
    with pytest.raises(OptikError, match=r"twist\[0\] \* dt: expected a step"):
        optik.diff_ik(PUMA, PUMA.mid_limits, twist, dt=0.01)
    twist[0] = 1e11  # 1e9 m in one step of 0.01 s: at the bound, still accepted
    dq = optik.diff_ik(PUMA, PUMA.mid_limits, twist, dt=0.01, objective="least_squares")
    assert _finite(dq)


@pytest.mark.filterwarnings("error::RuntimeWarning")
def test_python_family_far_target_is_unreachable_without_overflow() -> None:
    """The planar family squares coordinates: 1e300 m is ruled out before (reach sphere)."""
    for x in (1e155, 1e300, -1e300):
        assert optik.analytic_ik(PLANAR, [x, 0.0, 0.0], "position") == []
        assert optik.analytic_ik_batch(PLANAR, [[x, 0.0, 0.0]], "position").counts.tolist() == [0]
    assert optik.analytic_ik(PLANAR, [1.0, 0.5, 0.0], "position")  # a reachable point still solves


# ====================================================================== q0 tolerance
def _at_limit(robot: optik.Robot, joint: int, excess: float) -> np.ndarray:
    q = robot.mid_limits.copy()
    q[joint] = robot.upper[joint] + excess
    return q


@pytest.mark.parametrize("robot", [PUMA, PANDA], ids=["puma", "panda"])
def test_q0_within_clip_tolerance_is_clipped(robot: optik.Robot) -> None:
    q0 = _at_limit(robot, 1, 0.5 * Q_CLIP_TOLERANCE)
    target = robot.fk(np.clip(q0, robot.lower, robot.upper))
    result = optik.solve_ik(robot, target, q0=q0, solver="dls", restarts=0)
    assert result.success and result.limit_violation == 0.0
    batch = optik.solve_ik_batch(robot, target[None], q0=q0, restarts=0)
    assert batch.success.all()
    q_low = robot.mid_limits.copy()
    q_low[1] = robot.lower[1] - Q_CLIP_TOLERANCE  # exactly at the tolerance: accepted
    assert optik.solve_ik(robot, robot.fk(robot.mid_limits), q0=q_low).status in STATUSES


def test_the_clip_tolerance_is_the_documented_micro_unit() -> None:
    # The tests above scale the tolerance itself; these pin its documented 1e-6 (rad).
    target = PUMA.fk(PUMA.mid_limits)
    accepted = optik.solve_ik(PUMA, target, q0=_at_limit(PUMA, 1, 5e-7))
    assert accepted.success
    with pytest.raises(JointLimitError, match=PUMA.joints[1].name):
        optik.solve_ik(PUMA, target, q0=_at_limit(PUMA, 1, 5e-4))


@pytest.mark.parametrize("robot", [PUMA, PANDA], ids=["puma", "panda"])
def test_q0_beyond_clip_tolerance_is_rejected(robot: optik.Robot) -> None:
    q0 = _at_limit(robot, 1, 2.0 * Q_CLIP_TOLERANCE)
    name = robot.joints[1].name
    with pytest.raises(JointLimitError, match=name):
        optik.solve_ik(robot, robot.fk(robot.mid_limits), q0=q0)
    with pytest.raises(JointLimitError, match=name):
        optik.solve_ik_batch(robot, robot.fk(robot.mid_limits)[None], q0=q0)


def test_diff_ik_clips_within_tolerance_and_rejects_beyond() -> None:
    robot = PUMA
    inside = robot.mid_limits.copy()
    inside[1] = robot.upper[1]
    twist = np.array([0.0, 0.0, 0.0, 0.1, 0.0, 0.0])
    reference = optik.diff_ik(robot, inside, twist, dt=0.01, objective="least_squares")
    hair = inside.copy()
    hair[1] += 0.9 * Q_CLIP_TOLERANCE  # an encoder reading a hair past the limit
    dq = optik.diff_ik(robot, hair, twist, dt=0.01, objective="least_squares")
    # clipped onto the limit first: the same step as from the limit itself
    np.testing.assert_allclose(dq, reference, atol=1e-8)
    assert inside[1] + dq[1] <= robot.upper[1] + 1e-9
    beyond = inside.copy()
    beyond[1] += 1.1 * Q_CLIP_TOLERANCE
    with pytest.raises(JointLimitError, match=robot.joints[1].name):
        optik.diff_ik(robot, beyond, twist, dt=0.01)


# ====================================================================== hypothesis
IK_OPTIONS = st.sampled_from(
    ["mode", "solver", "warm_start", "tol", "max_iter", "timeout_s", "restarts", "seed"]
)
OPTION_VALUES = st.one_of(
    SCALARS,
    st.sampled_from(
        ["pose", "position", "auto", "dls", "analytic", "q0", ["dls"], "nonexistent", 1e-9, 0.05,
         10**9, 2**63, -5, 1e9, 7.0]
    ),
)  # fmt: skip


@FUZZ
@given(
    robot_name=st.sampled_from(sorted(ROBOTS)),
    target=st.one_of(hostile_pose(np.eye(4)), hostile_array(np.zeros(3)), st.just("fk")),
    q0=st.one_of(st.none(), hostile_array(np.full(6, 0.1)), hostile_array(np.full(7, 0.1))),
    option=st.one_of(st.none(), IK_OPTIONS),
    value=OPTION_VALUES,
)
# Answerable queries among the hostile ones: the checks of a success run too (drawn
# rarely: a reachable target with a valid q0 and option).
@example(robot_name="puma", target="fk", q0=None, option=None, value=0.5)
@example(robot_name="panda", target="fk", q0=None, option=None, value=0.5)
@example(robot_name="panda", target="fk", q0=np.full(7, 0.1), option="solver", value="dls")
def test_hostile_solve_ik(
    warm: None, robot_name: str, target: Any, q0: Any, option: str | None, value: Any
) -> None:
    robot = ROBOTS[robot_name]
    if isinstance(target, str):
        target = FK_TARGETS[robot_name]
    # A finite budget keeps a hard but legal query short; the options under test override.
    kwargs: dict[str, Any] = {"restarts": 3, "q0": q0}
    if option is not None:
        kwargs[option] = value
    if option in ("restarts", "max_iter"):
        kwargs["timeout_s"] = 2.0  # a legal 10**9 restarts is bounded by the clock
    result = HOSTILE.attempt("solve_ik", lambda: optik.solve_ik(robot, target, **kwargs))
    if result is not None:
        _check_ik(result, robot)
        if target is FK_TARGETS[robot_name] and q0 is None and option is None:
            assert result.success, result  # a reachable target and the defaults


@FUZZ
@given(
    robot_name=st.sampled_from(sorted(ROBOTS)),
    targets=st.one_of(
        hostile_array(np.stack([np.eye(4)] * 2)),
        hostile_array(np.zeros((2, 3))),
        st.sampled_from([np.zeros((0, 4, 4)), np.zeros((0, 3)), [], np.zeros((0,))]),
        st.just("fk"),
    ),
    q0=st.one_of(st.none(), hostile_array(np.full(6, 0.1)), hostile_array(np.full(7, 0.1))),
    option=st.one_of(
        st.none(), st.sampled_from(["mode", "tol", "max_iter", "restarts", "seed", "threads"])
    ),
    value=OPTION_VALUES,
)
def test_hostile_solve_ik_batch(
    warm: None, robot_name: str, targets: Any, q0: Any, option: str | None, value: Any
) -> None:
    robot = ROBOTS[robot_name]
    if isinstance(targets, str):
        targets = np.stack([robot.fk(robot.mid_limits)] * 3)
    kwargs: dict[str, Any] = {"restarts": 2, "max_iter": 30, "q0": q0}
    if option is not None:
        kwargs[option] = value
    if option == "restarts" and isinstance(value, int | float) and not isinstance(value, bool):
        kwargs["restarts"] = value if abs(value) < 1e3 else 2  # a legal 1e9 is just slow
    if option == "max_iter" and isinstance(value, int | float) and not isinstance(value, bool):
        kwargs["max_iter"] = value if abs(value) < 1e3 else 30
    result = HOSTILE.attempt(
        "solve_ik_batch", lambda: optik.solve_ik_batch(robot, targets, **kwargs)
    )
    if result is not None:
        n = result.q.shape[0]
        _check_batch(result, robot, n)


@FUZZ
@given(
    target=st.one_of(hostile_pose(np.eye(4)), st.just("fk")),
    mode=st.one_of(st.just("pose"), SCALARS, st.sampled_from(["position", "Pose"])),
    q_ref=st.one_of(st.none(), hostile_array(np.full(6, 0.1))),
    within_limits=st.one_of(st.just(True), st.just(False), SCALARS),
    batch=st.booleans(),
)
def test_hostile_analytic_ik(
    warm: None, target: Any, mode: Any, q_ref: Any, within_limits: Any, batch: bool
) -> None:
    if isinstance(target, str):
        target = PUMA.fk(PUMA.mid_limits)
    if batch:
        targets = np.asarray(target)[None] if isinstance(target, np.ndarray) else [target]
        out = HOSTILE.attempt(
            "analytic_ik_batch",
            lambda: optik.analytic_ik_batch(PUMA, targets, mode, q_ref, within_limits),
        )
        if out is not None:
            for k, count in enumerate(out.counts):
                assert _finite(out.q[k, :count])
    else:
        out = HOSTILE.attempt(
            "analytic_ik", lambda: optik.analytic_ik(PUMA, target, mode, q_ref, within_limits)
        )
        if out is not None:
            assert all(q.shape == (6,) and _finite(q) for q in out)


@FUZZ
@given(
    target=st.one_of(hostile_array(np.array([1.0, 0.5, 0.0])), hostile_pose(_pose(1.0, 0.5))),
    q_ref=st.one_of(st.none(), hostile_array(np.full(2, 0.1))),
    batch=st.booleans(),
)
def test_hostile_analytic_ik_python_family(
    warm: None, target: Any, q_ref: Any, batch: bool
) -> None:
    if batch:
        out = HOSTILE.attempt(
            "analytic_ik_batch",
            lambda: optik.analytic_ik_batch(PLANAR, [target], "position", q_ref),
        )
        if out is not None:
            for k, count in enumerate(out.counts):
                assert _finite(out.q[k, :count])
    else:
        out = HOSTILE.attempt(
            "analytic_ik", lambda: optik.analytic_ik(PLANAR, target, "position", q_ref)
        )
        if out is not None:
            assert all(_finite(q) for q in out)


DIFF_OPTIONS = {
    "dt": st.one_of(SCALARS, st.sampled_from([0.01, 1e-300, 1e300])),
    "objective": st.one_of(SCALARS, st.sampled_from(["least_norm", "least_squares", "x"])),
    "solver": st.one_of(SCALARS, st.sampled_from(["qp:proxqp", "proxqp", "qp:nope", ["qp"]])),
    "limits": st.one_of(SCALARS, st.booleans()),
    "velocity_limits": st.one_of(hostile_array(np.full(6, 1.0)), st.just(np.full(6, INF))),
    "damping": st.one_of(SCALARS, st.sampled_from([1e-3, 1e-300, 1e300])),
    "limit_gain": st.one_of(SCALARS, st.sampled_from([0.5, 1.0, 1.0000001])),
    "rows": st.one_of(
        SCALARS, st.sampled_from([(0, 1, 2), (), (6,), (-1,), (0, 0), (0.0, 1.0), "012", [True]])
    ),
}


@FUZZ
@given(
    q=st.one_of(st.just(PUMA.mid_limits), hostile_array(np.full(6, 0.1))),
    twist=st.one_of(st.just(np.full(6, 0.1)), hostile_array(np.full(6, 0.1))),
    option=st.sampled_from(sorted(DIFF_OPTIONS)),
    data=st.data(),
)
def test_hostile_diff_ik(warm: None, q: Any, twist: Any, option: str, data: st.DataObject) -> None:
    kwargs: dict[str, Any] = {"dt": 0.01, option: data.draw(DIFF_OPTIONS[option])}
    if option == "damping":
        kwargs["objective"] = "least_squares"
    dq = HOSTILE.attempt("diff_ik", lambda: optik.diff_ik(PUMA, q, twist, **kwargs))
    if dq is not None:
        assert dq.shape == (6,) and _finite(dq)


TRIG_VALUES = st.one_of(SCALARS, FLOATS, st.sampled_from([1.0, 0.5, -2.0, 1e200]))


@FUZZ
@given(
    a=TRIG_VALUES,
    b=TRIG_VALUES,
    c=TRIG_VALUES,
    free_value=st.one_of(st.just(0.0), TRIG_VALUES),
    tol=st.one_of(st.just(1e-12), TRIG_VALUES),
)
def test_hostile_solve_trig(warm: None, a: Any, b: Any, c: Any, free_value: Any, tol: Any) -> None:
    roots = HOSTILE.attempt(
        "solve_trig", lambda: optik.solve_trig(a, b, c, free_value=free_value, tol=tol)
    )
    if roots is not None:
        assert len(roots) <= 2 and _finite(roots)
        assert all(-math.pi < t <= math.pi for t in roots)


@FUZZ
@given(
    a=st.one_of(TRIG_VALUES, hostile_array(np.array([1.0, 2.0]))),
    b=st.one_of(TRIG_VALUES, hostile_array(np.array([0.5, 0.0]))),
    c=st.one_of(TRIG_VALUES, hostile_array(np.array([0.2, 3.0]))),
    free_value=st.one_of(st.just(0.0), TRIG_VALUES),
    tol=st.one_of(st.just(1e-12), TRIG_VALUES),
)
def test_hostile_solve_trig_batch(
    warm: None, a: Any, b: Any, c: Any, free_value: Any, tol: Any
) -> None:
    out = HOSTILE.attempt(
        "solve_trig_batch", lambda: solve_trig_batch(a, b, c, free_value=free_value, tol=tol)
    )
    if out is not None:
        t_plus, t_minus, valid = out
        assert _finite(t_plus, t_minus) and valid.dtype == bool


LINALG = {
    "min_norm": optik.min_norm,
    "least_squares": optik.least_squares,
    "generalized_inverse": optik.generalized_inverse,
}


@FUZZ
@given(
    name=st.sampled_from(sorted(LINALG)),
    A=st.one_of(
        st.just(np.array([[1.0, 2.0, 0.0], [0.0, 1.0, 1.0]])),
        hostile_array(np.array([[1.0, 2.0, 0.0], [0.0, 1.0, 1.0]])),
        st.sampled_from([np.zeros((0, 2, 3)), np.zeros((2, 0)), np.full((2, 2), 1e200)]),
    ),
    b=st.one_of(st.just(np.ones(2)), hostile_array(np.ones(2)), hostile_array(np.ones(3))),
    damping=st.one_of(st.just(0.0), SCALARS, st.sampled_from([1e-3, 1e-300, 1e300, 1e160])),
    max_condition=st.one_of(st.just(1e12), SCALARS),
    transpose=st.booleans(),
)
def test_hostile_linalg(
    warm: None, name: str, A: Any, b: Any, damping: Any, max_condition: Any, transpose: bool
) -> None:
    if transpose and isinstance(A, np.ndarray) and A.ndim >= 2:
        A = np.swapaxes(A, -1, -2)  # a strided view: least squares shapes
    fn = LINALG[name]
    kwargs = {"damping": damping, "max_condition": max_condition}
    call = (lambda: fn(A, **kwargs)) if name == "generalized_inverse" else (
        lambda: fn(A, b, **kwargs)
    )  # fmt: skip
    x = HOSTILE.attempt(name, call)
    if x is not None:
        assert _finite(x)


POSE_KEYS = ["position", "rotation", "quat_wxyz", "quat_xyzw", "rpy", "rpy_convention", "degrees"]
POSE_VALUES = st.one_of(
    SCALARS,
    hostile_array(np.zeros(3)),
    hostile_array(np.eye(3)),
    hostile_array(np.array([1.0, 0.0, 0.0, 0.0])),
    st.sampled_from(["xyz", "ZYX", "rpy", "nope", True, False]),
)


@FUZZ
@given(
    values=st.dictionaries(st.sampled_from(POSE_KEYS), POSE_VALUES, max_size=3),
    target=st.one_of(
        hostile_pose(_pose(0.1, 0.2, 0.3)),
        hostile_array(np.zeros(3)),
        st.tuples(hostile_array(np.zeros(3)), hostile_array(np.eye(3))),
        st.dictionaries(st.sampled_from([*POSE_KEYS, "bogus"]), POSE_VALUES, max_size=2),
    ),
    mode=st.one_of(st.sampled_from(["pose", "position"]), SCALARS),
    converter=st.sampled_from(
        ["to_position_rotation", "to_rotation", "to_quat_wxyz", "to_quat_xyzw", "to_rpy"]
    ),
)
def test_hostile_poses(
    warm: None, values: dict[str, Any], target: Any, mode: Any, converter: str
) -> None:
    T = HOSTILE.attempt("pose", lambda: optik.pose(**values))
    if T is not None:
        assert _finite(T)
    T = HOSTILE.attempt("as_target_pose", lambda: optik.as_target_pose(target, mode))
    if T is not None:
        assert _finite(T)
    out = HOSTILE.attempt(converter, lambda: getattr(optik, converter)(target))
    if out is not None and converter != "to_rotation":
        parts = out if isinstance(out, tuple) else (out,)
        assert _finite(*parts)
    if converter == "to_rpy":
        out = HOSTILE.attempt(
            "to_rpy", lambda: optik.to_rpy(_pose(), rpy_convention=mode, degrees=mode)
        )
        assert out is None or _finite(out)


@FUZZ
@given(robot=st.one_of(SCALARS, st.just(PUMA)), name=st.sampled_from(["solve_ik", "diff_ik"]))
def test_hostile_robot_argument(warm: None, robot: Any, name: str) -> None:
    """A non-Robot anywhere a robot is meant: an OptikError, never an AttributeError."""
    calls: dict[str, Callable[[], Any]] = {
        "solve_ik": lambda: optik.solve_ik(robot, np.eye(4), restarts=1),
        "diff_ik": lambda: optik.diff_ik(robot, np.zeros(6), np.zeros(6), dt=0.01),
    }
    extra: dict[str, Callable[[], Any]] = {
        "solve_ik_batch": lambda: optik.solve_ik_batch(robot, np.eye(4)[None], restarts=1),
        "analytic_ik": lambda: optik.analytic_ik(robot, np.eye(4)),
        "analytic_ik_batch": lambda: optik.analytic_ik_batch(robot, np.eye(4)[None]),
        "plan_path": lambda: optik.plan_path(robot, [np.eye(4)]),
        "reachability": lambda: optik.reachability(robot, np.zeros((1, 3))),
    }
    for label, call in (*calls.items(), *(extra.items() if name == "solve_ik" else ())):
        HOSTILE.attempt(label, call)


@FUZZ
@given(kind=st.one_of(SCALARS, st.sampled_from(["ik", "step", "IK", ["step"]])))
def test_hostile_available_solvers(kind: Any) -> None:
    names = HOSTILE.attempt("available_solvers", lambda: optik.available_solvers(kind=kind))
    if names is not None:
        assert kind in ("ik", "step") and names and all(isinstance(n, str) for n in names)


@pytest.mark.parametrize("bad", [3, "yes", 1.0, [print]])
def test_progress_options_are_checked_before_any_work(bad: Any, tmp_path: Path) -> None:
    """A ``progress`` that is neither a flag nor a callable was found only when first
    called (``plan_path``: a bare ``TypeError`` after its first waypoint was solved)."""
    from optik.campaign import capability_map
    from optik.campaign.batch import solve_batch
    from optik.compare import RunConfig, run
    from optik.paths import line

    robot = optik.load_problem("puma560").robot
    T0 = robot.fk(robot.mid_limits + 0.1)
    T1 = T0.copy()
    T1[:3, 3] += [0.0, 0.0, 0.05]
    calls: list[Callable[[], Any]] = [
        lambda: optik.plan_path(robot, line(T0, T1, 0.01), progress=bad),
        lambda: solve_batch(robot, T0[None], progress=bad),
        lambda: capability_map(robot, voxel=0.5, progress=bad),
        lambda: run(
            RunConfig(problems=("puma560",), solvers=("dls",)), tmp_path / "r.csv", progress=bad
        ),
    ]
    for call in calls:
        with pytest.raises(OptikError, match=r"progress: expected None"):
            call()


def test_plan_path_takes_no_progress_flag() -> None:
    robot = optik.load_problem("puma560").robot
    T0 = robot.fk(robot.mid_limits)
    with pytest.raises(OptikError, match=r"expected None or a callable progress\(done, total\)"):
        optik.plan_path(robot, T0[None], progress=True)
