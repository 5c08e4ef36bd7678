"""One Gauss–Newton step of a closed-form branch, on the robot's own chain.

A closed form found from the joint axes solves the ideal arm: axes that meet only to
within the geometry's tolerances (a URDF angle written to 11 digits) leave each branch
about 1e-11 from its target, more where a singularity magnifies it. One step on the
chain the FK check multiplies out anyway restores it to rounding, and costs little there:
:func:`optik.analytic._rows.fk_shared` has just formed every prefix product of the
branch, and joint ``i`` turns about the z axis of prefix ``i`` (through its origin), so
the Jacobian is a cross product per joint.

Two ways to solve for the step:

- an arm whose last three axes meet, with three arm joints before them (six joints, or
  seven with one of the first four held, outside a near miss): the Newton step referred
  to the wrist centre, where the Jacobian is block triangular (:func:`_wrist_step`, two
  3 x 3 solves by Cramer's rule instead of six normal equations);
- otherwise, or where a block is near singular: the damped normal equations
  ``(J^T J + lambda^2 I) dq = J^T e`` (:func:`_damped_step`,
  :data:`REFINE_DAMPING`: directions of ``J`` with singular
  values far below ``lambda`` are not moved, so a free angle keeps its reference).

Either leaves the linearised residual no larger than it was (``||e - J dq|| <= ||e||``;
the wrist step misses it only by the axes' miss times the step), and a step is applied
only when every component is at most :data:`REFINE_MAX_STEP`
(a larger one means an ill-posed system).

The wrist step, taken by nearly every row, is inlined into the step (3 % of the Kinova's
batch); the Jacobian and the damped solve, off that path, are compiled calls of their
own. The step's one caller, :func:`optik.analytic._row_steps._newton_move`, is compiled
once for every pipeline (run-time arguments), so inlining costs no install time. A call
costs little when its arrays are borrowed views (:func:`optik._nrt.borrowed`, as the
batch loops pass them): a counted array passed to a call costs an atomic increment and
decrement, which took a quarter of the Kinova's batch time (every row of it takes a step).
"""

from __future__ import annotations

import numpy as np

from optik._numba import inline as _inline
from optik._numba import jit as _jit

REFINE_DAMPING = 1e-6
"""Damping of :func:`_damped_step` (the Jacobian's scale is 1 m or 1): directions of the
Jacobian with singular values far below it (at a singularity) are not moved, so a free
angle keeps its reference."""
REFINE_MAX_STEP = 1e-4
"""Largest correction (rad or m) the refinement's :func:`newton_step` applies: a larger
one means an ill-posed system, and the closed form's values are kept (a near miss's
steps take :data:`optik.analytic._row_steps.NEAR_MISS_MAX_STEP`)."""
REFINE_TRUSTED_STEP = 1e-8
"""A correction up to this (rad or m) from a branch within half the FK check's tolerance
is kept without a second FK (:func:`optik.analytic._pipeline.postprocess_rows`): the
step never raises the linearised residual, and the rest is second order (about 1e-16)."""

REFINE_ROUNDING = 1e-14
"""A branch whose residual (2-norm, m and rad) is at most this is at rounding already (an
exact closed form's branches are, to a few 1e-16): it takes no step."""

RESIDUAL = 0
"""Offset of the residual ``e`` (6,) in the scratch of :func:`newton_step`."""


@_inline
def newton_work_size(dof: int) -> int:
    """Length of :func:`newton_step`'s flat scratch for ``dof`` joints.

    ``e`` (6), the saved row (dof), the step (dof), ``J`` (6 x dof), ``J^T J`` (dof x dof).
    """
    return 6 + 2 * dof + 6 * dof + dof * dof


