"""Closed-form families found from the joint axes: URDF and modified-DH robots.

The makers' URDFs come from the ``example-robot-data`` package (the ``test`` extra);
the tests that read them are skipped, with the reason, when it is absent.
"""

from __future__ import annotations

import contextlib
import importlib.metadata
import io
import math
import os
import re
from pathlib import Path

import numpy as np
import pytest
from conftest import assert_closed_form_round_trips
from scipy.spatial.transform import Rotation

from optik import Robot, load_problem, solve_ik
from optik.analytic import (
    FAMILIES,
    analytic_ik,
    analytic_ik_batch,
    detect_family,
    explain_family,
    family_of,
    match_families,
)
from optik.analytic.geometry import (
    DHModel,
    dh_fk,
    equivalent_dh,
    joint_axes,
)
from optik.errors import AnalyticIKError, ProblemFileError
from optik.problems import builtin_problems

REPO = Path(__file__).resolve().parents[1]


def _robots_dir() -> Path | None:
    try:
        dist = importlib.metadata.distribution("example-robot-data")
    except importlib.metadata.PackageNotFoundError:
        return None
    path = Path(str(dist.locate_file("cmeel.prefix/share/example-robot-data/robots")))
    return path if path.is_dir() else None


ROBOTS_DIR = _robots_dir()
# CI installs the test extra: there a missing package is a failure, never a skip.
needs_erd = pytest.mark.skipif(
    ROBOTS_DIR is None and not os.environ.get("CI"),
    reason="example-robot-data is not installed (pip install 'optik[test]'): "
    "the makers' URDFs are not available",
)
UR_MODELS = ("ur3", "ur5", "ur10")


def _ur_path(model: str) -> Path:
    assert ROBOTS_DIR is not None
    return ROBOTS_DIR / "ur_description" / "urdf" / f"{model}_robot.urdf"


def _ur(model: str, **kwargs: object) -> Robot:
    return Robot.from_urdf(_ur_path(model), "base_link", "tool0", **kwargs)  # type: ignore[arg-type]


def _wrapped_distance(a: np.ndarray, b: np.ndarray) -> float:
    """Max-abs angle difference after wrapping into (-pi, pi]."""
    return float(np.max(np.abs(np.remainder(a - b + math.pi, 2 * math.pi) - math.pi)))


def _check_branches(robot: Robot, n: int, seed: int) -> None:
    """On ``n`` in-limit configurations: the source is a branch; every branch round-trips.

    Continuous joints (no limits) are drawn in [-pi, pi].
    """
    rng = np.random.default_rng(seed)
    lower = np.where(np.isfinite(robot.lower), robot.lower, -math.pi)
    upper = np.where(np.isfinite(robot.upper), robot.upper, math.pi)
    Q = rng.uniform(lower, upper, (n, robot.dof))
    T = robot.fk(Q)
    for q, target in zip(Q, T, strict=True):
        branches = analytic_ik(robot, target)
        assert branches, f"no branch for q = {q}"
        assert min(_wrapped_distance(b, q) for b in branches) < 1e-9
        for b in branches:
            assert robot.within_limits(b)
            T_b = robot.fk(b)
            assert np.max(np.abs(T_b - target)) < 1e-10


# ---------------------------------------------------------------------- makers' URDFs
@needs_erd
@pytest.mark.parametrize("model", UR_MODELS)
def test_ur_urdfs_get_the_ur_closed_form(model: str) -> None:
    robot = _ur(model)
    assert robot.convention == "urdf"
    family = family_of(robot)
    assert family is FAMILIES["ur"]
    ur = next(m for m in match_families(robot) if m.family == "ur")
    assert ur.fits and ur.source == "joint axes"
    _check_branches(robot, 200, seed=len(model))
    rng = np.random.default_rng(7)
    for q in rng.uniform(robot.lower, robot.upper, (3, 6)):
        res = solve_ik(robot, robot.fk(q), solver="auto")
        assert res.success and res.solver == "analytic"


@needs_erd
def test_ur5_urdf_equals_the_ur5_problem_up_to_base_and_tool() -> None:
    """The table found from the URDF has the UR5's published lengths (independent data)."""
    model = FAMILIES["ur"].model(_ur("ur5"))
    rows = model.rows
    assert [round(r.a, 6) for r in rows] == [0.0, 0.425, 0.39225, 0.0, 0.0, 0.0]
    # h = d2 + d3 + d4: the offset along the parallel axes, 0.13585 - 0.1197 + 0.093 m.
    assert math.isclose(rows[1].d + rows[2].d + rows[3].d, 0.10915, abs_tol=1e-12)
    assert math.isclose(rows[4].d, 0.09465, abs_tol=1e-12)
    assert math.isclose(rows[5].d, 0.0823, abs_tol=1e-12)


