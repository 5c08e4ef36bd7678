"""The robot model: constructors, joints, limits and role defaults, and malformed input.

Each malformed input asserts the specific :class:`~optik.errors.OptikError` subclass and
that its message names what is wrong.
"""

from __future__ import annotations

import math
import pickle
import warnings
from pathlib import Path

import numpy as np
import pytest
from conftest import assert_close, robot_of

import optik
from optik.analytic import _compiled_plan
from optik.errors import (
    InvalidLimitsError,
    InvalidRotationError,
    ModelError,
    NonFiniteError,
    OptikError,
    ShapeError,
)
from optik.limits import LIMIT_TOLERANCE, ROLE_LIMITS_RAD
from optik.model import DHJoint, Mimic, Robot
from optik.problems import builtin_problems


def _arm(**overrides: object) -> list[dict[str, object]]:
    rows: list[dict[str, object]] = [
        {"name": "shoulder", "a": 0.5, "role": "arm"},
        {"name": "elbow", "a": 0.4, "lower": -1.0, "upper": 2.0},
    ]
    rows[1].update(overrides)
    return rows


# ---------------------------------------------------------------------- construction
def test_from_dh_mappings_and_type_alias() -> None:
    robot = Robot.from_dh(
        [
            {"a": 0.1, "alpha": 0.2, "role": "arm"},
            {"type": "prismatic", "theta": 0.3, "lower": 0.0, "upper": 0.5},
        ],
        name="two",
    )
    assert robot.name == "two"
    assert robot.dof == 2
    assert robot.joint_names == ("j1", "j2")
    assert [j.kind for j in robot.joints] == ["revolute", "prismatic"]
    assert robot.convention == "dh"
    assert robot.dh is not None and robot.dh[1].kind == "prismatic"
    assert repr(robot) == "Robot(name='two', dof=2, joints='RP')"


def test_from_mdh_convention() -> None:
    robot = Robot.from_mdh([DHJoint(role="arm"), DHJoint(a=0.3, alpha=0.5, role="wrist")])
    assert robot.convention == "mdh"
    # Modified DH puts a_{i-1}, alpha_{i-1} before joint i: at q = 0 the tool sits at x = 0.3.
    assert_close(robot.fk([0.0, 1.0])[:3, 3], [0.3, 0.0, 0.0], atol=1e-15)
    std = Robot.from_dh([DHJoint(role="arm"), DHJoint(a=0.3, alpha=0.5, role="wrist")])
    assert_close(std.fk([0.0, 1.0])[:3, 3], [0.3 * math.cos(1.0), 0.3 * math.sin(1.0), 0.0])


def test_limits_argument_overrides_rows() -> None:
    robot = Robot.from_dh(_arm(), limits=[[-0.5, 0.5], [-0.25, 0.75]])
    assert_close(robot.lower, [-0.5, -0.25], atol=0.0)
    assert_close(robot.upper, [0.5, 0.75], atol=0.0)
    with pytest.raises(ShapeError, match=r"limits: expected shape \(2, 2\), got \(3, 2\)"):
        Robot.from_dh(_arm(), limits=np.zeros((3, 2)))
    with pytest.raises(NonFiniteError, match="limits"):
        Robot.from_dh(_arm(), limits=[[0.0, 1.0], [math.nan, 1.0]])


def test_limits_apply_to_actuated_joints_only() -> None:
    rows = [
        DHJoint(name="drive", a=0.1, role="arm"),
        DHJoint(name="follow", mimic=Mimic("drive", -1.0)),
        DHJoint(name="wrist", role="wrist"),
    ]
    robot = Robot.from_dh(rows, limits=[[-1.0, 1.0], [-0.5, 0.5]])
    assert robot.joint_names == ("drive", "wrist")
    assert robot.chain_names == ("drive", "follow", "wrist")
    assert_close(robot.coupling, [[1.0, 0.0], [-1.0, 0.0], [0.0, 1.0]], atol=0.0)
    assert_close(robot.upper, [1.0, 0.5], atol=0.0)


def test_coupling_is_a_copy() -> None:
    robot = robot_of("dobot_magician")
    C = robot.coupling
    C[:] = 0.0
    assert np.count_nonzero(robot.coupling) == 6


def test_problem_robots_have_valid_limits(problem_robot: Robot) -> None:
    assert problem_robot.lower.shape == problem_robot.upper.shape == (problem_robot.dof,)
    assert not np.any(np.isnan(problem_robot.lower))
    assert np.all(problem_robot.lower < problem_robot.upper)
    for joint, lo, hi in zip(
        problem_robot.joints, problem_robot.lower, problem_robot.upper, strict=True
    ):
        assert (joint.lower, joint.upper) == (lo, hi)
        if joint.kind == "prismatic":
            assert math.isfinite(lo) and math.isfinite(hi)
    assert problem_robot.within_limits(problem_robot.mid_limits)


