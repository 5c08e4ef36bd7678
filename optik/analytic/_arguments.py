"""Arguments of the closed-form IK entry points: checked once, in one place.

The checks of :func:`optik.analytic.analytic_ik` and
:func:`optik.analytic.analytic_ik_batch` (robot, ``within_limits``, ``q_ref``, targets
one by one or in a batch), the array type the compiled kernels are specialised for, and
the batch's result (:class:`AnalyticBatch`).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import NDArray

from optik._checks import FloatArray, as_float_array, check_bool, check_finite
from optik._math import first_bad_pose
from optik.analytic import _compiled
from optik.errors import AnalyticIKError, OptikError, ShapeError
from optik.model import Robot
from optik.poses import as_target_pose
from optik.spatial import as_pose

F64 = np.dtype(np.float64)
"""The dtype the compiled kernels take (a target of any other goes through :func:`plain`)."""
POSE_SHAPE = (4, 4)
"""The shape of one pose."""


ROW_VIEWS: tuple[Callable[[FloatArray], list[FloatArray]], ...] = (
    lambda o: [],
    lambda o: [o[0]],
    lambda o: [o[0], o[1]],
    lambda o: [o[0], o[1], o[2]],
    lambda o: [o[0], o[1], o[2], o[3]],
    lambda o: [o[0], o[1], o[2], o[3], o[4]],
    lambda o: [o[0], o[1], o[2], o[3], o[4], o[5]],
    lambda o: [o[0], o[1], o[2], o[3], o[4], o[5], o[6]],
    lambda o: [o[0], o[1], o[2], o[3], o[4], o[5], o[6], o[7]],
)  # fmt: skip
"""``ROW_VIEWS[n](out)``: the list of the first ``n`` rows of ``out`` (8, dof), as views.

A closed form's single call returns its branches so; indexing each row written out
costs 0.26 us less for eight rows than a comprehension's loop (a fifth of the Python
part of the call)."""


def plain(array: FloatArray) -> FloatArray:
    """``array`` itself if C-contiguous, aligned and writeable float64, else such a copy.

    The compiled kernels are specialised for exactly this array type; any other layout
    would trigger a new compilation.
    """
    if array.dtype == F64 and array.flags.carray:
        return array
    return np.array(array, dtype=np.float64, order="C")


def check_robot(robot: Any) -> None:
    if not isinstance(robot, Robot):
        raise OptikError(f"robot must be an optik.Robot, got {type(robot).__name__}")


def check_within(within_limits: Any) -> bool:
    """``within_limits`` as a bool (a string ``"false"`` is not taken for true)."""
    if within_limits is True or within_limits is False:  # the common case, ~30 ns
        return within_limits
    return check_bool("within_limits", within_limits)


def check_ref(robot: Robot, q_ref: Any) -> FloatArray:
    """``q_ref`` validated as one configuration (dof,)."""
    ref = robot.check_q(q_ref, "q_ref")
    if ref.ndim != 1:
        raise AnalyticIKError("q_ref must be a single configuration (dof,)")
    return ref


def raise_input_error(robot: Robot, target: Any, q_ref: Any, code: int) -> None:
    """Raise the optik error for an input the compiled checks rejected (``code < 0``)."""
    as_target_pose(target, "pose")  # raises for a bad target
    if q_ref is not None:
        check_ref(robot, q_ref)  # ... or for a bad q_ref
    raise OptikError(  # pragma: no cover - the compiled checks replicate the Python ones
        f"target or q_ref rejected by the compiled checks (code {code}) but not by Python"
    )


IntArray = NDArray[np.int64]


class AnalyticBatch(NamedTuple):
    """Every branch of a batch of targets: :func:`analytic_ik_batch`'s result.

    Unpacks as ``Q, counts = analytic_ik_batch(robot, targets)``.

    Attributes:
        q: (N, B, dof) branches of target ``i`` in ``q[i, :counts[i]]`` (rad, m), in
            :func:`analytic_ik`'s order; the rows past ``counts[i]`` are NaN. ``B`` is
            :data:`optik.analytic._compiled.MAX_BRANCHES` (8), or more for a Python
            family that returned more.
        counts: (N,) number of branches of each target (0: unreachable, or only outside
            the limits when they are applied).
    """

    q: FloatArray
    counts: IntArray

    def branches(self, i: int) -> list[FloatArray]:
        """The branches of target ``i``, as :func:`analytic_ik` returns them.

        Args:
            i: index of the target in the batch, in ``[0, N)``.
        """
        return list(self.q[i, : int(self.counts[i])])

    @property
    def first(self) -> FloatArray:
        """(N, dof) the first branch of each target, NaN where there is none.

        With a ``q_ref`` it is the branch nearest the reference.
        """
        return self.q[:, 0, :]

    @property
    def solved(self) -> NDArray[np.bool_]:
        """(N,) whether each target has at least one branch."""
        return self.counts > 0


def batch_targets(targets: Any, mode: str) -> FloatArray:
    """Validate a batch of targets: (N, 4, 4) poses, or in position mode (N, 3) points.

    Returns (N, 4, 4) C-contiguous float64 poses (identity rotations in position mode).

    Raises:
        ShapeError: wrong shape (also a bad last row, as :func:`optik.spatial.as_pose`).
        NonFiniteError: a NaN or infinite entry.
        InvalidRotationError: a rotation block that is not a proper rotation (the message
            names the first bad target, ``targets[i]``).
    """
    T = as_float_array("targets", targets)
    if mode == "position" and T.ndim == 2 and T.shape[1] == 3:
        check_finite("targets", T)
        poses = np.zeros((len(T), 4, 4))
        poses[:, 0, 0] = poses[:, 1, 1] = poses[:, 2, 2] = poses[:, 3, 3] = 1.0
        poses[:, :3, 3] = T
        return poses
    if T.ndim != 3 or T.shape[1:] != (4, 4):
        expected = "(N, 4, 4)" + (" or (N, 3)" if mode == "position" else "")
        raise ShapeError("targets", expected, T.shape)
    T = plain(T)
    bad = first_bad_pose(T, *_compiled.pose_tolerances())
    if bad >= 0:
        as_pose(f"targets[{bad}]", T[bad])  # raises the error naming the first bad target
        raise OptikError(  # pragma: no cover - the compiled checks replicate as_pose
            f"targets[{bad}] rejected by the compiled checks but not by as_pose"
        )
    if mode == "position":
        positions = T[:, :3, 3]
        T = np.zeros_like(T)
        T[:, 0, 0] = T[:, 1, 1] = T[:, 2, 2] = T[:, 3, 3] = 1.0
        T[:, :3, 3] = positions
    return T


def batch_refs(robot: Robot, q_ref: Any, N: int) -> FloatArray | None:
    """``q_ref`` of a batch of ``N`` targets as (1, dof) or (N, dof), or ``None``."""
    if q_ref is None:
        return None
    dof = robot.dof
    refs = robot.check_q(q_ref, "q_ref")  # finite, within MAX_LENGTH_M, as one q_ref is
    refs = refs.reshape(1, dof) if refs.ndim == 1 else refs
    if refs.shape[0] not in (1, N):
        raise ShapeError("q_ref", f"({dof},) or ({N}, {dof})", refs.shape)
    return refs
