"""One differential-IK step as a quadratic program, built before it is solved.

The step ``dq`` (dof,) moves the tool by the task displacement ``v = twist * dt`` to first
order, ``J dq ~ v``, where ``J`` (m, dof) holds the selected rows of the geometric
Jacobian (rows 0-2 linear, m per joint unit; rows 3-5 angular, rad per joint unit). Two
programs, in the ``qpsolvers`` form ``min 1/2 x^T P x + c^T x  s.t.  A x = b,
lb <= x <= ub``:

* **least norm** (seed 000, eq. 50, with bounds)::

      min  1/2 (dq - d)^T W (dq - d)    s.t.   J dq = v,   lb <= dq <= ub

  ``P = W`` (default ``I``), ``c = -W d``, ``A = J``, ``b = v``. Without active bounds the
  answer is the closed form ``d + W^-1 J^T (J W^-1 J^T)^-1 (v - J d)``; with ``d = 0`` it
  is ``W^-1 J^T (J W^-1 J^T)^-1 v``, and with ``W = I`` too ``J^T (J J^T)^-1 v`` (eq. 48).

* **least squares** (seed 000, eq. 63, damped, with bounds)::

      min  1/2 ||J dq - v||^2_Wt + 1/2 lambda^2 (dq - d)^T W (dq - d)    s.t.   lb <= dq <= ub

  ``P = J^T Wt J + lambda^2 W``, ``c = -J^T Wt v - lambda^2 W d``. Without active bounds
  the answer is the damped closed form ``(J^T Wt J + lambda^2 W)^-1 (J^T Wt v +
  lambda^2 W d)``; with ``lambda = 0`` and ``J`` of full column rank, the least-squares
  answer ``(J^T J)^-1 J^T v`` (eq. 47).

The offset ``d`` (dof,), rad or m, is the step the cost pulls towards (default 0):
:func:`optik.diff_ik` sets ``d = posture_gain (q_ref - q)`` for a posture. In the least-norm
program it moves the step only within the null space of ``J``: the task rows still hold
exactly.

The damping ``lambda`` (default :data:`DEFAULT_DAMPING` = 1e-3, in task units per joint
unit: m/rad for linear rows) keeps ``P`` positive definite when ``J`` has fewer rows than
columns (redundant arms) or loses rank (singularities). Its bias on the answer is
``lambda^2 / (sigma^2 + lambda^2)`` along a singular direction of ``J`` with singular
value ``sigma``: below 1e-4 relative for ``sigma >= 0.1`` m. It also bounds the condition
number of ``P`` by ``(sigma_max^2 + lambda^2) / lambda^2`` (about 1e6 for arms of metre
size), which QP backends still solve to about 1e-10; a smaller default (1e-6) would make
``P`` numerically singular (condition 1e12) and the backends' answers inaccurate along
the null space of ``J``. See ``docs/programs.md``.

Bounds on ``dq`` come from the joint limits and from optional velocity limits::

    lb = max(gain * (lower - q), -vmax * dt),   ub = min(gain * (upper - q), vmax * dt)

so ``q + dq`` stays inside ``[lower, upper]``. Infinite limits stay infinite (no ``1e20``
sentinels); when every bound is infinite the program has no ``lb``/``ub`` at all.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Final, Literal, TypedDict

import numpy as np
import qpsolvers
import scipy.optimize

from optik._checks import (
    FloatArray,
    as_float_array,
    check_bool,
    check_finite,
    check_int,
    check_real,
    finite_array,
)
from optik.errors import NonFiniteError, OptikError, ShapeError
from optik.model import Robot

if TYPE_CHECKING:  # typing.Unpack is in the standard library from Python 3.11
    from typing_extensions import Unpack

__all__ = [
    "ALL_ROWS",
    "DEFAULT_DAMPING",
    "MAX_DAMPING",
    "OBJECTIVES",
    "POSITION_ROWS",
    "TASK_ROUNDING",
    "DiffIKProgram",
    "Equilibrated",
    "KKTReport",
    "Objective",
    "QPSolution",
    "build_program",
    "build_qp",
    "check_velocity_limits",
    "equilibration_scale",
    "step_bounds",
]

Objective = Literal["least_norm", "least_squares"]

#: The two objectives of a differential-IK step.
OBJECTIVES: Final[tuple[str, ...]] = ("least_norm", "least_squares")

#: Default damping ``lambda`` of the least-squares program (m/rad for linear rows).
DEFAULT_DAMPING: Final[float] = 1e-3

#: Largest accepted damping ``lambda``. The step shrinks like ``1 / lambda^2`` beyond the
#: largest singular value of ``J`` (about 1 m/rad for an arm), so at 1e3 it is below 1e-6
#: of the undamped one; larger values only scale ``P`` towards what QP backends cannot
#: solve in bounded time (1e300 made one run for minutes).
MAX_DAMPING: Final[float] = 1e3

#: Largest binary exponent of the equilibration scale (:func:`equilibration_scale`): a
#: scale of ``2**1000`` (1e301) still leaves a bound of a few rad finite, while the
#: reciprocal of a subnormal ``||v||_inf`` (``dt = 1e-309``) overflows to ``inf``.
MAX_SCALE_EXPONENT: Final[int] = 1000

#: Rounding allowance on ``J dq = v``, times ``max_r sum_i |J_ri dq_i|`` (the size of the
#: products the residual sums, m or rad): a step with a large null-space part (a far
#: posture) meets the task to its own rounding, not better. 64 unit roundoffs cover the
#: sum of a 7-joint row and the solve that produced ``dq``.
TASK_ROUNDING: Final[float] = 64.0 * 2.0**-53

#: The spacing of float64's subnormal numbers: below ``2**-1022`` rounding is absolute,
#: so a step of that size (``dt = 1e-315``) meets the task only to a few of these.
SUBNORMAL_SPACING: Final[float] = 2.0**-1074

#: The six rows of the geometric Jacobian: linear x, y, z then angular x, y, z.
ALL_ROWS: Final[tuple[int, ...]] = (0, 1, 2, 3, 4, 5)

#: The linear (position) rows of the geometric Jacobian.
POSITION_ROWS: Final[tuple[int, ...]] = (0, 1, 2)


@dataclass(frozen=True)
class QPSolution:
    """What a backend returned for a :class:`DiffIKProgram`, before optik checks it.

    Attributes:
        x: the returned point (dof,), or ``None`` when the backend returned nothing.
        found: the backend's own claim of success.
        status: the backend's status text (or the exception it raised).
        backend: the backend's name, e.g. ``"qp:proxqp"`` or ``"casadi:qrqp"``.
        iterations: iterations reported by the backend, -1 when unknown.
    """

    x: FloatArray | None
    found: bool
    status: str
    backend: str
    iterations: int = -1


@dataclass(frozen=True)
class KKTReport:
    """Karush-Kuhn-Tucker conditions of a program at a point, multipliers fitted by optik.

    With ``g`` the gradient of the objective (:meth:`DiffIKProgram.gradient`, equal to
    ``P x + c``) the stationarity condition is
    ``g + A^T y - z_lower + z_upper = 0`` with ``z_lower, z_upper >= 0`` supported on the
    lower / upper active bounds. The multipliers are the nonnegative least-squares fit of
    that equation over the active set (``scipy.optimize.lsq_linear``), so their signs are
    enforced and ``stationarity`` is the smallest residual any valid multipliers achieve.

    Attributes:
        stationarity: ``||g + A^T y - z_lower + z_upper||_inf`` at the fitted multipliers.
        primal: largest violation of ``A x = b`` and of the bounds.
        y: equality multipliers (m,) (empty for least squares).
        z_lower: lower-bound multipliers (dof,), zero off the lower active set.
        z_upper: upper-bound multipliers (dof,), zero off the upper active set.
        active_lower: the joints whose lower bound is active.
        active_upper: the joints whose upper bound is active.
        scale: ``||P||_inf ||x||_inf + ||c||_inf + ||A^T||_inf ||b||_inf``, for relative tests.
    """

    stationarity: float
    primal: float
    y: FloatArray
    z_lower: FloatArray
    z_upper: FloatArray
    active_lower: np.ndarray
    active_upper: np.ndarray
    scale: float


@dataclass(frozen=True)
class Equilibrated:
    """A program rescaled for a backend: same minimizer up to the factor ``scale``.

    The backend solves ``min 1/2 x'^T P x' + c^T x'  s.t.  A x' = b,  lb <= x' <= ub``
    and the step is ``dq = x' / scale``. ``lb``/``ub`` are ``None`` when unbounded and
    ``A``/``b`` ``None`` for least squares.
    """

    P: FloatArray
    c: FloatArray
    A: FloatArray | None
    b: FloatArray | None
    lb: FloatArray | None
    ub: FloatArray | None
    scale: float


@dataclass(frozen=True, eq=False)
class DiffIKProgram:
    """A differential-IK step program: the ``qpsolvers.Problem`` and the data it came from.

    Attributes:
        qp: the quadratic program ``min 1/2 x^T P x + c^T x s.t. A x = b, lb <= x <= ub``
            (``qp.q`` is ``c``); ``qp.A``/``qp.b`` only for least norm, ``qp.lb``/``qp.ub``
            only when some bound is finite.
        objective: ``"least_norm"`` or ``"least_squares"``.
        q: the configuration the step starts from (dof,).
        J: the task rows of the Jacobian at ``q`` (m, dof).
        v: the task displacement (m,), m and rad.
        rows: indices of ``J``'s rows in the 6-row geometric Jacobian.
        lower: lower bound on ``dq`` (dof,), ``-inf`` where unbounded.
        upper: upper bound on ``dq`` (dof,), ``+inf`` where unbounded.
        W: joint-space weight (dof, dof), symmetric positive definite.
        Wt: task-space weight (m, m), symmetric positive semidefinite (least squares).
        damping: ``lambda`` of the least-squares program (0 for least norm).
        offset: the step ``d`` (dof,) the cost pulls towards, rad or m (``None``: 0).
    """

    qp: qpsolvers.Problem
    objective: Objective
    q: FloatArray
    J: FloatArray
    v: FloatArray
    rows: tuple[int, ...]
    lower: FloatArray
    upper: FloatArray
    W: FloatArray
    Wt: FloatArray
    damping: float
    offset: FloatArray | None = None
    _cache: dict[str, float] = field(default_factory=dict, repr=False, compare=False)

    # ------------------------------------------------------------------ shape
    @property
    def dof(self) -> int:
        """Number of variables (joint coordinates)."""
        return int(self.J.shape[1])

    @property
    def task_dim(self) -> int:
        """Number of task rows ``m``."""
        return int(self.J.shape[0])

    @property
    def P(self) -> FloatArray:
        """Cost matrix (dof, dof)."""
        return np.asarray(self.qp.P, dtype=np.float64)

    @property
    def c(self) -> FloatArray:
        """Cost vector (dof,) (``qpsolvers`` calls it ``q``)."""
        return np.asarray(self.qp.q, dtype=np.float64)

    @property
    def magnitude(self) -> float:
        """The program's size, m or rad: ``max(||v||_inf, ||d||_inf)`` (the offset ``d``)."""
        size = float(np.max(np.abs(self.v), initial=0.0))
        if self.offset is not None:
            size = max(size, float(np.max(np.abs(self.offset), initial=0.0)))
        return size

    @property
    def bounds_consistent(self) -> bool:
        """Whether ``lower <= upper`` for every joint (else no ``dq`` exists)."""
        return bool(np.all(self.lower <= self.upper))

    def equilibrated(self) -> Equilibrated:
        """The program rescaled for a backend, whose tolerances are absolute.

        The minimizer does not change when the cost is divided by ``p = max |P|``, and it
        scales with ``(v, d, lb, ub)``: the backend solves for ``x' = s dq`` with
        ``s = 1 /`` :attr:`magnitude` (:func:`equilibration_scale`: 1 when it is 0, capped
        at ``2**1000``), so its absolute tolerances act relative to the size of the task
        and of the cost.
        """
        qp = self.qp
        p = float(np.max(np.abs(qp.P)))
        p = p if p > 0.0 else 1.0
        s = equilibration_scale(self.magnitude)
        return Equilibrated(
            P=qp.P / p,
            c=qp.q * (s / p),
            A=None if qp.A is None else np.array(qp.A, dtype=np.float64),
            b=None if qp.b is None else qp.b * s,
            lb=None if qp.lb is None else qp.lb * s,
            ub=None if qp.ub is None else qp.ub * s,
            scale=s,
        )

    # ------------------------------------------------------------------ evaluation
    def gradient(self, dq: FloatArray) -> FloatArray:
        """Gradient of the stated objective at ``dq`` (dof,), from ``J, v, W, Wt, d``.

        Least norm: ``W (dq - d)``; least squares: ``J^T Wt (J dq - v) + lambda^2 W
        (dq - d)``. Computed from the program's data, not from ``qp.P`` and ``qp.q``, so a
        check built on it also checks that the QP states the objective.

        Args:
            dq: joint step (dof,), rad or m.
        """
        dev = dq if self.offset is None else dq - self.offset
        g: FloatArray = self.W @ dev
        if self.objective == "least_squares":
            g = self.J.T @ (self.Wt @ (self.J @ dq - self.v)) + (self.damping**2) * g
        return g

    def cost(self, dq: FloatArray) -> float:
        """Objective value ``1/2 dq^T P dq + c^T dq``.

        Args:
            dq: joint step (dof,), rad or m.
        """
        return float(0.5 * dq @ self.P @ dq + self.c @ dq)

    def task_residual(self, dq: FloatArray) -> FloatArray:
        """``J dq - v`` (m,), m and rad.

        Args:
            dq: joint step (dof,), rad or m.
        """
        r: FloatArray = self.J @ dq - self.v
        return r

    def task_tolerance(self, dq: FloatArray, rtol: float) -> float:
        """Largest accepted ``||J dq - v||_inf`` at ``dq``, m or rad (least norm).

        ``rtol ||v||_inf + TASK_ROUNDING max_r sum_i |J_ri dq_i|``: relative to the task
        itself, not to the posture offset (a posture far away must not loosen the task),
        plus the rounding of the products ``J dq`` (:data:`TASK_ROUNDING`), plus the
        absolute rounding of subnormal numbers (:data:`SUBNORMAL_SPACING` times
        ``max_r sum_i |J_ri| + 2 dof + 1``: each ``dq_i``, product and sum rounded on
        that grid), which matters only for a task below about 1e-300.

        Args:
            dq: joint step (dof,), rad or m.
            rtol: relative tolerance on the task (``optik.diffik.FEASIBILITY_RTOL``).
        """
        vabs = float(np.max(np.abs(self.v), initial=0.0))
        rows = np.abs(self.J)
        size = float(np.max(rows @ np.abs(dq), initial=0.0))
        grid = float(np.max(rows.sum(axis=1), initial=0.0)) + 2 * self.dof + 1
        return rtol * vabs + TASK_ROUNDING * size + SUBNORMAL_SPACING * grid

    def bound_violation(self, dq: FloatArray) -> float:
        """Largest excursion of ``dq`` beyond ``[lower, upper]``, 0 inside.

        Args:
            dq: joint step (dof,), rad or m.
        """
        with np.errstate(invalid="ignore"):
            excess = np.maximum(self.lower - dq, dq - self.upper)
        return float(max(0.0, np.max(excess)))

    def clip(self, dq: FloatArray) -> FloatArray:
        """``dq`` clipped into ``[lower, upper]`` (bounds are exact afterwards).

        Args:
            dq: joint step (dof,), rad or m.
        """
        out: FloatArray = np.minimum(np.maximum(dq, self.lower), self.upper)
        return out

    def min_task_violation(self) -> float:
        """Smallest ``||J dq - v||_inf`` over ``lower <= dq <= upper`` (an LP).

        Solved by ``scipy.optimize.linprog`` (HiGHS), independently of the QP backend:
        ``min t  s.t.  -t <= J dq - v <= t,  lower <= dq <= upper``. Zero (to the LP's
        tolerance) when the least-norm equality can hold inside the bounds; ``inf`` when the
        bounds themselves are inconsistent.
        """
        if "min_task_violation" in self._cache:
            return self._cache["min_task_violation"]
        if not self.bounds_consistent:
            value = math.inf
        else:
            m, n = self.J.shape
            ones = np.ones((m, 1))
            A_ub = np.block([[self.J, -ones], [-self.J, -ones]])
            b_ub = np.concatenate([self.v, -self.v])
            cost = np.zeros(n + 1)
            cost[-1] = 1.0
            bounds = [
                (None if math.isinf(lo) else lo, None if math.isinf(hi) else hi)
                for lo, hi in zip(self.lower, self.upper, strict=True)
            ] + [(0.0, None)]
            res = scipy.optimize.linprog(
                cost,
                A_ub=A_ub,
                b_ub=b_ub,
                bounds=bounds,
                method="highs",
                options={
                    "primal_feasibility_tolerance": 1e-10,
                    "dual_feasibility_tolerance": 1e-10,
                },
            )
            if res.status == 0:
                # The LP's point: refine the violation from the point itself (not res.fun).
                x = np.clip(res.x[:n], self.lower, self.upper)
                value = float(np.max(np.abs(self.J @ x - self.v)))
            else:  # pragma: no cover - bounded LP with a feasible box is always solvable
                value = math.inf
        self._cache["min_task_violation"] = value
        return value

    def kkt(self, dq: FloatArray, active_tol: float = 1e-9) -> KKTReport:
        """The KKT conditions at ``dq`` with multipliers fitted over the active set.

        A bound counts as active when ``dq`` lies within ``active_tol`` of it. See
        :class:`KKTReport` for the conditions and how the multipliers are found.

        Args:
            dq: joint step (dof,), rad or m, finite.
            active_tol: distance to a bound, rad or m, within which the bound counts as
                active (>= 0).

        Raises:
            ShapeError, NonFiniteError: ``dq`` not a finite (dof,) array.
            ArgumentError: ``active_tol`` not a finite number >= 0.
        """
        dq = finite_array("dq", dq, (self.dof,))
        active_tol = check_real("active_tol", active_tol, nonnegative=True)
        n = self.dof
        g = self.gradient(dq)
        at_lower = np.isfinite(self.lower) & (dq - self.lower <= active_tol)
        at_upper = np.isfinite(self.upper) & (self.upper - dq <= active_tol)
        cols = []
        lo_bounds: list[float] = []
        hi_bounds: list[float] = []
        if self.objective == "least_norm":
            cols.append(self.J.T)
            lo_bounds += [-np.inf] * self.task_dim
            hi_bounds += [np.inf] * self.task_dim
        lower_idx = np.flatnonzero(at_lower)
        upper_idx = np.flatnonzero(at_upper)
        eye = np.eye(n)
        # g + A^T y + E_l (-z_l) + E_u z_u = 0, i.e. the columns of M times the unknowns.
        cols.append(-eye[:, lower_idx])
        cols.append(eye[:, upper_idx])
        lo_bounds += [0.0] * (lower_idx.size + upper_idx.size)
        hi_bounds += [np.inf] * (lower_idx.size + upper_idx.size)
        M = np.hstack(cols) if cols else np.zeros((n, 0))
        if M.shape[1] == 0:
            unknowns = np.zeros(0)
            residual = g
        else:
            fit = scipy.optimize.lsq_linear(
                M, -g, bounds=(np.array(lo_bounds), np.array(hi_bounds)), method="bvls"
            )
            unknowns = np.asarray(fit.x, dtype=np.float64)
            residual = g + M @ unknowns
        k = self.task_dim if self.objective == "least_norm" else 0
        y = unknowns[:k]
        z_lower = np.zeros(n)
        z_upper = np.zeros(n)
        z_lower[lower_idx] = unknowns[k : k + lower_idx.size]
        z_upper[upper_idx] = unknowns[k + lower_idx.size :]
        primal = self.bound_violation(dq)
        if self.objective == "least_norm":
            primal = max(primal, float(np.max(np.abs(self.task_residual(dq)), initial=0.0)))
        scale = float(
            np.max(np.abs(self.P)) * np.max(np.abs(dq), initial=0.0)
            + np.max(np.abs(self.c), initial=0.0)
            + (
                np.max(np.abs(self.J)) * np.max(np.abs(self.v), initial=0.0)
                if self.objective == "least_norm"
                else 0.0
            )
        )
        return KKTReport(
            stationarity=float(np.max(np.abs(residual), initial=0.0)),
            primal=primal,
            y=y,
            z_lower=z_lower,
            z_upper=z_upper,
            active_lower=at_lower,
            active_upper=at_upper,
            scale=scale,
        )