# ---------------------------------------------------------------------- limits and roles
@pytest.mark.parametrize(("role", "degrees"), [("arm", 135.0), ("wrist", 90.0), ("spindle", 180.0)])
def test_role_default_limits(role: str, degrees: float) -> None:
    robot = Robot.from_dh([DHJoint(a=1.0, role=role)])
    half = degrees * math.pi / 180.0
    assert robot.lower[0] == pytest.approx(-half, abs=1e-15)
    assert robot.upper[0] == pytest.approx(half, abs=1e-15)
    assert math.degrees(robot.upper[0] - robot.lower[0]) == pytest.approx(2 * degrees)
    assert robot.joints[0].role == role


def test_role_default_values_in_radians() -> None:
    assert ROLE_LIMITS_RAD["arm"][1] == pytest.approx(2.356194490192345, abs=1e-15)
    assert ROLE_LIMITS_RAD["wrist"][1] == pytest.approx(1.5707963267948966, abs=1e-15)
    assert ROLE_LIMITS_RAD["spindle"][1] == pytest.approx(3.141592653589793, abs=1e-15)


def test_stated_limits_override_role() -> None:
    robot = Robot.from_dh([DHJoint(role="wrist", lower=-0.1, upper=0.2)])
    assert_close(robot.lower, [-0.1], atol=0.0)
    assert_close(robot.upper, [0.2], atol=0.0)


def test_continuous_joint_limits_are_infinite() -> None:
    robot = Robot.from_dh([DHJoint(a=1.0, continuous=True), DHJoint(a=1.0, role="arm")])
    assert robot.lower[0] == -math.inf
    assert robot.upper[0] == math.inf
    assert robot.within_limits([1e9, 0.0])
    assert not robot.within_limits([1e9, 3.0])
    assert robot.limit_violation([1e9, 3.0]) == pytest.approx(3.0 - 0.75 * math.pi)


def test_mid_limits_of_continuous_joint_is_zero_without_warning() -> None:
    robot = Robot.from_dh([DHJoint(a=1.0, continuous=True), DHJoint(a=1.0, lower=0.2, upper=0.6)])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        mid = robot.mid_limits
    assert_close(mid, [0.0, 0.4], atol=1e-15)


def test_within_limits_tolerance_and_violation() -> None:
    robot = Robot.from_dh(_arm())
    up = robot.upper.copy()
    assert robot.within_limits(up)
    assert robot.within_limits(up + 0.5 * LIMIT_TOLERANCE)
    assert not robot.within_limits(up + 1e-9)
    assert robot.limit_violation(up + np.array([0.0, 0.25])) == pytest.approx(0.25)
    assert robot.limit_violation(robot.mid_limits) == 0.0
    batch = np.array([robot.mid_limits, robot.lower - np.array([0.3, 0.0])])
    assert list(robot.within_limits(batch)) == [True, False]
    assert_close(robot.limit_violation(batch), [0.0, 0.3], atol=1e-15)


# ---------------------------------------------------------------------- malformed input
def test_wrong_q_shape() -> None:
    robot = robot_of("puma560")
    with pytest.raises(ShapeError, match=r"q: expected shape \(6,?\) or \(N, 6\), got \(7,\)"):
        robot.fk(np.zeros(7))
    with pytest.raises(ShapeError, match=r"got \(2, 3, 6\)"):
        robot.jacobian(np.zeros((2, 3, 6)))
    with pytest.raises(ShapeError, match=r"q: expected shape \(6,?\)"):
        robot.frames(np.zeros((2, 6)))
    with pytest.raises(ShapeError, match="q"):
        robot.fk([[0.0] * 6, [0.0] * 5])  # ragged


@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf])
def test_non_finite_q(bad: float) -> None:
    robot = robot_of("puma560")
    q = np.zeros(6)
    q[2] = bad
    with pytest.raises(NonFiniteError, match=r"q: values must be finite.*index \(2,\)") as info:
        robot.fk(q)
    assert info.value.index == (2,)
    Q = np.zeros((3, 6))
    Q[1, 4] = bad
    with pytest.raises(NonFiniteError, match=r"index \(1, 4\)"):
        robot.fk_jacobian(Q)


def test_lower_above_upper() -> None:
    with pytest.raises(InvalidLimitsError, match=r"'elbow'.*\[2\.0, -1\.0\].*lower > upper") as e:
        Robot.from_dh(_arm(lower=2.0, upper=-1.0))
    assert (e.value.joint, e.value.lower, e.value.upper) == ("elbow", 2.0, -1.0)


