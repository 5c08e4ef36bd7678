"""The general arm of ``spherical_axes``: its quartic's roots and its singular shoulder.

References independent of the closed form: the roots of the trig polynomial by dense
sampling and scipy's ``brentq``, polynomials built from known roots, forward kinematics
written out (``test_spherical_axes``'s DH products) and the configuration each pose came
from. The branch sets against EAIK are in ``test_spherical_axes.py`` (its "general arm"
cases).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import general_arm, joint_distance, reference_fk, reference_frames
from scipy.optimize import brentq, least_squares

from optik import Robot
from optik.analytic import analytic_ik
from optik.analytic._quartic import sampled_roots, trig2_roots
from optik.analytic.geometry import joint_axes
from optik.analytic.spherical_axes import GENERAL, axes_plan


def _f(k: np.ndarray, t: np.ndarray) -> np.ndarray:
    return k[0] + k[1] * np.cos(t) + k[2] * np.sin(t) + k[3] * np.cos(2 * t) + k[4] * np.sin(2 * t)


def _reference_roots(k: np.ndarray) -> list[float]:
    """Sign changes of ``f`` on a grid of 20,000 steps over a turn, refined by brentq."""
    grid = np.linspace(-math.pi, math.pi, 20_001)
    values = _f(k, grid)
    roots = []
    for i in np.flatnonzero(np.sign(values[:-1]) * np.sign(values[1:]) < 0):
        roots.append(brentq(lambda t: float(_f(k, np.array(t))), grid[i], grid[i + 1]))
    return roots


def _roots(k: np.ndarray) -> np.ndarray:
    out = np.empty(4)
    n = trig2_roots(np.asarray(k, dtype=float), 1e-12, out)
    return out[:n]


def _turn_distance(a: float, b: float) -> float:
    return abs(math.remainder(a - b, 2 * math.pi))


def test_roots_of_random_polynomials_match_bracketing() -> None:
    """2,000 random polynomials (0, 2 or 4 real roots): the same roots as the bracketing
    reference, to 1e-10, ascending; none when there are none."""
    rng = np.random.default_rng(3)
    seen = set()
    for _ in range(2000):
        k = rng.normal(size=5)
        expected = _reference_roots(k)
        found = _roots(k)
        seen.add(len(expected))
        assert len(found) == len(expected), k
        assert np.all(np.diff(found) >= 0)
        for t in expected:
            assert min(_turn_distance(t, s) for s in found) < 1e-10, k
    assert seen == {0, 2, 4}


def test_subdivision_certifies_random_polynomials_and_leaves_double_roots() -> None:
    """The certified subdivision decides 2,000 random polynomials itself (the same roots as
    bracketing, 1e-12) and hands a double root to the eigenvalues (-1)."""
    rng = np.random.default_rng(4)
    out = np.empty(4)
    for _ in range(2000):
        k = rng.normal(size=5)
        n = sampled_roots(k, out)
        expected = _reference_roots(k)
        assert n == len(expected), k
        for t in expected:
            assert min(_turn_distance(t, s) for s in out[:n]) < 1e-12, k
    # (cos t - cos 1.2)^2: double roots at +-1.2.
    ca = math.cos(1.2)
    assert sampled_roots(np.array([0.5 + ca * ca, -2 * ca, 0.0, 0.5, 0.0]), out) == -1


def test_newton_stops_at_rounding(monkeypatch: pytest.MonkeyPatch) -> None:
    """Each root takes a few Newton steps from its interval's middle, never a bisection
    down to rounding: the iteration stops when a step or the bracket is at rounding,
    also where the slope is small (a root near a double one). Counted on the Python
    function with a counting ``f``, on 3,000 random polynomials."""
    from optik.analytic import _quartic

    calls = [0]
    evaluate = _quartic._trig2.py_func

    def counted(k: np.ndarray, t: float) -> tuple[float, float]:
        calls[0] += 1
        return evaluate(k, t)

    monkeypatch.setattr(_quartic, "_trig2", counted)
    bracketed = _quartic._bracketed_root.py_func
    rng = np.random.default_rng(1)
    worst = 0
    for k in rng.normal(size=(3000, 5)):
        expected = _reference_roots(k)
        for t in expected:
            width = 2 * math.pi / 16
            a = -math.pi + math.floor((t + math.pi) / width) * width
            b = a + width
            fa = float(_f(k, np.array(a)))
            fb = float(_f(k, np.array(b)))
            m = 0.5 * (a + b)
            fm, dm = evaluate(k, m)
            bound2 = abs(k[1]) + abs(k[2]) + 4 * (abs(k[3]) + abs(k[4]))
            if _quartic._verdict(fa, fb, fm, dm, width, bound2, 0.0) != 1:
                continue  # not proven monotone: halved first, not this test's case
            calls[0] = 0
            root = bracketed(k, a, b, fa, m, fm, dm)
            worst = max(worst, calls[0])
            assert abs(root - t) < 1e-12, k
    assert worst <= 12


@pytest.mark.parametrize("shift", [0.0, 0.7, math.pi])
def test_double_roots_of_a_folded_arm_are_kept(shift: float) -> None:
    """``(cos u - cos a)^2`` with ``u = t - shift`` has double roots at ``u = +-a``: each is
    found (within 1e-7, sqrt of rounding), and every value returned is a root to 1e-13."""
    for a in (0.3, 1.2, 2.9):
        ca = math.cos(a)
        # (cos u - ca)^2 = 1/2 + ca^2 - 2 ca cos u + cos(2u) / 2, with u = t - shift.
        c1, s1 = math.cos(shift), math.sin(shift)
        c2, s2 = math.cos(2 * shift), math.sin(2 * shift)
        k = np.array([0.5 + ca * ca, -2 * ca * c1, -2 * ca * s1, 0.5 * c2, 0.5 * s2])
        found = _roots(k)
        assert len(found) >= 2
        for t in (shift + a, shift - a):
            assert min(_turn_distance(t, s) for s in found) < 1e-7, (a, shift)
        assert np.all(np.abs(_f(k, found)) < 1e-13)


def test_first_harmonic_only_and_no_equation() -> None:
    """No second harmonic: the roots of ``k0 + k1 cos t + k2 sin t``; all zero: none."""
    found = _roots(np.array([0.5, 1.0, 0.0, 0.0, 0.0]))
    np.testing.assert_allclose(found, [-2 * math.pi / 3, 2 * math.pi / 3], atol=1e-14)
    assert len(_roots(np.zeros(5))) == 0
    assert len(_roots(np.array([2.0, 1.0, 0.0, 0.0, 0.0]))) == 0


def _general_robot() -> Robot:
    robot = general_arm()
    assert axes_plan(robot).kind == GENERAL
    return robot


def _poses_near_axis_1(robot: Robot, offset: float, n: int, seed: int) -> list[np.ndarray]:
    """Configurations whose wrist centre lies ``offset`` (m) from axis 1 (q2, q3 fitted by
    scipy's least squares; the other joints random)."""
    axes = joint_axes(robot)
    z1, p1 = axes.directions[0], axes.points[0]
    across = np.cross(z1, (0.3, 0.5, 0.8))
    across /= np.linalg.norm(across)

    def miss(x: np.ndarray) -> np.ndarray:
        q = np.zeros(6)
        q[1:3] = x
        d = reference_frames(robot, q)[4][:3, 3] - p1  # the wrist centre: frame 4's origin
        return d - np.dot(d, z1) * z1 - offset * across

    rng = np.random.default_rng(seed)
    found = []
    for start in rng.uniform(-math.pi, math.pi, (n, 2)):
        fit = least_squares(miss, start, xtol=1e-15, ftol=1e-15, gtol=1e-15)
        if np.linalg.norm(fit.fun) <= 1e-13:
            q = rng.uniform(-math.pi, math.pi, 6)
            q[1:3] = fit.x
            found.append(q)
    assert len(found) >= n // 2
    return found


def test_wrist_centre_on_axis_1_takes_the_reference() -> None:
    """Poses whose wrist centre lies on axis 1 leave q1 free: it takes ``q_ref``'s value,
    every branch reaches the pose and the source is among them."""
    robot = _general_robot()
    for q in _poses_near_axis_1(robot, 0.0, 30, seed=8):
        T = reference_fk(robot, q)
        branches = analytic_ik(robot, T, q_ref=q, within_limits=False)
        for b in branches:
            assert np.abs(reference_fk(robot, b) - T).max() < 1e-10
        assert min(joint_distance(robot, b, q) for b in branches) < 1e-8, q


@pytest.mark.parametrize("offset", [1e-7, 1e-5, 1e-3])
def test_near_axis_1_every_branch_at_rounding(offset: float) -> None:
    """A wrist centre a hair from axis 1: the quartic in q3 would pair its roots (their gap
    is det A, squared); eliminated the other way, every branch reaches its pose to 1e-13
    and the source is among them, to q1's conditioning there (rounding / offset)."""
    robot = _general_robot()
    for q in _poses_near_axis_1(robot, offset, 20, seed=9):
        T = reference_fk(robot, q)
        branches = analytic_ik(robot, T, q_ref=q, within_limits=False)
        for b in branches:
            assert np.abs(reference_fk(robot, b) - T).max() < 1e-13
        source_tol = max(1e-9, 1e-14 / offset)
        assert min(joint_distance(robot, b, q) for b in branches) < source_tol, (offset, q)
