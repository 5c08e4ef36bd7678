"""Batched and compiled closed-form IK: the batch equals the per-target call, the compiled
pipeline equals the numpy one, and bad input raises optik errors."""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np
import pytest
from conftest import random_q, robot_of

import optik
from optik import _kernels, _math
from optik.analytic import (
    AnalyticBatch,
    _compiled,
    _finish,
    _pipeline,
    _rows,
    analytic_ik,
    analytic_ik_batch,
    family_of,
)
from optik.analytic._base import angles
from optik.errors import (
    AnalyticIKError,
    InvalidRotationError,
    NonFiniteError,
    OptikError,
    ShapeError,
)
from optik.model import Robot
from optik.spatial import as_pose, invert_transform

COMPILED = ["puma560", "ur5", "stanford_arm", "jumbo_drill_6dof"]
N_RANDOM = 1000

# Joint values at each arm's singularities: wrist (q5 = 0 or pi), elbow stretched or
# folded, shoulder over the base where the structure allows it.
SINGULAR = {
    "puma560": [(4, 0.0), (2, math.atan2(0.0203, 0.4318) - math.pi / 2), (2, -math.pi / 2)],
    "ur5": [(4, 0.0), (4, math.pi), (2, 0.0), (2, math.pi)],
    "stanford_arm": [(4, 0.0), (1, 0.0)],
    "jumbo_drill_6dof": [(4, 0.0), (1, 0.0)],
}


def _configurations(name: str, rng: np.random.Generator) -> np.ndarray:
    """Random in-limit configurations, then singular and at-limit ones, on purpose."""
    robot = robot_of(name)
    lower = np.where(np.isfinite(robot.lower), robot.lower, -math.pi)
    upper = np.where(np.isfinite(robot.upper), robot.upper, math.pi)
    out = [random_q(robot, rng, N_RANDOM)]
    special = []
    for joint, value in SINGULAR[name]:
        for offset in (0.0, 1e-12, -1e-9, 1e-6):
            for _ in range(5):
                q = random_q(robot, rng)
                q[joint] = value + offset
                special.append(np.clip(q, lower, upper))
    for i in range(robot.dof):
        for bound in (lower[i], upper[i]):
            for nudge in (0.0, 1e-13, -1e-13):
                q = random_q(robot, rng)
                q[i] = bound + nudge  # just outside by 1e-13: inside the 1e-12 slack
                special.append(q)
    # Two singularities at once (wrist and elbow).
    for _ in range(10):
        q = random_q(robot, rng)
        for joint, value in SINGULAR[name][:2]:
            q[joint] = value
        special.append(np.clip(q, lower, upper))
    out.append(np.array(special))
    return np.vstack(out)


def _assert_same(batch: AnalyticBatch, k: int, expected: list[np.ndarray]) -> None:
    """Target ``k`` of ``batch`` holds exactly ``expected`` (same rows, same order)."""
    count = int(batch.counts[k])
    assert count == len(expected), f"target {k}: {count} branches, expected {len(expected)}"
    if expected:
        np.testing.assert_array_equal(batch.q[k, :count], np.array(expected))
    assert np.all(np.isnan(batch.q[k, count:]))


