"""Any six revolute joints: every branch by elimination to one 24 x 24 eigenproblem.

The arms that fit no decomposition (no spherical wrist, no three parallel axes, ...;
pybullet's xArm6, whose wrist is offset) still have finitely many answers, at most 16:
Raghavan and Roth's elimination (ASME J. Mech. Des. 1993) in the matrix form of Manocha
and Canny (IEEE T-RA 1994) finds them all. With the arm as standard-DH rows
(:func:`optik.analytic.geometry.equivalent_dh`, unsnapped) and its target ``X = A_1 ...
A_6``:

1. ``A_3 A_4 A_5 = (A_1 A_2)^-1 X A_6^-1``. The point ``o_5 + d_6 z_5`` and the direction
   ``z_5`` of the right side do not depend on ``theta_6`` (``p = p_X - a_6 x_X``,
   ``l = R_X Rx(-alpha_6) e_3``). With ``p . p``, ``p . l``, ``p x l`` and
   ``(p . p) l - 2 (p . l) p`` they give 14 equations, each a combination of the products
   of ``(sin, cos, 1)`` of ``theta_3``, ``theta_4``, ``theta_5`` on the left and of
   ``theta_1``, ``theta_2`` on the right (Raghavan and Roth's result). The coefficients
   are not derived by hand here: each side is evaluated on a 3 x 3 (x 3) grid of angles,
   where the products of ``(sin, cos, 1)`` form an invertible basis, so the coefficients
   follow exactly (the left side's once per robot, the right side's per target).
2. The eight products of ``theta_1, theta_2`` are eliminated by the left null space of
   their 14 x 8 coefficients: six equations in the nine products of ``theta_4,
   theta_5``, linear in ``(sin, cos, 1)`` of ``theta_3``.
3. Half-angle tangents ``x_i`` make them polynomials; with the same six times ``x_4``,
   twelve equations in twelve monomials ``x_4^i x_5^j`` (``i <= 3``, ``j <= 2``) whose
   matrix is quadratic in ``x_3``: its determinant vanishes at the answers' ``x_3``, the
   eigenvalues of a 24 x 24 pencil (two of degree 4 in ``x_3 = +-i`` aside).
4. Each real eigenvalue's eigenvector gives ``x_4`` and ``x_5``; the eight products give
   ``theta_1`` and ``theta_2`` (least squares over the 14 equations); ``A_6 = (A_1 ...
   A_5)^-1 X`` gives ``theta_6``. Gauss-Newton steps on the table's own chain (none for
   most roots, more for a double root) restore each to rounding; the caller verifies
   every branch by the robot's FK. Lengths are in units of the arm's largest ``a`` or
   ``d``, so that the same geometry at another size gives the same branches.

A fixed shift of ``theta_3``, ``theta_4`` and ``theta_5`` (:data:`SHIFTS`) keeps an answer
at 180 degrees off the pencil's infinite eigenvalue. Some geometries make the pencil
singular for every ``x_3`` (the Puma, the UR arms: their own families solve them); the
chain taken backwards (``X^-1`` by the joints in reverse) then often is not (the xArm6).
The family fits a robot when one of the two orders passes a self-test when the robot is
first matched: the configurations of :data:`SELF_TEST_POSES` random poses are each found
again. Being numerical (an eigenvalue near a double root may come out complex), an
empty answer is not a proof (``proves_unreachable = False``): callers search
numerically instead of reporting ``unreachable``. In Python, about 2 ms per pose (the
pencil's eigenvalues and each branch's Newton step): ``solve_ik`` keeps its numeric
solvers for such an arm (``fast = False``), and ``analytic_ik``, ``solve_ik_all`` and
``plan_path`` take every branch from here.
"""

from __future__ import annotations

import math
from typing import ClassVar, NamedTuple

import numpy as np
import scipy.linalg

from optik._checks import FloatArray
from optik.analytic._base import PlannedFamily, register
from optik.analytic.geometry import NoTable, dh_matrix, equivalent_dh, revolute_chain_reason
from optik.errors import AnalyticIKError
from optik.model import Robot

