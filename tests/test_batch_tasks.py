"""solve_ik_batch takes solve_ik's task keywords: frozen joints, a limit margin, q0 per target."""

from __future__ import annotations

import inspect

import numpy as np
import pytest

import optik
from optik.errors import JointLimitError, OptikError

PANDA = optik.load_problem("panda").robot
UR5 = optik.load_problem("ur5").robot


def _poses(
    robot: optik.Robot, n: int, seed: int, inset: float = 0.0
) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    Q = rng.uniform(robot.lower + inset, robot.upper - inset, size=(n, robot.dof))
    return Q, np.array([robot.fk(q) for q in Q])


def _pose_errors(robot: optik.Robot, q: np.ndarray, T: np.ndarray) -> tuple[float, float]:
    F = robot.fk(q)
    cos = (np.trace(T[:3, :3].T @ F[:3, :3]) - 1.0) / 2.0
    return float(np.linalg.norm(F[:3, 3] - T[:3, 3])), float(np.arccos(np.clip(cos, -1, 1)))


def test_entry_points_list_their_keywords() -> None:
    shared = ["mode", "axis", "weights", "q0", "tol", "max_iter", "restarts", "seed", "frozen",
              "limit_margin"]  # fmt: skip
    for fn in (optik.solve_ik, optik.solve_ik_all, optik.solve_ik_batch):
        parameters = inspect.signature(fn).parameters
        assert all(name in parameters for name in shared), fn.__name__
        assert not any(p.kind is p.VAR_KEYWORD for p in parameters.values()), fn.__name__
    with pytest.raises(TypeError, match="solve_ik"):
        optik.solve_ik(PANDA, PANDA.fk(PANDA.mid_limits), max_iters=3)  # type: ignore[call-arg]


def test_batch_takes_the_defaults_solve_ik_takes() -> None:
    """``max_iter=None`` is the solvers' own default in both entry points (100 iterations
    for the damped least squares): the same answers as ``max_iter=100``; a bad value is
    refused by both alike."""
    _, T = _poses(UR5, 12, 4)
    default = optik.solve_ik_batch(UR5, T, max_iter=None, threads=1)
    explicit = optik.solve_ik_batch(UR5, T, max_iter=100, threads=1)
    np.testing.assert_array_equal(default.q, explicit.q)
    np.testing.assert_array_equal(default.status, explicit.status)
    assert default.success.all()
    assert optik.solve_ik(UR5, T[0], solver="dls", max_iter=None).success
    for call in (optik.solve_ik, optik.solve_ik_batch):
        with pytest.raises(OptikError, match="max_iter"):
            call(UR5, T[:1] if call is optik.solve_ik_batch else T[0], max_iter=0)


def test_batch_holds_frozen_joints_and_answers_like_solve_ik() -> None:
    Q, T = _poses(PANDA, 120, 1)
    name = PANDA.joint_names[2]
    value = 0.3
    Q[:, 2] = value
    T = np.array([PANDA.fk(q) for q in Q])
    batch = optik.solve_ik_batch(PANDA, T, frozen={name: value}, threads=2)
    assert batch.success.mean() >= 0.99
    for k in np.flatnonzero(batch.success):
        assert batch.q[k, 2] == value
        position, orientation = _pose_errors(PANDA, batch.q[k], T[k])
        assert position <= 1e-6 and orientation <= 1e-6
        assert np.all(batch.q[k] >= PANDA.lower) and np.all(batch.q[k] <= PANDA.upper)
    single = optik.solve_ik(PANDA, T[0], solver="dls", frozen={name: value})
    assert single.success and single.q[2] == value


