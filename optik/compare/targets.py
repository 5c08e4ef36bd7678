"""Seeded targets of the comparison: in-limit configurations and per-target restart seeds."""

from __future__ import annotations

import math
import zlib

import numpy as np

from optik._checks import FloatArray
from optik.model import Robot

__all__ = ["random_configurations"]


def _stable_id(name: str) -> int:
    return zlib.crc32(name.encode("utf-8"))


def _bounded_box(robot: Robot, shrink: float = 0.0) -> tuple[FloatArray, FloatArray]:
    lower = np.where(np.isfinite(robot.lower), robot.lower, -math.pi)
    upper = np.where(np.isfinite(robot.upper), robot.upper, math.pi)
    margin = shrink * (upper - lower)
    return lower + margin, upper - margin


def random_configurations(
    robot: Robot, name: str, n: int, seed: int, shrink: float = 0.0
) -> FloatArray:
    """``n`` joint vectors drawn uniformly inside the limits, (n, dof), rad / m.

    Configuration ``k`` comes from its own generator seeded with ``(seed, crc32(name),
    k)``: it does not depend on ``n`` or on the other robots, so a larger ``n`` adds targets
    and keeps the first ones. Joints without limits draw in [-pi, pi].

    Args:
        robot: the robot.
        name: the problem's name (part of the seed).
        n: number of configurations.
        seed: the run's seed.
        shrink: keep this fraction of each joint's range away from both limits.
    """
    lower, upper = _bounded_box(robot, shrink)
    Q = np.empty((n, robot.dof))
    for k in range(n):
        rng = np.random.default_rng([seed, _stable_id(name), k])
        Q[k] = rng.uniform(lower, upper)
    return Q


def _solve_seed(seed: int, name: str, k: int) -> int:
    """The restart seed of target ``k`` of problem ``name`` (deterministic, well mixed)."""
    return int(np.random.SeedSequence([seed, _stable_id(name), k]).generate_state(1)[0])
