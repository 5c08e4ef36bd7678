"""Shared test helpers: tolerances, problem robots, seeded randomness, hypothesis profile.

Helpers are importable from test modules (``from conftest import assert_close``) and the
common ones are also fixtures. Every random draw in the suite is seeded: ``rng`` is a
fresh ``numpy.random.Generator`` per test, and hypothesis runs derandomized.
"""

from __future__ import annotations

import contextlib
import functools
import math
import os
import signal
from collections import Counter
from collections.abc import Callable, Iterator
from dataclasses import fields, replace
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import HealthCheck, settings
from scipy.spatial.transform import Rotation

from optik.compare import ResultRow, RunConfig, step_backends
from optik.errors import OptikError
from optik.model import Robot
from optik.problems import Problem, load_problem

ROOT = Path(__file__).resolve().parent.parent
PROBLEMS_DIR = ROOT / "problems"
PROBLEM_FILES: tuple[Path, ...] = tuple(sorted(PROBLEMS_DIR.glob("*.toml")))
PROBLEM_NAMES: tuple[str, ...] = tuple(p.stem for p in PROBLEM_FILES)
SEED = 20240611

settings.register_profile(
    "optik",
    derandomize=True,
    deadline=None,
    max_examples=40,
    print_blob=True,
    suppress_health_check=[HealthCheck.too_slow],
)
settings.register_profile("optik-long", parent=settings.get_profile("optik"), max_examples=1000)
settings.load_profile(os.environ.get("OPTIK_HYPOTHESIS_PROFILE", "optik"))


# ---------------------------------------------------------------------- tolerances
def assert_close(
    actual: Any,
    expected: Any,
    atol: float = 1e-12,
    rtol: float = 0.0,
    what: str = "",
) -> None:
    """Assert ``|actual - expected| <= atol + rtol |expected|`` elementwise.

    Unlike ``numpy.allclose`` it fails on any NaN (in either argument, even where both
    are NaN), on a shape mismatch, and reports the worst entry.
    """
    a = np.asarray(actual, dtype=float)
    e = np.asarray(expected, dtype=float)
    label = f"{what}: " if what else ""
    assert a.shape == e.shape, f"{label}shape {a.shape} != expected {e.shape}"
    assert not np.any(np.isnan(a)), f"{label}actual holds NaN:\n{a}"
    assert not np.any(np.isnan(e)), f"{label}expected holds NaN:\n{e}"
    if a.size == 0:
        return
    same_inf = np.isinf(a) & (a == e)
    with np.errstate(invalid="ignore"):
        err = np.where(same_inf, 0.0, np.abs(a - e))
    bound = atol + rtol * np.abs(np.where(np.isinf(e), 0.0, e))
    bad = err > bound
    if np.any(bad):
        k = np.unravel_index(int(np.argmax(np.where(bad, err - bound, -np.inf))), a.shape)
        raise AssertionError(
            f"{label}max violation at index {tuple(int(i) for i in k)}: actual {a[k]!r}, "
            f"expected {e[k]!r}, |diff| {err[k]:.3e} > {bound[k]:.3e} "
            f"(atol={atol:g}, rtol={rtol:g}); {int(bad.sum())} of {a.size} entries off"
        )


def assert_rigid(T: Any, atol: float = 1e-12, what: str = "") -> None:
    """Assert ``T`` (4x4 or batch) is a proper rigid transform: R^T R = I, det 1, last row."""
    T = np.asarray(T, dtype=float)
    R = T[..., :3, :3]
    gram = np.swapaxes(R, -1, -2) @ R
    assert_close(gram, np.broadcast_to(np.eye(3), gram.shape), atol=atol, what=f"{what} R^T R")
    assert_close(np.linalg.det(R), np.ones(R.shape[:-2]), atol=atol, what=f"{what} det R")
    bottom = np.broadcast_to([0.0, 0.0, 0.0, 1.0], T[..., 3, :].shape)
    assert_close(T[..., 3, :], bottom, atol=0.0, what=f"{what} last row")


