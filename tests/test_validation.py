"""The validation layer: every public entry point rejects bad input with an OptikError.

Part one checks each rule on its own (each test fails without its rule). Part two throws
hostile values at the entry points with hypothesis and asserts that each call either
succeeds with finite results or raises an ``OptikError``, never another exception, each
under a time limit.
"""

from __future__ import annotations

import math
import re
import threading
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from conftest import HostileCases
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from optik import paths
from optik._checks import (
    MAX_LENGTH_M,
    as_float_array,
    check_bool,
    check_choice,
    check_int,
    check_length,
    check_real,
    finite_array,
)
from optik.errors import (
    ArgumentError,
    InvalidLimitsError,
    ModelError,
    OptikError,
    ProblemFileError,
    ShapeError,
    URDFError,
)
from optik.ik import solve_ik
from optik.model import DHJoint, Mimic, Robot
from optik.paths import MAX_PATH_SAMPLES, PathFileError, read_path
from optik.planning import PLAN_STATUSES, plan_path
from optik.problems import load_problem
from optik.reachability import reachability

NAN, INF = math.nan, math.inf
EYE = np.eye(4)


def _pose(x: float = 0.0, y: float = 0.0, z: float = 0.0) -> np.ndarray:
    T = np.eye(4)
    T[:3, 3] = (x, y, z)
    return T


def _rows(**overrides: Any) -> list[dict[str, Any]]:
    """Two DH rows; ``overrides`` replace fields of the second."""
    rows: list[dict[str, Any]] = [
        {"name": "shoulder", "a": 1.0, "role": "arm"},
        {"name": "elbow", "a": 1.0, "lower": -2.5, "upper": 2.5},
    ]
    rows[1].update(overrides)
    return rows


PLANAR = Robot.from_dh(_rows())


# ====================================================================== scalar validators
@pytest.mark.parametrize("bad", [True, False, 1j, 1 + 0j, "1.0", None, [1.0], NAN, INF, -INF])
def test_check_real_rejects(bad: Any) -> None:
    with pytest.raises(ArgumentError, match=r"^tol: expected .*got ") as info:
        check_real("tol", bad)
    assert info.value.name == "tol"
    assert info.value.value is bad


def test_check_real_accepts_and_bounds() -> None:
    assert check_real("x", 3) == 3.0 and type(check_real("x", 3)) is float
    assert check_real("x", np.float32(0.5)) == 0.5
    assert check_real("x", np.array(2.0)) == 2.0
    assert check_real("x", INF, allow_inf=True) == INF
    assert math.isnan(check_real("x", NAN, allow_nan=True))
    assert math.copysign(1.0, check_real("x", -0.0, nonnegative=True)) == -1.0
    for kwargs, value in (
        ({"positive": True}, 0.0),
        ({"positive": True}, -0.0),
        ({"nonnegative": True}, -1e-300),
        ({"minimum": 1.0}, 0.5),
        ({"maximum": 1.0}, 1.5),
    ):
        with pytest.raises(ArgumentError, match="x: expected a"):
            check_real("x", value, **kwargs)
    with pytest.raises(ArgumentError, match="representable"):
        check_real("x", 10**400)


@pytest.mark.parametrize("bad", [True, 2.5, NAN, INF, "3", None, 1j, np.float64(0.1)])
def test_check_int_rejects(bad: Any) -> None:
    with pytest.raises(ArgumentError, match="n: expected an integer"):
        check_int("n", bad)


def test_check_int_accepts_and_bounds() -> None:
    assert check_int("n", 3.0) == 3 and type(check_int("n", 3.0)) is int
    assert check_int("n", np.int64(7)) == 7
    with pytest.raises(ArgumentError, match=r"n: expected an integer >= 1, got 0"):
        check_int("n", 0, minimum=1)
    with pytest.raises(ArgumentError, match=r"n: expected an integer <= 5, got 6"):
        check_int("n", 6, maximum=5)


@pytest.mark.parametrize("bad", ["false", "true", 0, 1, None, 1.0])
def test_check_bool_rejects(bad: Any) -> None:
    with pytest.raises(ArgumentError, match="flag: expected true or false"):
        check_bool("flag", bad)


def test_check_bool_and_choice_accept() -> None:
    assert check_bool("flag", np.bool_(True)) is True
    assert check_choice("mode", "pose", ("pose", "position")) == "pose"
    for bad in ("Pose", None, 1, ["pose"]):
        with pytest.raises(ArgumentError, match=r"mode: expected one of 'pose', 'position'"):
            check_choice("mode", bad, ("pose", "position"))


def test_check_length_bound() -> None:
    assert check_length("a", MAX_LENGTH_M) == MAX_LENGTH_M
    for bad in (2 * MAX_LENGTH_M, -1e154, 1e300):
        with pytest.raises(ArgumentError, match="a: expected a length of magnitude <= 1e"):
            check_length("a", bad)


# ====================================================================== arrays
@pytest.mark.parametrize(
    "bad",
    [
        [0.1, 0.2j],
        np.array([0.1, 0.2], dtype=complex),  # zero imaginary part: still not a real array
        np.array([True, False]),
        [True, 0.5],
        [np.bool_(True), 0.5],
        ["0.1", "0.2"],
        np.array([0.1, None], dtype=object),
        np.array([0.1, "x"], dtype=object),
        None,
        "0.1",
    ],
)
def test_as_float_array_rejects(bad: Any) -> None:
    with pytest.raises(ArgumentError, match=r"^q: expected ") as info:
        as_float_array("q", bad)
    assert info.value.name == "q"


def test_as_float_array_ragged_and_accepted() -> None:
    ragged = r"^q: expected rows of equal length, got a ragged sequence"
    with pytest.raises(ShapeError, match=ragged + r" \(row lengths 2, 1\)$"):
        as_float_array("q", [[1.0, 2.0], [3.0]])
    with pytest.raises(ShapeError, match=ragged + r" \(row lengths 2, a number\)$"):
        as_float_array("q", [[1.0, 2.0], 3.0])
    with pytest.raises(ShapeError, match=ragged + r" \(row lengths 2, 3\)$"):
        as_float_array("q", np.array([np.zeros(2), np.zeros(3)], dtype=object))
    with pytest.raises(ShapeError, match=ragged + "$"):  # ragged below the first level
        as_float_array("q", [[[1.0, 2.0], [3.0]]])
    assert as_float_array("q", np.array([1, 2], dtype=object)).dtype == np.float64
    assert as_float_array("q", [np.float32(1), 2]).tolist() == [1.0, 2.0]
    with pytest.raises(ArgumentError, match="complex"):
        finite_array("target", np.eye(4, dtype=complex), (4, 4))