def equilibration_scale(size: float) -> float:
    """The scale ``s`` of a step program: ``1 / size``, at most ``2**MAX_SCALE_EXPONENT``.

    The backend solves for ``x' = s dq``, so its absolute tolerances act relative to
    ``size``. The cap keeps ``s`` finite: the reciprocal of a subnormal ``size`` (a task
    below 1e-301, e.g. ``dt = 1e-309``) overflows to ``inf``, and the scaled program to
    NaN. Such a task reaches the backend below unit size; its answer is then solved again
    exactly on its active set (see :func:`optik.diffik.verify_step`). 1 for a zero or
    non-finite ``size``.

    Args:
        size: the program's magnitude (:attr:`DiffIKProgram.magnitude`), m or rad.
    """
    if not (size > 0.0 and math.isfinite(size)):
        return 1.0
    return 1.0 / size if size >= _SMALLEST_SCALED else _LARGEST_SCALE


_LARGEST_SCALE: Final = math.ldexp(1.0, MAX_SCALE_EXPONENT)
_SMALLEST_SCALED: Final = math.ldexp(1.0, -MAX_SCALE_EXPONENT)


# ---------------------------------------------------------------------- validation
def _check_rows(rows: Sequence[int] | None, v: FloatArray) -> tuple[tuple[int, ...], FloatArray]:
    """Resolve the task rows and the task vector they select."""
    if v.ndim != 1:
        raise ShapeError("v", "(6,), (3,) or (len(rows),)", v.shape)
    if rows is None:
        if v.shape == (6,):
            return ALL_ROWS, v
        if v.shape == (3,):
            return POSITION_ROWS, v
        raise ShapeError("v", "(6,) or (3,) (or pass rows)", v.shape)
    if isinstance(rows, str | bytes) or not isinstance(rows, Sequence | np.ndarray):
        raise OptikError(f"rows must be a sequence of integers in 0..5, got {rows!r}")
    picked = tuple(check_int(f"rows[{i}]", r, minimum=0, maximum=5) for i, r in enumerate(rows))
    if not picked or len(set(picked)) != len(picked):
        raise OptikError(f"rows must be distinct integers in 0..5, got {rows!r}")
    if v.shape == (len(picked),):
        return picked, v
    if v.shape == (6,):
        return picked, v[list(picked)]
    raise ShapeError("v", f"(6,) or ({len(picked)},) for rows {picked}", v.shape)


