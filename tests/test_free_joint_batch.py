"""The compiled held-joint pipeline and ``analytic_ik_batch(..., free_joint=...)``.

The single call runs in one compiled call (:func:`optik.analytic.free_joint.solve`); its
answers are checked row for row against the numpy steps (the Newton step on
``Robot.jacobian``, then ``_finish``: wrap, limits, ``Robot.fk``, dedupe, sort) on the same
raw branches, and the batch against single calls.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pybullet_data  # the test extra: its absence is a failure, not a skip
import pytest
from conftest import newton_reference

from optik import Robot
from optik.analytic import _finish, analytic_ik, analytic_ik_batch
from optik.analytic.held_joint import free_joint_raw, free_plan
from optik.errors import AnalyticIKError, NonFiniteError, OptikError, ShapeError

IIWA_URDF = Path(pybullet_data.getDataPath()) / "kuka_iiwa" / "model.urdf"
HELD = (2, 0, 6)  # the direct form (joints 3 and 1) and the chain read backwards (7)


@pytest.fixture(scope="module")
def iiwa() -> Robot:
    return Robot.from_urdf(IIWA_URDF, "lbr_iiwa_link_0", "lbr_iiwa_link_7")


def _targets(robot: Robot, rng: np.random.Generator, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Poses of in-limit configurations (some of them singular: q2, q4 or q6 = 0)."""
    Q = rng.uniform(robot.lower, robot.upper, (n, 7))
    Q[::7, 3] = 0.0
    Q[1::7, 5] = 0.0
    Q[2::7, 1] = 0.0
    return Q, robot.fk(Q)


@pytest.mark.parametrize("k", HELD)
@pytest.mark.parametrize("within", [True, False])
@pytest.mark.parametrize("sort", [True, False])
def test_compiled_call_gives_the_numpy_steps_row_for_row(
    iiwa: Robot, k: int, within: bool, sort: bool
) -> None:
    rng = np.random.default_rng(100 + k)
    name = iiwa.joint_names[k]
    plan = free_plan(iiwa, k)
    Q, T = _targets(iiwa, rng, 120)
    Q[::5] = rng.uniform(iiwa.lower - 1.0, iiwa.upper + 1.0, (len(Q[::5]), 7))  # some out
    Q[::5, k] = np.clip(Q[::5, k], iiwa.lower[k], iiwa.upper[k])
    T = iiwa.fk(Q)
    compared = 0
    for q, target in zip(Q, T, strict=True):
        ref = rng.uniform(iiwa.lower, iiwa.upper) if sort else iiwa.mid_limits.copy()
        got = analytic_ik(
            iiwa,
            target,
            q_ref=ref if sort else None,
            within_limits=within,
            free_joint=name,
            free_value=q[k],
        )
        ref[k] = q[k]
        raw = newton_reference(iiwa, free_joint_raw(plan, q[k], target, ref), target, k)
        expected = _finish(iiwa, raw, target, "pose", ref, sort, within, (k, q[k]))
        if not expected:
            continue  # the fallback's case (polish), not the compiled steps'
        compared += 1
        assert len(got) == len(expected)
        for a, b in zip(got, expected, strict=True):
            assert a[k] == q[k]
            # The Newton step formed twice (compiled, numpy) agrees to rounding times the
            # normal equations' condition: up to 2e-11 next to a singularity.
            np.testing.assert_allclose(a, b, rtol=0.0, atol=1e-9)
    assert compared >= 90


