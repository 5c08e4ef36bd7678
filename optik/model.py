"""The robot model: a serial chain of revolute and prismatic joints.

All constructors (:meth:`Robot.from_dh`, :meth:`Robot.from_mdh`, :meth:`Robot.from_urdf`)
produce one internal form, the product
``T_base_tool = K[0] M(t_1) K[1] ... M(t_n) K[n]`` evaluated by :mod:`optik._kernels`.

The chain variables ``t`` are the joint coordinates ``q`` (what limits and solvers see)
through a linear coupling ``t = C q``: the identity for ordinary arms, and passive
joints that mimic an actuated one (``t_i = m q_j``), as in parallelogram-driven arms such
as the DOBOT Magician, where the forearm keeps its angle to the horizontal.
"""

from __future__ import annotations

import copy
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TypeVar

import numpy as np

from optik import _kernels
from optik._checks import (
    FloatArray,
    as_float_array,
    check_length_array,
    finite_length_array,
)
from optik._clock import one_time_setup
from optik.chain import Chain, ChainLink, JointKind, Mimic, read_only
from optik.chain_checks import JOINT_KINDS, check_mimic_range, checked_link, rigid
from optik.dh_rows import DHJoint, checked_dh_rows, dh_links, dh_row, joint_motion
from optik.errors import ArgumentError, InvalidLimitsError, ModelError, ShapeError
from optik.limits import (
    check_limit_magnitude,
    finite_or_inf_limits,
    limit_violation,
    resolve_limits,
    within_limits,
)
from optik.spatial import as_pose

_KINDS = JOINT_KINDS


@dataclass(frozen=True)
class Joint:
    """A joint coordinate of a :class:`Robot` (an entry of ``q``)."""

    name: str
    kind: JointKind
    lower: float
    upper: float
    role: str | None = None


T_cached = TypeVar("T_cached")

DECLARED_FAMILY_CHECKS: list[Callable[[Robot], object]] = []
"""Checks run when a robot declares a closed-form family (``analytic=``). The closed-form
layer (:mod:`optik.analytic`, which imports this module) adds its own on import, so the
model never imports it back."""


def _finite_multiplier(name: str, mimic: Mimic) -> float:
    value = mimic.multiplier
    try:
        number = math.nan if isinstance(value, bool) else float(value)
    except (TypeError, ValueError):
        number = math.nan
    if not math.isfinite(number):
        raise ModelError(f"joint {name!r}: mimic multiplier must be a finite number, got {value!r}")
    return number


def _check_frame(name: str, value: Any) -> FloatArray:
    """A base or tool pose: a proper 4x4 transform whose translation is a valid length."""
    T = as_pose(name, value)
    try:
        check_length_array(f"{name} translation", T[:3, 3])
    except ArgumentError as exc:
        raise ModelError(str(exc)) from exc
    return T


def _check_names(name: Any, analytic: Any) -> None:
    if not isinstance(name, str) or not name:
        raise ModelError(f"name: expected a non-empty string, got {name!r}")
    if analytic is not None and not isinstance(analytic, str):
        raise ModelError(f"analytic: expected a family name or None, got {analytic!r}")