def _check_weight(name: str, value: Any, size: int, definite: bool) -> FloatArray:
    """A weight given as a diagonal (size,) or a matrix (size, size); returns the matrix."""
    if value is None:
        return np.eye(size)
    arr = as_float_array(name, value)
    if arr.shape == (size,):
        check_finite(name, arr)
        if np.any(arr < 0.0) or (definite and np.any(arr <= 0.0)):
            kind = "positive" if definite else "nonnegative"
            raise OptikError(f"{name}: diagonal weights must be {kind}, got {arr}")
        return np.diag(arr)
    if arr.shape != (size, size):
        raise ShapeError(name, f"({size},) or ({size}, {size})", arr.shape)
    check_finite(name, arr)
    top = float(np.max(np.abs(arr)))
    if not np.allclose(arr, arr.T, rtol=0.0, atol=1e-12 * max(1.0, top)):
        raise OptikError(f"{name}: weight matrix must be symmetric")
    sym = 0.5 * arr + 0.5 * arr.T  # halves first: arr + arr.T overflows near 1e308
    # The eigenvalues of sym / top (entries <= 1): LAPACK's fail to converge near 1e308.
    try:
        smallest = float(np.linalg.eigvalsh(sym / top)[0]) * top if top > 0.0 else 0.0
    except np.linalg.LinAlgError as exc:  # pragma: no cover - finite entries <= 1
        raise OptikError(f"{name}: eigenvalues of the weight matrix not computable") from exc
    if smallest < 0.0 or (definite and smallest <= 0.0):
        kind = "positive definite" if definite else "positive semidefinite"
        raise OptikError(f"{name}: weight matrix must be {kind} (smallest eigenvalue {smallest})")
    return sym