@needs_erd
def test_declared_family_is_checked_when_built() -> None:
    assert family_of(_ur("ur5", analytic="ur")) is FAMILIES["ur"]
    with pytest.raises(AnalyticIKError, match="axis 6 misses the point of axes 4, 5"):
        _ur("ur5", analytic="spherical_wrist")


@needs_erd
def test_flipped_parallel_axis_is_taken_with_its_variable_negated() -> None:
    """Elbow axis reversed: the table takes it reversed, with ``-q3``; the branches are
    the original UR5's with q3 negated (an independent reference: the unflipped URDF)."""
    text = _ur_path("ur5").read_text()
    head, tail = text.split('<joint name="elbow_joint"', 1)
    tail = tail.replace('<axis xyz="0 1 0"/>', '<axis xyz="0 -1 0"/>', 1)
    robot = Robot.from_urdf(head + '<joint name="elbow_joint"' + tail, "base_link", "tool0")
    original = _ur("ur5")
    assert family_of(robot) is FAMILIES["ur"]
    assert FAMILIES["ur"].model(robot).senses == (1.0, 1.0, -1.0, 1.0, 1.0, 1.0)
    flip = np.array([1.0, 1.0, -1.0, 1.0, 1.0, 1.0])
    rng = np.random.default_rng(3)
    for q in rng.uniform(original.lower, original.upper, (100, 6)):
        target = original.fk(q)
        assert np.max(np.abs(robot.fk(q * flip) - target)) < 1e-12  # the same arm
        ours = analytic_ik(robot, target, within_limits=False)
        theirs = analytic_ik(original, target, within_limits=False)
        assert len(ours) == len(theirs) >= 1
        for b in ours:
            assert min(_wrapped_distance(b * flip, t) for t in theirs) < 1e-9
    _check_branches(robot, 100, seed=4)


@needs_erd
def test_near_miss_axes_are_solved_on_the_ideal_arm_then_refined() -> None:
    """A wrist tilted by 1e-10 rad: within the angle tolerance, not to rounding.

    The snapped table misses the robot's FK by about 1e-11 (no exact table), so the UR
    closed form solves the ideal arm and each branch takes a Newton step on the robot's
    own axes: the raw branches miss, the returned ones round-trip to rounding.
    """
    text = _ur_path("ur5").read_text()
    head, tail = text.split('<joint name="wrist_2_joint"', 1)
    tail = tail.replace('rpy="0.0 0.0 0.0"', 'rpy="1e-10 0.0 0.0"', 1)
    robot = Robot.from_urdf(head + '<joint name="wrist_2_joint"' + tail, "base_link", "tool0")
    assert family_of(robot) is FAMILIES["ur"]
    model = FAMILIES["ur"].model(robot)
    assert not model.exact
    miss = np.max(np.abs(dh_fk(model, np.full(6, 0.3)) - robot.fk(np.full(6, 0.3))))
    assert 1e-13 < miss < 1e-9
    rng = np.random.default_rng(5)
    raw_miss = 0.0
    for q in rng.uniform(robot.lower, robot.upper, (50, 6)):
        target = robot.fk(q)
        for b in FAMILIES["ur"].candidates(robot, target, "pose", robot.mid_limits):
            raw_miss = max(raw_miss, float(np.max(np.abs(robot.fk(b) - target))))
        for b in analytic_ik(robot, target):
            assert np.max(np.abs(robot.fk(b) - target)) < 1e-14
    assert raw_miss > 1e-13  # the step is what makes them exact
    _check_branches(robot, 100, seed=6)


@needs_erd
def test_axes_off_by_more_than_the_tolerance_are_declined_with_the_reason() -> None:
    """A wrist tilted by 1e-6 rad (a URDF angle written to 6 digits): no UR table, but
    axes 2, 3, 4 stay parallel, so ``three_parallel`` (any twists) solves it exactly."""
    text = _ur_path("ur5").read_text()
    head, tail = text.split('<joint name="wrist_2_joint"', 1)
    tail = tail.replace('rpy="0.0 0.0 0.0"', 'rpy="1e-6 0.0 0.0"', 1)
    robot = Robot.from_urdf(head + '<joint name="wrist_2_joint"' + tail, "base_link", "tool0")
    reason = FAMILIES["ur"].explain(robot) or ""
    assert reason.startswith("alpha") and "needs" in reason and "perpendicular" in reason
    family = family_of(robot)
    assert family is not None and family.name == "three_parallel"
    assert_closed_form_round_trips(robot, family, 30, seed=3, most={"pose": 8})