class Robot:
    """A serial robot arm: joints, limits and kinematics.

    Attributes:
        name: robot name.
        joints: the joint coordinates, aligned with ``q``.
        lower: lower limits (dof,), rad or m.
        upper: upper limits (dof,), rad or m.
        T_world_base: pose of the chain's frame 0 in the world (robot base) frame.
        dh: the DH rows the robot was built from (``None`` for URDF), with ``convention``.
        analytic: name of the closed-form IK family, if one is declared.
        velocity_limits: (dof,) speed limits (rad/s or m/s), ``inf`` where unknown.
        acceleration_limits: (dof,) acceleration limits (rad/s² or m/s²), ``inf`` where
            unknown.
    """

    def __init__(
        self,
        links: Sequence[ChainLink],
        *,
        name: str = "robot",
        base: Any = None,
        tool: Any = None,
        dh: tuple[DHJoint, ...] | None = None,
        convention: str = "dh",
        analytic: str | None = None,
    ) -> None:
        if not isinstance(name, str) or not name:
            raise ModelError(f"robot name: expected a non-empty string, got {name!r}")
        if isinstance(links, str | bytes | Mapping) or not isinstance(links, Sequence):
            raise ModelError(
                f"robot {name!r}: links must be a sequence of ChainLink, got "
                f"{type(links).__name__} (build robots with Robot.from_dh, from_mdh or "
                "from_urdf)"
            )
        if not links:
            raise ModelError(f"robot {name!r}: a chain needs at least one joint")
        links = [checked_link(name, i, link) for i, link in enumerate(links)]
        T_base = np.eye(4) if base is None else rigid(as_pose("base", base))
        T_tool = np.eye(4) if tool is None else rigid(as_pose("tool", tool))
        names = [link.name for link in links]
        if len(set(names)) != len(names):
            raise ModelError(f"robot {name!r}: duplicate joint names in {names}")

        actuated = [link for link in links if link.mimic is None]
        index = {link.name: k for k, link in enumerate(actuated)}
        coupling = np.zeros((len(links), len(actuated)))
        joints = []
        for link in actuated:
            lo, hi = resolve_limits(
                link.name, link.kind, link.role, link.lower, link.upper, link.continuous
            )
            joints.append(Joint(link.name, link.kind, lo, hi, link.role))
        for i, link in enumerate(links):
            if link.mimic is None:
                coupling[i, index[link.name]] = 1.0
                continue
            if link.mimic.joint not in index:
                raise ModelError(
                    f"joint {link.name!r}: mimics {link.mimic.joint!r}, which is not an "
                    f"actuated joint of {name!r} (actuated: {list(index)})"
                )
            if link.lower is not None or link.upper is not None:
                raise ModelError(f"joint {link.name!r}: a mimic joint takes no limits")
            driver = joints[index[link.mimic.joint]]
            multiplier = _finite_multiplier(link.name, link.mimic)
            check_mimic_range(link, driver.name, driver.lower, driver.upper, multiplier)
            coupling[i, index[link.mimic.joint]] = multiplier

        n = len(links)
        K = np.empty((n + 1, 4, 4))
        E = np.empty((n, 4, 4))
        K[0] = T_base @ links[0].before @ joint_motion(links[0].kind, links[0].offset)
        for i, link in enumerate(links):
            nxt = (
                links[i + 1].before @ joint_motion(links[i + 1].kind, links[i + 1].offset)
                if i + 1 < n
                else T_tool
            )
            K[i + 1] = link.after @ nxt
            E[i] = link.after
        self.name = name
        self.joints: tuple[Joint, ...] = tuple(joints)
        self.chain_names: tuple[str, ...] = tuple(names)
        self.lower: FloatArray = read_only(np.array([j.lower for j in joints], dtype=float))
        self.upper: FloatArray = read_only(np.array([j.upper for j in joints], dtype=float))
        self.velocity_limits: FloatArray = read_only(
            np.array([math.inf if a.velocity is None else a.velocity for a in actuated])
        )
        self.acceleration_limits: FloatArray = read_only(
            np.array([math.inf if a.acceleration is None else a.acceleration for a in actuated])
        )
        self.T_world_base = T_base
        self.T_flange_tool = T_tool
        self.dh = dh
        self.convention = convention
        self.analytic = analytic
        self._K = read_only(K)
        self._E = read_only(E)
        self._prismatic = read_only(np.array([link.kind == "prismatic" for link in links]))
        self._coupling = read_only(coupling)
        self._identity_coupling = coupling.shape[0] == coupling.shape[1] and bool(
            np.all(coupling == np.eye(n))
        )
        self._cache: dict[Callable[[Robot], Any], Any] = {}
        if analytic is not None:
            # A declared closed-form family must fit when the robot is built, not first
            # fail inside solve_ik (AnalyticIKError names the relation that fails).
            for check in DECLARED_FAMILY_CHECKS:
                check(self)

    # ------------------------------------------------------------------ constructors
    @classmethod
    def from_dh(
        cls,
        rows: Sequence[DHJoint | Mapping[str, Any]],
        *,
        limits: Any = None,
        name: str = "robot",
        base: Any = None,
        tool: Any = None,
        analytic: str | None = None,
    ) -> Robot:
        """Build from standard DH rows, ``A = Rz(theta) Tz(d) Tx(a) Rx(alpha)``.

        Args:
            rows: one :class:`DHJoint` (or mapping with its field names; ``type`` is
                accepted for ``kind``) per joint, SI units and radians.
            limits: optional ``(dof, 2)`` array of ``[lower, upper]`` overriding the rows.
            name: robot name.
            base: 4x4 pose of frame 0 in the world frame (default identity).
            tool: 4x4 pose of the tool in the last link frame (default identity).
            analytic: name of a closed-form IK family (see :mod:`optik.analytic`).
        """
        return cls._from_rows(rows, False, limits, name, base, tool, analytic)

    @classmethod
    def from_mdh(
        cls,
        rows: Sequence[DHJoint | Mapping[str, Any]],
        *,
        limits: Any = None,
        name: str = "robot",
        base: Any = None,
        tool: Any = None,
        analytic: str | None = None,
    ) -> Robot:
        """Build from modified (Craig) DH rows, ``A = Rx(alpha) Tx(a) Rz(theta) Tz(d)``.

        Row ``i`` holds ``alpha_{i-1}, a_{i-1}, theta_i, d_i``.

        Args:
            rows: one :class:`DHJoint` (or mapping with its field names; ``type`` is
                accepted for ``kind``) per joint, m and rad.
            limits: optional ``(dof, 2)`` array of ``[lower, upper]``, rad or m, overriding
                the rows.
            name: robot name.
            base: 4x4 pose of frame 0 in the world frame, m (default identity).
            tool: 4x4 pose of the tool in the last link frame, m (default identity).
            analytic: name of a closed-form IK family (see :mod:`optik.analytic`).
        """
        return cls._from_rows(rows, True, limits, name, base, tool, analytic)

    @classmethod
    def _from_rows(
        cls,
        rows: Sequence[Any],
        modified: bool,
        limits: Any,
        name: str,
        base: Any,
        tool: Any,
        analytic: str | None,
    ) -> Robot:
        _check_names(name, analytic)
        dh_rows = [dh_row(row, i) for i, row in enumerate(checked_dh_rows(rows))]
        base = None if base is None else _check_frame("base", base)
        tool = None if tool is None else _check_frame("tool", tool)
        if limits is not None:
            actuated = [i for i, row in enumerate(dh_rows) if row.mimic is None]
            lim = finite_or_inf_limits(limits, len(actuated))
            for k, i in enumerate(actuated):
                row = dh_rows[i]
                dh_rows[i] = DHJoint(
                    **{**row.__dict__, "lower": float(lim[k, 0]), "upper": float(lim[k, 1])}
                )
        links = dh_links(dh_rows, modified)
        return cls(
            links,
            name=name,
            base=base,
            tool=tool,
            dh=tuple(dh_rows),
            convention="mdh" if modified else "dh",
            analytic=analytic,
        )

    @classmethod
    def from_urdf(
        cls,
        source: str | Path,
        base_link: str,
        tip_link: str,
        *,
        name: str | None = None,
        tool: Any = None,
        analytic: str | None = None,
    ) -> Robot:
        """Build the chain between two links of a URDF file or string.

        Fixed joints fold into the neighbouring transforms, ``continuous`` joints are
        unbounded; mimic, floating and planar joints are rejected. See :mod:`optik.urdf`.

        Args:
            source: the URDF file's path, or the URDF text itself (a string holding ``<``).
            base_link: the link the chain starts from; its frame is the world frame.
            tip_link: the link the chain ends at.
            name: robot name (default: the URDF's robot name).
            tool: 4x4 pose of the tool in the ``tip_link`` frame, m (default identity).
            analytic: name of a closed-form IK family (see :mod:`optik.analytic`).
        """
        from optik.urdf import parse_urdf_chain

        if name is not None:
            _check_names(name, analytic)
        elif analytic is not None:
            _check_names("robot", analytic)
        robot_name, links, T_last_tip = parse_urdf_chain(source, base_link, tip_link)
        T_tip_tool = np.eye(4) if tool is None else _check_frame("tool", tool)
        return cls(
            links,
            name=name or robot_name,
            tool=T_last_tip @ T_tip_tool,
            dh=None,
            convention="urdf",
            analytic=analytic,
        )

    # ------------------------------------------------------------------ properties
    @property
    def dof(self) -> int:
        """Number of joint coordinates (entries of ``q``)."""
        return len(self.joints)

    @property
    def joint_names(self) -> tuple[str, ...]:
        """Names of the joint coordinates, in ``q`` order."""
        return tuple(j.name for j in self.joints)

    @property
    def chain(self) -> Chain:
        """The kinematics and limits as the kernels take them (:class:`optik.chain.Chain`)."""
        return self.cached(_build_chain)

    def cached(self, build: Callable[[Robot], T_cached]) -> T_cached:
        """``build(self)``, computed once per robot and kept (the one caching pattern).

        Derived data (the chain, the seed table, the closed-form family and its packed
        parameters) is keyed by the function that builds it, so no module writes string
        keys into the robot. :meth:`with_limits` starts a fresh cache. Building is
        one-time setup: a query's ``timeout_s`` does not count it
        (:func:`optik._clock.one_time_setup`).

        Args:
            build: function of the robot that computes the value; also its cache key.
        """
        try:
            return self._cache[build]
        except KeyError:
            with one_time_setup():
                value = self._cache[build] = build(self)
            return value

    def __getstate__(self) -> dict[str, Any]:
        """The robot as pickled (a Dask worker's copy): without its cache of derived values.

        The cache holds compiled kernels; numba pickles one as its source, which the
        receiving process compiles again (about 20 s for a closed form) instead of loading
        it from its cache. Everything in the cache is rebuilt there on demand.
        """
        state = self.__dict__.copy()
        state["_cache"] = {}
        return state

    def cached_value(self, build: Callable[[Robot], T_cached]) -> T_cached | None:
        """What :meth:`cached` holds for ``build``, or ``None`` if it was not built yet.

        Args:
            build: the function the value was (or would be) built with, as given to :meth:`cached`.
        """
        return self._cache.get(build)

    @property
    def coupling(self) -> FloatArray:
        """``C`` with chain variables ``t = C q``, shape (chain joints, dof)."""
        return self._coupling.copy()

    @property
    def mid_limits(self) -> FloatArray:
        """Middle of each joint's range (0 for a continuous joint); a new array."""
        return self.cached(_mid_limits).copy()

    def __repr__(self) -> str:
        kinds = "".join("P" if j.kind == "prismatic" else "R" for j in self.joints)
        return f"Robot(name={self.name!r}, dof={self.dof}, joints={kinds!r})"

    # ------------------------------------------------------------------ kinematics
    def check_q(self, q: Any, name: str = "q") -> FloatArray:
        """Validate a configuration ``(dof,)`` or batch ``(N, dof)``; returns float64.

        Entries must be finite and of magnitude at most
        :data:`~optik._checks.MAX_LENGTH_M` (rad or m): beyond it a prismatic joint's
        translation would overflow the solvers' squared distances.

        Args:
            q: configuration (dof,) or batch (N, dof), rad or m.
            name: the argument's name in error messages.
        """
        return finite_length_array(name, q, (self.dof,), batch=True, unit="rad or m")

    def _theta(self, q: FloatArray) -> FloatArray:
        if self._identity_coupling:
            return np.ascontiguousarray(q)
        return np.ascontiguousarray(q @ self._coupling.T)

    def fk(self, q: Any) -> FloatArray:
        """Pose of the tool in the world frame: (4, 4), or (N, 4, 4) for q of shape (N, dof).

        Args:
            q: configuration (dof,) or batch (N, dof), rad or m.
        """
        q = self.check_q(q)
        theta = self._theta(q)
        if q.ndim == 1:
            out = np.empty((4, 4))
            _kernels.fk_into(self._K, self._prismatic, theta, out)
            return out
        return _kernels.fk_batch(self._K, self._prismatic, theta)

    def jacobian(self, q: Any) -> FloatArray:
        """Geometric Jacobian (6, dof) in the world frame at the tool point; batched too.

        Rows 0-2 map joint rates to the tool's linear velocity (m/s), rows 3-5 to its
        angular velocity (rad/s).

        Args:
            q: configuration (dof,) or batch (N, dof), rad or m; a batch gives (N, 6, dof).
        """
        return self.fk_jacobian(q)[1]

    def fk_jacobian(self, q: Any) -> tuple[FloatArray, FloatArray]:
        """Tool pose and Jacobian in one pass: ((4, 4), (6, dof)) or batched.

        Args:
            q: configuration (dof,) or batch (N, dof), rad or m;
                a batch gives ((N, 4, 4), (N, 6, dof)).
        """
        q = self.check_q(q)
        theta = self._theta(q)
        if q.ndim == 1:
            T = np.empty((4, 4))
            J = np.empty((6, self._prismatic.shape[0]))
            _kernels.fk_jacobian_into(self._K, self._prismatic, theta, T, J)
        else:
            T, J = _kernels.fk_jacobian_batch(self._K, self._prismatic, theta)
        if not self._identity_coupling:
            J = J @ self._coupling
        return T, J

    def frames(self, q: Any) -> FloatArray:
        """Every frame, world-relative: frame 0, link frames 1..n, then the tool.

        Args:
            q: one configuration (dof,), rad or m (a batch raises ``ShapeError``).

        Returns:
            ``(n + 2, 4, 4)`` for one configuration, where ``n`` counts chain joints
            (``dof`` plus any mimic joints).
        """
        q = self.check_q(q)
        if q.ndim != 1:
            raise ShapeError("q", f"({self.dof},)", q.shape)
        return _kernels.joint_frames(
            self._K, self._prismatic, self._E, self.T_world_base, self._theta(q)
        )

    def with_limits(self, lower: Any, upper: Any) -> Robot:
        """A copy of this robot with other joint limits (dof,) each; kinematics shared.

        Args:
            lower: lower joint limits (dof,), rad or m (``-inf`` allowed for a revolute joint).
            upper: upper joint limits (dof,), rad or m (``inf`` allowed for a revolute joint).

        Raises:
            InvalidLimitsError: NaN, ``lower > upper`` for some joint, a prismatic
                limit that is infinite, or a finite limit beyond
                :data:`~optik._checks.MAX_LENGTH_M` (rad or m).
            ArgumentError: complex, boolean or non-numeric limits.
            ShapeError: wrong shapes.
        """
        lo = as_float_array("lower", lower)
        hi = as_float_array("upper", upper)
        for name, arr in (("lower", lo), ("upper", hi)):
            if arr.shape != (self.dof,):
                raise ShapeError(name, f"({self.dof},)", arr.shape)
        joints = []
        for joint, a, b in zip(self.joints, lo, hi, strict=True):
            if math.isnan(a) or math.isnan(b) or a > b:
                raise InvalidLimitsError(joint.name, float(a), float(b))
            check_limit_magnitude(joint.name, joint.kind, float(a), float(b))
            joints.append(Joint(joint.name, joint.kind, float(a), float(b), joint.role))
        clone = copy.copy(self)
        clone.joints = tuple(joints)
        clone.lower = read_only(lo)
        clone.upper = read_only(hi)
        clone._cache = {}
        return clone

    @property
    def reach_sphere(self) -> tuple[FloatArray, float]:
        """A ball (centre (3,), radius m) in the world frame that contains every tool position.

        By the triangle inequality the tool lies within the sum of the chain's constant
        translations (plus each prismatic joint's largest stroke) of the first frame. When
        the first joint's next translation lies on its own axis (true of most arms: the
        shoulder sits on the base axis), that point does not move with the first joint and
        the ball is centred there, which is much tighter. Points outside are unreachable.
        """
        centre, radius = self.cached(_reach_sphere)
        return centre.copy(), radius

    def _reach_sphere_uncached(self) -> tuple[FloatArray, float]:
        lengths = np.linalg.norm(self._K[:, :3, 3], axis=1)
        strokes = np.zeros(len(self._prismatic))
        for i, prismatic in enumerate(self._prismatic):
            if prismatic:
                reach = np.maximum(np.abs(self.lower), np.abs(self.upper))
                # Over the driving joints only: a continuous joint's infinite range
                # times its zero coupling would be NaN.
                driven = self._coupling[i] != 0.0
                strokes[i] = float(np.sum(np.abs(self._coupling[i][driven]) * reach[driven]))
        K0, K1 = self._K[0], self._K[1]
        if not self._prismatic[0] and float(np.hypot(K1[0, 3], K1[1, 3])) < 1e-12:
            # K1's translation is on joint 1's z axis: a fixed point of the first motion.
            center = K0[:3, 3] + K0[:3, 2] * K1[2, 3]
            radius = float(np.sum(lengths[2:]) + np.sum(strokes[1:]))
        else:
            center = K0[:3, 3].copy()
            radius = float(np.sum(lengths[1:]) + np.sum(strokes))
        return center, radius

    def limit_violation(self, q: Any) -> float | FloatArray:
        """Largest excursion (rad or m) of ``q`` beyond its limits; 0 inside.

        Args:
            q: configuration (dof,) or batch (N, dof), rad or m;
                a batch gives one value per row (N,).
        """
        return limit_violation(self.check_q(q), self.lower, self.upper)

    def within_limits(self, q: Any, tol: float = 1e-12) -> bool | FloatArray:
        """Whether ``q`` (or each row) respects the limits up to ``tol``.

        Args:
            q: configuration (dof,) or batch (N, dof), rad or m;
                a batch gives one answer per row (N,).
            tol: accepted excursion beyond each limit, rad or m.
        """
        return within_limits(self.check_q(q), self.lower, self.upper, tol)


def _mid_limits(robot: Robot) -> FloatArray:
    mid = [
        0.5 * (lo + hi) if math.isfinite(lo) and math.isfinite(hi) else 0.0
        for lo, hi in zip(robot.lower.tolist(), robot.upper.tolist(), strict=True)
    ]
    return np.array(mid)


def _reach_sphere(robot: Robot) -> tuple[FloatArray, float]:
    return robot._reach_sphere_uncached()


def _build_chain(robot: Robot) -> Chain:
    """The :class:`Chain` of ``robot`` (see :attr:`Robot.chain`)."""
    return Chain(
        robot._K,
        robot._E,
        robot._prismatic,
        robot._coupling,
        robot._identity_coupling,
        robot.lower,
        robot.upper,
    )


__all__ = ["DHJoint", "Joint", "Mimic", "Robot"]