def _check_positive(
    name: str, value: Any, allow_zero: bool = False, maximum: float | None = None
) -> float:
    """A finite real number > 0 (``>= 0`` with ``allow_zero``), at most ``maximum``."""
    x = check_real(name, value, allow_nan=True, allow_inf=True)  # bool, str, complex fail
    if not math.isfinite(x):
        raise NonFiniteError(name)
    if x < 0.0 or (x == 0.0 and not allow_zero):
        raise OptikError(f"{name} must be {'>= 0' if allow_zero else '> 0'}, got {x}")
    if maximum is not None and x > maximum:
        raise OptikError(f"{name} must be <= {maximum:g}, got {x}")
    return x


def check_velocity_limits(velocity_limits: Any, dof: int) -> FloatArray:
    """Joint speed limits (dof,), rad/s or m/s: ``>= 0``, ``inf`` allowed, NaN rejected.

    Raises:
        ShapeError: not of shape (dof,).
        NonFiniteError: a NaN entry.
        OptikError: a negative entry.
    """
    vmax = as_float_array("velocity_limits", velocity_limits)
    if vmax.shape != (dof,):
        raise ShapeError("velocity_limits", f"({dof},)", vmax.shape)
    if np.any(np.isnan(vmax)):
        raise NonFiniteError("velocity_limits", tuple(np.argwhere(np.isnan(vmax))[0]))
    if np.any(vmax < 0.0):
        raise OptikError(f"velocity_limits must be >= 0, got {vmax}")
    return np.ascontiguousarray(vmax, dtype=np.float64)