@pytest.mark.parametrize("k", HELD)
def test_batch_equals_single_calls(iiwa: Robot, k: int) -> None:
    rng = np.random.default_rng(200 + k)
    name = iiwa.joint_names[k]
    Q, T = _targets(iiwa, rng, 60)
    T[5, :3, 3] = (3.0, 0.0, 0.5)  # unreachable: no branch
    per_target_ref = rng.uniform(iiwa.lower, iiwa.upper, (60, 7))
    cases = [
        (None, Q[:, k]),  # one value per target, mid-limits reference
        (per_target_ref[0], Q[:, k]),  # one reference for all
        (per_target_ref, float(Q[0, k])),  # one value for all, one reference each
    ]
    for q_ref, values in cases:
        for within in (True, False):
            batch = analytic_ik_batch(
                iiwa, T, q_ref=q_ref, within_limits=within, free_joint=name, free_value=values
            )
            assert batch.q.shape == (60, 8, 7) and batch.counts.shape == (60,)
            assert batch.counts[5] == 0 and np.all(np.isnan(batch.q[5]))
            for i in range(60):
                value = values[i] if np.ndim(values) else values
                ref_i = None if q_ref is None else (q_ref[i] if np.ndim(q_ref) == 2 else q_ref)
                single = analytic_ik(
                    iiwa, T[i], q_ref=ref_i, within_limits=within, free_joint=name,
                    free_value=value,
                )  # fmt: skip
                assert batch.counts[i] == len(single)
                if single:
                    np.testing.assert_array_equal(batch.q[i, : len(single)], np.array(single))
                    assert np.all(batch.q[i, : len(single), k] == value)
                assert np.all(np.isnan(batch.q[i, len(single) :]))


def test_batch_bad_free_values(iiwa: Robot) -> None:
    rng = np.random.default_rng(7)
    Q, T = _targets(iiwa, rng, 4)
    name = "lbr_iiwa_joint_3"
    with pytest.raises(ShapeError, match="free_value"):
        analytic_ik_batch(iiwa, T, free_joint=name, free_value=Q[:3, 2])
    values = Q[:, 2].copy()
    values[2] = 3.0
    with pytest.raises(OptikError, match=r"free_value\[2\] = 3.0 is outside the limits"):
        analytic_ik_batch(iiwa, T, free_joint=name, free_value=values)
    values[2] = math.nan
    with pytest.raises(NonFiniteError, match="free_value"):
        analytic_ik_batch(iiwa, T, free_joint=name, free_value=values)
    with pytest.raises(OptikError, match="free_value is required"):
        analytic_ik_batch(iiwa, T, free_joint=name)
    with pytest.raises(OptikError, match="free_value is given without free_joint"):
        analytic_ik_batch(iiwa, T, free_value=Q[:, 2])
    with pytest.raises(AnalyticIKError, match="mode must be 'pose'"):
        analytic_ik_batch(iiwa, T[:, :3, 3], mode="position", free_joint=name, free_value=0.1)
    with pytest.raises(AnalyticIKError, match="does not change the distance"):
        analytic_ik_batch(iiwa, T, free_joint="lbr_iiwa_joint_4", free_value=0.1)
    bad = T.copy()
    bad[1, :3, :3] *= 2.0
    with pytest.raises(OptikError, match=r"targets\[1\]"):
        analytic_ik_batch(iiwa, bad, free_joint=name, free_value=0.1)


def test_single_call_bad_target_and_reference(iiwa: Robot) -> None:
    """The compiled checks reject what the Python ones reject, with the same errors."""
    target = iiwa.fk(np.full(7, 0.3))
    name = "lbr_iiwa_joint_3"
    bad = target.copy()
    bad[0, 0] = math.nan
    with pytest.raises(NonFiniteError):
        analytic_ik(iiwa, bad, free_joint=name, free_value=0.3)
    bad = target.copy()
    bad[:3, :3] *= 1.1
    with pytest.raises(OptikError, match="rotation"):
        analytic_ik(iiwa, bad, free_joint=name, free_value=0.3)
    with pytest.raises(NonFiniteError, match="q_ref"):
        analytic_ik(iiwa, target, q_ref=np.full(7, math.inf), free_joint=name, free_value=0.3)
    with pytest.raises(ShapeError, match="q_ref"):
        analytic_ik(iiwa, target, q_ref=np.zeros(6), free_joint=name, free_value=0.3)
    # A list target and a non-contiguous one take the same path as a plain array.
    plain = analytic_ik(iiwa, target, free_joint=name, free_value=0.3)
    assert len(plain) >= 1
    as_list = analytic_ik(iiwa, target.tolist(), free_joint=name, free_value=0.3)
    strided = np.asfortranarray(target)
    np.testing.assert_array_equal(np.array(as_list), np.array(plain))
    np.testing.assert_array_equal(
        np.array(analytic_ik(iiwa, strided, free_joint=name, free_value=0.3)), np.array(plain)
    )
