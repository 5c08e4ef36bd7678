"""A pose whose every closed-form branch lies outside the limits is proven so at once.

The quick proof (:mod:`optik.analytic._outside`) answers "no branch in the limits" without
the Gauss-Newton polish when all eight branches exist, are isolated and lie outside by a
margin. It must give what the polish gives, be sound (checked here by scipy's bounded
least squares), and leave the polish to every pose it cannot settle: a branch near a
limit (modulo 2 pi too) or at a singularity. A pose without any candidate (beyond the
elbow's reach) has nothing to polish.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import scaled_problem
from scipy.optimize import least_squares

import optik
import optik.analytic as analytic
from optik.problems import load_problem
from optik.spatial import rotation_angle


@pytest.fixture(scope="module")
def puma() -> optik.Robot:
    return load_problem("puma560").robot


def _counted(monkeypatch: pytest.MonkeyPatch, name: str) -> list[int]:
    """Counts the calls of ``optik.analytic.<name>`` during a test (one entry a call)."""
    calls: list[int] = []
    original = getattr(analytic, name)

    def counted(*args, **kwargs):
        calls.append(1)
        return original(*args, **kwargs)

    monkeypatch.setattr(analytic, name, counted)
    return calls


@pytest.fixture
def polish_calls(monkeypatch: pytest.MonkeyPatch) -> list[int]:
    """Counts the fallback's runs (``optik.analytic._degenerate``) during a test."""
    return _counted(monkeypatch, "_degenerate")


def _narrowed(robot: optik.Robot, fraction: float) -> optik.Robot:
    mid, half = robot.mid_limits, (robot.upper - robot.lower) / 2
    return robot.with_limits(mid - fraction * half, mid + fraction * half)


def _poses(robot: optik.Robot, n: int, seed: int) -> np.ndarray:
    """Poses of configurations 30 % beyond the limits on either side (n, 4, 4)."""
    half = (robot.upper - robot.lower) / 2
    rng = np.random.default_rng(seed)
    Q = rng.uniform(robot.lower - 0.3 * half, robot.upper + 0.3 * half, (n, robot.dof))
    return robot.fk(Q)


def _never_proven(robot, pipeline, T, *args):
    return np.zeros(len(T), dtype=bool)


def test_the_quick_proof_gives_what_the_polish_gives(puma, monkeypatch, polish_calls):
    robot = _narrowed(puma, 0.4)
    T = _poses(robot, 120, 1)
    ref = robot.mid_limits + 0.05
    quick = [analytic.analytic_ik(robot, t, q_ref=ref) for t in T]
    quick_batch = analytic.analytic_ik_batch(robot, T)
    polished_quickly = len(polish_calls)
    monkeypatch.setattr(analytic, "proven_outside", _never_proven)
    slow = [analytic.analytic_ik(robot, t, q_ref=ref) for t in T]
    slow_batch = analytic.analytic_ik_batch(robot, T)
    empty = sum(not branches for branches in slow)
    assert empty >= 60  # the narrowed arm misses most of these poses
    # Both passes (single calls and the batch) polish only what the proof leaves: most
    # of the empty poses are settled without it.
    assert polished_quickly <= empty // 2
    for a, b in zip(quick, slow, strict=True):
        assert len(a) == len(b) and all(map(np.array_equal, a, b))
    assert np.array_equal(quick_batch.counts, slow_batch.counts)
    assert np.array_equal(quick_batch.q, slow_batch.q, equal_nan=True)


def _outside_distance(robot: optik.Robot, q: np.ndarray) -> float:
    """How far ``q`` is outside the limits, over every 2 pi shift of revolute joints."""
    worst = 0.0
    for j, joint in enumerate(robot.joints):
        lo, hi = robot.lower[j], robot.upper[j]
        shifts = range(-3, 4) if joint.kind == "revolute" else [0]
        worst = max(
            worst,
            min(max(lo - (q[j] + 2 * math.pi * k), q[j] + 2 * math.pi * k - hi) for k in shifts),
        )
    return worst