SHIFTS: tuple[float, ...] = (0.0, 0.0, 0.3141, 0.7071, 1.1347, 0.0)
"""Fixed shifts (rad) of the solver's angle variables (any values away from 0 and pi)."""

SELF_TEST_POSES = 16
"""Random configurations whose poses an order of the chain must solve back to fit."""

IMAG_TOL = 1e-3
"""An eigenvalue ``x_3`` with ``|Im| <= IMAG_TOL max(1, |x_3|)`` is taken as real: at a
singular configuration the answer is a double root, which rounding splits into a
complex pair (the Newton steps and the FK check judge every candidate)."""

FOUND_TOL = 1e-6
"""How close (rad) a self-test branch must come to the configuration it was posed from."""

NEWTON_STEPS = 20
"""Gauss-Newton steps at most per branch, on the table's own chain (most roots take
none or one; a double root converges only linearly)."""

NEWTON_SKIP = 1e-13
"""A branch whose pose error (m, rad) is at most this takes no step."""

# Half-angle forms, times (1 + x^2), of the basis (sin, cos, 1): coefficients of 1, x, x^2.
_HALF_ANGLE = np.array([[0.0, 2.0, 0.0], [1.0, 0.0, -1.0], [1.0, 0.0, 1.0]])
# The exact-fit grid of angles: (sin, cos, 1) at these three is an invertible basis.
_GRID = np.array([0.0, 2.0 * math.pi / 3.0, 4.0 * math.pi / 3.0])
_GRID_BASIS_INV = np.linalg.inv(np.stack([np.sin(_GRID), np.cos(_GRID), np.ones(3)], axis=1))


class Order(NamedTuple):
    """One order of the chain as the elimination takes it.

    Attributes:
        rows: (6, 4) ``theta offset (shift included), d, a, alpha`` per row (m, rad).
        lhs: (14, 3, 3, 3) the left side's coefficients on ``(sin, cos, 1)`` of
            ``theta_3``, ``theta_4``, ``theta_5`` (in that index order).
        reverse: whether the rows are the chain backwards.
        before: (4, 4) ``B`` of the backwards chain (``A'_1 ... A'_6 = B^-1 X^-1``).
    """

    rows: FloatArray
    lhs: FloatArray
    reverse: bool
    before: FloatArray


class Plan(NamedTuple):
    """A robot's general-6R solver, or why it has none.

    Attributes:
        reason: ``""`` when the family fits, else why not (one line).
        order: the order that passed the self-test.
        T_world_0: (4, 4) world pose of the DH frame 0.
        T_n_tool: (4, 4) the tool in the last DH frame.
        senses: (6,) +1 or -1: the table's joint variable is ``senses * q``.
        length: the unit of the order's lengths (m): the arm's largest ``a`` or ``d``.
    """

    reason: str
    order: Order | None = None
    T_world_0: FloatArray | None = None
    T_n_tool: FloatArray | None = None
    senses: FloatArray | None = None
    length: float = 1.0


def _dh(rows: FloatArray, theta: FloatArray) -> FloatArray:
    """``Rz(theta) Tz(d) Tx(a) Rx(alpha)`` for each row and angle: (..., 4, 4).

    ``rows`` (..., 4) as in :class:`Order` (the offset is added to ``theta``).
    """
    t = rows[..., 0] + theta
    d, a, alpha = (np.broadcast_to(rows[..., k], t.shape) for k in (1, 2, 3))
    ct, st, ca, sa = np.cos(t), np.sin(t), np.cos(alpha), np.sin(alpha)
    zero, one = np.zeros_like(t), np.ones_like(t)
    return np.stack(
        [
            np.stack([ct, -st * ca, st * sa, a * ct], axis=-1),
            np.stack([st, ct * ca, -ct * sa, a * st], axis=-1),
            np.stack([zero, sa, ca, d], axis=-1),
            np.stack([zero, zero, zero, one], axis=-1),
        ],
        axis=-2,
    )