def test_batch_keeps_the_limit_margin() -> None:
    margin = 0.15
    _, T = _poses(UR5, 80, 2, inset=margin)
    batch = optik.solve_ik_batch(UR5, T, limit_margin=margin)
    assert batch.success.mean() >= 0.99
    finite = np.isfinite(UR5.upper - UR5.lower)
    for k in np.flatnonzero(batch.success):
        q = batch.q[k]
        assert np.all(q[finite] >= UR5.lower[finite] + margin - 1e-12)
        assert np.all(q[finite] <= UR5.upper[finite] - margin + 1e-12)
        position, orientation = _pose_errors(UR5, q, T[k])
        assert position <= 1e-6 and orientation <= 1e-6


def test_batch_takes_one_q0_per_target() -> None:
    Q, T = _poses(PANDA, 70, 3)
    near = Q + 1e-3  # each target's own start, next to its source configuration
    near = np.clip(near, PANDA.lower, PANDA.upper)
    batch = optik.solve_ik_batch(PANDA, T, q0=near, restarts=0, threads=2)
    assert batch.success.all()
    # From a start 1e-3 rad away the answer is the source configuration's neighbour.
    assert np.max(np.abs(batch.q - Q)) < 1e-2
    assert batch.restarts.max() == 0
    # The same per-target starts, one call per target, give the same answers.
    for k in (0, 33, 69):
        alone = optik.solve_ik_batch(PANDA, T[k : k + 1], q0=near[k], restarts=0, seed=k)
        np.testing.assert_array_equal(alone.q[0], batch.q[k])


@pytest.mark.parametrize(
    ("kwargs", "error", "field"),
    [
        ({"q0": np.zeros((3, 7))}, OptikError, "q0"),  # neither (dof,) nor (N, dof)
        ({"q0": np.full((5, 7), 10.0)}, JointLimitError, "panda_joint1"),
        ({"frozen": {"nope": 0.0}}, OptikError, "frozen"),
        ({"frozen": {"panda_joint1": 9.0}}, JointLimitError, "panda_joint1"),
        ({"limit_margin": 3.0}, OptikError, "limit_margin"),
        ({"limit_margin": -0.1}, OptikError, "limit_margin"),
    ],
)
def test_batch_bad_keywords(kwargs: dict[str, object], error: type, field: str) -> None:
    _, T = _poses(PANDA, 5, 4)
    with pytest.raises(error, match=field):
        optik.solve_ik_batch(PANDA, T, **kwargs)  # type: ignore[arg-type]


@pytest.mark.parametrize("name", ["panda", "ur5"])
def test_every_joint_frozen_is_judged_not_searched(name: str) -> None:
    # One configuration in the box: the target it reaches converges, another is a proof
    # of "unreachable" at once (a search ran restart after restart to its budget: 86,574
    # in a 0.5 s timeout, then "timeout"), in solve_ik, solve_ik_all and the batch alike.
    robot = optik.load_problem(name).robot
    q = robot.mid_limits + 0.2
    frozen = dict(zip(robot.joint_names, q.tolist(), strict=True))
    reached, missed = robot.fk(q), robot.fk(robot.mid_limits)
    for kw in ({}, {"timeout_s": 0.5}, {"weights": [1, 1, 1, 1, 1, 0.5]}):
        hit = optik.solve_ik(robot, reached, frozen=frozen, **kw)
        assert hit.success and hit.status == "converged" and np.array_equal(hit.q, q)
        miss = optik.solve_ik(robot, missed, frozen=frozen, **kw)
        assert not miss.success and miss.status == "unreachable"
        assert (
            miss.restarts == 0 and miss.iterations == 0 and "every joint is frozen" in miss.message
        )
        assert np.array_equal(miss.q, q)
        batch_kw = {key: value for key, value in kw.items() if key != "timeout_s"}
        batch = optik.solve_ik_batch(robot, np.stack([reached, missed]), frozen=frozen, **batch_kw)
        assert batch.success.tolist() == [True, False]
        assert batch.status.tolist() == ["converged", "unreachable"]
        assert np.array_equal(batch.q, np.stack([q, q]))
    assert [a.q.tolist() for a in optik.solve_ik_all(robot, reached, frozen=frozen)] == [q.tolist()]
    assert optik.solve_ik_all(robot, missed, frozen=frozen) == []