def test_a_quick_proof_is_sound(puma, polish_calls):
    robot = _narrowed(puma, 0.4)
    T = _poses(robot, 60, 2)
    proven = [t for t in T if not analytic.analytic_ik(robot, t)]
    assert len(proven) - len(polish_calls) >= 20  # poses the quick proof settled
    rng = np.random.default_rng(3)
    for target in proven[:20]:
        # Every branch of the arm without limits: eight, each outside, none singular.
        branches = analytic.analytic_ik(robot, target, within_limits=False)
        assert len(branches) == 8
        for q in branches:
            T_q = robot.fk(q)
            assert np.linalg.norm(T_q[:3, 3] - target[:3, 3]) < 1e-9
            assert rotation_angle(T_q[:3, :3].T @ target[:3, :3]) < 1e-9
            assert _outside_distance(robot, q) > 1e-6
            assert np.linalg.svd(robot.jacobian(q), compute_uv=False)[-1] > 1e-6

        # An independent search inside the limits finds no answer either.
        def residual(q, target=target):
            T_q = robot.fk(q)
            return np.concatenate(
                [T_q[:3, 3] - target[:3, 3], (T_q[:3, :3] - target[:3, :3]).ravel()]
            )

        for _ in range(6):
            fit = least_squares(
                residual, rng.uniform(robot.lower, robot.upper), bounds=(robot.lower, robot.upper)
            )
            assert np.linalg.norm(fit.fun) > 1e-6


def _boxed_around(robot: optik.Robot, q: np.ndarray, joint: int, lower: float, upper: float):
    """``robot`` limited to ``q +- 0.3`` but for ``joint``, limited to ``[lower, upper]``."""
    lo, hi = q - 0.3, q + 0.3
    lo[joint], hi[joint] = lower, upper
    return robot.with_limits(lo, hi)


Q_OWN = np.array([0.3, -0.2, 0.25, 0.4, 0.6, -0.5])


@pytest.mark.parametrize(
    ("turn", "gap", "quick"),
    [(False, 1e-8, False), (False, 1e-3, True), (True, 1e-7, False), (True, 1e-3, True)],
    ids=["just-below", "far-below", "just-above-a-turn-on", "far-above-a-turn-on"],
)
def test_a_branch_near_a_limit_is_left_to_the_polish(puma, polish_calls, turn, gap, quick):
    # The pose's own branch q lies outside only by joint 1: below its lower limit by
    # `gap`; or (a turn on) 0.5 below its lower limit but, shifted by 2 pi, `gap` above
    # its upper one.
    q = puma.mid_limits + Q_OWN
    if turn:
        robot = _boxed_around(puma, q.copy(), 0, q[0] + 0.5, q[0] + 2 * math.pi - gap)
    else:
        robot = _boxed_around(puma, q.copy(), 0, q[0] + gap, q[0] + 1.0)
    target = puma.fk(q)
    # With q as the reference the closed form keeps q's own angle for joint 1, not the
    # one a turn on: the proof must judge every turn.
    assert len(analytic.analytic_ik(robot, target, q_ref=q, within_limits=False)) == 8
    assert analytic.analytic_ik(robot, target, q_ref=q) == []
    assert (len(polish_calls) == 0) is quick


def _wrist_boxed(puma: optik.Robot, q5: float) -> tuple[optik.Robot, np.ndarray, np.ndarray]:
    """The Puma with q5 = ``q5``, limited away from q but around q with q4 and q6 turned.

    Returns ``(robot, q, moved)``: with q5 = 0 the wrist is aligned and ``moved`` reaches
    q's pose too (q4 and q6 turn together along a continuum of answers).
    """
    q = puma.mid_limits + Q_OWN
    q[4] = q5
    moved = q.copy()
    moved[3] -= 1.7
    moved[5] += 1.7
    if not np.allclose(puma.fk(moved), puma.fk(q), atol=1e-6):
        moved[5] -= 3.4  # the other sense of the aligned axes
    lo, hi = q - 0.3, q + 0.3
    lo[[3, 5]], hi[[3, 5]] = moved[[3, 5]] - 0.2, moved[[3, 5]] + 0.2
    return puma.with_limits(lo, hi), q, moved


def test_a_singular_branch_is_left_to_the_polish(puma, polish_calls):
    # The closed form returns one point of the continuum, the reference's (here q itself,
    # outside the limits); the polish follows the continuum into the limits.
    robot, q, moved = _wrist_boxed(puma, 0.0)
    assert np.allclose(puma.fk(moved), puma.fk(q), atol=1e-12)
    target = puma.fk(q)
    found = analytic.analytic_ik(robot, target, q_ref=q)
    assert polish_calls
    assert found  # the continuum enters the limits near `moved`
    for branch in found:
        assert np.allclose(robot.fk(branch), target, atol=1e-9)
        assert np.all(branch >= robot.lower - 1e-12) and np.all(branch <= robot.upper + 1e-12)