def _chain(rows: FloatArray, theta: FloatArray) -> FloatArray:
    """The product of the rows' transforms at ``theta`` (n,): (4, 4)."""
    T = np.eye(4)
    for row, angle in zip(rows.tolist(), theta.tolist(), strict=True):
        T = T @ dh_matrix(row[2], row[3], row[1], row[0] + angle)
    return T


def _equations(p: FloatArray, line: FloatArray) -> FloatArray:
    """Raghavan and Roth's 14 quantities of a point ``p`` and a direction ``line``.

    Both (..., 3); returns (..., 14).
    """
    pp = np.einsum("...i,...i->...", p, p)[..., None]
    pl = np.einsum("...i,...i->...", p, line)[..., None]
    return np.concatenate([p, line, pp, pl, np.cross(p, line), pp * line - 2.0 * pl * p], axis=-1)


def _left_side(rows: FloatArray) -> FloatArray:
    """Coefficients (14, 3, 3, 3) of the left side on ``(sin, cos, 1)`` of theta_3, 4, 5."""
    g3, g4, g5 = np.meshgrid(_GRID, _GRID, _GRID, indexing="ij")
    A = _dh(rows[2], g3) @ _dh(rows[3], g4) @ _dh(rows[4], g5)
    p = A[..., :3, 2] * rows[5, 1] + A[..., :3, 3]  # o_5 + d_6 z_5, frame 2
    values = _equations(p, A[..., :3, 2])  # (3, 3, 3, 14)
    inv = _GRID_BASIS_INV
    return np.einsum("ma,nb,oc,abck->kmno", inv, inv, inv, values)


def _right_side(rows: FloatArray, X: FloatArray) -> FloatArray:
    """Coefficients (14, 3, 3) of the right side on ``(sin, cos, 1)`` of theta_1, 2."""
    alpha6, a6 = rows[5, 3], rows[5, 2]
    point = X[:3, 3] - a6 * X[:3, 0]
    direction = X[:3, :3] @ np.array([0.0, math.sin(alpha6), math.cos(alpha6)])
    g1, g2 = np.meshgrid(_GRID, _GRID, indexing="ij")
    A = _dh(rows[0], g1) @ _dh(rows[1], g2)  # (3, 3, 4, 4)
    R = np.swapaxes(A[..., :3, :3], -1, -2)  # (A_1 A_2)^-1's rotation
    p = np.einsum("...ij,j->...i", R, point) - np.einsum("...ij,...j->...i", R, A[..., :3, 3])
    line = np.einsum("...ij,j->...i", R, direction)
    values = _equations(p, line)  # (3, 3, 14)
    inv = _GRID_BASIS_INV
    return np.einsum("ma,nb,abk->kmn", inv, inv, values)


