"""The choice of one candidate per waypoint of a path (:func:`optik.planning.plan_path`).

Dynamic programming over the waypoints' candidate configurations: fewest steps beyond
``max_joint_step`` (branch switches) first, then the shortest such steps, then the joint
motion plus the distance to the *comfort box* (the limits shrunk by :data:`MARGIN_BAND`),
weighted by :data:`MARGIN_WEIGHT`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from optik._checks import FloatArray
from optik.model import Robot

SWITCH_PENALTY = 1e6
"""Cost of one step beyond ``max_joint_step``: larger than any path's motion (rad, m)."""

SWITCH_MOTION_WEIGHT = 1e3
"""Weight of a flagged step's own motion (per rad or m): a step that must be flagged is
no licence to switch branch. Weighted like the others, a 3.1 rad flagged jump into the
comfort box won over the 0.25 rad step the path needed (its margin saved more than 3 rad
over the rest of the path)."""

MARGIN_BAND = 0.1
"""Width of the soft band inside each finite joint limit, as a fraction of the joint's
range, that the path's cost steers away from (the hard ``limit_margin`` is separate)."""

MARGIN_WEIGHT = 1.0
"""Weight of a waypoint's distance to the comfort box in the path's cost (rad / rad)."""


@dataclass(frozen=True)
class Comfort:
    """The comfort box: the joint limits shrunk by :data:`MARGIN_BAND` of each range.

    Joints with an infinite limit or held by ``frozen`` (a zero range) are not shrunk.
    """

    lower: FloatArray
    upper: FloatArray

    @classmethod
    def of(cls, robot: Robot) -> Comfort:
        """The box of ``robot``'s limits (as held: frozen joints have a zero range)."""
        span = robot.upper - robot.lower
        band = np.where(np.isfinite(span), MARGIN_BAND * span, 0.0)
        return cls(robot.lower + band, robot.upper - band)

    def distance(self, Q: FloatArray) -> FloatArray:
        """Euclidean distance (rad, m) of each configuration (..., dof) to the box."""
        return np.linalg.norm(Q - np.clip(Q, self.lower, self.upper), axis=-1)

    def towards(self, q: FloatArray, most: float) -> FloatArray:
        """``q`` moved towards the box, each joint by at most ``most`` (rad, m)."""
        return q + np.clip(np.clip(q, self.lower, self.upper) - q, -most, most)


def choose(
    layers: list[list[FloatArray]],
    max_step: float,
    greedy: bool,
    start: FloatArray | None,
    comfort: Comfort,
) -> list[int]:
    """Index of the chosen candidate per layer (-1 for empty layers).

    The cost of a stretch of solved waypoints: :data:`SWITCH_PENALTY` per step larger
    than ``max_step``, and :data:`SWITCH_MOTION_WEIGHT` times that step's motion, plus
    the joint motion ``sum ||q_k - q_k-1||`` of the others, plus
    :data:`MARGIN_WEIGHT` times ``sum d(q_k)``, the distance of each waypoint's
    configuration to the comfort box (:class:`Comfort`); with ``start``, the move from
    it to the first waypoint is a step too. ``greedy`` ignores the margin.
    """
    choice = [-1] * len(layers)
    if greedy:
        anchor = start
        for k, layer in enumerate(layers):
            if not layer:
                anchor = None
                continue
            if anchor is None:
                choice[k] = 0
            else:
                choice[k] = int(np.argmin([np.max(np.abs(q - anchor)) for q in layer]))
            anchor = layer[choice[k]]
        return choice
    # Dynamic programming over each stretch of solved waypoints.
    k = 0
    n = len(layers)
    while k < n:
        if not layers[k]:
            k += 1
            continue
        end = k
        while end < n and layers[end]:
            end += 1
        stretch = [np.array(layers[i]) for i in range(k, end)]
        cost = MARGIN_WEIGHT * comfort.distance(stretch[0])
        if start is not None and k == 0:
            # The move from the current configuration is a step like the others.
            cost = cost + step_cost(start[None, :] - stretch[0], max_step)
        back: list[np.ndarray] = []
        for i in range(1, len(stretch)):
            diff = stretch[i][None, :, :] - stretch[i - 1][:, None, :]
            total = (
                cost[:, None]
                + step_cost(diff, max_step)
                + MARGIN_WEIGHT * comfort.distance(stretch[i])[None, :]
            )
            back.append(np.argmin(total, axis=0))
            cost = total[back[-1], np.arange(total.shape[1])]
        j = int(np.argmin(cost))
        for i in range(len(stretch) - 1, -1, -1):
            choice[k + i] = j
            if i > 0:
                j = int(back[i - 1][j])
        k = end
    return choice


def step_cost(diff: np.ndarray, max_step: float) -> np.ndarray:
    """Euclidean motion of steps ``diff`` (..., dof); past ``max_step``, the switch's cost.

    A flagged step costs :data:`SWITCH_PENALTY` plus :data:`SWITCH_MOTION_WEIGHT` times
    its motion.
    """
    switch = np.max(np.abs(diff), axis=-1) > max_step
    motion = np.linalg.norm(diff, axis=-1)
    return np.asarray(np.where(switch, SWITCH_PENALTY + SWITCH_MOTION_WEIGHT * motion, motion))