def test_a_nearly_singular_branch_is_left_to_the_polish(puma, monkeypatch, polish_calls):
    # q5 = 1e-7: eight isolated branches, two of them with sigma_min(J) = 1e-8, below the
    # gate: the quick proof does not judge them.
    robot, q, _ = _wrist_boxed(puma, 1e-7)
    target = puma.fk(q)
    branches = analytic.analytic_ik(robot, target, q_ref=q, within_limits=False)
    assert len(branches) == 8
    assert min(np.linalg.svd(robot.jacobian(b), compute_uv=False)[-1] for b in branches) < 1e-6
    found = analytic.analytic_ik(robot, target, q_ref=q)
    assert polish_calls
    monkeypatch.setattr(analytic, "proven_outside", _never_proven)
    assert len(found) == len(analytic.analytic_ik(robot, target, q_ref=q))


def _tolerance_answer(robot: optik.Robot, branch: np.ndarray, joint: int, gap: float):
    """``robot`` limited so that ``branch`` lies ``gap`` beyond ``joint``'s upper limit,
    and a configuration inside the limits that reaches ``branch``'s pose within the FK
    check's tolerance: ``branch`` moved along the Jacobian's weakest direction onto the
    limit. Returns ``(limited robot, that configuration)``."""
    v = np.linalg.svd(robot.jacobian(branch))[2][-1]
    v *= np.sign(v[joint])
    step = gap * 1.001 / v[joint]
    inside = branch - step * v
    lo, hi = branch - 0.05 - step * np.abs(v), branch + 0.05 + step * np.abs(v)
    hi[joint], lo[joint] = branch[joint] - gap, branch[joint] - gap - 0.1
    return robot.with_limits(lo, hi), inside


@pytest.mark.parametrize(
    ("arm", "q5"),
    [("puma", 3e-5), ("puma", 1e-5), ("millimetre puma", -0.091)],
    ids=["wrist-3e-5", "wrist-1e-5", "millimetre-arm"],
)
def test_an_answer_at_the_tolerance_inside_the_limits_is_not_proven_away(
    puma, monkeypatch, polish_calls, arm, q5
):
    # An exact branch 2e-6 beyond a limit whose Jacobian is weak (sigma_min ~ 1e-5): a
    # configuration inside the limits reaches its pose within the FK check's 1e-9, which
    # the polish returns. The quick proof must leave such a pose to it.
    robot = scaled_problem("puma560", 1e-3) if arm.startswith("millimetre") else puma
    branch = np.array([0.3, 0.4, -0.5, 0.6, q5, -0.7])
    if arm.startswith("millimetre"):
        branch = np.array([-0.48, 1.222, -1.148, 0.643, q5, 0.021])
    target = robot.fk(branch)
    limited, inside = _tolerance_answer(robot, branch, 3, 2e-6)
    assert np.linalg.svd(robot.jacobian(branch), compute_uv=False)[-1] < 3e-5
    assert limited.within_limits(inside)
    reached = robot.fk(inside)
    assert np.linalg.norm(reached[:3, 3] - target[:3, 3]) < 1e-9
    assert rotation_angle(reached[:3, :3].T @ target[:3, :3]) < 1e-9
    found = analytic.analytic_ik(limited, target, q_ref=inside)
    batch = analytic.analytic_ik_batch(limited, target[None], q_ref=inside)
    assert found and batch.counts[0] == len(found)
    for q in found:
        assert limited.within_limits(q)
        assert np.allclose(limited.fk(q), target, atol=1e-9)
    monkeypatch.setattr(analytic, "proven_outside", _never_proven)
    slow = analytic.analytic_ik(limited, target, q_ref=inside)
    assert len(slow) == len(found) and all(map(np.array_equal, slow, found))