@_inline
def pose_residual(pre: np.ndarray, dof: int, T: np.ndarray, k: int, work: np.ndarray) -> float:
    """The residual of the pose in ``pre[dof]`` against ``T[k]`` into ``work[:6]``.

    ``pre[dof]`` holds the top three rows of the pose, row-major (as
    :func:`optik.analytic._rows.fk_shared` leaves them). The residual is the position
    error ``p_T - p`` (m), then the axial vector of the skew part of ``R_T R^T`` (rad, the
    rotation error to second order), both in the world frame. Returns its squared
    2-norm (comparisons need no square root).
    """
    d = dof
    work[RESIDUAL] = T[k, 0, 3] - pre[d, 3]
    work[RESIDUAL + 1] = T[k, 1, 3] - pre[d, 7]
    work[RESIDUAL + 2] = T[k, 2, 3] - pre[d, 11]
    # E = R_T R^T: E[i][j] = sum_m T[i, m] R[j, m].
    e21 = T[k, 2, 0] * pre[d, 4] + T[k, 2, 1] * pre[d, 5] + T[k, 2, 2] * pre[d, 6]
    e12 = T[k, 1, 0] * pre[d, 8] + T[k, 1, 1] * pre[d, 9] + T[k, 1, 2] * pre[d, 10]
    e02 = T[k, 0, 0] * pre[d, 8] + T[k, 0, 1] * pre[d, 9] + T[k, 0, 2] * pre[d, 10]
    e20 = T[k, 2, 0] * pre[d, 0] + T[k, 2, 1] * pre[d, 1] + T[k, 2, 2] * pre[d, 2]
    e10 = T[k, 1, 0] * pre[d, 0] + T[k, 1, 1] * pre[d, 1] + T[k, 1, 2] * pre[d, 2]
    e01 = T[k, 0, 0] * pre[d, 4] + T[k, 0, 1] * pre[d, 5] + T[k, 0, 2] * pre[d, 6]
    work[RESIDUAL + 3] = 0.5 * (e21 - e12)
    work[RESIDUAL + 4] = 0.5 * (e02 - e20)
    work[RESIDUAL + 5] = 0.5 * (e10 - e01)
    acc = 0.0
    for i in range(6):
        acc += work[RESIDUAL + i] * work[RESIDUAL + i]
    return acc


@_jit
def _jacobian(
    params: np.ndarray,
    at: int,
    stride: int,
    dof: int,
    held: int,
    pre: np.ndarray,
    work: np.ndarray,
    jac: int,
) -> None:
    """The world Jacobian at the tool point (6 x dof) into ``work[jac:]``, by columns.

    Rows: linear, then angular velocity. Joint ``i`` turns about (slides along) the z
    axis of ``pre[i]``, through its origin; the tool point is ``pre[dof]``'s. The column
    of ``held`` is zero.
    """
    px, py, pz = pre[dof, 3], pre[dof, 7], pre[dof, 11]
    for i in range(dof):
        wx, wy, wz = pre[i, 2], pre[i, 6], pre[i, 10]
        c = jac + 6 * i
        if i == held:
            for m in range(6):
                work[c + m] = 0.0
        elif params[at + stride * i] != 0.0:
            work[c], work[c + 1], work[c + 2] = wx, wy, wz
            work[c + 3] = work[c + 4] = work[c + 5] = 0.0
        else:
            # Linear velocity of the tool point: w x (p - o), o a point of the axis.
            dx, dy, dz = px - pre[i, 3], py - pre[i, 7], pz - pre[i, 11]
            work[c] = wy * dz - wz * dy
            work[c + 1] = wz * dx - wx * dz
            work[c + 2] = wx * dy - wy * dx
            work[c + 3], work[c + 4], work[c + 5] = wx, wy, wz


BLOCK_CONDITION = 1e-6
"""Smallest ``|det| / (|a| |b| |c|)`` of a 3 x 3 system :func:`_wrist_step` solves (the
volume of its unit columns): below it the block is near singular (an elbow, shoulder or
wrist singularity) and the damped step of the whole Jacobian takes over."""