def test_nan_limit() -> None:
    with pytest.raises(InvalidLimitsError, match=r"'elbow'.*NaN limit"):
        Robot.from_dh(_arm(lower=math.nan))


def test_infinite_limit_on_bounded_joint() -> None:
    with pytest.raises(InvalidLimitsError, match=r"'elbow'.*only a continuous revolute"):
        Robot.from_dh(_arm(upper=math.inf))
    with pytest.raises(InvalidLimitsError, match=r"'slide'.*only a continuous revolute"):
        Robot.from_dh([DHJoint(name="slide", kind="prismatic", lower=-math.inf, upper=math.inf)])


def test_only_one_limit() -> None:
    with pytest.raises(ModelError, match=r"'elbow'.*only one of lower/upper"):
        Robot.from_dh(_arm(upper=None))


def test_unknown_joint_type() -> None:
    with pytest.raises(ModelError, match=r"'elbow'.*unknown joint type 'spherical'") as info:
        Robot.from_dh(_arm(type="spherical"))
    assert type(info.value) is ModelError


def test_prismatic_joint_without_range() -> None:
    rows = [{"name": "slide", "type": "prismatic", "role": "arm"}]
    with pytest.raises(ModelError, match=r"'slide'.*prismatic joint must state its range"):
        Robot.from_dh(rows)


def test_joint_with_neither_limits_nor_role() -> None:
    with pytest.raises(ModelError, match=r"'elbow'.*neither limits nor a role") as info:
        Robot.from_dh(_arm(lower=None, upper=None))
    assert type(info.value) is ModelError


def test_unknown_role() -> None:
    with pytest.raises(ModelError, match=r"'elbow'.*unknown role 'elbow_joint'"):
        Robot.from_dh(_arm(role="elbow_joint"))


def test_continuous_with_limits_or_prismatic() -> None:
    with pytest.raises(ModelError, match=r"'elbow'.*continuous joint takes no lower/upper"):
        Robot.from_dh(_arm(continuous=True))
    with pytest.raises(ModelError, match=r"'s'.*only a revolute joint can be continuous"):
        Robot.from_dh([DHJoint(name="s", kind="prismatic", continuous=True)])


def test_mimic_of_missing_joint() -> None:
    rows = [DHJoint(name="drive", role="arm"), DHJoint(name="follow", mimic=Mimic("motor"))]
    with pytest.raises(ModelError, match=r"'follow'.*mimics 'motor'.*actuated: \['drive'\]"):
        Robot.from_dh(rows)


def test_mimic_of_mimic_joint() -> None:
    rows = [
        DHJoint(name="drive", role="arm"),
        DHJoint(name="f1", mimic=Mimic("drive")),
        DHJoint(name="f2", mimic=Mimic("f1")),
    ]
    with pytest.raises(ModelError, match=r"'f2'.*mimics 'f1'"):
        Robot.from_dh(rows)


def test_mimic_joint_with_limits() -> None:
    rows = [DHJoint(name="drive", role="arm"), DHJoint(name="f", mimic=Mimic("drive"), upper=1)]
    with pytest.raises(ModelError, match=r"'f'.*mimic joint takes no limits"):
        Robot.from_dh(rows)


def test_duplicate_joint_names() -> None:
    with pytest.raises(ModelError, match=r"duplicate joint names.*'shoulder', 'shoulder'"):
        Robot.from_dh(_arm(name="shoulder"))


def test_empty_chain() -> None:
    with pytest.raises(ModelError, match="at least one joint"):
        Robot.from_dh([], name="nothing")


def test_unknown_row_key_and_bad_parameter() -> None:
    with pytest.raises(ModelError, match=r"DH row 1: unknown keys \['length'\]"):
        Robot.from_dh(_arm(length=3.0))
    with pytest.raises(
        ModelError, match=r"DH row 1 \(joint 'elbow'\): a: expected a number, not NaN"
    ):
        Robot.from_dh(_arm(a=math.nan))
    with pytest.raises(ModelError, match=r"DH row 0: expected a mapping or DHJoint, got list"):
        Robot.from_dh([[0.0, 0.1, 0.2, 0.3]])