@pytest.mark.parametrize("name", ["ur5", "puma560"])
def test_a_pose_without_any_candidate_is_answered_without_the_polish(name, monkeypatch):
    # Beyond the elbow's reach (inside the reach sphere, which a cheaper test rules out
    # first) the compiled closed form has no candidate at all: nothing to refine, and
    # mid-limits is no near-solution. A caller's q_ref may be one: it is still polished.
    robot = load_problem(name).robot
    polished = _counted(monkeypatch, "polish")
    rng = np.random.default_rng(5)
    centre, radius = robot.reach_sphere
    targets = []
    while len(targets) < 12:
        T = robot.fk(rng.uniform(robot.lower, robot.upper))
        T[:3, 3] = centre + 1.25 * (T[:3, 3] - centre)
        if np.linalg.norm(T[:3, 3] - centre) < 0.9 * radius and not analytic.analytic_ik(
            robot, T, within_limits=False
        ):
            targets.append(T)
    assert not polished
    counts = analytic.analytic_ik_batch(robot, np.array(targets)).counts
    assert not counts.any() and not polished
    q_ref = rng.uniform(robot.lower, robot.upper)
    assert analytic.analytic_ik(robot, targets[0], q_ref=q_ref) == []
    assert polished  # the caller's reference

    # Unreachable indeed: an independent search without limits finds no answer.
    for target in targets[:6]:

        def residual(q, target=target):
            T_q = robot.fk(q)
            return np.concatenate(
                [T_q[:3, 3] - target[:3, 3], (T_q[:3, :3] - target[:3, :3]).ravel()]
            )

        for _ in range(4):
            fit = least_squares(residual, rng.uniform(-math.pi, math.pi, robot.dof))
            assert np.linalg.norm(fit.fun) > 1e-6


def test_the_python_families_still_polish_a_target_without_candidates():
    # Their bands are absolute, not yet relative to the arm: a planar 2R target a few
    # 1e-12 m past full stretch, or a DOBOT position 5e-10 m off a singular configuration
    # along the direction it cannot move, has no raw candidate, and the polish from
    # mid-limits reaches a configuration that reproduces it within the FK check (2e-9 m
    # for the 2 m planar arm).
    planar = load_problem("planar_2r").robot
    q = np.array([-0.3342, 0.0])  # stretched, inside the limits
    T = planar.fk(q)
    T[:3, 3] += 2e-12 * T[:3, 3] / np.linalg.norm(T[:3, 3])
    for mode in ("pose", "position"):
        target = T if mode == "pose" else T[:3, 3]
        branches = analytic.analytic_ik(planar, target, mode=mode)
        assert branches, mode
        assert np.linalg.norm(planar.fk(branches[0])[:3, 3] - T[:3, 3]) <= 2.5e-9
    dobot = load_problem("dobot_magician").robot

    def sigma_min(x):
        return [np.linalg.svd(dobot.jacobian(x)[:3], compute_uv=False)[-1]]

    start = np.array([0.92293906, 0.06128863, 1.63212131, 0.36008221])
    q = least_squares(sigma_min, start, xtol=1e-15, ftol=1e-15, gtol=1e-15).x
    assert dobot.within_limits(q) and sigma_min(q)[0] < 1e-9
    U = np.linalg.svd(dobot.jacobian(q)[:3])[0]
    target = dobot.fk(q)[:3, 3] + 5e-10 * U[:, -1]
    branches = analytic.analytic_ik(dobot, target, mode="position")
    assert branches
    assert all(np.linalg.norm(dobot.fk(b)[:3, 3] - target) <= 1e-9 for b in branches)


@pytest.mark.parametrize("gap", [1e-8, 1e-6])
def test_a_refined_branch_just_beyond_a_limit_is_no_answer(gap: float) -> None:
    # The Kinova's table is the ideal arm's: each branch takes a Newton step on the
    # robot's chain. Its own branch 1e-8 or 1e-6 below a narrowed limit of joint 2 is put
    # on the limit, and no Newton step brings it to its pose: a compromise within the FK
    # check's tolerance is not an answer, and the set stays empty (a proof).
    import importlib.metadata
    from pathlib import Path

    robots = importlib.metadata.distribution("example-robot-data").locate_file(
        "cmeel.prefix/share/example-robot-data/robots"
    )
    kinova = optik.Robot.from_urdf(
        Path(str(robots)) / "kinova_description" / "robots" / "kinova.urdf",
        "j2s6s200_link_base",
        "j2s6s200_end_effector",
    )
    q = np.array([0.3, 2.9, 1.5, 0.4, 2.0, -0.5])
    target = kinova.fk(q)
    robot = _boxed_around(kinova, q.copy(), 1, q[1] + gap, q[1] + 1.0)
    assert any(
        np.max(np.abs(b - q)) < 1e-9
        for b in analytic.analytic_ik(robot, target, q_ref=q, within_limits=False)
    )
    assert analytic.analytic_ik(robot, target, q_ref=q) == []