# ---------------------------------------------------------------------- problems
@functools.cache
def load(name: str) -> Problem:
    """A built-in problem by file stem (parsed once per test session)."""
    return load_problem(PROBLEMS_DIR / f"{name}.toml")


def robot_of(name: str) -> Robot:
    """The robot of a built-in problem by file stem."""
    return load(name).robot


def axes_urdf_robot(H: np.ndarray, P: np.ndarray, path: Path) -> Robot:
    """Six revolute joints as URDF text from their axes ``H`` (6, 3) and offsets ``P`` (7, 3)
    (EAIK's form): every link frame aligned with the base at ``q = 0``; limits +-3.1."""

    def xyz(v: np.ndarray) -> str:
        return " ".join(repr(float(x)) for x in v)

    links = "".join(f'<link name="l{i}"/>' for i in range(8))
    joints = "".join(
        f'<joint name="j{i + 1}" type="revolute"><parent link="l{i}"/>'
        f'<child link="l{i + 1}"/><origin xyz="{xyz(P[i])}"/><axis xyz="{xyz(H[i])}"/>'
        '<limit lower="-3.1" upper="3.1" effort="1" velocity="1"/></joint>'
        for i in range(6)
    )
    tool = (
        '<joint name="tool" type="fixed"><parent link="l6"/><child link="l7"/>'
        f'<origin xyz="{xyz(P[6])}"/></joint>'
    )
    path.write_text(f'<robot name="arm">{links}{joints}{tool}</robot>')
    return Robot.from_urdf(path, "l0", "l7")


def poe_fk(H: np.ndarray, P: np.ndarray, q: np.ndarray) -> np.ndarray:
    """``R_1(q_1) ... R_6(q_6) M`` with each ``R_i`` a turn about axis ``i`` (written out)."""
    points = np.cumsum(P[:6], axis=0)
    T = np.eye(4)
    for h, point, qi in zip(H, points, q, strict=True):
        turn = np.eye(4)
        turn[:3, :3] = Rotation.from_rotvec(h * qi).as_matrix()
        turn[:3, 3] = point - turn[:3, :3] @ point
        T = T @ turn
    M = np.eye(4)
    M[:3, 3] = P.sum(axis=0)
    return T @ M


def joint_distance(robot: Robot, a: Any, b: Any) -> float:
    """Largest joint difference of two configurations, revolute ones wrapped to (-pi, pi]."""
    d = np.asarray(a, dtype=float) - np.asarray(b, dtype=float)
    revolute = np.array([j.kind == "revolute" for j in robot.joints])
    d[revolute] = np.arctan2(np.sin(d[revolute]), np.cos(d[revolute]))
    return float(np.max(np.abs(d)))


def assert_closed_form_round_trips(
    robot: Robot, family: Any, n: int, seed: int, most: dict[str, int]
) -> None:
    """On ``n`` seeded in-limit configurations, in each mode of the family: every branch of
    ``analytic_ik`` reaches its pose (1e-10), the configuration the pose came from is one
    of them, at most ``most[mode]`` are returned, and the raw branches of ``family``'s
    closed form (before any wrap, filter or polish) reach the target: every one its
    position in position mode, one the whole pose (1e-10) in pose mode."""
    from optik import analytic_ik

    rng = np.random.default_rng(seed)
    for q in rng.uniform(robot.lower, robot.upper, (n, robot.dof)):
        T = robot.fk(q)
        for mode, target in (("pose", T), ("position", T[:3, 3])):
            if mode not in family.modes:
                continue
            branches = analytic_ik(robot, target, mode=mode)
            assert 1 <= len(branches) <= most[mode]
            for b in branches:
                F = robot.fk(b)
                assert np.linalg.norm(F[:3, 3] - T[:3, 3]) < 1e-10
                if mode == "pose":
                    assert np.max(np.abs(F[:3, :3] - T[:3, :3])) < 1e-10
            assert min(joint_distance(robot, b, q) for b in branches) < 1e-9, (mode, q)
            T_0 = np.linalg.inv(robot.T_world_base) @ T @ np.linalg.inv(robot.T_flange_tool)
            raw = family.candidates(robot, T_0, mode, robot.mid_limits)
            errors = [np.abs(robot.fk(b) - T)[:3] for b in raw]
            if mode == "position":
                assert raw and all(float(np.max(e[:, 3])) < 1e-10 for e in errors), (q, raw)
            else:
                assert any(float(np.max(e)) < 1e-10 for e in errors), (q, raw)