@pytest.mark.parametrize("which", ["base", "tool"])
def test_bad_base_or_tool_transform(which: str) -> None:
    reflection = np.diag([1.0, 1.0, -1.0, 1.0])
    with pytest.raises(InvalidRotationError, match=rf"{which}: not a rotation.*det = -1") as e:
        Robot.from_dh(_arm(), **{which: reflection})
    assert e.value.name == which
    sheared = np.eye(4)
    sheared[0, 1] = 0.01
    with pytest.raises(InvalidRotationError, match=rf"{which}: not a rotation") as e:
        Robot.from_dh(_arm(), **{which: sheared})
    assert e.value.orthogonality_error == pytest.approx(0.01, rel=1e-6)
    with pytest.raises(ShapeError, match=rf"{which}: expected shape \(4, 4\), got \(3, 3\)"):
        Robot.from_dh(_arm(), **{which: np.eye(3)})
    bad_row = np.eye(4)
    bad_row[3, 0] = 1.0
    with pytest.raises(ShapeError, match=rf"{which}: .*last row"):
        Robot.from_dh(_arm(), **{which: bad_row})


def test_error_tree() -> None:
    for cls in (ShapeError, NonFiniteError, InvalidRotationError, ModelError):
        assert issubclass(cls, OptikError)
    assert issubclass(InvalidLimitsError, ModelError)
    assert issubclass(OptikError, ValueError)


# ---------------------------------------------------------------------- library bugs
# These fail on the current library (see the final report for the fix in optik/model.py
# and optik/limits.py): user input must end in an OptikError, never a bare ValueError
# or a silent NaN.
def test_non_finite_mimic_multiplier_rejected() -> None:
    rows = [DHJoint(name="drive", a=1.0, role="arm"), DHJoint(name="f", a=1.0)]
    for bad in (math.nan, math.inf):
        rows[1] = DHJoint(name="f", a=1.0, mimic=Mimic("drive", bad))
        with pytest.raises(ModelError, match=r"'f'.*multiplier"):
            Robot.from_dh(rows)


def test_non_numeric_mimic_multiplier_is_model_error() -> None:
    rows = [
        {"name": "drive", "role": "arm"},
        {"name": "f", "mimic": {"joint": "drive", "multiplier": "two"}},
    ]
    with pytest.raises(ModelError, match=r"'f'.*multiplier"):
        Robot.from_dh(rows)


def test_non_numeric_limit_is_invalid_limits_error() -> None:
    with pytest.raises(InvalidLimitsError, match=r"'elbow'"):
        Robot.from_dh(_arm(lower="low"))


def test_public_names() -> None:
    """The contract of design.md section 3 (``optik.load_problem`` is in it)."""
    assert optik.Robot is Robot
    assert hasattr(optik, "load_problem"), "optik.load_problem is not exported"


def test_a_locked_joint_with_equal_limits_loads(tmp_path: Path) -> None:
    # lower == upper: a joint held by its limits (a fixed axis in a maker's table).
    rows = [
        {"a": 1.0, "lower": -1.0, "upper": 1.0},
        {"a": 0.5, "lower": 0.5, "upper": 0.5},
    ]
    robot = Robot.from_dh(rows)
    assert robot.lower[1] == robot.upper[1] == 0.5
    result = optik.solve_ik(robot, robot.fk([0.2, 0.5])[:3, 3], mode="position")
    assert result.success and result.q[1] == 0.5
    (source,) = [p for p in builtin_problems() if p.stem == "planar_2r"]
    text = source.read_text()
    elbow = 'name = "elbow"\na = 1.0\nlower = -180\nupper = 180'
    assert elbow in text
    locked = tmp_path / "locked.toml"
    locked.write_text(text.replace(elbow, 'name = "elbow"\na = 1.0\nlower = 30\nupper = 30'))
    loaded = optik.load_problem(locked).robot
    assert loaded.lower[1] == loaded.upper[1] == pytest.approx(math.radians(30.0))


def test_a_pickled_robot_travels_without_its_cache() -> None:
    # A Dask worker gets the robot pickled: the cache's compiled kernels would travel as
    # numba's source and be compiled again there (about 20 s), so the cache stays behind.
    robot = optik.load_problem("ur5").robot
    before = pickle.dumps(robot)
    q = np.array([0.3, -1.1, 1.4, -0.6, 0.9, 0.2])
    T = robot.fk(q)
    expected = optik.analytic_ik(robot, T)
    assert robot.cached_value(_compiled_plan) is not None
    assert pickle.dumps(robot) == before  # the same bytes as the unused robot
    clone = pickle.loads(before)
    assert clone.cached_value(_compiled_plan) is None
    assert robot.cached_value(_compiled_plan) is not None  # the original keeps its own
    branches = optik.analytic_ik(clone, T)  # rebuilt on demand
    assert len(branches) == len(expected) > 0
    for a, b in zip(branches, expected, strict=True):
        np.testing.assert_array_equal(a, b)
    assert np.min([np.max(np.abs(b - q)) for b in branches]) < 1e-9