def _solve_order(order: Order, X: FloatArray) -> list[FloatArray]:
    """The solver's angles (6,) reaching ``X = A_1 ... A_6`` for one order (raw)."""
    rows = order.rows
    right = _right_side(rows, X)  # (14, 3, 3)
    left = order.lhs.copy()
    left[:, 2, 2, 2] -= right[:, 2, 2]  # the constants to the left side
    products = right.reshape(14, 9)[:, :8]  # theta_1, theta_2 products but the constant
    U, s, _ = np.linalg.svd(products)
    if not s[-1] > 1e-10 * s[0]:
        return []  # the products are dependent at this target: no elimination
    null = U[:, 8:].T  # (6, 14)
    solve_products = np.linalg.pinv(products)  # least squares over the 14 equations
    M = np.einsum("ek,kmab->emab", null, left)
    H = _HALF_ANGLE
    S = np.einsum("emab,mp,ai,bj->peij", M, H, H, H)  # (x_3 power, eq, x_4 power, x_5 power)
    blocks = np.zeros((3, 12, 4, 3))
    blocks[:, :6, :3, :] = S
    blocks[:, 6:, 1:, :] = S  # the six times x_4
    big = blocks.reshape(3, 12, 12)
    zero, eye = np.zeros((12, 12)), np.eye(12)
    pencil_a = np.block([[zero, eye], [-big[0], -big[1]]])
    pencil_b = np.block([[eye, zero], [zero, big[2]]])
    values, vectors = scipy.linalg.eig(pencil_a, pencil_b)
    found = []
    for x3, vector in zip(values, vectors.T, strict=True):
        if not np.isfinite(x3) or abs(x3.imag) > IMAG_TOL * max(1.0, abs(x3)):
            continue
        x3 = float(x3.real)
        v = vector[:12].reshape(4, 3)
        v = (v * np.conj(v[np.unravel_index(np.argmax(np.abs(v)), v.shape)])).real
        i, j = np.unravel_index(np.argmax(np.abs(v[:3, :2])), (3, 2))
        x5 = v[i, j + 1] / v[i, j] if v[i, j] != 0.0 else math.inf
        i, j = np.unravel_index(np.argmax(np.abs(v[:3, :])), (3, 3))
        x4 = v[i + 1, j] / v[i, j] if v[i, j] != 0.0 else math.inf
        t3, t4, t5 = 2.0 * math.atan(x3), 2.0 * math.atan(x4), 2.0 * math.atan(x5)
        basis = [np.array([math.sin(t), math.cos(t), 1.0]) for t in (t3, t4, t5)]
        y = solve_products @ np.einsum("kmab,m,a,b->k", left, *basis)
        # y over (s1, c1, 1) x (s2, c2, 1) without the constant: s1 at 2, c1 at 5, s2 at 6.
        t1, t2 = math.atan2(y[2], y[5]), math.atan2(y[6], y[7])
        partial = np.array([t1, t2, t3, t4, t5])
        A6 = np.linalg.solve(_chain(rows[:5], partial), X)
        t6 = math.atan2(A6[1, 0], A6[0, 0]) - rows[5, 0]
        found.append(_newton(rows, np.append(partial, t6), X))
    return found


def _newton(rows: FloatArray, theta: FloatArray, X: FloatArray) -> FloatArray:
    """Gauss-Newton steps of ``theta`` towards ``A_1 ... A_6 = X``.

    At most :data:`NEWTON_STEPS`; none once the pose is met to :data:`NEWTON_SKIP` (most
    roots come out of the eigenproblem so).
    """
    for _ in range(NEWTON_STEPS):
        T = np.eye(4)
        axes, origins = np.empty((6, 3)), np.empty((6, 3))
        for i, (row, angle) in enumerate(zip(rows.tolist(), theta.tolist(), strict=True)):
            axes[i], origins[i] = T[:3, 2], T[:3, 3]
            T = T @ dh_matrix(row[2], row[3], row[1], row[0] + angle)
        # Half the sum of t_i x x_i over the columns: the vee of M - M^T, M = X R^T.
        M = X[:3, :3] @ T[:3, :3].T
        rotation_error = 0.5 * np.array([M[2, 1] - M[1, 2], M[0, 2] - M[2, 0], M[1, 0] - M[0, 1]])
        error = np.concatenate([X[:3, 3] - T[:3, 3], rotation_error])
        if not float(np.max(np.abs(error))) > NEWTON_SKIP:
            break
        J = np.concatenate([np.cross(axes, T[:3, 3] - origins).T, axes.T])
        theta = theta + np.linalg.lstsq(J, error, rcond=None)[0]
    return theta


def _reversed(rows: FloatArray) -> tuple[FloatArray, FloatArray]:
    """The chain backwards: rows' with ``A'_1 ... A'_6 = B^-1 (A_1 ... A_6)^-1``.

    ``A_i^-1 = Rx(-alpha_i) Tx(-a_i) Tz(-d_i) Rz(-theta_i)``: regrouped, row ``k`` of the
    backwards chain is joint ``7 - k`` with ``theta' = -theta``, ``d' = -d`` and the twist
    and length of the joint before it negated; ``B = Rx(-alpha_6) Tx(-a_6)``.
    """
    o, d, a, alpha = rows.T
    back = np.array(
        [
            [-o[5 - k], -d[5 - k], -a[4 - k] if k < 5 else 0.0, -alpha[4 - k] if k < 5 else 0.0]
            for k in range(6)
        ]
    )
    c, s = math.cos(-alpha[5]), math.sin(-alpha[5])
    before = np.array(
        [[1.0, 0.0, 0.0, -a[5]], [0.0, c, -s, 0.0], [0.0, s, c, 0.0], [0.0, 0.0, 0.0, 1.0]]
    )
    return back, before