def assert_batch_equals_single(robot: Robot, targets: np.ndarray, mode: str) -> None:
    """``analytic_ik_batch`` gives every target the branches ``analytic_ik`` gives it."""
    from optik import analytic_ik, analytic_ik_batch

    batch = analytic_ik_batch(robot, targets, mode=mode)
    for k in range(len(targets)):
        single = analytic_ik(robot, targets[k], mode=mode)
        assert batch.counts[k] == len(single) >= 1
        np.testing.assert_array_equal(batch.q[k, : len(single)], np.array(single))


def frozen_answers_among_branches(
    robot: Robot,
    fk: Callable[[np.ndarray], np.ndarray],
    k: int,
    rng: np.random.Generator,
    distance: Callable[[list[np.ndarray], np.ndarray], float],
) -> int:
    """``solve_ik`` with joint ``k`` frozen finds nothing ``analytic_ik(free_joint=...)`` lacks.

    Six in-limit configurations drawn from ``rng``, their poses by ``fk``; from five random
    starts each (joint ``k`` held), every answer the numeric solver verifies keeps joint
    ``k`` to 1e-12 and lies within 1e-6 (``distance(branches, q)``, rad) of a branch.

    Returns:
        How many answers the numeric solver found.
    """
    from optik import analytic_ik, solve_ik

    name = robot.joint_names[k]
    found = 0
    for q in rng.uniform(robot.lower, robot.upper, (6, robot.dof)):
        T = fk(q)
        branches = analytic_ik(robot, T, free_joint=name, free_value=q[k])
        for seed in range(5):
            q0 = rng.uniform(robot.lower, robot.upper)
            q0[k] = q[k]
            # warm_start="q0": from q0 alone (the closed form would start it on a branch)
            res = solve_ik(
                robot, T, q0=q0, seed=seed, frozen={name: q[k]}, tol=1e-10, solver="dls",
                warm_start="q0",
            )  # fmt: skip
            if not res.success:
                continue
            found += 1
            assert res.q[k] == pytest.approx(q[k], abs=1e-12)
            assert distance(branches, res.q) < 1e-6, (q, res.q)
    return found


def as_modified_dh(dh: Robot) -> Robot:
    """A standard-DH robot rebuilt from modified (Craig) DH rows: each row's twist and
    length move to the next row, the last row's to the tool; the same FK, base and tool."""
    assert dh.dh is not None
    rows, prev = [], None
    for i, r in enumerate(dh.dh):
        rows.append(
            {
                "alpha": prev.alpha if prev else 0.0,
                "a": prev.a if prev else 0.0,
                "theta": r.theta,
                "d": r.d,
                "kind": r.kind,
                "lower": float(dh.lower[i]),
                "upper": float(dh.upper[i]),
            }
        )
        prev = r
    last = dh.dh[-1]
    tool = dh_matrix(last.a, last.alpha, 0.0, 0.0) @ dh.T_flange_tool
    return Robot.from_mdh(rows, name=f"{dh.name}_mdh", base=dh.T_world_base, tool=tool)


GENERAL_ARM = [
    (0.1, 60.0, 0.4, 0.2),
    (0.5, 40.0, 0.1, 0.1),
    (0.05, 75.0, 0.0, -0.3),
    (0.0, -90.0, 0.45, 0.0),
    (0.0, 90.0, 0.0, 0.3),
    (0.0, 0.0, 0.1, 0.0),
]
"""Standard DH rows (a m, alpha deg, d m, theta rad): a general arm, a spherical wrist
(the quartic of ``spherical_axes``, :mod:`optik.analytic.general_arm`)."""


