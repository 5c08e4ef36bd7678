"""What :func:`optik.solve_ik` and :func:`optik.solve_ik_batch` validate alike.

The budget limits (iterations per attempt, restarts, seeds) and the checks of ``q0`` and
of the keywords both entry points take.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, TypedDict

from optik._checks import FloatArray, check_choice, check_int, check_real
from optik.diffik import clip_into_limits
from optik.model import Robot

DEFAULT_RESTARTS = 100
"""Restarts after the first attempt when neither ``restarts`` nor ``timeout_s`` is given."""

UNLIMITED_RESTARTS = 2**62
"""The restart budget within a finite ``timeout_s`` when ``restarts`` is not given."""

MAX_ITERATIONS = 100_000
"""Largest ``max_iter``: one attempt runs inside compiled code without looking at the
clock, so its length must be bounded (100,000 LM iterations of a 7-dof arm take about
0.1 s); the deadline is checked between attempts."""

MAX_SEED = 2**63 - 1
"""Largest ``seed`` (the streams are 64-bit)."""


class TaskKeywords(TypedDict, total=False):
    """The task keywords every IK entry point takes, as :func:`optik.task.make_task` does.

    ``make_task`` holds their defaults (``mode="pose"``, ``axis="z"``, ``weights=None``,
    ``tol=1e-6``) and checks them.
    """

    mode: str
    axis: str
    weights: Any
    tol: float | tuple[float, float]


class QueryKeywords(TaskKeywords, total=False):
    """The keywords of one IK query: :func:`optik.solve_ik`'s and :func:`optik.solve_ik_all`'s.

    ``solve_ik`` documents them with their defaults.
    """

    solver: str
    q0: Any
    warm_start: str
    max_iter: int | None
    timeout_s: float | None
    restarts: int | None
    seed: int
    frozen: Mapping[str, float] | None
    limit_margin: float


def check_q0(robot: Robot, q0: Any) -> FloatArray:
    """``q0`` as a (dof,) array inside the limits; see :func:`optik.diffik.clip_into_limits`."""
    if q0 is None:
        return robot.mid_limits
    return clip_into_limits(robot, "q0", q0)


def check_options(
    warm_start: Any,
    timeout_s: Any,
    restarts: Any,
    max_iter: Any = None,
    seed: Any = 0,
) -> None:
    """Validate the budget keywords shared by :func:`solve_ik` and :func:`solve_ik_batch`.

    (The task keywords are :func:`optik.task.make_task`'s to check.)
    """
    check_choice("warm_start", warm_start, ("analytic", "q0"))
    if timeout_s is not None:
        check_real("timeout_s", timeout_s, positive=True, allow_inf=True)
    if restarts is not None:
        check_int("restarts", restarts, minimum=0, maximum=UNLIMITED_RESTARTS)
    if max_iter is not None:
        check_int("max_iter", max_iter, minimum=1, maximum=MAX_ITERATIONS)
    check_int("seed", seed, minimum=0, maximum=MAX_SEED)