def step_bounds(
    robot: Robot,
    q: FloatArray,
    *,
    limits: bool = True,
    limit_gain: float = 1.0,
    velocity_limits: Any = None,
    dt: float | None = None,
) -> tuple[FloatArray, FloatArray]:
    """Bounds on one step ``dq`` from the joint limits and optional velocity limits.

    ``lb = max(gain (lower - q), -vmax dt)``, ``ub = min(gain (upper - q), vmax dt)``;
    infinite limits stay infinite.

    Args:
        robot: the robot (its ``lower``/``upper`` limits, rad or m).
        q: configuration (dof,), already validated.
        limits: apply the joint limits.
        limit_gain: fraction in (0, 1] of the distance to a limit one step may cover.
        velocity_limits: ``vmax`` (dof,) in rad/s or m/s, ``>= 0``, ``inf`` allowed.
        dt: the time step (s), required with ``velocity_limits``.

    Returns:
        ``(lb, ub)``, each (dof,).

    Raises:
        OptikError: ``limit_gain`` outside (0, 1], ``dt <= 0``, negative velocity limits or
            velocity limits without ``dt``.
        ShapeError, NonFiniteError: a bad ``velocity_limits`` array.
    """
    gain = _check_positive("limit_gain", limit_gain)
    if gain > 1.0:
        raise OptikError(f"limit_gain must lie in (0, 1], got {gain}")
    if limits is not True and limits is not False:
        check_bool("limits", limits)
    n = robot.dof
    lb = np.full(n, -np.inf)
    ub = np.full(n, np.inf)
    if limits:
        with np.errstate(invalid="ignore"):
            lb = np.where(np.isfinite(robot.lower), gain * (robot.lower - q), -np.inf)
            ub = np.where(np.isfinite(robot.upper), gain * (robot.upper - q), np.inf)
    if velocity_limits is not None:
        if dt is None:
            raise OptikError("velocity_limits need the time step dt")
        step = _check_positive("dt", dt)
        reach = check_velocity_limits(velocity_limits, n) * step
        lb = np.maximum(lb, -reach)
        ub = np.minimum(ub, reach)
    return lb, ub