@pytest.mark.parametrize("n", [3, 200])  # both sides of the quick test's size switch
def test_quick_tests_are_exact(n: int) -> None:
    from optik._checks import check_finite, finite_length_array

    big = np.full(n, 1e200)
    assert check_finite("x", big) is big  # finite, however large
    for bad in (NAN, INF, -INF):
        values = np.zeros(n)
        values[n - 1] = bad
        with pytest.raises(OptikError, match=rf"x: values must be finite.*\({n - 1},\)"):
            check_finite("x", values)
    edge = np.full((n, 1), MAX_LENGTH_M)  # every entry at the bound: accepted
    assert finite_length_array("q", edge, (1,), batch=True) is not None
    edge[n // 2, 0] = -MAX_LENGTH_M * (1 + 1e-15)
    with pytest.raises(ArgumentError, match=rf"q\[{n // 2}, 0\]: expected a length"):
        finite_length_array("q", edge, (1,), batch=True)


def test_complex_q_is_rejected_not_truncated() -> None:
    with pytest.raises(ArgumentError, match="q: expected a real array"):
        PLANAR.fk([0.1 + 0.5j, 0.2])
    with pytest.raises(ArgumentError, match="q: expected a numeric array"):
        PLANAR.jacobian([True, False])


def test_joint_values_beyond_length_bound() -> None:
    with pytest.raises(
        ArgumentError, match=r"q\[1\]: expected a value of magnitude <= 1e\+09 rad or m"
    ):
        PLANAR.fk([0.0, 1e154])


def test_a_limit_of_hundreds_of_digits_is_cut_in_the_message() -> None:
    # The 401-digit integer was printed in full, twice.
    with pytest.raises(InvalidLimitsError) as info:
        Robot.from_dh([{"lower": -(10**400), "upper": 1}])
    message = str(info.value)
    assert re.match(r"joint 'j1': invalid limits \[-10{38}\.\.\., 1\]", message), message
    assert len(message) < 300, message


def test_finite_revolute_limits_beyond_the_value_bound_are_refused() -> None:
    """A finite revolute bound beyond 1e9 rad would let no configuration near it be
    checked (joint values are bounded alike): refused when the robot is built, by every
    route that sets limits; infinite limits (a continuous joint) and 1e6 rad are kept."""
    message = r"joint 'j1': invalid limits .*within \+-1e\+09 rad"
    with pytest.raises(InvalidLimitsError, match=message):
        Robot.from_dh([DHJoint(a=0.4, lower=-1e10, upper=1e10), DHJoint(a=0.3, role="arm")])
    arm = [DHJoint(a=0.4, role="arm"), DHJoint(a=0.3, role="arm")]
    with pytest.raises(InvalidLimitsError, match=message):
        Robot.from_dh(arm, limits=[[-1e10, 1.0], [-1.0, 1.0]])
    with pytest.raises(InvalidLimitsError, match=message):
        Robot.from_dh(arm).with_limits([-1e10, -1.0], [1.0, 1.0])
    wide = Robot.from_dh([DHJoint(a=0.4, lower=-1e6, upper=1e6), DHJoint(a=0.3, role="arm")])
    q = np.array([5e5, 0.3])
    assert solve_ik(wide, wide.fk(q), tol=1e-6).success
    continuous = Robot.from_dh([DHJoint(a=0.4, continuous=True), DHJoint(a=0.3, role="arm")])
    assert continuous.upper[0] == INF


# ====================================================================== DH rows
@pytest.mark.parametrize("rows", [None, 5, "rows", b"rows", {"a": 1.0}, DHJoint(a=1.0)])
def test_from_dh_rejects_non_sequences(rows: Any) -> None:
    for build in (Robot.from_dh, Robot.from_mdh):
        with pytest.raises(ModelError, match="rows: expected a sequence of DH rows"):
            build(rows)


@pytest.mark.parametrize("key", ["a", "alpha", "d", "theta"])
@pytest.mark.parametrize("bad", [NAN, INF, -INF, None, True, 1j, "0.5"])
def test_dh_fields_must_be_finite_reals(key: str, bad: Any) -> None:
    with pytest.raises(ModelError, match=rf"DH row 1 \(joint 'elbow'\): {key}: expected"):
        Robot.from_dh(_rows(**{key: bad}))
    with pytest.raises(ModelError, match=rf"DH row 0 \(joint 'j1'\): {key}: expected"):
        Robot.from_mdh([DHJoint(role="arm", **{key: bad})])  # a DHJoint is checked too


@pytest.mark.parametrize("key", ["a", "d"])
def test_dh_lengths_bounded(key: str) -> None:
    with pytest.raises(ModelError, match=rf"{key}: expected a length of magnitude <= 1e\+09"):
        Robot.from_dh(_rows(**{key: 1e154}))
    assert Robot.from_dh(_rows(**{key: 1e8})).dof == 2


@pytest.mark.parametrize("bad", ["false", "true", 0, 1, None])
def test_continuous_must_be_a_real_bool(bad: Any) -> None:
    with pytest.raises(ModelError, match="continuous: expected true or false"):
        Robot.from_dh([{"name": "j", "continuous": bad}])


def test_kind_name_role_and_robot_name() -> None:
    for bad in (None, 1, ["revolute"], "spherical"):
        with pytest.raises(ModelError, match=r"'elbow'.*unknown joint type"):
            Robot.from_dh(_rows(kind=bad))
    with pytest.raises(ModelError, match=r"DH row 1: name: expected a non-empty string"):
        Robot.from_dh(_rows(name=7))
    with pytest.raises(ModelError, match=r"role: expected a non-empty string"):
        Robot.from_dh(_rows(role=["arm"]))
    with pytest.raises(ModelError, match="name: expected a non-empty string, got 5"):
        Robot.from_dh(_rows(), name=5)  # type: ignore[arg-type]
    with pytest.raises(ModelError, match="analytic: expected a family name"):
        Robot.from_dh(_rows(), analytic=1)  # type: ignore[arg-type]
    with pytest.raises(ModelError, match="either 'type' or 'kind'"):
        Robot.from_dh(_rows(type="revolute", kind="prismatic"))


@pytest.mark.parametrize("bad", [True, "low", 1j, [0.0]])
def test_limits_must_be_numbers(bad: Any) -> None:
    with pytest.raises(InvalidLimitsError, match="'elbow'"):
        Robot.from_dh(_rows(lower=bad))


def test_prismatic_range_bounded() -> None:
    slide = {"name": "s", "kind": "prismatic", "lower": 0.0, "upper": 1e154}
    with pytest.raises(InvalidLimitsError, match=r"'s'.*prismatic range must lie within"):
        Robot.from_dh([slide])
    robot = Robot.from_dh([{**slide, "upper": 1.0}])
    with pytest.raises(InvalidLimitsError, match=r"'s'.*prismatic range must lie within"):
        robot.with_limits([0.0], [1e154])
    with pytest.raises(ArgumentError, match="upper: expected a real array"):
        robot.with_limits([0.0], [1.0 + 0j])


def test_mimic_mapping_checked() -> None:
    rows: list[Any] = [{"name": "drive", "role": "arm"}]
    with pytest.raises(ModelError, match=r"mimic must be .*got keys \['factor', 'joint'\]"):
        Robot.from_dh([*rows, {"name": "f", "mimic": {"joint": "drive", "factor": 2}}])
    with pytest.raises(ModelError, match=r"'f'.*mimic.multiplier: expected a real number"):
        Robot.from_dh([*rows, DHJoint(name="f", mimic=Mimic("drive", True))])
    with pytest.raises(ModelError, match=r"mimic.joint: expected a non-empty string"):
        Robot.from_dh([*rows, DHJoint(name="f", mimic=Mimic(3, 1.0))])  # type: ignore[arg-type]


@pytest.mark.parametrize("which", ["base", "tool"])
def test_base_and_tool_translation_bounded(which: str) -> None:
    with pytest.raises(ModelError, match=rf"{which} translation\[0\]: expected a length"):
        Robot.from_dh(_rows(), **{which: _pose(1e154)})
    with pytest.raises(ArgumentError, match=rf"{which}: expected a real array"):
        Robot.from_dh(_rows(), **{which: EYE.astype(complex)})


# ====================================================================== URDF
def _joint(name: str, parent: str, child: str, xyz: str = "0 0 0.1", kind: str = "revolute",
           axis: str = "0 0 1", lower: str = "-1", upper: str = "1") -> str:  # fmt: skip
    return (
        f'<joint name="{name}" type="{kind}"><parent link="{parent}"/><child link="{child}"/>'
        f'<origin xyz="{xyz}" rpy="0 0 0"/><axis xyz="{axis}"/>'
        f'<limit lower="{lower}" upper="{upper}"/></joint>'
    )


def _urdf(*joints: str, links: tuple[str, ...] = ("base", "l1", "l2")) -> str:
    body = "".join(f'<link name="{name}"/>' for name in links)
    return f'<robot name="r">{body}{"".join(joints)}</robot>'


GOOD_URDF = _urdf(
    _joint("j1", "base", "l1"),
    _joint("j2", "l1", "l2", "0.5 0 0", "prismatic", "1 0 0", "0", "0.2"),
)


def _finishes(call: Callable[[], Any], seconds: float = 30.0) -> BaseException | None:
    """Run ``call`` in a daemon thread; fail if it does not return in time (a hang)."""
    outcome: list[BaseException | None] = []

    def run() -> None:
        try:
            call()
            outcome.append(None)
        except BaseException as exc:  # handed back to the test
            outcome.append(exc)

    worker = threading.Thread(target=run, daemon=True)
    worker.start()
    worker.join(seconds)
    assert outcome, f"did not return within {seconds} s"
    return outcome[0]


def test_urdf_cycle_is_an_error_not_a_hang() -> None:
    text = _urdf(_joint("j2", "l1", "l2"), _joint("j3", "l2", "l1"))
    exc = _finishes(lambda: Robot.from_urdf(text, "base", "l2"))
    assert isinstance(exc, URDFError)
    assert "cycle through link" in str(exc) and "'j2'" in str(exc) and "'j3'" in str(exc)


def test_urdf_self_loop_is_an_error_not_a_hang() -> None:
    text = _urdf(_joint("j1", "base", "l1"), _joint("loop", "l2", "l2"))
    exc = _finishes(lambda: Robot.from_urdf(text, "base", "l2"))
    assert isinstance(exc, URDFError)
    assert "joint 'loop' connects link 'l2' to itself" in str(exc)


def test_urdf_link_with_two_parents() -> None:
    text = _urdf(_joint("j1", "base", "l1"), _joint("j2", "l1", "l2"), _joint("jx", "base", "l2"))
    with pytest.raises(URDFError, match="link 'l2' has two parent joints, 'j2' and 'jx'"):
        Robot.from_urdf(text, "base", "l2")


def test_urdf_cycle_is_refused_whichever_chain_is_asked_for() -> None:
    """A URDF describes a tree: a cycle anywhere in the file is an error, also when the
    chain asked for (``b -> l1``) would not walk round it."""
    text = _urdf(_joint("j1", "base", "l1"), _joint("j2", "l1", "base"))
    for tip in ("l1", "base"):
        with pytest.raises(URDFError, match=r"the joints \['j1', 'j2'\] form a cycle"):
            Robot.from_urdf(text, "base", tip)
    longer = _urdf(_joint("j1", "base", "l1"), _joint("j2", "l2", "l3"), _joint("j3", "l3", "l2"))
    with pytest.raises(URDFError, match=r"form a cycle through link 'l[23]'"):
        Robot.from_urdf(longer, "base", "l1")


def test_urdf_unreadable_files(tmp_path: Path) -> None:
    latin = tmp_path / "latin.urdf"
    latin.write_bytes(GOOD_URDF.replace('name="r"', 'name="r\xe9"').encode("latin-1"))
    with pytest.raises(URDFError, match="not a UTF-8 text file"):
        Robot.from_urdf(latin, "base", "l2")
    folder = tmp_path / "folder.urdf"
    folder.mkdir()
    with pytest.raises(URDFError, match="a folder, not a file"):
        Robot.from_urdf(folder, "base", "l2")
    for source in (None, 5, b"<robot/>"):
        with pytest.raises(URDFError, match="source: expected a URDF path or XML text"):
            Robot.from_urdf(source, "base", "l2")  # type: ignore[arg-type]
    with pytest.raises(URDFError, match="tip_link: expected a link name"):
        Robot.from_urdf(GOOD_URDF, "base", None)  # type: ignore[arg-type]


def test_urdf_huge_numbers() -> None:
    huge_origin = _urdf(_joint("j1", "base", "l1", xyz="1e154 0 0"), links=("base", "l1"))
    with pytest.raises(URDFError, match=r"joint 'j1' origin xyz: '1e154 0 0'.*beyond 1e\+09 m"):
        Robot.from_urdf(huge_origin, "base", "l1")
    huge_stroke = _urdf(
        _joint("s", "base", "l1", kind="prismatic", upper="1e154"), links=("base", "l1")
    )
    with pytest.raises(URDFError, match=r"joint 's': prismatic range \[-1, 1e\+154\] m"):
        Robot.from_urdf(huge_stroke, "base", "l1")
    # An axis is a direction: huge or tiny entries are scaled, not overflowed to NaN.
    for axis in ("1e300 1e300 0", "1e-300 1e-300 0"):
        text = _urdf(_joint("j1", "base", "l1", xyz="0 0 0", axis=axis), links=("base", "l1"))
        robot = Robot.from_urdf(text, "base", "l1", tool=_pose(0, 0, 1))
        reference = Robot.from_urdf(
            text.replace(axis, "1 1 0"), "base", "l1", tool=_pose(0, 0, 1)
        ).fk([0.7])
        assert np.allclose(robot.fk([0.7]), reference, atol=1e-15)


# ====================================================================== problem files
PROBLEM = """\
description = "t"
[robot]
name = "t"
source = "s"
{robot}
[[robot.joints]]
a = 1.0
role = "arm"
{joint}
[[robot.joints]]
a = 1.0
lower = -1.0
upper = 1.0
[robot.tool]
translation = [0.0, 0.0, 0.0]
{tool}
[[targets]]
name = "t1"
position = [1.0, 1.0, 0.0]
{target}
[[paths]]
name = "p1"
positions = [[1.0, 1.0, 0.0], [1.2, 0.8, 0.0]]
{path}
"""


def _problem(tmp_path: Path, **parts: str) -> Path:
    fields = {k: "" for k in ("robot", "joint", "tool", "target", "path")}
    fields.update(parts)
    file = tmp_path / "p.toml"
    file.write_text(PROBLEM.format(**fields), encoding="utf-8")
    return file


def test_problem_template_loads(tmp_path: Path) -> None:
    problem = load_problem(_problem(tmp_path))
    assert problem.robot.dof == 2 and list(problem.paths) == ["p1"]


@pytest.mark.parametrize("path", [None, 5, b"p.toml", ["p.toml"]])
def test_load_problem_rejects_non_paths(path: Any) -> None:
    with pytest.raises(ProblemFileError, match="path: expected a file path"):
        load_problem(path)


@pytest.mark.parametrize(
    ("part", "table"),
    [
        ("robot", "robot"),
        ("joint", r"robot.joints\[0\]"),
        ("tool", "robot.tool"),
        ("target", r"targets\[0\]"),
        ("path", r"paths\[0\]"),
    ],
)
def test_unknown_key_in_every_table(tmp_path: Path, part: str, table: str) -> None:
    with pytest.raises(ProblemFileError, match=rf"\[{table}\] field 'lenght_unit': unknown"):
        load_problem(_problem(tmp_path, **{part: 'lenght_unit = "mm"'}))


def test_unknown_top_level_and_mimic_keys(tmp_path: Path) -> None:
    file = tmp_path / "top.toml"
    file.write_text('colour = "red"\n' + PROBLEM.format(robot="", joint="", tool="", target="",
                                                         path=""))  # fmt: skip
    with pytest.raises(ProblemFileError, match=r"\(top level\) field 'colour': unknown"):
        load_problem(file)
    mimic = 'mimic = { joint = "j1", factor = 2.0 }'
    with pytest.raises(ProblemFileError, match=r"mimic\] field 'factor': unknown"):
        load_problem(_problem(tmp_path, joint="").parent / _problem_with_mimic(tmp_path, mimic))


def _problem_with_mimic(tmp_path: Path, mimic: str) -> str:
    text = PROBLEM.format(robot="", joint="", tool="", target="", path="")
    text = text.replace("lower = -1.0\nupper = 1.0\n", mimic + "\n")
    (tmp_path / "mimic.toml").write_text(text, encoding="utf-8")
    return "mimic.toml"


def test_continuous_string_rejected(tmp_path: Path) -> None:
    file = _problem(tmp_path, joint='continuous = "false"')
    with pytest.raises(ProblemFileError, match=r"field 'continuous': expected true or false"):
        load_problem(file)


def test_problem_not_utf8_or_unreadable(tmp_path: Path) -> None:
    file = tmp_path / "latin.toml"
    file.write_bytes(PROBLEM.format(robot="", joint="", tool="", target="", path="")
                     .replace('"t"', '"t\xe9"').encode("latin-1"))  # fmt: skip
    with pytest.raises(ProblemFileError, match="not a UTF-8 text file"):
        load_problem(file)
    (tmp_path / "dir.toml").mkdir()
    with pytest.raises(ProblemFileError, match="a folder, not a file"):
        load_problem(tmp_path / "dir.toml")


@pytest.mark.parametrize(
    ("part", "text", "field"),
    [
        ("robot", 'length_unit = "mm"', "a"),  # 2e12 mm is 2e9 m
        ("joint", "d = 2e9", "d"),
        ("tool", "", r"translation\[2\]"),
        ("target", "", r"position\[0\]"),
    ],
)
def test_problem_lengths_bounded(tmp_path: Path, part: str, text: str, field: str) -> None:
    source = PROBLEM.format(robot="", joint="", tool="", target="", path="")
    if part == "robot":
        source = source.replace("a = 1.0\nrole", "a = 2e12\nrole").replace(
            'source = "s"\n', f'source = "s"\n{text}\n'
        )
    elif part == "joint":
        source = source.replace('role = "arm"\n', f'role = "arm"\n{text}\n')
    elif part == "tool":
        source = source.replace("[0.0, 0.0, 0.0]", "[0.0, 0.0, 1e154]")
    else:
        source = source.replace("position = [1.0, 1.0, 0.0]", "position = [1e154, 0.0, 0.0]")
    file = tmp_path / "big.toml"
    file.write_text(source, encoding="utf-8")
    with pytest.raises(ProblemFileError, match=rf"field '{field}': .* m is beyond the 1e\+09 m"):
        load_problem(file)


# ====================================================================== path files
def test_csv_without_header_is_an_error(tmp_path: Path) -> None:
    file = tmp_path / "p.csv"
    file.write_text("0.1,0.2,0.3\n0.2,0.2,0.3\n0.3,0.2,0.3\n")
    with pytest.raises(PathFileError, match=r"line 1 must be the header 'x,y,z' or 'x,y,z,roll"):
        read_path(file)
    file.write_text("a,b,c\n0.1,0.2,0.3\n")
    with pytest.raises(PathFileError, match="got 'a,b,c'"):
        read_path(file)
    file.write_text(" X, y ,Z\n0.1,0.2,0.3\n0.2,0.2,0.3\n")
    poses, mode = read_path(file)
    assert mode == "position" and poses[:, :3, 3].tolist() == [[0.1, 0.2, 0.3], [0.2, 0.2, 0.3]]


def test_path_files_bad_content(tmp_path: Path) -> None:
    toml = tmp_path / "p.toml"
    toml.write_text('lenght_unit = "mm"\npositions = [[100, 0, 0]]\n')
    with pytest.raises(PathFileError, match="unknown key 'lenght_unit'"):
        read_path(toml)
    toml.write_text("length_unit = 5\npositions = [[100, 0, 0]]\n")
    with pytest.raises(PathFileError, match="length_unit must be one of"):
        read_path(toml)
    toml.write_text("positions = [[1e154, 0, 0]]\n")
    with pytest.raises(PathFileError, match=r"positions\[0, 0\]: expected a length"):
        read_path(toml)
    csv = tmp_path / "latin.csv"
    csv.write_bytes("x,y,z\n# caf\xe9\n0,0,0\n".encode("latin-1"))
    with pytest.raises(PathFileError, match="not a UTF-8 text file"):
        read_path(csv)
    npz = tmp_path / "broken.npz"
    npz.write_bytes(b"PK\x03\x04 not a zip archive")
    with pytest.raises(PathFileError, match=r"broken\.npz"):
        read_path(npz)
    for bad in (None, 3, b"p.csv"):
        with pytest.raises(PathFileError, match="path: expected a file path"):
            read_path(bad)  # type: ignore[arg-type]


@pytest.mark.parametrize("step", [None, "0.1", True, NAN, INF, -INF, 0.0, -0.0, -0.1, 0.1j])
def test_primitive_steps_checked(step: Any) -> None:
    with pytest.raises(ArgumentError, match="step: expected a"):
        paths.line(_pose(), _pose(1.0), step)
    with pytest.raises(ArgumentError, match="step: expected a"):
        paths.circle(_pose(1.0), np.zeros(3), [0, 0, 1], step)


def test_primitive_arguments_checked() -> None:
    with pytest.raises(ArgumentError, match="start: expected a real array"):
        paths.line(EYE.astype(complex), _pose(1.0), 0.1)
    with pytest.raises(ArgumentError, match="end translation"):
        paths.line(_pose(), _pose(1e154), 0.1)
    with pytest.raises(ArgumentError, match="center: expected"):
        paths.arc(_pose(1.0), _pose(0.0, 1.0), ["0", "0", "0"], 0.1)
    with pytest.raises(ArgumentError, match="long_way: expected true or false"):
        paths.arc(_pose(1.0), _pose(0.0, 1.0), np.zeros(3), 0.1, long_way="no")  # type: ignore[arg-type]
    with pytest.raises(ArgumentError, match="normal: expected a numeric array"):
        paths.circle(_pose(1.0), np.zeros(3), [True, False, True], 0.1)
    # A huge normal is a direction like any other (its norm must not overflow to NaN).
    circle = paths.circle(_pose(1.0), np.zeros(3), [0.0, 0.0, 1e300], 0.5)
    assert np.allclose(circle, paths.circle(_pose(1.0), np.zeros(3), [0.0, 0.0, 1.0], 0.5))


def test_sample_count_capped() -> None:
    with pytest.raises(OptikError, match="more than 10,000,000 samples"):
        paths.line(_pose(), _pose(1.0), 1e-300)
    with pytest.raises(OptikError, match="more than 10,000,000 samples"):
        paths.circle(_pose(1.0), np.zeros(3), [0, 0, 1], 1e-9)
    step = 1.0 / (MAX_PATH_SAMPLES - 1)
    with pytest.raises(OptikError, match="samples"):
        paths.line(_pose(), _pose(1.0), step * 0.999)
    assert len(paths.line(_pose(), _pose(1.0), 0.25)) == 5


# ====================================================================== planning options
PATH3 = np.array([[1.0, 1.0, 0.0], [1.1, 1.0, 0.0], [1.2, 1.0, 0.0]])


@pytest.mark.parametrize(
    ("option", "bad"),
    [
        ("max_candidates", 0),
        ("max_candidates", True),
        ("max_candidates", 2.5),
        ("restarts", -1),
        ("restarts", 10**9),
        ("restarts", "2"),
        ("seed", -1),
        ("seed", NAN),
        ("tol", 0.0),
        ("tol", NAN),
        ("tol", "1e-6"),
        ("max_joint_step", "0.1"),
        ("max_joint_step", INF),
        ("limit_margin", -0.1),
        ("limit_margin", None),
        ("singular_threshold", NAN),
        ("greedy", "false"),
        ("greedy", 1),
        ("mode", "positions"),
    ],
)
def test_plan_path_options(option: str, bad: Any) -> None:
    with pytest.raises(ArgumentError, match=rf"^{option}: expected "):
        plan_path(PLANAR, PATH3, **{option: bad})


def test_plan_path_robot_and_path() -> None:
    with pytest.raises(OptikError, match=r"robot: expected an optik\.Robot, got str"):
        plan_path("planar_2r", PATH3)  # type: ignore[arg-type]
    with pytest.raises(ArgumentError, match=r"path translation\[1, 0\]: expected a length"):
        plan_path(PLANAR, [[1.0, 0.0, 0.0], [1e154, 0.0, 0.0]])
    with pytest.raises(ArgumentError, match="path: expected a real array"):
        plan_path(PLANAR, PATH3 + 0j)
    plan = plan_path(PLANAR, PATH3, max_candidates=1, max_joint_step=0.5)
    assert plan.status == ["ok", "ok", "ok"]  # one candidate kept per waypoint is enough


@pytest.mark.parametrize(
    ("option", "bad"),
    [("tol", -1.0), ("tol", True), ("restarts", 1.5), ("restarts", 10**9), ("seed", "0")],
)
def test_reachability_options(option: str, bad: Any) -> None:
    with pytest.raises(ArgumentError, match=rf"^{option}: expected "):
        reachability(PLANAR, PATH3, **{option: bad})


def test_reachability_arguments() -> None:
    with pytest.raises(OptikError, match="orientation: not a rotation"):
        reachability(PLANAR, PATH3, orientation=2 * np.eye(3))
    with pytest.raises(ArgumentError, match="orientation: expected a real array"):
        reachability(PLANAR, PATH3, orientation=np.eye(3, dtype=complex))
    with pytest.raises(ArgumentError, match=r"points\[0, 2\]: expected a length"):
        reachability(PLANAR, [[0.0, 0.0, -1e154]])
    with pytest.raises(OptikError, match=r"robot: expected an optik\.Robot"):
        reachability(None, PATH3)  # type: ignore[arg-type]


# ====================================================================== hostile values
TIME_LIMIT_S = 30.0  # a hard stop per case: a hang fails the test instead of blocking it
FUZZ = settings(
    max_examples=max(200, settings().max_examples),  # the optik-long profile asks for more
    deadline=None,  # the per-case alarm bounds each case; a cold compile may take seconds
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)
HOSTILE = HostileCases(TIME_LIMIT_S)

SCALARS = st.sampled_from(
    [NAN, INF, -INF, 1e300, -1e300, 1e154, 1e10, -0.0, 0.0, 0.5, 1.0, -1, 3, 1j, 1 + 0j,
     True, False, "1.0", "x", "", None, [], [1.0], {}, (), 10**400, np.float64(NAN),
     np.int64(2), np.float32(0.5), 5e-324, np.bool_(True)]
)  # fmt: skip
FLOATS = st.sampled_from([NAN, INF, -INF, 1e300, -1e300, 1e154, 1e10, -0.0, 0.0, 0.3, -1.2, 5e-324])
DTYPES = st.sampled_from([complex, bool, object, str, np.float32, np.int64])


@pytest.fixture(scope="module", autouse=True)
def _report_stats() -> Iterator[None]:
    """Print the tally of hostile cases (run with ``-s -p no:xdist`` to see all of it)."""
    yield
    HOSTILE.report()


@pytest.fixture(scope="module")
def warm() -> None:
    """Compile the kernels once, outside the per-example deadline."""
    plan_path(PLANAR, PATH3, max_joint_step=0.5)
    reachability(PLANAR, PATH3)
    PRISMATIC.frames([0.1, 0.2])


PRISMATIC = Robot.from_dh(
    [{"name": "turn", "role": "arm", "a": 0.2},
     {"name": "slide", "kind": "prismatic", "lower": 0.0, "upper": 0.5, "alpha": 1.0}]
)  # fmt: skip


def _finite(*arrays: Any) -> bool:
    return all(bool(np.all(np.isfinite(np.asarray(a, dtype=float)))) for a in arrays)


def hostile_array(shape: tuple[int, ...]) -> st.SearchStrategy[Any]:
    """Arrays meant to be of ``shape``: hostile entries, wrong shapes and dtypes, ragged."""
    n = int(np.prod(shape))
    good = np.full(shape, 0.3)
    filled = st.lists(FLOATS, min_size=n, max_size=n).map(
        lambda v: np.array(v, dtype=float).reshape(shape)
    )
    one_bad = st.tuples(st.integers(0, n - 1), FLOATS).map(
        lambda iv: np.where(np.arange(n).reshape(shape) == iv[0], iv[1], good)
    )
    junk_entry = st.tuples(st.integers(0, n - 1), SCALARS).map(
        lambda iv: [iv[1] if i == iv[0] else 0.3 for i in range(n)]
    )
    dtyped = DTYPES.map(lambda d: good.astype(d))
    reshaped = st.sampled_from([(0,), (0, *shape), (*shape, 1), (1, *shape), (n + 1,), ()]).map(
        np.zeros
    )
    ragged = st.just([[0.1] * max(shape[-1], 2), [0.1]])
    return st.one_of(st.just(good), filled, one_bad, junk_entry, dtyped, reshaped, ragged, SCALARS)


def hostile_pose() -> st.SearchStrategy[Any]:
    """4x4 poses: a good one, hostile translations, and everything of :func:`hostile_array`."""
    translated = st.tuples(FLOATS, FLOATS, FLOATS).map(lambda p: _pose(*p))
    return st.one_of(st.just(_pose(0.3, 0.2, 0.1)), translated, hostile_array((4, 4)))


# ---------------------------------------------------------------------- models
DH_KEYS = ["a", "alpha", "d", "theta", "kind", "type", "name", "role", "lower", "upper",
           "continuous", "mimic", "length"]  # fmt: skip
DH_VALUES = st.one_of(
    SCALARS,
    st.sampled_from(["revolute", "prismatic", "spherical", "arm", "wrist", {"joint": "shoulder"},
                     {"joint": "shoulder", "multiplier": NAN}, Mimic("shoulder", 2.0)]),
)  # fmt: skip


def _check_robot(robot: Robot) -> None:
    q = np.zeros(robot.dof)
    T, J = robot.fk_jacobian(q)
    assert _finite(T, J, robot.frames(q)), "non-finite kinematics from an accepted robot"
    assert not np.any(np.isnan(robot.lower)) and not np.any(np.isnan(robot.upper))


@FUZZ
@given(
    build=st.sampled_from(["from_dh", "from_mdh"]),
    key=st.sampled_from(DH_KEYS),
    value=DH_VALUES,
    whole=st.one_of(st.none(), SCALARS, hostile_array((2,))),
    option=st.sampled_from(["limits", "base", "tool", "name", None]),
    option_value=st.one_of(hostile_pose(), hostile_array((2, 2)), SCALARS),
)
def test_hostile_dh(
    warm: None, build: str, key: str, value: Any, whole: Any, option: str | None,
    option_value: Any,
) -> None:  # fmt: skip
    rows: Any = _rows(**{key: value}) if whole is None else whole
    kwargs = {option: option_value} if option else {}
    robot = HOSTILE.attempt(build, lambda: getattr(Robot, build)(rows, **kwargs))
    if robot is not None:
        _check_robot(robot)


URDF_NUMBERS = ["nan", "inf", "-inf", "1e300", "1e154", "-0.0", "0", "0.5", "abc", "", "1 2",
                "1e-320", "0x1f", " 1 ", "1e9", "1.1e9"]  # fmt: skip
URDF_TRIPLES = ["0 0 0", "0 0 1", "nan 0 0", "inf 0 0", "1e300 0 0", "1e154 1e154 0", "1 2",
                "1 2 3 4", "a b c", "", "1e-300 0 0", "-0.0 -0.0 -0.0", "0 0 1e9", "0 0 1.1e9",
                "1e300 1e300 1e300"]  # fmt: skip
URDF_SHAPES = ["chain", "cycle", "self_loop", "two_parents", "no_child", "mimic", "floating"]


def _hostile_urdf(shape: str, xyz: str, axis: str, lower: str, upper: str, kind: str) -> str:
    second = _joint("j2", "l1", "l2", xyz, kind, axis, lower, upper)
    if shape == "cycle":
        return _urdf(second, _joint("j3", "l2", "l1"))
    if shape == "self_loop":
        return _urdf(_joint("j1", "base", "l1"), second, _joint("loop", "l1", "l1"))
    if shape == "two_parents":
        return _urdf(_joint("j1", "base", "l1"), second, _joint("jx", "base", "l2"))
    if shape == "no_child":
        return _urdf(_joint("j1", "base", "l1"), second.replace('<child link="l2"/>', ""))
    if shape == "mimic":
        second = second.replace("</joint>", '<mimic joint="j1"/></joint>')
    if shape == "floating":
        second = second.replace(f'type="{kind}"', 'type="floating"')
    return _urdf(_joint("j1", "base", "l1"), second)


@FUZZ
@given(
    shape=st.sampled_from(URDF_SHAPES),
    xyz=st.sampled_from(URDF_TRIPLES),
    axis=st.sampled_from(URDF_TRIPLES),
    lower=st.sampled_from(URDF_NUMBERS),
    upper=st.sampled_from(URDF_NUMBERS),
    kind=st.sampled_from(["revolute", "prismatic", "continuous", "fixed", "ball"]),
    tip=st.sampled_from(["l2", "l2", "l2", "l1", "nope", None, 5]),
    as_file=st.booleans(),
    tool=st.one_of(st.none(), hostile_pose()),
)
def test_hostile_urdf(
    warm: None, tmp_path: Path, shape: str, xyz: str, axis: str, lower: str, upper: str,
    kind: str, tip: Any, as_file: bool, tool: Any,
) -> None:  # fmt: skip
    text = _hostile_urdf(shape, xyz, axis, lower, upper, kind)
    source: Any = text
    if as_file:
        source = tmp_path / "r.urdf"
        source.write_text(text, encoding="utf-8")
    robot = HOSTILE.attempt("from_urdf", lambda: Robot.from_urdf(source, "base", tip, tool=tool))
    if robot is not None:
        _check_robot(robot)


# ---------------------------------------------------------------------- problem files
TOML_LITERALS = ["nan", "inf", "-inf", "1e300", "1e154", "-0.0", "0", "1", '"1.0"', "true",
                 '"false"', "[]", "[1.0, 2.0]", "[1.0, 2.0, 3.0]", "{}", '"mm"', '"deg"', '"x"',
                 "1e400", '"revolute"', '"prismatic"', "[nan, 0.0, 0.0]", "[1e154, 0.0, 0.0]",
                 "= broken", '{ joint = "j1" }', "[[1.0, 1.0, 0.0], [1.0, 1.0]]",
                 "[[1.0, 1.0, 0.0]]", '"j1"', '"arm"', '"dh"', '"urdf"']  # fmt: skip
TOML_SECTIONS: list[tuple[str, dict[str, str], list[str]]] = [
    ("", {"description": '"t"'}, ["description", "colour"]),
    ("[robot]", {"name": '"t"', "source": '"s"'},
     ["name", "source", "convention", "length_unit", "angle_unit", "analytic", "lenght_unit"]),
    ("[[robot.joints]]", {"a": "1.0", "role": '"arm"'},
     ["a", "alpha", "d", "theta", "type", "role", "lower", "upper", "continuous", "name",
      "mimic", "lenght"]),
    ("[[robot.joints]]", {"a": "1.0", "lower": "-1.0", "upper": "1.0"},
     ["a", "d", "lower", "upper", "continuous", "type", "mimic"]),
    ("[robot.tool]", {"translation": "[0.0, 0.0, 0.1]"}, ["translation", "rpy", "xyz"]),
    ("[[targets]]", {"name": '"t1"', "position": "[1.0, 1.0, 0.0]"},
     ["name", "position", "rpy", "tolerance", "angle_tolerance", "pos"]),
    ("[[paths]]", {"name": '"p1"', "positions": "[[1.0, 1.0, 0.0], [1.2, 0.8, 0.0]]"},
     ["name", "positions", "rpy", "tolerance", "step"]),
]  # fmt: skip


@FUZZ
@given(
    edits=st.lists(
        st.tuples(
            st.integers(0, len(TOML_SECTIONS) - 1),
            st.integers(0, 20),
            st.sampled_from(TOML_LITERALS),
        ),
        min_size=1,
        max_size=3,
    )
)
def test_hostile_problem_file(
    warm: None, tmp_path: Path, edits: list[tuple[int, int, str]]
) -> None:
    sections = [(header, dict(fields), keys) for header, fields, keys in TOML_SECTIONS]
    for index, key_index, literal in edits:
        _, fields, keys = sections[index]
        fields[keys[key_index % len(keys)]] = literal
    lines = []
    for header, fields, _ in sections:
        lines += [header] if header else []
        lines += [f"{key} = {value}" for key, value in fields.items()]
    file = tmp_path / "hostile.toml"
    file.write_text("\n".join(lines) + "\n", encoding="utf-8")
    problem = HOSTILE.attempt("load_problem", lambda: load_problem(file))
    if problem is not None:
        _check_robot(problem.robot)
        for target in problem.targets.values():
            assert _finite(target.pose, target.tolerance, target.angle_tolerance)
        for path in problem.paths.values():
            assert _finite(path.poses, path.tolerance)


# ---------------------------------------------------------------------- paths
STEPS = st.one_of(SCALARS, st.sampled_from([0.1, 0.5, 1e300]))


@FUZZ
@given(
    kind=st.sampled_from(["line", "arc", "circle"]),
    start=hostile_pose(),
    end=st.one_of(hostile_pose(), st.just(_pose(0.2, 0.3, 0.1))),
    center=st.one_of(st.just(np.array([0.0, 0.0, 0.1])), hostile_array((3,))),
    normal=st.one_of(st.just(np.array([0.0, 0.0, 1.0])), hostile_array((3,))),
    step=STEPS,
    long_way=st.one_of(st.booleans(), SCALARS),
)
def test_hostile_primitives(
    warm: None, kind: str, start: Any, end: Any, center: Any, normal: Any, step: Any,
    long_way: Any,
) -> None:  # fmt: skip
    calls: dict[str, Callable[[], Any]] = {
        "line": lambda: paths.line(start, end, step),
        "arc": lambda: paths.arc(start, end, center, step, long_way=long_way),
        "circle": lambda: paths.circle(start, center, normal, step),
    }
    poses = HOSTILE.attempt(kind, calls[kind])
    if poses is not None:
        assert poses.ndim == 3 and poses.shape[1:] == (4, 4) and len(poses) <= MAX_PATH_SAMPLES
        assert _finite(poses)


CSV_HEADERS = ["x,y,z", "x,y,z,roll,pitch,yaw", "", "a,b,c", "X, Y, Z", "x,y"]


@FUZZ
@given(
    fmt=st.sampled_from(["csv", "toml", "npz", "garbage"]),
    header=st.sampled_from(CSV_HEADERS),
    cells=st.lists(st.sampled_from(URDF_NUMBERS), min_size=1, max_size=7),
    toml_key=st.sampled_from(["positions", "rpy", "length_unit", "angle_unit", "lenght_unit"]),
    literal=st.sampled_from(TOML_LITERALS),
    array=st.one_of(hostile_array((2, 3)), hostile_array((2, 4, 4))),
    array_name=st.sampled_from(["positions", "poses", "points"]),
)
def test_hostile_path_files(
    warm: None, tmp_path: Path, fmt: str, header: str, cells: list[str], toml_key: str,
    literal: str, array: Any, array_name: str,
) -> None:  # fmt: skip
    file = tmp_path / f"path.{fmt}"
    if fmt == "csv":
        file.write_text(f"{header}\n0.1,0.2,0.3\n{','.join(cells)}\n", encoding="utf-8")
    elif fmt == "toml":
        fields = {"positions": "[[0.1, 0.2, 0.3]]", toml_key: literal}
        file.write_text("\n".join(f"{k} = {v}" for k, v in fields.items()) + "\n")
    elif fmt == "npz":
        try:
            np.savez(file, **{array_name: np.asarray(array)})
        except (TypeError, ValueError):  # the array itself cannot exist (ragged)
            file.write_bytes(b"PK\x03\x04 truncated")
    else:
        file.write_bytes(bytes(range(256)))
    result = HOSTILE.attempt("read_path", lambda: read_path(file))
    if result is not None:
        poses, mode = result
        assert mode in ("pose", "position") and poses.shape[1:] == (4, 4) and _finite(poses)


# ---------------------------------------------------------------------- planning
PLAN_OPTIONS = ["max_joint_step", "limit_margin", "mode", "q_start", "tol", "restarts", "seed",
                "singular_threshold", "max_candidates", "greedy", None]  # fmt: skip
OPTION_VALUES = st.one_of(
    SCALARS, st.sampled_from([0, 1, 2, 0.1, 1e300, "pose", "position", [0.1, 0.2]])
)


def _check_plan(plan: Any, n: int) -> None:
    assert len(plan.status) == n and set(plan.status) <= set(PLAN_STATUSES)
    solved = plan.solved
    assert _finite(plan.q[solved], plan.manipulability[solved])
    assert np.all(np.isnan(plan.q[~solved]))


@FUZZ
@given(
    option=st.sampled_from(PLAN_OPTIONS),
    value=OPTION_VALUES,
    path=st.one_of(st.just(PATH3), hostile_array((3, 3)), hostile_array((2, 4, 4))),
)
def test_hostile_plan_path(warm: None, option: str | None, value: Any, path: Any) -> None:
    kwargs = {option: value} if option else {}
    plan = HOSTILE.attempt("plan_path", lambda: plan_path(PLANAR, path, **kwargs))
    if plan is not None:
        _check_plan(plan, len(plan.poses))


@FUZZ
@given(
    option=st.sampled_from(["orientation", "tol", "restarts", "seed", None]),
    value=st.one_of(OPTION_VALUES, hostile_array((3, 3)), st.just(np.eye(3))),
    points=st.one_of(st.just(PATH3), hostile_array((3, 3))),
)
def test_hostile_reachability(warm: None, option: str | None, value: Any, points: Any) -> None:
    kwargs = {option: value} if option else {}
    result = HOSTILE.attempt("reachability", lambda: reachability(PLANAR, points, **kwargs))
    if result is not None:
        assert _finite(result.q[result.reachable])


# ---------------------------------------------------------------------- kinematics
@FUZZ
@given(
    robot=st.sampled_from([PLANAR, PRISMATIC]),
    method=st.sampled_from(["fk", "jacobian", "frames", "limit_violation", "within_limits"]),
    q=st.one_of(hostile_array((2,)), hostile_array((3, 2))),
    lower=hostile_array((2,)),
    upper=st.one_of(st.just(np.array([2.0, 0.4])), hostile_array((2,))),
)
def test_hostile_kinematics(
    warm: None, robot: Robot, method: str, q: Any, lower: Any, upper: Any
) -> None:
    out = HOSTILE.attempt(method, lambda: getattr(robot, method)(q))
    if out is not None:
        assert _finite(out)
    clone = HOSTILE.attempt("with_limits", lambda: robot.with_limits(lower, upper))
    if clone is not None:
        assert not np.any(np.isnan(clone.lower)) and np.all(clone.lower <= clone.upper)
        assert _finite(clone.fk(np.zeros(2)))


def test_shape_and_frozen_joint_messages_read_as_numpy_and_list_the_joints() -> None:
    puma = load_problem("puma560").robot
    with pytest.raises(ShapeError, match=r"q0: expected shape \(6,\), got \(3,\)"):
        solve_ik(puma, puma.fk(np.zeros(6)), q0=[0.0, 0.0, 0.0])
    with pytest.raises(ShapeError, match=r"expected shape \(6,\) or \(N, 6\), got \(3,\)"):
        puma.fk([0.0, 0.0, 0.0])
    with pytest.raises(OptikError) as info:
        solve_ik(puma, puma.fk(np.zeros(6)), frozen={"j9": 0.0})
    names = ", ".join(puma.joint_names)
    assert str(info.value) == f"frozen: 'j9' is not a joint of 'puma560' (joints: {names})"
