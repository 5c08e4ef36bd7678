"""The chain description that every kernel, program and closed form consumes.

A robot's kinematics, whatever it was built from (standard DH, modified DH, URDF), is
one product of constant transforms and joint motions::

    T_world_tool = K[0] M(t_1) K[1] M(t_2) ... M(t_n) K[n]

where ``M(t)`` is a rotation about z by ``t`` (revolute) or a translation along z by
``t`` (prismatic), and the chain variables ``t`` are the joint coordinates ``q`` through
a linear coupling ``t = C q`` (the identity for ordinary arms; passive joints that mimic
an actuated one otherwise). :class:`Chain` holds exactly these arrays, read-only; the
compiled kernels (:mod:`optik._kernels`, :mod:`optik.solvers._lm_kernel`), the CasADi
programs and the closed forms take it instead of reaching into :class:`optik.Robot`.

:class:`ChainLink` is one joint before assembly, the common output of the DH and URDF
readers.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal, NamedTuple

import numpy as np

from optik._checks import FloatArray

JointKind = Literal["revolute", "prismatic"]

KernelChain = tuple[FloatArray, np.ndarray, FloatArray, bool, FloatArray, FloatArray]
"""``(K, prismatic, C, identity, lower, upper)``: a chain as the compiled solvers take it
(one argument: numba accepts a tuple of arrays)."""


@dataclass(frozen=True)
class Mimic:
    """A passive joint driven by another: ``t = multiplier * q[joint]`` (plus its offset)."""

    joint: str
    multiplier: float = 1.0


@dataclass(frozen=True)
class ChainLink:
    """A chain joint before assembly: constant ``before``, the motion, link frame ``after``.

    Attributes:
        name: joint name.
        kind: ``"revolute"`` or ``"prismatic"``.
        before: 4x4 constant transform before the joint's motion.
        after: 4x4 constant transform from the moved frame to the link frame.
        offset: joint value (rad or m) of the motion at ``q = 0``.
        mimic: the actuated joint this one follows, if passive.
        role: ``"arm"``, ``"wrist"``, ``"spindle"`` or ``None`` (default limits).
        lower: lower limit (rad or m) or ``None`` for the role default.
        upper: upper limit (rad or m) or ``None`` for the role default.
        continuous: an unbounded revolute joint.
        velocity: speed limit (rad/s or m/s) or ``None`` when unknown.
        acceleration: acceleration limit (rad/s² or m/s²) or ``None`` when unknown.
    """

    name: str
    kind: JointKind
    before: FloatArray
    after: FloatArray
    offset: float
    mimic: Mimic | None = None
    role: str | None = None
    lower: float | None = None
    upper: float | None = None
    continuous: bool = False
    velocity: float | None = None
    acceleration: float | None = None


class Chain(NamedTuple):
    """A robot's kinematics and limits as the kernels take them (read-only arrays).

    Attributes:
        K: (n + 1, 4, 4) constant transforms, world frame first, tool last.
        E: (n, 4, 4) link offsets: link frame ``i`` is the frame after motion ``i`` times
            ``E[i - 1]`` (for :meth:`optik.Robot.frames`).
        prismatic: (n,) bool, the joint type of each chain joint.
        C: (n, dof) coupling, chain variables ``t = C q``.
        identity: whether ``C`` is the identity (then ``t = q`` and no product is formed).
        lower: (dof,) lower limits (rad or m, ``-inf`` for a continuous joint).
        upper: (dof,) upper limits.
    """

    K: FloatArray
    E: FloatArray
    prismatic: np.ndarray
    C: FloatArray
    identity: bool
    lower: FloatArray
    upper: FloatArray

    @property
    def n(self) -> int:
        """Number of chain joints (``dof`` plus any passive mimic joints)."""
        return int(self.prismatic.shape[0])

    @property
    def dof(self) -> int:
        """Number of joint coordinates (entries of ``q``)."""
        return int(self.lower.shape[0])

    def kernel_args(self, bounds: tuple[FloatArray, FloatArray] | None = None) -> KernelChain:
        """The :data:`KernelChain` of the compiled solvers, with ``bounds`` as its limits.

        Args:
            bounds: ``(lower, upper)`` (dof,) each, the box the solver keeps ``q`` in;
                ``None`` for the chain's own limits.
        """
        lower, upper = (self.lower, self.upper) if bounds is None else bounds
        return self.K, self.prismatic, self.C, self.identity, lower, upper


def read_only(array: np.ndarray) -> np.ndarray:
    """A C-contiguous float or bool copy of ``array`` that cannot be written."""
    out = np.array(array, order="C")
    out.flags.writeable = False
    return out