def _kinova() -> Robot:
    assert ROBOTS_DIR is not None
    path = ROBOTS_DIR / "kinova_description" / "robots" / "kinova.urdf"
    return Robot.from_urdf(path, "j2s6s200_link_base", "j2s6s200_end_effector")


def _newton(robot: Robot, q: np.ndarray, target: np.ndarray, steps: int = 2) -> np.ndarray:
    """Gauss-Newton steps of ``q`` towards ``target`` on ``Robot.fk`` / ``Robot.jacobian``."""
    for _ in range(steps):
        F = robot.fk(q)
        R = target[:3, :3] @ F[:3, :3].T
        err = np.concatenate(
            [
                target[:3, 3] - F[:3, 3],
                0.5 * np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]]),
            ]
        )
        q = q + np.linalg.lstsq(robot.jacobian(q), err, rcond=None)[0]
    return q


@needs_erd
def test_kinova_j2s6s200_urdf_gets_the_spherical_wrist_branches_of_eaik() -> None:
    """The Jaco 2 (spherical wrist): its third axis is written reversed (parallel to the
    second, opposite) and its right angles to 11 digits (1.57079632679, 5e-12 rad off).

    Against EAIK on the same URDF, each pose formed by each library's own FK at the same
    configuration (EAIK's end frame is not the URDF's end effector): the same number of
    exact branches on 200 random poses, each of ours equal to one of EAIK's after
    wrapping (1e-9). EAIK solves the ideal arm and stops there (its branches miss their
    pose by up to 5e-13, which one pose of 200 turns into 1.2e-9 rad): its branches are
    compared after two Gauss-Newton steps on optik's FK and Jacobian.
    """
    from eaik.IK_URDF import UrdfRobot

    robot = _kinova()
    assert family_of(robot) is FAMILIES["spherical_wrist"]
    model = FAMILIES["spherical_wrist"].model(robot)
    assert model.senses == (1.0, 1.0, -1.0, 1.0, 1.0, 1.0) and not model.exact
    eaik_robot = UrdfRobot(str(ROBOTS_DIR / "kinova_description" / "robots" / "kinova.urdf"))  # type: ignore[operator]
    rng = np.random.default_rng(0)
    Q = rng.uniform(np.maximum(robot.lower, -math.pi), np.minimum(robot.upper, math.pi), (200, 6))
    for q in Q:
        sol = eaik_robot.IK(eaik_robot.fwdKin(q))
        T = robot.fk(q)
        exact = [
            _newton(robot, np.asarray(x), T)
            for x, ls in zip(sol.Q, sol.is_LS, strict=True)
            if not ls
        ]
        branches = analytic_ik(robot, T, within_limits=False)
        assert len(branches) == len(exact), q
        for b in branches:
            assert np.max(np.abs(robot.fk(b) - T)) < 1e-12
            assert min(_wrapped_distance(b, e) for e in exact) < 1e-9
    _check_branches(robot, 200, seed=8)
    for q in Q[:3]:
        res = solve_ik(robot, robot.fk(q), solver="auto")
        assert res.success and res.solver == "analytic"


@needs_erd
def test_kinova_batch_equals_single_calls() -> None:
    """The batch pipeline turns the reversed joint and refines the branches as well."""
    robot = _kinova()
    rng = np.random.default_rng(9)
    lower, upper = np.maximum(robot.lower, -math.pi), np.minimum(robot.upper, math.pi)
    T = robot.fk(rng.uniform(lower, upper, (40, 6)))
    ref = rng.uniform(lower, upper, (40, 6))
    for q_ref in (None, ref):
        batch = analytic_ik_batch(robot, T, q_ref=q_ref)
        for i in range(40):
            single = analytic_ik(robot, T[i], q_ref=None if q_ref is None else q_ref[i])
            assert batch.counts[i] == len(single) >= 1
            np.testing.assert_array_equal(batch.q[i, : len(single)], np.array(single))


# ---------------------------------------------------------------------- built-ins
BEFORE = {
    "dobot_magician": "dobot",
    "jumbo_drill_6dof": "spherical_wrist",
    "jumbo_spherical_arm": "spherical_rrp",
    "panda": None,
    "planar_2r": "planar_2r",
    "puma560": "spherical_wrist",
    "stanford_arm": "spherical_wrist",
    "ur5": "ur",
}
"""The families detected in every built-in problem before detection from the axes."""