@pytest.mark.parametrize("name", COMPILED)
def test_batch_equals_per_target_calls(name: str, rng: np.random.Generator) -> None:
    robot = robot_of(name)
    assert family_of(robot) is not None and family_of(robot).kernel  # type: ignore[union-attr]
    Q = _configurations(name, rng)
    T = robot.fk(Q)
    other = random_q(robot, rng, len(Q))
    shared = random_q(robot, rng)
    runs: list[tuple[dict[str, Any], Callable[[int], dict[str, Any]]]] = [
        ({}, lambda k: {}),
        ({"q_ref": Q}, lambda k: {"q_ref": Q[k]}),
        ({"q_ref": shared}, lambda k: {"q_ref": shared}),
        (
            {"q_ref": other, "within_limits": False},
            lambda k: {"q_ref": other[k], "within_limits": False},
        ),
        ({"within_limits": False}, lambda k: {"within_limits": False}),
    ]
    for batch_kwargs, single_kwargs in runs:
        batch = analytic_ik_batch(robot, T, **batch_kwargs)
        assert batch.q.shape == (len(Q), _compiled.MAX_BRANCHES, robot.dof)
        assert batch.counts.shape == (len(Q),) and batch.counts.dtype == np.int64
        for k in range(len(Q)):
            _assert_same(batch, k, analytic_ik(robot, T[k], **single_kwargs(k)))
    # Every in-limit configuration is recovered: the batch never loses a branch.
    nearest = analytic_ik_batch(robot, T, q_ref=Q)
    assert np.all(nearest.counts > 0)
    assert np.max(np.abs(nearest.first[:N_RANDOM] - Q[:N_RANDOM])) < 1e-6