def general_arm(limit: float = 4.0, tool: np.ndarray | None = None) -> Robot:
    """The arm of :data:`GENERAL_ARM`, joints in ``[-limit, limit]`` rad, with ``tool``."""
    rows = [
        {"a": a, "alpha": math.radians(al), "d": d, "theta": th, "lower": -limit, "upper": limit}
        for a, al, d, th in GENERAL_ARM
    ]
    return Robot.from_dh(rows, name="general", tool=tool)


def scaled_dh(rows: Any, scale: float, limit: float, base: np.ndarray | None = None) -> Robot:
    """A DH arm from ``rows`` (mappings of ``a``, ``d`` in m, ``alpha`` in rad), every
    length times ``scale``, joints in ``[-limit, limit]`` rad, ``base`` its base pose."""
    scaled = [
        {
            "a": row.get("a", 0.0) * scale,
            "d": row.get("d", 0.0) * scale,
            "alpha": row.get("alpha", 0.0),
            "lower": -limit,
            "upper": limit,
        }
        for row in rows
    ]
    return Robot.from_dh(scaled, base=base)


def scaled_problem(name: str, scale: float) -> Robot:
    """A built-in robot with every length (links, slides, base, tool) times ``scale``."""
    robot = load_problem(name).robot
    rows = []
    for row in robot.dh:
        change = {"a": row.a * scale, "d": row.d * scale}
        if row.kind == "prismatic":
            change |= {"lower": row.lower * scale, "upper": row.upper * scale}
        rows.append(replace(row, **change))
    base = robot.T_world_base.copy()
    base[:3, 3] *= scale
    tool = robot.T_flange_tool.copy()
    tool[:3, 3] *= scale
    build = Robot.from_mdh if robot.convention == "mdh" else Robot.from_dh
    return build(rows, base=base, tool=tool)


def random_q(robot: Robot, rng: np.random.Generator, n: int | None = None) -> np.ndarray:
    """Configurations inside the limits: uniform over a finite range, [-pi, pi] if unbounded.

    Returns ``(dof,)`` when ``n`` is None, else ``(n, dof)``.
    """
    lo = np.where(np.isfinite(robot.lower), robot.lower, -math.pi)
    hi = np.where(np.isfinite(robot.upper), robot.upper, math.pi)
    shape = (robot.dof,) if n is None else (n, robot.dof)
    return rng.uniform(lo, hi, size=shape)


@pytest.fixture
def rng() -> np.random.Generator:
    """A seeded generator, fresh for each test (independent of test order)."""
    return np.random.default_rng(SEED)


@pytest.fixture(params=PROBLEM_NAMES)
def problem_name(request: pytest.FixtureRequest) -> str:
    """Every file in problems/, by stem."""
    return str(request.param)


@pytest.fixture
def problem_robot(problem_name: str) -> Robot:
    """The robot of every file in problems/ (parametrized)."""
    return robot_of(problem_name)


problem_robots = pytest.mark.parametrize("name", PROBLEM_NAMES)
"""Decorator form: parametrize a test's ``name`` argument over every file in problems/."""


# ---------------------------------------------------------------------- reference kinematics
# Written out entry by entry from the textbook formulas, independent of optik's code.
def dh_matrix(a: float, alpha: float, d: float, theta: float) -> np.ndarray:
    """Standard DH ``A = Rz(theta) Tz(d) Tx(a) Rx(alpha)``, expanded."""
    ct, st = math.cos(theta), math.sin(theta)
    ca, sa = math.cos(alpha), math.sin(alpha)
    return np.array(
        [
            [ct, -st * ca, st * sa, a * ct],
            [st, ct * ca, -ct * sa, a * st],
            [0.0, sa, ca, d],
            [0.0, 0.0, 0.0, 1.0],
        ]
    )