@_inline
def _cramer(
    ax: float,
    ay: float,
    az: float,
    bx: float,
    by: float,
    bz: float,
    cx: float,
    cy: float,
    cz: float,
    rx: float,
    ry: float,
    rz: float,
) -> tuple[float, float, float, bool]:
    """``[a b c] x = r`` by Cramer's rule; ``ok`` False when near singular.

    Near singular: ``|det|`` below :data:`BLOCK_CONDITION` times the product of the
    columns' norms (or not finite).
    """  # fmt: skip
    # Cross products of the columns: det = a . (b x c), and x_i = r . (col_j x col_k) / det.
    bcx, bcy, bcz = by * cz - bz * cy, bz * cx - bx * cz, bx * cy - by * cx
    cax, cay, caz = cy * az - cz * ay, cz * ax - cx * az, cx * ay - cy * ax
    abx, aby, abz = ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx
    det = ax * bcx + ay * bcy + az * bcz
    # Squared, to spare the square root: det^2 against (condition |a| |b| |c|)^2.
    scale2 = (
        (ax * ax + ay * ay + az * az) * (bx * bx + by * by + bz * bz)
        * (cx * cx + cy * cy + cz * cz)
    )  # fmt: skip
    if not det * det >= BLOCK_CONDITION * BLOCK_CONDITION * scale2 or scale2 == 0.0:
        return 0.0, 0.0, 0.0, False
    inverse = 1.0 / det
    return (
        (rx * bcx + ry * bcy + rz * bcz) * inverse,
        (rx * cax + ry * cay + rz * caz) * inverse,
        (rx * abx + ry * aby + rz * abz) * inverse,
        True,
    )