def _order(rows: FloatArray, reverse: bool) -> Order:
    before = np.eye(4)
    if reverse:
        rows, before = _reversed(rows)
    shifted = rows.copy()
    shifted[:, 0] += np.array(SHIFTS)
    return Order(shifted, _left_side(shifted), reverse, before)


def solve_angles(order: Order, X: FloatArray) -> list[FloatArray]:
    """The table's joint angles (6,) (offsets excluded) reaching ``X`` in frame 0, raw."""
    if order.reverse:
        target = np.linalg.solve(order.before, np.linalg.inv(X))
        return [-(theta + np.array(SHIFTS))[::-1] for theta in _solve_order(order, target)]
    return [theta + np.array(SHIFTS) for theta in _solve_order(order, X)]


def _passes(order: Order, base_rows: FloatArray) -> bool:
    """Whether ``order`` solves back the configurations of :data:`SELF_TEST_POSES` poses."""
    rng = np.random.default_rng(6)
    for _ in range(SELF_TEST_POSES):
        theta = rng.uniform(-math.pi, math.pi, 6)
        X = _chain(base_rows, theta)
        found = solve_angles(order, X)
        if not any(
            float(np.max(np.abs(np.angle(np.exp(1j * (branch - theta)))))) <= FOUND_TOL
            for branch in found
        ):
            return False
    return True


def general_plan(robot: Robot) -> Plan:
    """The robot's general-6R solver (:class:`Plan`), or why it has none."""
    reason = revolute_chain_reason(robot, 6)
    if reason is not None:
        return Plan(reason)
    try:
        model = equivalent_dh(robot, snap=False)
    except NoTable as exc:
        return Plan(str(exc))
    rows = np.array([[r.theta, r.d, r.a, r.alpha] for r in model.rows])
    # In units of the arm's largest length: the 14 equations mix terms in 1, L and L^2,
    # and the same geometry at another size must give the same branches.
    length = float(np.max(np.abs(rows[:, 1:3])))
    if not length > 0.0:
        return Plan("every length of the arm is zero")
    rows[:, 1:3] /= length
    base_rows = rows.copy()
    for reverse in (False, True):
        order = _order(rows, reverse)
        if _passes(order, base_rows):
            senses = np.array(model.senses or (1.0,) * 6)
            return Plan("", order, model.T_world_0, model.T_n_tool, senses, length)
    return Plan(
        "the elimination is singular (or too ill-conditioned) for this geometry in both "
        "orders of the chain"
    )


@register
class General6R(PlannedFamily):
    """Any six revolute joints (module docstring): up to 16 branches, numerically.

    Fits six uncoupled revolute joints whose elimination passes the self-test
    (:func:`general_plan`).
    """

    name = "general_6r"
    modes = ("pose",)
    proves_unreachable: ClassVar[bool] = False
    fast: ClassVar[bool] = False
    plan = staticmethod(general_plan)

    def candidates(
        self, robot: Robot, T_0_target: FloatArray, mode: str, q_ref: FloatArray
    ) -> list[FloatArray]:
        """Every real root's branch (up to 16), before wrapping and the FK check.

        Raises:
            AnalyticIKError: ``robot`` does not fit the family (the reason).
        """
        plan = robot.cached(general_plan)
        order, T_world_0, T_n_tool, senses = plan.order, plan.T_world_0, plan.T_n_tool, plan.senses
        if order is None or T_world_0 is None or T_n_tool is None or senses is None:
            raise AnalyticIKError(f"robot {robot.name!r} does not fit general_6r: {plan.reason}")
        world = robot.T_world_base @ T_0_target @ robot.T_flange_tool
        X = np.linalg.solve(T_world_0, world) @ np.linalg.inv(T_n_tool)
        if not np.all(np.isfinite(X)):
            return []
        X[:3, 3] /= plan.length
        return [senses * theta for theta in solve_angles(order, X)]