def mdh_matrix(alpha: float, a: float, theta: float, d: float) -> np.ndarray:
    """Modified (Craig) DH ``A = Rx(alpha_{i-1}) Tx(a_{i-1}) Rz(theta_i) Tz(d_i)``, expanded."""
    ct, st = math.cos(theta), math.sin(theta)
    ca, sa = math.cos(alpha), math.sin(alpha)
    return np.array(
        [
            [ct, -st, 0.0, a],
            [st * ca, ct * ca, -sa, -sa * d],
            [st * sa, ct * sa, ca, ca * d],
            [0.0, 0.0, 0.0, 1.0],
        ]
    )


def coupling_from_rows(robot: Robot) -> np.ndarray:
    """``C`` (chain rows, dof) with ``t = C q``, read from the DH rows' ``mimic`` fields."""
    assert robot.dh is not None
    names = [row.name or f"j{i + 1}" for i, row in enumerate(robot.dh)]
    actuated = [n for n, row in zip(names, robot.dh, strict=True) if row.mimic is None]
    C = np.zeros((len(names), len(actuated)))
    for i, row in enumerate(robot.dh):
        if row.mimic is None:
            C[i, actuated.index(names[i])] = 1.0
        else:
            C[i, actuated.index(row.mimic.joint)] = row.mimic.multiplier
    return C


def reference_frames(robot: Robot, q: Any) -> list[np.ndarray]:
    """World frames from the DH rows: ``[T_world_base, base A_1, ..., base A_1..A_n, tool]``.

    Uses the rows in ``robot.dh``, the convention in ``robot.convention``, chain variables
    ``t = C q`` from the rows' mimic fields, and ``robot.T_world_base`` /
    ``robot.T_flange_tool``.
    """
    assert robot.dh is not None, "reference_frames needs a DH robot"
    t = coupling_from_rows(robot) @ np.asarray(q, dtype=float)
    T = np.array(robot.T_world_base, dtype=float)
    frames = [T]
    for row, ti in zip(robot.dh, t, strict=True):
        theta = row.theta + (ti if row.kind == "revolute" else 0.0)
        d = row.d + (ti if row.kind == "prismatic" else 0.0)
        if robot.convention == "mdh":
            A = mdh_matrix(row.alpha, row.a, theta, d)
        else:
            assert robot.convention == "dh", robot.convention
            A = dh_matrix(row.a, row.alpha, d, theta)
        T = T @ A
        frames.append(T)
    frames.append(T @ robot.T_flange_tool)
    return frames


def reference_fk(robot: Robot, q: Any) -> np.ndarray:
    """Tool pose in the world frame from the DH rows (see :func:`reference_frames`)."""
    return reference_frames(robot, q)[-1]


def vee_of(M: np.ndarray) -> np.ndarray:
    """``(M21, M02, M10)``: the vector of a skew-symmetric 3x3 matrix."""
    return np.array([M[2, 1], M[0, 2], M[1, 0]])


def fd_jacobian(robot: Robot, q: np.ndarray, h: float = 1e-6) -> np.ndarray:
    """Central finite differences of ``robot.fk``: linear rows from the position, angular
    rows from ``vee((dR/dq) R^T)``, world frame."""
    T0 = robot.fk(q)
    J = np.empty((6, robot.dof))
    for k in range(robot.dof):
        dq = np.zeros(robot.dof)
        dq[k] = h
        Tp, Tm = robot.fk(q + dq), robot.fk(q - dq)
        dT = (Tp - Tm) / (2.0 * h)
        J[:3, k] = dT[:3, 3]
        W = dT[:3, :3] @ T0[:3, :3].T
        J[3:, k] = vee_of(0.5 * (W - W.T))
    return J