@pytest.mark.parametrize("name", COMPILED)
def test_compiled_pipeline_equals_numpy_pipeline(name: str, rng: np.random.Generator) -> None:
    """Wrapping, limits, FK check, dedupe and sort: compiled == numpy, on the same raw rows."""
    robot = robot_of(name)
    family = family_of(robot)
    assert family is not None
    Q = _configurations(name, rng)[::3]
    refs = np.vstack([Q[: len(Q) // 2], random_q(robot, rng, len(Q) - len(Q) // 2)])
    T_base_inv = invert_transform(robot.T_world_base)
    T_tool_inv = invert_transform(robot.T_flange_tool)
    for q, ref in zip(Q, refs, strict=True):
        T = robot.fk(q)
        raw = family.candidates(robot, T_base_inv @ T @ T_tool_inv, "pose", ref)
        for within in (True, False):
            expected = _finish(robot, raw, T, "pose", ref, True, within)
            got = analytic_ik(robot, T, q_ref=ref, within_limits=within)
            assert len(got) == len(expected)
            if got:
                np.testing.assert_array_equal(np.array(got), np.array(expected))


@pytest.mark.parametrize("name", ["puma560", "ur5", "stanford_arm"])
def test_verification_rejects_what_fk_rejects(name: str, rng: np.random.Generator) -> None:
    """Every returned branch reaches the target by ``Robot.fk``; nothing is lost either."""
    robot = robot_of(name)
    Q = random_q(robot, rng, 300)
    T = robot.fk(Q)
    batch = analytic_ik_batch(robot, T, within_limits=False)
    for k in range(len(Q)):
        B = batch.q[k, : batch.counts[k]]
        T_b = robot.fk(B)
        assert np.all(np.linalg.norm(T_b[:, :3, 3] - T[k, :3, 3], axis=1) <= 1e-9)
        for T_i in T_b:
            assert optik.spatial.pose_error(T_i, T[k])[1] <= 1e-9


def test_fk_shared_prefix_is_fk_into_bit_for_bit(rng: np.random.Generator) -> None:
    """Given libm's sines and cosines, the pipeline's FK is fk_into's arithmetic exactly."""
    for name in COMPILED:
        robot = robot_of(name)
        n = robot.dof
        K, prismatic = robot.chain.K, robot.chain.prismatic
        params = _compiled.params_of(robot, family_of(robot).kernel)  # type: ignore[union-attr]
        pre = np.empty((n + 2, 12))
        pre[0] = K[0, :3, :].reshape(-1)
        block = np.empty((3 * _compiled.MAX_BRANCHES, n))  # rows, their sines, cosines
        depth = 0
        out = np.empty((4, 4))
        q = random_q(robot, rng)
        for _ in range(300):
            # Keep a random prefix of the previous configuration, change the rest.
            keep = int(rng.integers(0, n + 1))
            q = np.concatenate([q[:keep], random_q(robot, rng)[keep:]])
            r = int(rng.integers(0, _compiled.MAX_BRANCHES))
            block[r] = q
            block[_compiled.MAX_BRANCHES + r] = [math.sin(v) for v in q]
            block[2 * _compiled.MAX_BRANCHES + r] = [math.cos(v) for v in q]
            depth = _rows.fk_shared(params, _pipeline.SIX_JOINT_LAYOUT, block, r, pre, depth)
            _kernels.fk_into(K, prismatic, q, out)
            np.testing.assert_array_equal(pre[n], out[:3].reshape(-1))


def test_inline_sincos_is_within_one_ulp_of_libm(rng: np.random.Generator) -> None:
    k = np.arange(-5000, 5000) * (math.pi / 2)
    x = np.concatenate(
        [
            rng.uniform(-7.0, 7.0, 20000),
            rng.uniform(-1e5, 1e5, 5000),
            rng.normal(size=2000) * 1e-9,
            k,
            np.nextafter(k, np.inf),
            np.nextafter(k, -np.inf),
            [0.0, -0.0, math.pi / 4, -math.pi / 4, 1e5, -1e5, 1e6, 1e300, np.inf, np.nan],
        ]
    )
    # The pipeline's block form: 8 rows of 6 values, sines and cosines below them.
    m = _compiled.MAX_BRANCHES
    S = np.empty_like(x)
    C = np.empty_like(x)
    block = np.empty((3 * m, 6))
    for start in range(0, len(x), 6 * m):
        chunk = x[start : start + 6 * m]
        rows = -(-len(chunk) // 6)
        block[:rows] = np.resize(chunk, (rows, 6))  # pads the last row by repetition
        _pipeline.sincos_block(block.reshape(-1), rows * 6, 6)
        S[start : start + len(chunk)] = block[m : m + rows].reshape(-1)[: len(chunk)]
        C[start : start + len(chunk)] = block[2 * m : 2 * m + rows].reshape(-1)[: len(chunk)]
    finite = np.isfinite(x)
    S_ref = np.array([math.sin(v) if math.isfinite(v) else math.nan for v in x])
    C_ref = np.array([math.cos(v) if math.isfinite(v) else math.nan for v in x])
    assert np.all(np.isnan(S[~finite])) and np.all(np.isnan(C[~finite]))
    for got, ref in ((S[finite], S_ref[finite]), (C[finite], C_ref[finite])):
        err = np.abs(got - ref)
        assert err.max() <= 2e-16  # absolute, everywhere (also next to the zeros)
        away = np.abs(ref) > 1e-3  # relative, away from the zeros: at most one ulp
        assert np.all(err[away] <= np.spacing(np.abs(ref[away])))
    assert math.copysign(1.0, _math.sincos(-0.0)[0]) == -1.0
    for i in range(0, len(x), 97):
        if finite[i]:
            assert _math.sincos(x[i]) == (S[i], C[i])


def test_singular_coefficients_make_a_free_joint_or_no_root(rng: np.random.Generator) -> None:
    # The closed forms' rule on top of the trig equation: a = b = 0 (relative 1e-12) is a
    # free joint (the reference angle) when c = 0 (relative 1e-9), else no root.
    assert angles(0.0, 0.0, 0.0, 0.25) == (0.25,)
    assert angles(1e-14, -1e-14, 1e-10, 0.25) == (0.25,)
    assert angles(0.0, 0.0, 1e-6, 0.25) == ()
    assert angles(1e-14, 0.0, 1.0, 0.25) == ()
    # Away from it, the roots of solve_trig, each a root of the equation (independent check).
    for _ in range(500):
        a, b, c = rng.normal(size=3) * rng.choice([1e-3, 1.0, 10.0])
        roots = angles(a, b, c, 0.25)
        assert roots == optik.solve_trig(a, b, c)
        for t in roots:
            assert abs(a * math.cos(t) + b * math.sin(t) - c) <= 1e-6 * max(1.0, abs(c))


def test_compiled_pose_checks_match_as_pose(rng: np.random.Generator) -> None:
    rot_tol, row_tol = _compiled.pose_tolerances()
    for _ in range(2000):
        T = robot_of("puma560").fk(random_q(robot_of("puma560"), rng))
        scale = rng.choice([0.0, 1e-10, 5e-7, 1e-6, 2e-6, 1e-3])
        T[:3, :3] += rng.normal(size=(3, 3)) * scale
        if rng.random() < 0.1:
            T[3, int(rng.integers(0, 4))] += rng.choice([1e-10, 2e-9])
        try:
            as_pose("T", T)
            valid = True
        except OptikError:
            valid = False
        assert (_math.pose_defect(T[None], 0, rot_tol, row_tol) == 0) == valid


@pytest.mark.parametrize("name", ["puma560", "ur5", "stanford_arm", "jumbo_drill_6dof"])
def test_unreachable_targets_give_no_branch(name: str) -> None:
    robot = robot_of(name)
    T = np.tile(np.eye(4), (3, 1, 1))
    T[:, :3, 3] = [[10.0, 0.0, 0.0], [0.0, -50.0, 3.0], [0.0, 0.0, 100.0]]
    batch = analytic_ik_batch(robot, T)
    np.testing.assert_array_equal(batch.counts, [0, 0, 0])
    assert np.all(np.isnan(batch.q))
    assert not np.any(batch.solved)
    assert batch.branches(1) == []


def test_mixed_batch_and_result_helpers(rng: np.random.Generator) -> None:
    robot = robot_of("ur5")
    Q = random_q(robot, rng, 4)
    T = robot.fk(Q)
    T[2, :3, 3] = [5.0, 5.0, 5.0]  # unreachable
    batch = analytic_ik_batch(robot, T, q_ref=Q)
    q, counts = batch  # unpacks as a pair
    assert q is batch.q and counts is batch.counts
    np.testing.assert_array_equal(batch.solved, [True, True, False, True])
    assert np.all(np.isnan(batch.first[2]))
    np.testing.assert_allclose(batch.first[[0, 1, 3]], Q[[0, 1, 3]], atol=1e-9)
    branches = batch.branches(0)
    assert len(branches) == counts[0]
    for got, expected in zip(branches, analytic_ik(robot, T[0], q_ref=Q[0]), strict=True):
        np.testing.assert_array_equal(got, expected)


def test_empty_batch() -> None:
    robot = robot_of("puma560")
    batch = analytic_ik_batch(robot, np.empty((0, 4, 4)))
    assert batch.q.shape == (0, _compiled.MAX_BRANCHES, 6)
    assert batch.counts.shape == (0,)


def _python_family_targets(robot: Robot, rng: np.random.Generator) -> np.ndarray:
    """Configurations for a family run in Python: random ones inside the limits, random
    ones anywhere in [-pi, pi] (some reachable only outside the limits), and each joint
    at 0 and pi in turn (the planar arm stretched and folded onto its base)."""
    Q = [random_q(robot, rng, 40), rng.uniform(-math.pi, math.pi, (20, robot.dof))]
    for j in range(robot.dof):
        for value in (0.0, math.pi):
            q = robot.mid_limits.copy()
            q[j] = value
            Q.append(q[None])
    return np.concatenate(Q)


@pytest.mark.parametrize(
    ("name", "mode"),
    [
        ("planar_2r", "position"),
        ("jumbo_spherical_arm", "position"),
        ("jumbo_spherical_arm", "pose"),
        ("dobot_magician", "position"),
        ("dobot_magician", "pose"),
    ],
)
def test_python_families_batch_equals_per_target_calls(
    name: str, mode: str, rng: np.random.Generator
) -> None:
    """The batched checks (one wrap, limit test and FK over every row) give each target
    exactly what analytic_ik gives it alone: reachable, reachable only outside the
    limits (the polish then runs and finds none), singular, beyond reach."""
    robot = robot_of(name)
    family = family_of(robot)
    assert family is not None and not family.kernel
    Q = _python_family_targets(robot, rng)
    T = robot.fk(Q)
    T[-1, :3, 3] = robot.reach_sphere[0] + 10.0 * robot.reach_sphere[1]  # beyond reach
    targets = T if mode == "pose" else T[:, :3, 3]
    ref = random_q(robot, rng)
    runs: list[tuple[dict[str, Any], Callable[[int], dict[str, Any]]]] = [
        ({}, lambda k: {}),
        ({"q_ref": Q}, lambda k: {"q_ref": Q[k]}),
        ({"q_ref": ref}, lambda k: {"q_ref": ref}),
        ({"within_limits": False}, lambda k: {"within_limits": False}),
    ]
    for kwargs, single in runs:
        batch = analytic_ik_batch(robot, targets, mode=mode, **kwargs)
        assert batch.q.shape[0] == len(Q) and batch.q.shape[2] == robot.dof
        for k in range(len(Q)):
            _assert_same(batch, k, analytic_ik(robot, targets[k], mode=mode, **single(k)))
        prismatic = any(joint.kind == "prismatic" for joint in robot.joints)
        if kwargs.get("within_limits", True) or not prismatic:
            assert batch.counts[-1] == 0  # beyond reach
        else:  # the sphere counts strokes up to the limits: beyond them a branch reaches
            for q in batch.q[-1, : batch.counts[-1]]:
                F = robot.fk(q)
                assert np.linalg.norm(F[:3, 3] - T[-1, :3, 3]) <= 1e-9 * np.linalg.norm(
                    T[-1, :3, 3]
                )
                assert not robot.within_limits(q)
        assert np.all(batch.counts[:40] >= 1)  # inside the limits: found
    if mode == "position":  # a batch of 4x4 poses is accepted, its translations used
        batch = analytic_ik_batch(robot, T, mode=mode)
        np.testing.assert_array_equal(
            batch.counts, analytic_ik_batch(robot, targets, mode=mode).counts
        )


def test_single_call_accepts_any_array_like(rng: np.random.Generator) -> None:
    """The fast path (float64, C-contiguous) and the validated path give the same branches."""
    robot = robot_of("puma560")
    q = random_q(robot, rng)
    T = robot.fk(q)
    expected = analytic_ik(robot, T, q_ref=q)
    readonly = T.copy()
    readonly.flags.writeable = False
    for target in (T.tolist(), np.asfortranarray(T), readonly, np.repeat(T, 2, axis=1)[:, ::2]):
        got = analytic_ik(robot, target, q_ref=q.tolist())
        np.testing.assert_array_equal(np.array(got), np.array(expected))
    # Returned arrays are independent of later calls.
    first = analytic_ik(robot, T)
    snapshot = [b.copy() for b in first]
    analytic_ik(robot, robot.fk(random_q(robot, rng)))
    for a, b in zip(first, snapshot, strict=True):
        np.testing.assert_array_equal(a, b)


def test_hot_path_takes_kernel_arrays_as_they_are(
    rng: np.random.Generator, monkeypatch: pytest.MonkeyPatch
) -> None:
    """float64 C-contiguous targets (also rows of Robot.fk's batch, whose dtype object is
    not numpy's singleton) skip the Python validators: the kernel checks them."""
    import optik.analytic as analytic

    robot = robot_of("ur5")
    Q = random_q(robot, rng, 3)
    poses = robot.fk(Q)  # made by a numba kernel
    analytic_ik(robot, poses[0])  # builds the robot's plan

    def fail(*args: Any, **kwargs: Any) -> Any:
        raise AssertionError("the hot path called a Python validator")

    monkeypatch.setattr(analytic, "as_target_pose", fail)
    monkeypatch.setattr(analytic, "check_ref", fail)
    for k in range(3):
        assert analytic_ik(robot, poses[k], q_ref=Q[k].copy())
        assert analytic_ik(robot, np.array(poses[k]))


def test_bad_batches_raise_optik_errors() -> None:
    robot = robot_of("puma560")
    T = np.tile(robot.fk(robot.mid_limits), (5, 1, 1))
    bad = T.copy()
    bad[3, 0, 3] = np.nan
    with pytest.raises(NonFiniteError):
        analytic_ik_batch(robot, bad)
    with pytest.raises(ShapeError):
        analytic_ik_batch(robot, T[:, :3, :])
    with pytest.raises(ShapeError):
        analytic_ik_batch(robot, T[0])  # one pose is not a batch
    with pytest.raises(ShapeError):
        analytic_ik_batch(robot, [[1.0, 2.0], [3.0]])  # ragged
    skewed = T.copy()
    skewed[2, 0, 1] += 0.1
    with pytest.raises(InvalidRotationError, match=r"targets\[2\]"):
        analytic_ik_batch(robot, skewed)
    mirrored = T.copy()
    mirrored[4, :3, 0] *= -1.0  # det = -1
    with pytest.raises(InvalidRotationError, match=r"targets\[4\]"):
        analytic_ik_batch(robot, mirrored)
    last_row = T.copy()
    last_row[1, 3, 0] = 1.0
    with pytest.raises(ShapeError, match=r"targets\[1\]"):
        analytic_ik_batch(robot, last_row)
    with pytest.raises(ShapeError):
        analytic_ik_batch(robot, T, q_ref=np.zeros((2, 6)))  # neither one nor N references
    with pytest.raises(ShapeError):
        analytic_ik_batch(robot, T, q_ref=np.zeros(5))
    with pytest.raises(NonFiniteError):
        analytic_ik_batch(robot, T, q_ref=np.full(6, np.inf))
    with pytest.raises(AnalyticIKError, match="mode"):
        analytic_ik_batch(robot, T, mode="orientation")
    with pytest.raises(AnalyticIKError, match="solves mode"):
        analytic_ik_batch(robot, T[:, :3, 3], mode="position")
    panda = robot_of("panda")
    with pytest.raises(AnalyticIKError, match="no closed-form"):
        analytic_ik_batch(panda, T)
    planar = robot_of("planar_2r")
    with pytest.raises(NonFiniteError):
        analytic_ik_batch(planar, [[1.0, np.nan, 0.0]], mode="position")


def test_single_call_rejects_bad_input_on_the_fast_path() -> None:
    robot = robot_of("ur5")
    T = robot.fk(robot.mid_limits)
    bad = T.copy()
    bad[1, 1] = np.inf
    with pytest.raises(NonFiniteError):
        analytic_ik(robot, bad)
    skewed = T.copy()
    skewed[0, 1] += 1e-3
    with pytest.raises(InvalidRotationError):
        analytic_ik(robot, skewed)
    with pytest.raises(NonFiniteError):
        analytic_ik(robot, T, q_ref=np.array([0.0, np.nan, 0.0, 0.0, 0.0, 0.0]))
    with pytest.raises(AnalyticIKError, match="single configuration"):
        analytic_ik(robot, T, q_ref=np.zeros((2, 6)))
    with pytest.raises(ShapeError):
        analytic_ik(robot, T, q_ref=np.zeros(4))


def test_base_and_tool_frames_are_honoured(rng: np.random.Generator) -> None:
    """A robot with a base pose and a tool offset: the compiled path removes both."""
    puma = robot_of("puma560")
    assert puma.dh is not None
    base = np.eye(4)
    base[:3, :3] = optik.spatial.rpy_to_matrix(0.1, -0.2, 0.3)
    base[:3, 3] = [0.5, -0.2, 0.1]
    tool = np.eye(4)
    tool[:3, :3] = optik.spatial.rot_x(0.4)
    tool[:3, 3] = [0.0, 0.02, 0.1]
    robot = Robot.from_dh(
        puma.dh, name="puma_tool", base=base, tool=tool, analytic="spherical_wrist"
    )
    Q = random_q(robot, rng, 100)
    T = robot.fk(Q)
    batch = analytic_ik_batch(robot, T, q_ref=Q)
    assert np.all(batch.counts > 0)
    np.testing.assert_allclose(batch.first, Q, atol=1e-6)
    for k in range(len(Q)):
        _assert_same(batch, k, analytic_ik(robot, T[k], q_ref=Q[k]))