def test_builtin_problems_detect_the_same_families() -> None:
    found = {}
    for path in builtin_problems():
        robot = load_problem(path).robot
        detected = detect_family(robot)
        declared = family_of(robot)
        found[path.stem] = detected.name if detected else None
        assert (declared.name if declared else None) == found[path.stem]
        if declared is not None and declared.kernel:
            # Robots built from standard DH keep their own rows (and packed parameters).
            assert declared.model(robot).source == "dh rows"
    assert found == BEFORE


def test_panda_urdf_explains_why_there_is_no_family() -> None:
    robot = Robot.from_urdf(REPO / "problems" / "panda.urdf", "panda_link0", "panda_hand")
    text = explain_family(robot)
    assert text.splitlines()[0].endswith("no closed-form family")
    assert "ur: 7 joints (the family takes 6)" in text
    with pytest.raises(AnalyticIKError, match="7 joints"):
        Robot.from_urdf(
            REPO / "problems" / "panda.urdf", "panda_link0", "panda_hand", analytic="ur"
        )


# ---------------------------------------------------------------------- modified DH, URDF
def _rz(t: float) -> np.ndarray:
    c, s = math.cos(t), math.sin(t)
    return np.array([[c, -s, 0, 0], [s, c, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1.0]])


def _rx(t: float) -> np.ndarray:
    c, s = math.cos(t), math.sin(t)
    return np.array([[1, 0, 0, 0], [0, c, -s, 0], [0, s, c, 0], [0, 0, 0, 1.0]])


def _trans(x: float, y: float, z: float) -> np.ndarray:
    T = np.eye(4)
    T[:3, 3] = (x, y, z)
    return T


def _as_mdh(problem: str) -> tuple[Robot, Robot]:
    """A built-in DH arm and the same arm as modified-DH rows (Craig: shifted alphas, a's)."""
    puma = load_problem(problem).robot
    assert puma.dh is not None
    rows = []
    for i, r in enumerate(puma.dh):
        prev = puma.dh[i - 1] if i else None
        rows.append(
            {
                "alpha": prev.alpha if prev else 0.0,
                "a": prev.a if prev else 0.0,
                "theta": r.theta,
                "d": r.d,
                "lower": float(puma.lower[i]),
                "upper": float(puma.upper[i]),
            }
        )
    last = puma.dh[-1]
    tool = _trans(last.a, 0, 0) @ _rx(last.alpha) @ puma.T_flange_tool
    mdh = Robot.from_mdh(rows, name=f"{problem}_mdh", base=puma.T_world_base, tool=tool)
    return puma, mdh


@pytest.mark.parametrize(("problem", "family"), [("puma560", "spherical_wrist"), ("ur5", "ur")])
def test_modified_dh_arms_get_their_family_branches(problem: str, family: str) -> None:
    puma, mdh = _as_mdh(problem)
    rng = np.random.default_rng(3)
    Q = rng.uniform(puma.lower, puma.upper, (50, 6))
    assert np.max(np.abs(mdh.fk(Q) - puma.fk(Q))) < 1e-12  # the same arm (independent)
    assert family_of(mdh) is FAMILIES[family]
    assert FAMILIES[family].model(mdh).source == "joint axes"
    _check_branches(mdh, 100, seed=4)
    # The same branch set as the standard-DH Puma, pose by pose.
    for target in puma.fk(Q[:20]):
        a = analytic_ik(puma, target)
        b = analytic_ik(mdh, target)
        assert len(a) == len(b)
        for qa in a:
            assert min(float(np.max(np.abs(qa - qb))) for qb in b) < 1e-9


def _rpy(T: np.ndarray) -> tuple[float, float, float]:
    """URDF roll-pitch-yaw of ``T``'s rotation (R = Rz(y) Ry(p) Rx(r))."""
    R = T[:3, :3]
    pitch = math.atan2(-R[2, 0], math.hypot(R[0, 0], R[1, 0]))
    roll = math.atan2(R[2, 1], R[2, 2])
    yaw = math.atan2(R[1, 0], R[0, 0])
    return roll, pitch, yaw


def _origin(T: np.ndarray) -> str:
    xyz = " ".join(repr(float(v)) for v in T[:3, 3])
    rpy = " ".join(repr(v) for v in _rpy(T))
    return f'<origin xyz="{xyz}" rpy="{rpy}"/>'