def pose_residual_reference(robot: Robot, q: np.ndarray, target: np.ndarray) -> np.ndarray:
    """(6,) position error ``p_T - p`` (m), then the axial vector of ``R_T R(q)^T``'s skew part."""
    T = robot.fk(q)
    E = target[:3, :3] @ T[:3, :3].T
    axial = 0.5 * np.array([E[2, 1] - E[1, 2], E[0, 2] - E[2, 0], E[1, 0] - E[0, 1]])
    return np.concatenate([target[:3, 3] - T[:3, 3], axial])


def damped_step_reference(J: np.ndarray, e: np.ndarray) -> np.ndarray:
    """numpy's solve of ``(J^T J + lambda^2 I) dq = J^T e`` (``REFINE_DAMPING``)."""
    from optik.analytic._newton import REFINE_DAMPING

    return np.linalg.solve(J.T @ J + REFINE_DAMPING**2 * np.eye(J.shape[1]), J.T @ e)


def _skew(v: np.ndarray) -> np.ndarray:
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def wrist_step_reference(
    robot: Robot, q: np.ndarray, e: np.ndarray, held: int | None
) -> np.ndarray | None:
    """The wrist-centre Newton step, or ``None`` where the closed forms take the damped one.

    Taken when the last three axes meet (to 1e-9 of the arm's reach) with three arm
    joints before them (six joints, none held; seven, one of the first four held) and
    neither 3 x 3 block is near singular (``BLOCK_CONDITION``): then it is the Newton
    step of the free columns, ``J_F dq = e``. The wrist centre ``W`` comes from the
    Jacobian alone: a wrist joint's column referred to ``W`` has no linear part, so
    ``z_i x (p - W) = J_v,i`` for the three.
    """
    from optik.analytic._newton import BLOCK_CONDITION

    n = robot.dof
    if not (n == 6 and held is None) and not (n == 7 and held is not None and held < 4):
        return None
    J = robot.jacobian(q)
    p = robot.fk(q)[:3, 3]
    wrist = range(n - 3, n)
    A = np.vstack([_skew(J[3:, i]) for i in wrist])
    b = np.concatenate([J[:3, i] for i in wrist])
    r = np.linalg.lstsq(A, b, rcond=None)[0]  # p - W
    reach = 1.0 + float(np.linalg.norm(p))
    if np.linalg.norm(A @ r - b) > 1e-9 * reach:
        return None  # the last three axes do not meet
    arm = [i for i in range(n - 3) if i != held]
    blocks = (
        np.column_stack([J[:3, i] - np.cross(J[3:, i], r) for i in arm]),
        np.column_stack([J[3:, i] for i in wrist]),
    )
    for block in blocks:
        scale = float(np.prod(np.linalg.norm(block, axis=0)))
        if not abs(np.linalg.det(block)) >= BLOCK_CONDITION * scale:
            return None
    free = [i for i in range(n) if i != held]
    dq = np.zeros(n)
    dq[free] = np.linalg.solve(J[:, free], e)
    return dq


def newton_reference(
    robot: Robot, rows: list[np.ndarray], target: np.ndarray, held: int | None = None
) -> list[np.ndarray]:
    """Each row after the closed forms' Newton step, in numpy on ``Robot.fk``/``jacobian``.

    The wrist-centre step where it applies (:func:`wrist_step_reference`), else the
    damped least-squares step (:func:`damped_step_reference`), with the column of
    ``held`` left out; kept when every component is at most ``REFINE_MAX_STEP`` and the
    residual (:func:`pose_residual_reference`) does not grow.
    """
    from optik.analytic._newton import REFINE_MAX_STEP

    out = []
    for q in rows:
        e = pose_residual_reference(robot, q, target)
        J = robot.jacobian(q)
        if held is not None:
            J[:, held] = 0.0
        dq = wrist_step_reference(robot, q, e, held)
        if dq is None or not np.max(np.abs(dq)) <= REFINE_MAX_STEP:
            dq = damped_step_reference(J, e)
        moved = q + dq
        keep = np.max(np.abs(dq)) <= REFINE_MAX_STEP
        grows = np.linalg.norm(pose_residual_reference(robot, moved, target)) > np.linalg.norm(e)
        out.append(moved if keep and not grows else q)
    return out