# Tool-axis targets of the UR5 (tool point, tool z axis) that an axis-mode capability map
# sampled: reachable over a narrow stretch of roll only, which three restarts of the
# search miss.
NARROW_ROLL_TARGETS = [
    ((-0.75, -0.5, -0.160541), (0.08104581592239497, -0.923475270768781, 0.375)),
    ((-0.75, -0.5, -0.160541), (-0.22313565385811268, -0.4296341233855995, -0.875)),
    ((-0.25, -0.5, -0.660541), (0.782182092608331, -0.4975602214836433, -0.375)),
]


def _axis_target(point: tuple[float, ...], axis: tuple[float, ...]) -> np.ndarray:
    """A pose whose translation is ``point`` and whose z column is ``axis``."""
    z = np.array(axis) / np.linalg.norm(axis)
    x = np.cross([0.0, 0.0, 1.0] if abs(z[2]) < 0.9 else [1.0, 0.0, 0.0], z)
    x /= np.linalg.norm(x)
    T = np.eye(4)
    T[:3, :3] = np.column_stack([x, np.cross(z, x), z])
    T[:3, 3] = point
    return T


def test_axis_targets_on_a_narrow_roll_are_answered_by_the_rolled_closed_form() -> None:
    """As solve_ik does, the batch answers a tool-axis task from the closed form over a grid
    of rolls where its search misses: every target here is solved, exactly."""
    T = np.array([_axis_target(p, a) for p, a in NARROW_ROLL_TARGETS])
    for threads in (1, 2):
        batch = optik.solve_ik_batch(UR5, T, mode="axis", restarts=3, seed=0, threads=threads)
        assert list(batch.status) == ["converged"] * len(T)
        for k in range(len(T)):
            F = UR5.fk(batch.q[k])
            assert np.linalg.norm(F[:3, 3] - T[k, :3, 3]) <= 1e-9
            assert np.linalg.norm(np.cross(F[:3, 2], T[k, :3, 2])) <= 1e-9
            assert F[:3, 2] @ T[k, :3, 2] > 0.0
            assert np.all(batch.q[k] >= UR5.lower) and np.all(batch.q[k] <= UR5.upper)
        assert np.all(batch.position_error <= 1e-9)
    single = [optik.solve_ik(UR5, t, mode="axis", restarts=3, seed=0) for t in T]
    assert all(r.success and r.solver == "analytic" for r in single)


def test_a_plain_task_on_a_large_arm_takes_no_compromise() -> None:
    """On an arm of several metres the search runs in the arm's units (a balanced twin
    of the task), which is no graded task: a row beyond the reach sphere stays NaN and a
    missed row keeps its best attempt, as on an arm of a metre and as in solve_ik. The
    rows took the weighted compromise instead (the slide driven to its end)."""
    arm = optik.load_problem("jumbo_spherical_arm").robot
    centre, radius = arm.reach_sphere
    far = np.eye(4)
    far[:3, 3] = centre + 2.0 * radius * np.array([0.6, 0.0, 0.8])
    _, T = _poses(arm, 2, 5)
    miss = T[0].copy()
    miss[:3, :3] = T[1][:3, :3] @ np.diag([1.0, -1.0, -1.0])  # a turned orientation
    batch = optik.solve_ik_batch(arm, np.stack([far, miss]), restarts=0, max_iter=1, proofs=False)
    assert batch.status[0] == "unreachable" and np.all(np.isnan(batch.q[0]))
    assert batch.status[1] == "max_iter" and batch.iterations[1] == 1
    single = optik.solve_ik(arm, miss, restarts=0, max_iter=1, warm_start="q0")
    assert not single.success
    np.testing.assert_allclose(batch.q[1], single.q, atol=1e-12)