def _puma_urdf() -> tuple[str, Robot]:
    """A URDF of the Puma: joints 1 and 4 counted the other way (axis -z), joint 2's frame
    turned by pi about x (axis -z again, the same physical axis), a fixed joint splitting
    link 3."""
    puma = load_problem("puma560").robot
    assert puma.dh is not None
    links = ["<link name='l0'/>"]
    joints = []
    before = np.eye(4)  # the standard DH link transform before joint i's motion
    for i, r in enumerate(puma.dh):
        origin = before @ _rz(r.theta) @ _trans(0, 0, r.d)
        axis = "0 0 1"
        lower, upper = float(puma.lower[i]), float(puma.upper[i])
        if i in (0, 3):
            # Reversed axis: q_urdf = -q_dh, so the range is mirrored.
            axis = "0 0 -1"
            lower, upper = -upper, -lower
        if i == 1:
            # The frame turned by pi about x, so its -z is the DH z.
            origin = origin @ _rx(math.pi)
            axis = "0 0 -1"
        parent = f"l{i}" if i != 3 else "l3b"
        joints.append(
            f'<joint name="j{i + 1}" type="revolute"><parent link="{parent}"/>'
            f'<child link="l{i + 1}"/>{_origin(origin)}<axis xyz="{axis}"/>'
            f'<limit lower="{lower!r}" upper="{upper!r}" effort="1" '
            f'velocity="1"/></joint>'
        )
        links.append(f"<link name='l{i + 1}'/>")
        after = _trans(r.a, 0, 0) @ _rx(r.alpha)
        before = (_rx(math.pi) if i == 1 else np.eye(4)) @ after
        if i == 2:
            half = _trans(0.01, -0.02, 0.03) @ _rz(0.4)
            joints.append(
                f'<joint name="split" type="fixed"><parent link="l3"/><child link="l3b"/>'
                f"{_origin(half)}</joint>"
            )
            links.append("<link name='l3b'/>")
            before = np.linalg.inv(half) @ before
    joints.append(
        f'<joint name="flange" type="fixed"><parent link="l6"/><child link="tip"/>'
        f"{_origin(before)}</joint>"
    )
    links.append("<link name='tip'/>")
    return "<robot name='puma_urdf'>" + "".join(links + joints) + "</robot>", puma


def test_urdf_written_from_the_puma_dh_gets_the_spherical_wrist() -> None:
    text, puma = _puma_urdf()
    robot = Robot.from_urdf(text, "l0", "tip")
    rng = np.random.default_rng(5)
    Q = rng.uniform(puma.lower, puma.upper, (30, 6))
    flip = np.array([-1.0, 1, 1, -1, 1, 1])
    # The same arm with joints 1 and 4 counted the other way (independent check).
    assert np.max(np.abs(robot.fk(Q * flip) - puma.fk(Q))) < 1e-12
    assert family_of(robot) is FAMILIES["spherical_wrist"]
    lo = np.minimum(puma.lower * flip, puma.upper * flip)
    hi = np.maximum(puma.lower * flip, puma.upper * flip)
    assert np.array_equal(robot.lower, lo) and np.array_equal(robot.upper, hi)
    _check_branches(robot, 100, seed=6)


# ---------------------------------------------------------------------- the construction
@pytest.mark.parametrize("problem", ["puma560", "ur5"])
def test_raw_candidates_of_a_table_from_the_axes_take_the_robots_frame_0(problem: str) -> None:
    """``candidates`` gets the flange target in the robot's frame 0, as for DH robots."""
    _, plain = _as_mdh(problem)
    assert plain.dh is not None
    base = _trans(0.2, -0.1, 0.4) @ _rz(0.7) @ _rx(0.2)
    mdh = Robot.from_mdh(plain.dh, base=base, tool=plain.T_flange_tool)
    family = family_of(mdh)
    assert family is not None
    q = np.array([0.3, -0.4, 0.5, 0.6, -0.7, 0.8])
    T_0 = np.linalg.inv(mdh.T_world_base) @ mdh.fk(q) @ np.linalg.inv(mdh.T_flange_tool)
    raw = family.candidates(mdh, T_0, "pose", mdh.mid_limits)
    assert min(_wrapped_distance(np.asarray(b), q) for b in raw) < 1e-9