# ---------------------------------------------------------------------------- comparison runs
class Interrupt(Exception):
    """Raised from an ``on_row`` callback to stop a run as a kill would."""


def one_qp_and_one_casadi() -> tuple[str, ...]:
    names = step_backends()
    picked = [n for n in names if n.startswith("qp:")][:1]
    picked += [n for n in names if n.startswith("casadi:")][:1]
    return tuple(picked)


def tiny_config(seeds: bool = False, **overrides: object) -> RunConfig:
    """Two small robots, three fast solvers, three targets, one closed-form configuration."""
    values: dict[str, object] = {
        "problems": ("planar_2r", "dobot_magician"),
        "solvers": ("auto", "dls", "pinv"),
        "n": 3,
        "seed": 5,
        "timeout_s": 0.5,
        "closed_form_problems": ("dobot_magician",),
        "closed_form_configs": 1,
        "step_backends": one_qp_and_one_casadi(),
        "seeds": seeds,
    }
    values.update(overrides)
    return RunConfig(**values)  # type: ignore[arg-type]


def without_timing(rows: list[ResultRow]) -> list[tuple[object, ...]]:
    """Rows as tuples without the wall time (the only field allowed to differ)."""
    return [tuple(getattr(r, f.name) for f in fields(r) if f.name != "time_s") for r in rows]


# ---------------------------------------------------------------------- a clock of the test's
class FakeClock:
    """``time.perf_counter`` of :mod:`optik._clock` (what the budget clock, its deadlines
    and the one-time work it leaves out are measured on), moved by the test alone.

    It advances by ``tick`` at each reading and by :meth:`advance`, never with the
    machine's time: a deadline passes after a known number of readings, and one-time
    work takes the time the test gives it, however loaded the machine is. ``checks``
    holds the budget clock's values as optik's solvers read them (``budget_now``: the
    first of a ``solve_ik`` sets its deadline, the others check it); one-time work reads
    the fake clock too, but is no check. (``IKResult.time_s`` stays on the real clock.)
    """

    def __init__(self, start: float, tick: float = 0.0) -> None:
        self.now = start
        self.tick = tick
        self.checks: list[float] = []

    def perf_counter(self) -> float:
        value = self.now
        self.now += self.tick
        return value

    def advance(self, seconds: float) -> None:
        """Let ``seconds`` pass."""
        self.now += seconds


@pytest.fixture
def fake_clock(monkeypatch: pytest.MonkeyPatch) -> FakeClock:
    """The budget clock on a :class:`FakeClock` for the test (``tick`` 0 until it is set)."""
    import time

    from optik import _clock
    from optik.solvers import _base

    # Swapped only between pieces of one-time work: one begun on the real clock and
    # ended on the fake one would be measured across the two.
    assert _clock._TIMER.idle()
    clock = FakeClock(time.perf_counter())
    # The one-time work timed on the fake clock is forgotten afterwards, so that the
    # budget clock goes on from its value before the test.
    monkeypatch.setattr(_clock._TIMER, "_done", dict(_clock._TIMER._done))
    monkeypatch.setattr(_clock, "time", clock)

    def checked() -> float:
        value = _clock.budget_clock()
        clock.checks.append(value)
        return value

    monkeypatch.setattr(_base, "budget_clock", checked)  # what budget_now reads
    return clock


# ---------------------------------------------------------------------- time limits
class Hang(Exception):
    """A call ran past its :func:`time_limit`."""