@_inline
def _wrist_step(
    params: np.ndarray,
    at: int,
    stride: int,
    dof: int,
    held: int,
    wrist_at: int,
    pre: np.ndarray,
    work: np.ndarray,
    step: int,
    max_step: float,
) -> bool:
    """The step of an arm whose last three axes meet, by two 3 x 3 solves.

    Referred to the wrist centre ``W`` (``params[wrist_at:wrist_at + 3]``, in the tool's
    frame) instead of the tool point, the Jacobian is block lower-triangular: the wrist
    joints turn about axes through ``W`` and do not move it. So the arm joints (the
    three before the wrist, or the three of the first four that are not ``held``) come
    from ``W``'s error ``e_p + e_w x (W - p)``, then the wrist joints from the rotation
    error the arm joints leave (Cramer's rule, each system refused when its determinant
    is below :data:`BLOCK_CONDITION` of the product of its columns' norms). Axes that
    meet only to within the geometry's tolerances leave a block of size ``d`` (the miss,
    m) out of ``J``: the step then misses the linearised target by ``d |dq|``, about
    1e-20. The held joint's step is 0. Returns whether the step was solved, with every
    component at most ``max_step``.
    """
    d = dof
    w = dof - 3  # the first wrist joint
    wl0, wl1, wl2 = params[wrist_at], params[wrist_at + 1], params[wrist_at + 2]
    px, py, pz = pre[d, 3], pre[d, 7], pre[d, 11]
    rx = pre[d, 0] * wl0 + pre[d, 1] * wl1 + pre[d, 2] * wl2
    ry = pre[d, 4] * wl0 + pre[d, 5] * wl1 + pre[d, 6] * wl2
    rz = pre[d, 8] * wl0 + pre[d, 9] * wl1 + pre[d, 10] * wl2
    ex, ey, ez = work[RESIDUAL], work[RESIDUAL + 1], work[RESIDUAL + 2]
    wx, wy, wz = work[RESIDUAL + 3], work[RESIDUAL + 4], work[RESIDUAL + 5]
    # The wrist centre's error: the velocity of W for the tool's twist (e_p, e_w).
    bx = ex + wy * rz - wz * ry
    by = ey + wz * rx - wx * rz
    bz = ez + wx * ry - wy * rx
    cx, cy, cz = px + rx, py + ry, pz + rz
    # Columns of the arm block: w_i x (W - o_i), or w_i for a sliding joint; the arm
    # joints are i0 < i1 < i2, the joints before the wrist less the held one.
    i0 = 1 if held == 0 else 0
    i1 = i0 + 1 + (1 if held == i0 + 1 else 0)
    i2 = i1 + 1 + (1 if held == i1 + 1 else 0)
    a0x = a0y = a0z = a1x = a1y = a1z = a2x = a2y = a2z = 0.0
    for c in range(3):
        i = i0 if c == 0 else (i1 if c == 1 else i2)
        zx, zy, zz = pre[i, 2], pre[i, 6], pre[i, 10]
        if params[at + stride * i] != 0.0:
            vx, vy, vz = zx, zy, zz
        else:
            dx, dy, dz = cx - pre[i, 3], cy - pre[i, 7], cz - pre[i, 11]
            vx, vy, vz = zy * dz - zz * dy, zz * dx - zx * dz, zx * dy - zy * dx
        if c == 0:
            a0x, a0y, a0z = vx, vy, vz
        elif c == 1:
            a1x, a1y, a1z = vx, vy, vz
        else:
            a2x, a2y, a2z = vx, vy, vz
    x0, x1, x2, ok = _cramer(
        a0x, a0y, a0z, a1x, a1y, a1z, a2x, a2y, a2z, bx, by, bz
    )  # fmt: skip
    if not ok:
        return False
    # The rotation the arm joints leave to the wrist.
    for c in range(3):
        i = i0 if c == 0 else (i1 if c == 1 else i2)
        if params[at + stride * i] == 0.0:
            xi = x0 if c == 0 else (x1 if c == 1 else x2)
            wx -= xi * pre[i, 2]
            wy -= xi * pre[i, 6]
            wz -= xi * pre[i, 10]
    y0, y1, y2, ok = _cramer(
        pre[w, 2], pre[w, 6], pre[w, 10], pre[w + 1, 2], pre[w + 1, 6], pre[w + 1, 10],
        pre[w + 2, 2], pre[w + 2, 6], pre[w + 2, 10], wx, wy, wz,
    )  # fmt: skip
    if not ok:
        return False
    largest = max(abs(x0), abs(x1), abs(x2), abs(y0), abs(y1), abs(y2))
    if not largest <= max_step:
        return False
    for j in range(w):
        work[step + j] = 0.0  # the held joint's
    work[step + i0], work[step + i1], work[step + i2] = x0, x1, x2
    work[step + w], work[step + w + 1], work[step + w + 2] = y0, y1, y2
    return True


@_jit
def _damped_step(
    dof: int, work: np.ndarray, jac: int, step: int, normal: int, max_step: float
) -> bool:
    """``(J^T J + lambda^2 I) dq = J^T e`` by Gaussian elimination (positive definite).

    ``J`` (6 x dof) by columns at ``work[jac:]``, ``e`` at ``work[:6]``, ``dq`` to
    ``work[step:step + dof]``, the matrix at ``work[normal:]``. Returns whether every
    component is at most ``max_step``.
    """
    for i in range(dof):
        ci = jac + 6 * i
        acc = 0.0
        for m in range(6):
            acc += work[ci + m] * work[RESIDUAL + m]
        work[step + i] = acc
        for j in range(i, dof):
            cj = jac + 6 * j
            acc = 0.0
            for m in range(6):
                acc += work[ci + m] * work[cj + m]
            work[normal + dof * i + j] = acc
            work[normal + dof * j + i] = acc
        work[normal + dof * i + i] += REFINE_DAMPING * REFINE_DAMPING
    for col in range(dof):
        inverse = 1.0 / work[normal + dof * col + col]
        for row in range(col + 1, dof):
            f = work[normal + dof * row + col] * inverse
            for j in range(col, dof):
                work[normal + dof * row + j] -= f * work[normal + dof * col + j]
            work[step + row] -= f * work[step + col]
    for col in range(dof - 1, -1, -1):
        acc = work[step + col]
        for j in range(col + 1, dof):
            acc -= work[normal + dof * col + j] * work[step + j]
        value = acc / work[normal + dof * col + col]
        if not abs(value) <= max_step:
            return False
        work[step + col] = value
    return True