@pytest.mark.parametrize("seed", range(5))
def test_equivalent_table_of_random_arms_reproduces_fk(seed: int) -> None:
    """Random skew, intersecting and parallel axes: the table's FK is the robot's."""
    rng = np.random.default_rng(seed)
    rows = []
    for i in range(6):
        kind = rng.integers(3)
        alpha = [0.0, math.pi / 2, float(rng.uniform(-3, 3))][kind]
        a = 0.0 if i % 2 else float(rng.uniform(-0.5, 0.5))
        rows.append(
            {
                "a": a,
                "alpha": alpha,
                "d": float(rng.uniform(-0.3, 0.3)),
                "theta": float(rng.uniform(-3, 3)),
                "role": "arm",
            }
        )
    base = _trans(*rng.uniform(-1, 1, 3)) @ _rz(float(rng.uniform(-3, 3))) @ _rx(0.3)
    robot = Robot.from_mdh(rows, base=base, tool=_trans(0.1, 0.2, 0.3) @ _rx(1.0))
    model = equivalent_dh(robot, (1, -1, 1, -1, 1))
    assert isinstance(model, DHModel) and model.source == "joint axes"
    Q = rng.uniform(-math.pi, math.pi, (40, 6))
    for q, T in zip(Q, robot.fk(Q), strict=True):
        assert np.max(np.abs(dh_fk(model, q) - T)) < 1e-12
    # Each DH z axis is the joint's axis, with the joint's direction.
    axes = joint_axes(robot)
    F = model.T_world_0
    for i, row in enumerate(model.rows):
        assert np.allclose(F[:3, 2], axes.directions[i], atol=1e-12)
        F = (
            F
            @ _trans(0, 0, 0)
            @ _rz(row.theta)
            @ _trans(0, 0, row.d)
            @ _trans(row.a, 0, 0)
            @ _rx(row.alpha)
        )