@contextlib.contextmanager
def time_limit(seconds: float) -> Iterator[None]:
    """Interrupt the enclosed block with :class:`Hang` after ``seconds`` (SIGALRM).

    The limit is on optik's budget clock (:func:`optik._clock.budget_clock`): time numba
    spends compiling a kernel does not count, and an alarm during a compilation waits for
    it to end (interrupting numba mid-compile leaves its dispatcher broken). Main thread
    only (as pytest runs tests, also under xdist); compiled code that holds the
    interpreter is interrupted when it returns, so a hang there still fails.
    """
    from optik._clock import budget_clock, compiling

    end = budget_clock() + seconds

    def on_alarm(signum: int, frame: Any) -> None:
        left = end - budget_clock()
        if compiling() or left > 0.0:
            signal.setitimer(signal.ITIMER_REAL, max(left, 0.5))
            return
        raise Hang(f"no answer within {seconds} s")

    previous = signal.signal(signal.SIGALRM, on_alarm)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)


class HostileCases:
    """A module's hostile cases: each runs under :func:`time_limit`, its outcome tallied.

    A case returns (a success) or raises an :class:`~optik.errors.OptikError` (a typed
    error); any other exception, or running past ``seconds``, fails the test.
    """

    def __init__(self, seconds: float) -> None:
        self.seconds = seconds
        self.stats: Counter[str] = Counter()

    def attempt(self, target: str, call: Callable[[], Any]) -> Any:
        """Run one hostile case: its result, or ``None`` if it raised an OptikError.

        Any other exception, or running past the time limit, fails the test.
        """
        self.stats["cases"] += 1
        self.stats[f"cases {target}"] += 1
        try:
            with time_limit(self.seconds):
                result = call()
        except Hang as exc:
            self.stats["hangs"] += 1
            raise AssertionError(f"{target}: {exc}") from exc
        except OptikError as exc:
            assert isinstance(exc, ValueError)
            self.stats["typed errors"] += 1
            return None
        except Exception as exc:
            self.stats["other exceptions"] += 1
            raise AssertionError(f"{target} raised {type(exc).__name__}: {exc}") from exc
        self.stats["successes"] += 1
        return result

    def report(self) -> None:
        """Print the tally (run with ``-s -p no:xdist`` to see all of it)."""
        if self.stats["cases"]:
            print("\nhostile cases:", dict(sorted(self.stats.items())))


def two_link_robot() -> Robot:
    """A planar arm of links 1.0 and 0.6 m, joints within +-pi: a small map's robot."""
    return Robot.from_dh(
        [
            {"a": 1.0, "lower": -math.pi, "upper": math.pi},
            {"a": 0.6, "lower": -math.pi, "upper": math.pi},
        ],
        name="two_link",
    )


def plan_from_q(robot: Robot, Q: np.ndarray) -> Any:
    """A :class:`optik.planning.PathPlan` of configurations ``Q`` (n, dof), all ``ok``."""
    from optik.planning import PathPlan

    n = len(Q)
    steps = np.concatenate([[np.nan], np.max(np.abs(np.diff(Q, axis=0)), axis=1)])
    return PathPlan(
        poses=robot.fk(Q),
        mode="pose",
        q=Q,
        status=["ok"] * n,
        limit_margin=np.minimum(Q - robot.lower, robot.upper - Q),
        manipulability=np.ones(n),
        step=steps,
        candidates=np.ones(n, dtype=int),
        max_joint_step=1.0,
        joint_names=robot.joint_names,
    )


def out_of_reach_and_back(puma: Robot) -> np.ndarray:
    """(N, 4, 4) poses on a line from a PUMA 560 pose 2.5 m along x and back, 0.05 m apart:
    the middle stretch lies beyond the arm's reach, both ends on it."""
    from optik.paths import line

    start = puma.fk(np.array([0.2, 0.5, -0.8, 0.1, 0.6, 0.3]))
    far = start.copy()
    far[:3, 3] = start[:3, 3] + np.array([2.5, 0.0, 0.0])
    return np.concatenate([line(start, far, 0.05), line(far, start, 0.05)])


def run_cli(argv: list[str]) -> tuple[int, str]:
    """``optik`` run in this process on ``argv``: its exit code and what it printed to
    stderr (stdout is dropped)."""
    import contextlib
    import io

    from optik.cli import main

    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        code = main(argv)
    return code, err.getvalue()