@_inline
def newton_step(
    params: np.ndarray,
    at: int,
    stride: int,
    dof: int,
    held: int,
    wrist_at: int,
    pre: np.ndarray,
    rows: np.ndarray,
    r: int,
    work: np.ndarray,
    max_step: float,
) -> float:
    """One Gauss–Newton step of ``rows[r]`` from the residual in ``work[:6]``.

    An arm with a wrist centre (``wrist_at >= 0``) and three arm joints before it (six
    joints, none held; or seven, one of the first four held, for a step of at most
    :data:`REFINE_MAX_STEP`) takes the wrist-centre step (:func:`_wrist_step`: two 3 x 3
    solves), which equals the Newton step of the whole Jacobian wherever its blocks are
    well conditioned. Where it is refused (near a singularity), and for other chains, the
    damped least-squares step (:func:`_damped_step`), which leaves the weak directions
    where they are.

    Args:
        params: the vector holding joint ``j``'s prismatic flag at ``at + stride * j``
            (and the wrist centre, see ``wrist_at``).
        at: offset of joint 1's prismatic flag in ``params``.
        stride: distance between two joints' flags.
        dof: number of joints.
        held: a joint that must not move (its column of ``J`` left out), or -1.
        wrist_at: offset in ``params`` of the point where the last three axes meet, in
            the tool's frame (m), or -1 when they do not.
        pre: (dof + 2, 12) the prefix products of the row's FK (top three rows of
            each, row-major): joint ``i`` turns about the z axis of ``pre[i]``, the pose
            is ``pre[dof]``.
        rows: the branches (rad, m); row ``r`` is moved in place.
        r: the row.
        work: :func:`newton_work_size` scratch, residual in ``work[:6]``
            (:func:`pose_residual`); the row before the step is saved after it.
        max_step: the largest component of a step taken (rad or m; the refinement's
            :data:`REFINE_MAX_STEP`): a larger one means an ill-posed system.

    Returns:
        The largest component of the step applied (rad or m), or 0.0 when the row was
        not moved (every step above ``max_step``, or not finite).
    """
    saved = RESIDUAL + 6
    step = saved + dof
    jac = step + dof
    normal = jac + 6 * dof
    solved = False
    # Three arm joints before the wrist: six joints, or seven with one of the first
    # four held. A held arm's near miss (a larger step, at a singular pose) keeps the
    # damped step: at an iiwa's stretched elbow the exact step overshot and lost a
    # wrist-flip branch the damped steps recover.
    held_arm = dof == 7 and 0 <= held < 4 and max_step <= REFINE_MAX_STEP
    if wrist_at >= 0 and ((dof == 6 and held < 0) or held_arm):
        solved = _wrist_step(
            params, at, stride, dof, held, wrist_at, pre, work, step, max_step
        )  # fmt: skip
    if not solved:
        _jacobian(params, at, stride, dof, held, pre, work, jac)
        solved = _damped_step(dof, work, jac, step, normal, max_step)
    if not solved:
        return 0.0
    largest = 0.0
    for j in range(dof):
        largest = max(largest, abs(work[step + j]))
        work[saved + j] = rows[r, j]
        rows[r, j] += work[step + j]
    return largest


@_inline
def restore_row(dof: int, rows: np.ndarray, r: int, work: np.ndarray) -> None:
    """Put back the row :func:`newton_step` saved before its step."""
    for j in range(dof):
        rows[r, j] = work[RESIDUAL + 6 + j]
