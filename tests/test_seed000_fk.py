"""Seed 000, section III: the spherical (RRP) arm of the jumbo drilling robot.

The seed prints three A-matrices and their product 0A3 (eq. 6, repeated as eq. 23).
Here the printed A-matrices are multiplied numerically and compared, entry by entry,
with the printed 0A3. One printed entry is wrong: row 1, column 3 (1-based) reads
``-s1``; the product gives ``+s1``. (With ``-s1`` the printed rotation is not even
orthonormal: its third column must be ``n x o = (s1, -c1, 0)``.) Every other entry,
including the position column used by eqs. 9-10 and 24-25, is right.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import assert_close, random_q, robot_of


def printed_0A1(t1: float, a1: float) -> np.ndarray:
    c1, s1 = math.cos(t1), math.sin(t1)
    return np.array(
        [[c1, 0.0, s1, a1 * c1], [s1, 0.0, -c1, a1 * s1], [0.0, 1.0, 0.0, 0.0], [0, 0, 0, 1.0]]
    )


def printed_1A2(t2: float) -> np.ndarray:
    c2, s2 = math.cos(t2), math.sin(t2)
    return np.array(
        [[c2, 0.0, -s2, 0.0], [s2, 0.0, c2, 0.0], [0.0, -1.0, 0.0, 0.0], [0, 0, 0, 1.0]]
    )


def printed_2A3(d3: float) -> np.ndarray:
    return np.array(
        [[1.0, 0.0, 0.0, 0.0], [0.0, 0.0, -1.0, 0.0], [0.0, 1.0, 0.0, d3], [0, 0, 0, 1.0]]
    )


def printed_0A3(t1: float, t2: float, d3: float, a1: float) -> np.ndarray:
    """Eq. (6) = eq. (23) exactly as printed."""
    c1, s1, c2, s2 = math.cos(t1), math.sin(t1), math.cos(t2), math.sin(t2)
    return np.array(
        [
            [c1 * c2, -c1 * s2, -s1, -c1 * (s2 * d3 - a1)],
            [s1 * c2, -s1 * s2, -c1, -s1 * (s2 * d3 - a1)],
            [s2, c2, 0.0, c2 * d3],
            [0.0, 0.0, 0.0, 1.0],
        ]
    )


def corrected_0A3(t1: float, t2: float, d3: float, a1: float) -> np.ndarray:
    """Eq. (6) with the erratum fixed: entry (1, 3) is ``+s1``."""
    T = printed_0A3(t1, t2, d3, a1)
    T[0, 2] = math.sin(t1)
    return T


WRONG_ENTRIES = {(0, 2)}  # 0-based (row, column) of the printed entries that are wrong


def _values(rng: np.random.Generator, n: int = 50) -> list[tuple[float, float, float, float]]:
    """Random (theta1, theta2, d3, a1), theta1 kept away from 0 and pi so s1 != 0."""
    out = []
    while len(out) < n:
        t1, t2 = rng.uniform(-math.pi, math.pi, 2)
        if abs(math.sin(t1)) > 0.1:
            out.append((t1, t2, rng.uniform(0.5, 8.0), rng.uniform(-2.0, 2.0)))
    return out


def _product(t1: float, t2: float, d3: float, a1: float) -> np.ndarray:
    return printed_0A1(t1, a1) @ printed_1A2(t2) @ printed_2A3(d3)


def test_corrected_0A3_equals_product_of_printed_A_matrices(rng: np.random.Generator) -> None:
    for t1, t2, d3, a1 in _values(rng):
        assert_close(corrected_0A3(t1, t2, d3, a1), _product(t1, t2, d3, a1), atol=1e-14)


@pytest.mark.parametrize("row", range(4))
@pytest.mark.parametrize("col", range(4))
def test_printed_0A3_entry(row: int, col: int, rng: np.random.Generator) -> None:
    """Every printed entry matches the product except the pinned erratum, which differs."""
    for t1, t2, d3, a1 in _values(rng):
        printed = printed_0A3(t1, t2, d3, a1)[row, col]
        product = _product(t1, t2, d3, a1)[row, col]
        if (row, col) in WRONG_ENTRIES:
            assert abs(printed - product) > 0.19, (printed, product)
            assert printed == pytest.approx(-product, abs=1e-14)  # a sign error
        else:
            assert printed == pytest.approx(product, abs=1e-14)


def test_printed_rotation_is_not_orthonormal_but_corrected_one_is(
    rng: np.random.Generator,
) -> None:
    for t1, t2, d3, a1 in _values(rng, 10):
        R_printed = printed_0A3(t1, t2, d3, a1)[:3, :3]
        R_fixed = corrected_0A3(t1, t2, d3, a1)[:3, :3]
        n, o = R_fixed[:, 0], R_fixed[:, 1]
        assert_close(R_fixed[:, 2], np.cross(n, o), atol=1e-15)
        assert_close(R_fixed.T @ R_fixed, np.eye(3), atol=1e-15)
        assert np.max(np.abs(R_printed.T @ R_printed - np.eye(3))) > 0.01


def test_position_equations_9_10(rng: np.random.Generator) -> None:
    """Px = -c1 (s2 d3 - a1), Py = -s1 (s2 d3 - a1), Pz = c2 d3 (eqs. 9-10, 24-25)."""
    for t1, t2, d3, a1 in _values(rng, 10):
        p = _product(t1, t2, d3, a1)[:3, 3]
        k = math.sin(t2) * d3 - a1
        assert_close(p, [-math.cos(t1) * k, -math.sin(t1) * k, math.cos(t2) * d3], atol=1e-14)


def test_jumbo_spherical_arm_fk_equals_product(rng: np.random.Generator) -> None:
    robot = robot_of("jumbo_spherical_arm")
    assert robot.dh is not None
    a1 = robot.dh[0].a
    assert a1 == pytest.approx(0.6)
    d3_offset = robot.dh[2].d
    for q in random_q(robot, rng, 24):
        t1, t2, d3 = q[0], q[1], q[2] + d3_offset
        assert_close(robot.fk(q), _product(t1, t2, d3, a1), atol=1e-13)
        assert_close(robot.fk(q), corrected_0A3(t1, t2, d3, a1), atol=1e-13)


def test_jumbo_drill_6dof_shares_the_arm(rng: np.random.Generator) -> None:
    """The 6-dof drill's frame 3 is the spherical arm's 0A3."""
    robot = robot_of("jumbo_drill_6dof")
    assert robot.dh is not None
    a1 = robot.dh[0].a
    for q in random_q(robot, rng, 10):
        frames = robot.frames(q)
        assert_close(frames[3], corrected_0A3(q[0], q[1], q[2], a1), atol=1e-13)