# ---------------------------------------------------------------------- builders
def build_program(
    robot: Robot,
    q: Any,
    v: Any,
    *,
    objective: Objective = "least_norm",
    dt: float | None = None,
    W: Any = None,
    Wt: Any = None,
    damping: float | None = None,
    limits: bool = True,
    limit_gain: float = 1.0,
    velocity_limits: Any = None,
    rows: Sequence[int] | None = None,
    offset: Any = None,
) -> DiffIKProgram:
    """Build the least-norm or least-squares step program at ``q`` (see the module doc).

    Args:
        robot: the robot.
        q: configuration (dof,), rad or m.
        v: task displacement ``twist * dt``: (6,) linear (m) then angular (rad), (3,) for
            the position rows, or one entry per index of ``rows``.
        objective: ``"least_norm"`` or ``"least_squares"``.
        dt: time step (s) that scales ``velocity_limits``; required with them.
        W: joint weight, (dof,) diagonal or (dof, dof) symmetric positive definite
            (default ``I``).
        Wt: task weight of the least-squares residual, (m,) or (m, m) symmetric positive
            semidefinite (default ``I``).
        damping: ``lambda >= 0`` of the least-squares program (default
            :data:`DEFAULT_DAMPING`); must stay ``None`` for least norm.
        limits: bound ``q + dq`` by the joint limits.
        limit_gain: fraction in (0, 1] of the distance to each limit a step may use.
        velocity_limits: joint speed limits (dof,), rad/s or m/s, ``inf`` allowed.
        rows: indices (0..5) of the Jacobian rows of the task (default: all six for a
            (6,) ``v``, the position rows for a (3,) ``v``).
        offset: the step ``d`` (dof,), rad or m, the cost pulls towards (default 0): the
            joint term becomes ``(dq - d)^T W (dq - d)``.

    Returns:
        The :class:`DiffIKProgram`; its ``qp`` is the ``qpsolvers.Problem``.

    Raises:
        ShapeError: ``q``, ``v``, ``W``, ``Wt``, ``offset`` or ``velocity_limits`` has a
            wrong shape.
        NonFiniteError: one of them holds NaN (or infinity where not allowed).
        OptikError: an unknown objective, ``limit_gain`` outside (0, 1], ``dt <= 0``,
            ``damping < 0`` or given for least norm, bad ``rows``, or weights that are not
            symmetric (semi)definite; ``limits`` not a bool (``ArgumentError``).
    """
    if not isinstance(robot, Robot):
        raise OptikError(f"robot must be an optik.Robot, got {type(robot).__name__}")
    if objective not in OBJECTIVES:
        raise OptikError(f"objective must be one of {OBJECTIVES}, got {objective!r}")
    if limits is not True and limits is not False:
        check_bool("limits", limits)  # as diff_ik: "no" is not True, None not False
    if dt is not None:
        _check_positive("dt", dt)
    q_arr = finite_array("q", q, (robot.dof,))
    v_raw = as_float_array("v", v)
    picked, v_arr = _check_rows(rows, v_raw)
    v_arr = check_finite("v", np.array(v_arr, dtype=np.float64))
    n, m = robot.dof, len(picked)
    W_mat = _check_weight("W", W, n, definite=True)
    Wt_mat = _check_weight("Wt", Wt, m, definite=False)
    d = None if offset is None else finite_array("offset", offset, (n,)).copy()
    if objective == "least_norm":
        if damping is not None:
            raise OptikError("damping applies to the least_squares objective only")
        if Wt is not None:
            raise OptikError("Wt applies to the least_squares objective only")
        lam = 0.0
    else:
        lam = (
            DEFAULT_DAMPING
            if damping is None
            else _check_positive("damping", damping, True, maximum=MAX_DAMPING)
        )
    lb, ub = step_bounds(
        robot, q_arr, limits=limits, limit_gain=limit_gain, velocity_limits=velocity_limits, dt=dt
    )
    J = np.ascontiguousarray(robot.jacobian(q_arr)[list(picked)])
    bounded = bool(np.any(np.isfinite(lb)) or np.any(np.isfinite(ub)))
    qp_lb = lb.copy() if bounded else None
    qp_ub = ub.copy() if bounded else None
    if objective == "least_norm":
        c = np.zeros(n) if d is None else -(W_mat @ d)
        qp = qpsolvers.Problem(W_mat.copy(), c, A=J.copy(), b=v_arr.copy(), lb=qp_lb, ub=qp_ub)
    else:
        P = J.T @ Wt_mat @ J + lam * lam * W_mat
        P = 0.5 * (P + P.T)
        c = -(J.T @ (Wt_mat @ v_arr))
        if d is not None:
            c -= lam * lam * (W_mat @ d)
        qp = qpsolvers.Problem(P, c, lb=qp_lb, ub=qp_ub)
    return DiffIKProgram(
        qp=qp,
        objective=objective,
        q=q_arr.copy(),
        J=J,
        v=v_arr,
        rows=picked,
        lower=lb,
        upper=ub,
        W=W_mat,
        Wt=Wt_mat,
        damping=lam,
        offset=d,
    )