@pytest.mark.parametrize("index", [0, 1, 2])
def test_docs_examples_print_what_the_page_shows(
    index: int, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The Python blocks of docs/analytic.md, each followed by its printed output."""
    text = (REPO / "docs" / "analytic.md").read_text(encoding="utf-8")
    pairs = re.findall(r"```python\n(.*?)```\s*```text\n(.*?)```", text, flags=re.S)
    assert len(pairs) == 3
    code, shown = pairs[index]
    if "example-robot-data" in code:  # a test dependency: its absence is a failure
        assert ROBOTS_DIR is not None, "example-robot-data is not installed (the test extra)"
    monkeypatch.chdir(REPO)
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        exec(compile(code, "docs/analytic.md", "exec"), {"__name__": "__doc__"})
    assert out.getvalue() == shown


def test_batch_of_a_table_from_the_axes_equals_single_calls() -> None:
    """``analytic_ik_batch`` runs the same packed table as ``analytic_ik``."""
    _, mdh = _as_mdh("ur5")
    rng = np.random.default_rng(11)
    T = mdh.fk(rng.uniform(mdh.lower, mdh.upper, (40, 6)))
    batch = analytic_ik_batch(mdh, T)
    for i, target in enumerate(T):
        single = analytic_ik(mdh, target)
        assert int(batch.counts[i]) == len(single)
        for a, b in zip(batch.branches(i), single, strict=True):
            assert np.array_equal(a, b)


def test_problem_file_declaring_a_family_that_does_not_fit_fails_to_load(tmp_path: Path) -> None:
    text = (REPO / "problems" / "planar_2r.toml").read_text(encoding="utf-8")
    path = tmp_path / "wrong.toml"
    path.write_text(text.replace('analytic = "planar_2r"', 'analytic = "ur"'), encoding="utf-8")
    with pytest.raises(ProblemFileError, match=r"'analytic'.*does not fit family 'ur': 2 joints"):
        load_problem(path)


def test_urdf_problem_file_declaring_a_family_that_does_not_fit_fails_to_load(
    tmp_path: Path,
) -> None:
    (tmp_path / "panda.urdf").write_bytes((REPO / "problems" / "panda.urdf").read_bytes())
    (tmp_path / "arm.toml").write_text(
        '[robot]\nname = "panda_urdf"\nconvention = "urdf"\nurdf = "panda.urdf"\n'
        'base_link = "panda_link0"\ntip_link = "panda_hand"\nanalytic = "ur"\nsource = "test"\n',
        encoding="utf-8",
    )
    with pytest.raises(ProblemFileError, match=r"'analytic'.*'ur': 7 joints"):
        load_problem(tmp_path / "arm.toml")


def _random_rotation(rng: np.random.Generator) -> np.ndarray:
    """A uniformly random 4x4 rotation (QR of a Gaussian matrix, det +1)."""
    Qm, Rm = np.linalg.qr(rng.normal(size=(3, 3)))
    Qm = Qm @ np.diag(np.sign(np.diag(Rm)))
    if np.linalg.det(Qm) < 0:
        Qm[:, 0] = -Qm[:, 0]
    T = np.eye(4)
    T[:3, :3] = Qm
    return T


def _random_urdf(problem: str, flips: tuple[int, ...], seed: int) -> tuple[str, Robot, np.ndarray]:
    """A built-in DH arm written as a URDF with random link frames.

    Link ``i``'s frame is the DH frame after joint ``i``'s motion times a random
    ``G_i = Tz(t) R`` (any orientation, origin anywhere on the axis), so each joint's axis
    is a random direction in its URDF frame; joints in ``flips`` turn about the reversed
    axis (``q_urdf = -q_dh``, limits mirrored). Returns the URDF, the DH robot and the
    signs ``s`` with ``fk_urdf(s * q) = fk_dh(q)``.
    """
    dh = load_problem(problem).robot
    assert dh.dh is not None
    rng = np.random.default_rng(seed)
    signs = np.array([-1.0 if i + 1 in flips else 1.0 for i in range(6)])
    G_prev = np.eye(4)
    X_prev = dh.T_world_base
    links = ["<link name='l0'/>"]
    joints = []
    for i, r in enumerate(dh.dh):
        G = _trans(0, 0, float(rng.uniform(-0.2, 0.2))) @ _random_rotation(rng)
        origin = np.linalg.inv(G_prev) @ X_prev @ _rz(r.theta) @ G
        axis = signs[i] * G[:3, :3].T @ np.array([0.0, 0.0, 1.0])
        lo, hi = float(dh.lower[i]), float(dh.upper[i])
        if signs[i] < 0:
            lo, hi = -hi, -lo
        joints.append(
            f'<joint name="j{i + 1}" type="revolute"><parent link="l{i}"/>'
            f'<child link="l{i + 1}"/>{_origin(origin)}'
            f'<axis xyz="{" ".join(repr(float(v)) for v in axis)}"/>'
            f'<limit lower="{lo!r}" upper="{hi!r}" effort="1" velocity="1"/></joint>'
        )
        links.append(f"<link name='l{i + 1}'/>")
        G_prev = G
        X_prev = _trans(0, 0, r.d) @ _trans(r.a, 0, 0) @ _rx(r.alpha)
    tip = np.linalg.inv(G_prev) @ X_prev @ dh.T_flange_tool
    joints.append(
        f'<joint name="tip" type="fixed"><parent link="l6"/><child link="tip"/>'
        f"{_origin(tip)}</joint>"
    )
    links.append("<link name='tip'/>")
    return "<robot name='random'>" + "".join(links + joints) + "</robot>", dh, signs


@pytest.mark.parametrize(
    ("problem", "family", "flips"),
    [
        ("ur5", "ur", ()),
        ("ur5", "ur", (1, 5)),
        ("ur5", "ur", (2, 3, 4, 6)),
        ("puma560", "spherical_wrist", (1, 4, 6)),
        ("puma560", "spherical_wrist", (2, 3, 5)),
        # One reversed axis of a parallel pair: taken reversed, with -q (joint_senses).
        ("ur5", "ur", (3,)),
        ("puma560", "spherical_wrist", (2,)),
    ],
)
def test_random_urdf_frames_and_reversed_axes_keep_the_family(
    problem: str, family: str, flips: tuple[int, ...]
) -> None:
    """Any URDF frames and reversed axes (also one of a parallel pair) are absorbed."""
    for seed in range(3):
        text, dh, signs = _random_urdf(problem, flips, seed)
        robot = Robot.from_urdf(text, "l0", "tip")
        Q = np.random.default_rng(seed).uniform(dh.lower, dh.upper, (20, 6))
        assert np.max(np.abs(robot.fk(Q * signs) - dh.fk(Q))) < 1e-12  # independent
        assert family_of(robot) is FAMILIES[family], explain_family(robot)
        _check_branches(robot, 40, seed=seed)


@needs_erd
def test_stretched_elbows_next_to_singular_wrists_keep_their_branches() -> None:
    """A stretched elbow whose reach, computed next to a second singularity, lands just
    beyond the arm's exact reach takes the tangent (stretched) elbow instead of losing
    every branch (found by a hostile-input search): the UR5 at ``q3 = 1e-9`` with
    ``q5`` of 1e-10 to 1e-8 (``q6`` then carries the error of two entries of order ``sin
    q5``), and the Jaco 2 from its URDF stretched (``q3 = pi``) with ``q6 = -pi/2`` (its
    URDF's angles fit the ideal arm to 11 digits). Each pose keeps a branch, every branch
    reaching it (1e-9), the nearest within 2e-3 rad of the source: next to two
    singularities at once the configurations that reach a pose within 1e-9 spread that
    far (the UR5 at ``q3 = -1e-9``, ``q5 = 1e-10``: two branches 1e-3 rad apart in the
    elbow, both within 1e-9 of the pose)."""
    ur5 = load_problem("ur5").robot
    cases = [
        (ur5, np.array([0.3, -1.0, q3, -1.0, q5, 0.5]))
        for q3 in (1e-9, -1e-9)
        for q5 in (1e-10, 1e-9, 1e-8)
    ]
    kinova = _kinova()
    cases += [
        (kinova, np.array([0.3, 2.0, math.pi, 0.5, 2.0, q6])) for q6 in (-math.pi / 2, -1.5698)
    ]
    for robot, q in cases:
        T = robot.fk(q)
        branches = analytic_ik(robot, T, within_limits=False)
        assert branches, q
        nearest = min(
            float(np.max(np.abs(np.remainder(b - q + math.pi, 2 * math.pi) - math.pi)))
            for b in branches
        )
        assert nearest <= 2e-3, (q, nearest)
        for b in branches:
            F = robot.fk(b)
            assert np.linalg.norm(F[:3, 3] - T[:3, 3]) <= 1e-9
            assert Rotation.from_matrix(F[:3, :3].T @ T[:3, :3]).magnitude() <= 1e-9


@needs_erd
def test_a_branch_on_its_limit_next_to_a_singularity_is_kept_on_the_limit() -> None:
    """The Jaco 2 stretched (``q3 = pi``) with its wrist on its lower limit
    (``q5 = 0.523598775598``, the URDF's bound to 12 digits): its branch is refined by a
    Newton step on the chain, which left it 1e-10 beyond the bound, and it was dropped
    (found by a hostile-input search). A row off its bound by at most ``LIMIT_CLIP`` is
    now put on it, its FK taken anew there: the source comes back, inside the limits
    exactly, reaching the pose."""
    kinova = _kinova()
    q = np.array([1e-12, math.pi, math.pi, 0.0, 0.523598775598, -math.pi / 2])
    assert kinova.within_limits(q, 0.0)
    T = kinova.fk(q)
    branches = analytic_ik(kinova, T)
    assert min(float(np.max(np.abs(b - q))) for b in branches) < 1e-9
    for b in branches:
        assert np.all(b >= kinova.lower) and np.all(b <= kinova.upper)
        F = kinova.fk(b)
        assert np.linalg.norm(F[:3, 3] - T[:3, 3]) <= 1e-9
        assert Rotation.from_matrix(F[:3, :3].T @ T[:3, :3]).magnitude() <= 1e-9


@needs_erd
def test_a_declared_spherical_axes_arm_takes_its_newton_step_at_the_wrist_centre() -> None:
    """The Jaco 2 declared ``spherical_axes``: its URDF's axes meet only to about 1e-12 m,
    so every branch takes a Newton step, referred to where axes 4, 5 and 6 meet (two
    3 x 3 solves). The centre is fixed in the last link and in link 3 alike: it does not
    move with the wrist joints. Without it (NaN) the step is the damped 6 x 6 one; both
    give the same branches, each reaching its pose to rounding."""
    from optik.analytic.spherical_axes import (
        AT_WRIST,
        axes_plan,
        kind_pipeline,
        pack_axes_params,
    )

    assert ROBOTS_DIR is not None
    path = ROBOTS_DIR / "kinova_description" / "robots" / "kinova.urdf"
    robot = Robot.from_urdf(
        path, "j2s6s200_link_base", "j2s6s200_end_effector", analytic="spherical_axes"
    )
    plan = axes_plan(robot)
    params = pack_axes_params(robot, plan)
    centre = np.append(params[AT_WRIST : AT_WRIST + 3], 1.0)
    assert np.all(np.isfinite(centre))
    rng = np.random.default_rng(11)
    lower, upper = np.maximum(robot.lower, -math.pi), np.minimum(robot.upper, math.pi)
    for q in rng.uniform(lower, upper, (20, 6)):
        moved = q.copy()
        moved[3:] = rng.uniform(lower[3:], upper[3:])
        np.testing.assert_allclose(robot.fk(moved) @ centre, robot.fk(q) @ centre, atol=1e-12)
    damped = params.copy()
    damped[AT_WRIST : AT_WRIST + 3] = np.nan
    solve = kind_pipeline(plan.kind).solve
    ref = robot.mid_limits
    steps = 0
    for q in rng.uniform(lower, upper, (200, 6)):
        T = robot.fk(q)
        at_wrist, plain = np.empty((8, 6)), np.empty((8, 6))
        n = solve(params, T, ref, 0, at_wrist)
        assert solve(damped, T, ref, 0, plain) == n > 0
        np.testing.assert_allclose(at_wrist[:n], plain[:n], rtol=0.0, atol=1e-12)
        for b in at_wrist[:n]:
            F = robot.fk(b)
            assert np.max(np.abs(F - T)) <= 1e-13
        steps += n
    assert steps >= 1000  # every pose has its 8 branches in all (limits off: flags 0)