class StepProgramOptions(TypedDict, total=False):
    """The keywords of :func:`build_program` after ``robot, q, v`` (see it for each)."""

    objective: Objective
    dt: float | None
    W: Any
    Wt: Any
    damping: float | None
    limits: bool
    limit_gain: float
    velocity_limits: Any
    rows: Sequence[int] | None
    offset: Any


def build_qp(
    robot: Robot, q: Any, v: Any, **options: Unpack[StepProgramOptions]
) -> qpsolvers.Problem:
    """The ``qpsolvers.Problem`` of one differential-IK step.

    Least norm: ``min 1/2 ||dq - d||^2_W  s.t.  J dq = v,  lb <= dq <= ub``; least squares:
    ``min 1/2 ||J dq - v||^2_Wt + 1/2 lambda^2 ||dq - d||^2_W  s.t.  lb <= dq <= ub``. The
    keywords (those of :class:`StepProgramOptions`), raises and bounds are as in
    :func:`build_program` (which also keeps ``J``, ``v`` and the bounds next to the problem).

    Args:
        robot: the robot.
        q: configuration (dof,), rad or m.
        v: task displacement ``twist * dt``: (6,) linear (m) then angular (rad), (3,) for
            the position rows, or one entry per index of ``rows``.
    """
    return build_program(robot, q, v, **options).qp
