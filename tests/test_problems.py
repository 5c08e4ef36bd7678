"""Problem files: the built-in problems, unit conversion, defaults and malformed files.

A malformed file raises :class:`~optik.errors.ProblemFileError` whose message holds the
file path, the table and the field.
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pytest
from conftest import PROBLEM_FILES, assert_close, load, random_q

from optik.errors import OptikError, ProblemFileError
from optik.model import DHJoint
from optik.problems import PROBLEMS_DIR, _joint_error, _Reader, builtin_problems, load_problem

DEG = math.pi / 180.0

# ---------------------------------------------------------------------- built-in problems
EXPECTED_PROBLEMS = {
    "dobot_magician",
    "jumbo_drill_6dof",
    "jumbo_spherical_arm",
    "panda",
    "planar_2r",
    "puma560",
    "stanford_arm",
    "ur5",
}


def test_builtin_problem_list() -> None:
    assert {p.stem for p in builtin_problems()} >= EXPECTED_PROBLEMS
    assert [p.resolve() for p in builtin_problems()] == [p.resolve() for p in PROBLEM_FILES]
    assert PROBLEMS_DIR.resolve() == PROBLEM_FILES[0].parent.resolve()


def test_every_problem_loads(problem_name: str) -> None:
    problem = load(problem_name)
    assert problem.name == problem_name  # robot name matches the file name
    assert problem.robot.name == problem_name
    assert problem.source.strip()
    assert problem.description.strip()
    assert problem.path is not None and problem.path.name == f"{problem_name}.toml"


def test_builtin_lookup_by_name() -> None:
    by_name = load_problem("puma560")
    by_path = load_problem(PROBLEMS_DIR / "puma560.toml")
    q = np.radians([10.0, 20.0, -30.0, 40.0, 50.0, 60.0])
    assert_close(by_name.robot.fk(q), by_path.robot.fk(q), atol=0.0)


def test_targets_and_paths_in_si_units() -> None:
    dobot = load("dobot_magician")
    assert set(dobot.targets) == {"part1", "part2", "part3"}
    part1 = dobot.targets["part1"]
    assert part1.mode == "position"
    assert_close(part1.position, [0.100, 0.150, 0.160], atol=1e-15)
    assert_close(part1.pose[:3, :3], np.eye(3), atol=0.0)
    assert part1.tolerance == pytest.approx(200e-6)  # the arm's 200 um repeatability
    path = dobot.paths["table2"]
    assert path.mode == "position"
    assert path.poses.shape == (3, 4, 4)
    assert_close(path.poses[2, :3, 3], [0.150, 0.180, 0.140], atol=1e-15)
    assert path.tolerance == pytest.approx(200e-6)
    planar = load("planar_2r").targets["seed003"]
    assert_close(planar.position, [1.2, 1.3, 0.0], atol=0.0)
    assert planar.tolerance == 0.01


def test_dobot_limits_are_table_1() -> None:
    robot = load("dobot_magician").robot
    assert robot.joint_names == ("J1", "J2", "J3", "J4")
    assert_close(robot.lower / DEG, [-90.0, 0.0, -10.0, -90.0], atol=1e-12)
    assert_close(robot.upper / DEG, [90.0, 85.0, 95.0, 90.0], atol=1e-12)


def test_jumbo_roles_and_stroke() -> None:
    robot = load("jumbo_drill_6dof").robot
    assert [j.role for j in robot.joints] == ["arm", "arm", None, "wrist", "wrist", "spindle"]
    assert_close(robot.upper / DEG, [135.0, 135.0, 6.0 / DEG, 90.0, 90.0, 180.0], atol=1e-12)
    assert_close(robot.lower[2], 2.0, atol=0.0)


def test_panda_tool_is_hand_frame() -> None:
    robot = load("panda").robot
    c, s = math.cos(-45 * DEG), math.sin(-45 * DEG)
    expected = np.array(
        [[c, -s, 0.0, 0.0], [s, c, 0.0, 0.0], [0.0, 0.0, 1.0, 0.103], [0.0, 0.0, 0.0, 1.0]]
    )
    assert_close(robot.T_flange_tool, expected, atol=1e-15)
    assert_close(robot.T_world_base, np.eye(4), atol=0.0)


def test_problem_files_have_no_python() -> None:
    for path in PROBLEMS_DIR.iterdir():
        assert path.suffix in {".toml", ".urdf"}, path


# ---------------------------------------------------------------------- units and defaults
MM_DEG = """
[robot]
name = "units"
convention = "{convention}"
length_unit = "mm"
angle_unit = "deg"
source = "test"

[robot.base]
translation = [10.0, -20.0, 300.0]
rpy = [5.0, -10.0, 30.0]

[robot.tool]
translation = [0.0, 0.0, 103.0]
rpy = [0.0, 0.0, -45.0]

[[robot.joints]]
name = "a"
d = 333.0
alpha = -90.0
theta = 15.0
lower = -166.0
upper = 166.0

[[robot.joints]]
name = "b"
type = "prismatic"
a = 82.5
theta = 30.0
alpha = 90.0
d = 100.0
lower = 50.0
upper = 400.0

[[robot.joints]]
name = "c"
role = "wrist"
a = -88.0
alpha = 45.0

[[robot.joints]]
name = "d"
continuous = true
d = 107.0

[[targets]]
name = "t"
position = [400.0, 0.0, 500.0]
rpy = [180.0, 0.0, 90.0]
tolerance = 0.5
angle_tolerance = 0.1

[[paths]]
name = "p"
positions = [[100.0, 0.0, 0.0], [0.0, 200.0, 0.0]]
tolerance = 2.0
"""


def _si(deg: float) -> float:
    return deg * math.pi / 180.0


M_RAD = f"""
[robot]
name = "units"
convention = "{{convention}}"
length_unit = "m"
angle_unit = "rad"
source = "test"

[robot.base]
translation = [0.010, -0.020, 0.300]
rpy = [{_si(5.0)!r}, {_si(-10.0)!r}, {_si(30.0)!r}]

[robot.tool]
translation = [0.0, 0.0, 0.103]
rpy = [0.0, 0.0, {_si(-45.0)!r}]

[[robot.joints]]
name = "a"
d = 0.333
alpha = {_si(-90.0)!r}
theta = {_si(15.0)!r}
lower = {_si(-166.0)!r}
upper = {_si(166.0)!r}

[[robot.joints]]
name = "b"
type = "prismatic"
a = 0.0825
theta = {_si(30.0)!r}
alpha = {_si(90.0)!r}
d = 0.1
lower = 0.05
upper = 0.4

[[robot.joints]]
name = "c"
role = "wrist"
a = -0.088
alpha = {_si(45.0)!r}

[[robot.joints]]
name = "d"
continuous = true
d = 0.107

[[targets]]
name = "t"
position = [0.4, 0.0, 0.5]
rpy = [{_si(180.0)!r}, 0.0, {_si(90.0)!r}]
tolerance = 0.0005
angle_tolerance = {_si(0.1)!r}

[[paths]]
name = "p"
positions = [[0.1, 0.0, 0.0], [0.0, 0.2, 0.0]]
tolerance = 0.002
"""


@pytest.mark.parametrize("convention", ["dh", "mdh"])
def test_mm_deg_file_equals_m_rad_file(
    tmp_path: Path, convention: str, rng: np.random.Generator
) -> None:
    mm = tmp_path / "mm.toml"
    m = tmp_path / "m.toml"
    mm.write_text(MM_DEG.replace("{convention}", convention))
    m.write_text(M_RAD.replace("{convention}", convention))
    a, b = load_problem(mm), load_problem(m)
    assert a.robot.convention == b.robot.convention == convention
    assert_close(a.robot.lower, b.robot.lower, atol=1e-15)
    assert_close(a.robot.upper, b.robot.upper, atol=1e-15)
    assert_close(a.robot.lower[:3], [-166 * DEG, 0.05, -90 * DEG], atol=1e-15)
    assert a.robot.upper[3] == math.inf
    assert_close(a.robot.T_world_base, b.robot.T_world_base, atol=1e-15)
    assert_close(a.robot.T_flange_tool, b.robot.T_flange_tool, atol=1e-15)
    assert_close(a.robot.T_world_base[:3, 3], [0.01, -0.02, 0.3], atol=1e-15)
    for q in random_q(a.robot, rng, 20):
        assert_close(a.robot.fk(q), b.robot.fk(q), atol=1e-14)
    ta, tb = a.targets["t"], b.targets["t"]
    assert ta.mode == tb.mode == "pose"
    assert_close(ta.pose, tb.pose, atol=1e-15)
    assert ta.tolerance == pytest.approx(tb.tolerance) == pytest.approx(5e-4)
    assert ta.angle_tolerance == pytest.approx(tb.angle_tolerance)
    assert_close(a.paths["p"].poses, b.paths["p"].poses, atol=1e-15)
    assert a.paths["p"].tolerance == pytest.approx(0.002)


def test_default_units_and_tolerances(tmp_path: Path) -> None:
    path = tmp_path / "defaults.toml"
    path.write_text(
        '[robot]\nname = "d"\nsource = "s"\n[[robot.joints]]\nrole = "arm"\nalpha = 1.0\n'
        '[[targets]]\nname = "t"\nposition = [1, 2, 3]\n'
    )
    problem = load_problem(path)
    robot = problem.robot
    assert robot.convention == "dh"  # default convention
    assert robot.joint_names == ("j1",)
    assert robot.dh is not None and robot.dh[0].alpha == 1.0  # radians by default
    assert_close(robot.upper, [135 * DEG], atol=1e-15)
    target = problem.targets["t"]
    assert_close(target.position, [1.0, 2.0, 3.0], atol=0.0)  # metres by default
    assert target.tolerance == pytest.approx(1e-6)
    assert target.angle_tolerance == pytest.approx(1e-6)
    assert problem.paths == {}


def test_role_defaults_from_file(tmp_path: Path) -> None:
    path = tmp_path / "roles.toml"
    joints = "".join(
        f'[[robot.joints]]\nname = "{r}"\nrole = "{r}"\n' for r in ("arm", "wrist", "spindle")
    )
    path.write_text(f'[robot]\nname = "r"\nsource = "s"\nangle_unit = "deg"\n{joints}')
    robot = load_problem(path).robot
    assert_close(robot.upper, [0.75 * math.pi, 0.5 * math.pi, math.pi], atol=1e-15)
    assert_close(robot.lower, [-0.75 * math.pi, -0.5 * math.pi, -math.pi], atol=1e-15)


def test_urdf_problem_file(tmp_path: Path, rng: np.random.Generator) -> None:
    path = tmp_path / "panda_urdf.toml"
    urdf = (PROBLEMS_DIR / "panda.urdf").resolve()
    path.write_text(
        f'[robot]\nname = "pu"\nconvention = "urdf"\nsource = "s"\nurdf = "{urdf}"\n'
        'base_link = "panda_link0"\ntip_link = "panda_link7"\nlength_unit = "mm"\n'
        'angle_unit = "deg"\n[robot.tool]\ntranslation = [0, 0, 103]\nrpy = [0, 0, -45]\n'
    )
    robot = load_problem(path).robot
    assert robot.name == "pu"
    mdh = load("panda").robot
    for q in random_q(mdh, rng, 10):
        assert_close(robot.fk(q), mdh.fk(q), atol=1e-12)


# ---------------------------------------------------------------------- malformed files
GOOD = """
[robot]
name = "x"
source = "test"
length_unit = "m"

[[robot.joints]]
name = "j1"
role = "arm"
a = 1.0
"""


def _expect_error(
    tmp_path: Path, text: str, table: str, field: str, detail: str
) -> ProblemFileError:
    path = tmp_path / "bad.toml"
    path.write_text(text)
    with pytest.raises(ProblemFileError) as info:
        load_problem(path)
    err = info.value
    message = str(err)
    assert str(path) in message, message
    assert (err.table, err.field) == (table, field), message
    if table:
        assert f"[{table}]" in message, message
    if field:
        assert repr(field) in message, message
    assert detail in message, message
    return err


def test_good_file_loads(tmp_path: Path) -> None:
    path = tmp_path / "good.toml"
    path.write_text(GOOD)
    assert load_problem(path).robot.dof == 1


def test_not_toml(tmp_path: Path) -> None:
    _expect_error(tmp_path, GOOD + "\n[robot\n", "", "", "not valid TOML")


def test_missing_file(tmp_path: Path) -> None:
    missing = tmp_path / "nowhere.toml"
    with pytest.raises(ProblemFileError, match=r"nowhere\.toml.*file not found"):
        load_problem(missing)


def test_an_empty_path_is_named_empty() -> None:
    # Path("") is ".": the message read ".: file not found".
    with pytest.raises(ProblemFileError, match=r"^'': path: empty"):
        load_problem("")


def test_missing_robot_table(tmp_path: Path) -> None:
    _expect_error(tmp_path, 'description = "no robot"\n', "", "robot", "missing or not a table")


def test_missing_source(tmp_path: Path) -> None:
    # Said missing (it read "got None", as if the file had set it), with the way out.
    text = GOOD.replace('source = "test"\n', "")
    err = _expect_error(tmp_path, text, "robot", "source", "missing: a problem file names")
    assert "--dh FILE" in str(err)


def test_unknown_field_in_joint(tmp_path: Path) -> None:
    _expect_error(tmp_path, GOOD + "lenght = 2.0\n", "robot.joints[0]", "lenght", "unknown field")


def test_unknown_field_in_robot(tmp_path: Path) -> None:
    text = GOOD.replace('name = "x"', 'name = "x"\nmass = 3.0')
    _expect_error(tmp_path, text, "robot", "mass", "unknown field")


def test_unknown_top_level_field(tmp_path: Path) -> None:
    _expect_error(tmp_path, "version = 2\n" + GOOD, "", "version", "unknown field")


def test_bad_length_unit(tmp_path: Path) -> None:
    text = GOOD.replace('length_unit = "m"', 'length_unit = "inch"')
    _expect_error(tmp_path, text, "robot", "length_unit", "'inch' is not one of")


def test_bad_angle_unit(tmp_path: Path) -> None:
    text = GOOD.replace('length_unit = "m"', 'angle_unit = "grad"')
    _expect_error(tmp_path, text, "robot", "angle_unit", "'grad' is not one of")


def test_bad_number(tmp_path: Path) -> None:
    text = GOOD.replace("a = 1.0", 'a = "one"')
    _expect_error(tmp_path, text, "robot.joints[0]", "a", "expected a number, got 'one'")


def test_boolean_is_not_a_number(tmp_path: Path) -> None:
    text = GOOD.replace("a = 1.0", "d = true")
    _expect_error(tmp_path, text, "robot.joints[0]", "d", "expected a number")


def test_nan_limit(tmp_path: Path) -> None:
    text = GOOD + "lower = nan\nupper = 1.0\n"
    _expect_error(tmp_path, text, "robot.joints[0]", "lower", "expected a finite number")


def test_infinite_link_length(tmp_path: Path) -> None:
    text = GOOD.replace("a = 1.0", "a = inf")
    _expect_error(tmp_path, text, "robot.joints[0]", "a", "expected a finite number")


def test_bad_joint_type(tmp_path: Path) -> None:
    _expect_error(tmp_path, GOOD + 'type = "ball"\n', "robot.joints[0]", "type", "'ball'")


def test_bad_role(tmp_path: Path) -> None:
    text = GOOD.replace('role = "arm"', 'role = "elbow"')
    _expect_error(tmp_path, text, "robot.joints[0]", "role", "'elbow' is not one of")


def test_bad_continuous_flag(tmp_path: Path) -> None:
    text = GOOD + 'continuous = "yes"\n'
    _expect_error(tmp_path, text, "robot.joints[0]", "continuous", "expected true or false")


def test_bad_convention(tmp_path: Path) -> None:
    text = GOOD.replace('name = "x"', 'name = "x"\nconvention = "craig"')
    _expect_error(tmp_path, text, "robot", "convention", "'craig' is not one of")


def test_no_joints(tmp_path: Path) -> None:
    text = '[robot]\nname = "x"\nsource = "s"\n'
    _expect_error(tmp_path, text, "robot", "joints", "one or more [[robot.joints]]")


def test_bad_tool_vector(tmp_path: Path) -> None:
    text = GOOD.replace("[[robot.joints]]", "[robot.tool]\ntranslation = [0, 0]\n[[robot.joints]]")
    _expect_error(tmp_path, text, "robot.tool", "translation", "expected a list of 3 numbers")


def test_bad_mimic(tmp_path: Path) -> None:
    text = GOOD + 'mimic = { joint = "j0", gain = 2 }\n'
    _expect_error(tmp_path, text, "robot.joints[0].mimic", "gain", "unknown field")


def test_inverted_limits_are_reported_at_their_row(tmp_path: Path) -> None:
    text = GOOD + "lower = 1.0\nupper = -1.0\n"
    _expect_error(tmp_path, text, "robot.joints[0]", "upper", "-1.0 is below lower 1.0")


@pytest.mark.parametrize(("given", "missing"), [("lower", "upper"), ("upper", "lower")])
def test_one_limit_alone_is_reported_at_the_missing_one(
    tmp_path: Path, given: str, missing: str
) -> None:
    text = GOOD + f"{given} = 0.5\n"
    _expect_error(tmp_path, text, "robot.joints[0]", missing, f"missing: {given} is given")


def test_a_joint_name_used_twice_is_reported_at_the_second(tmp_path: Path) -> None:
    text = GOOD + "[[robot.joints]]\n" + GOOD.split("[[robot.joints]]\n")[1]
    _expect_error(tmp_path, text, "robot.joints[1]", "name", "'j1' is joint 0's name too")


@pytest.mark.parametrize("mimicked", ["nowhere", "j2"])
def test_a_mimic_of_no_other_joint_is_reported_at_its_field(tmp_path: Path, mimicked: str) -> None:
    # "j2" is the row's own name: a joint cannot mimic itself.
    second = f'[[robot.joints]]\nname = "j2"\na = 1.0\nmimic = {{ joint = "{mimicked}" }}\n'
    detail = f"{mimicked!r} is not another joint of this table (joints: ['j1'])"
    _expect_error(tmp_path, GOOD + second, "robot.joints[1].mimic", "joint", detail)


def test_a_models_error_naming_a_joint_is_reported_at_its_row(tmp_path: Path) -> None:
    # The model's own rules (here: a prismatic joint states its range) point at the row.
    second = '[[robot.joints]]\nname = "slide"\ntype = "prismatic"\n'
    err = _expect_error(tmp_path, GOOD + second, "robot.joints[1]", "", "must state its range")
    assert "'slide'" not in str(err)  # the row is named by its place, not twice


def test_a_models_error_naming_no_row_is_reported_at_the_table() -> None:
    # The file's own checks leave no such error reachable from a file; the mapping alone.
    rows = [DHJoint(a=1.0, name="j1", role="arm")]
    for message in ("robot 'x': some rule of the whole chain", "joint 'j9': not a row"):
        err = _joint_error(_Reader("f.toml"), rows, OptikError(message))
        assert (err.table, err.field, err.detail) == ("robot", "joints", message)
    err = _joint_error(_Reader("f.toml"), rows, OptikError("joint 'j1': a rule of the row"))
    assert (err.table, err.field, err.detail) == ("robot.joints[0]", "", "a rule of the row")


def test_bad_target(tmp_path: Path) -> None:
    text = GOOD + '[[targets]]\nname = "t"\nposition = [1, 2, "z"]\n'
    _expect_error(tmp_path, text, "targets[0]", "position[2]", "expected a number")


def test_duplicate_target(tmp_path: Path) -> None:
    target = '[[targets]]\nname = "t"\nposition = [1, 2, 3]\n'
    _expect_error(tmp_path, GOOD + target + target, "targets[1]", "name", "duplicate target")


def test_negative_tolerance(tmp_path: Path) -> None:
    text = GOOD + '[[targets]]\nname = "t"\nposition = [1, 2, 3]\ntolerance = -1.0\n'
    _expect_error(tmp_path, text, "targets[0]", "tolerance", "must be positive")


def test_path_rpy_count(tmp_path: Path) -> None:
    text = GOOD + '[[paths]]\nname = "p"\npositions = [[1, 2, 3], [4, 5, 6]]\nrpy = [[0, 0, 0]]\n'
    _expect_error(tmp_path, text, "paths[0]", "rpy", "one [r, p, y] per position")


@pytest.mark.parametrize(
    ("folder", "detail"), [(False, "file not found"), (True, "a folder, not a file")]
)
def test_urdf_file_missing_or_a_folder(tmp_path: Path, folder: bool, detail: str) -> None:
    # A folder was "file not found" too, about a path that exists.
    if folder:
        (tmp_path / "arm.urdf").mkdir()
    text = (
        '[robot]\nname = "u"\nconvention = "urdf"\nsource = "s"\nurdf = "arm.urdf"\n'
        'base_link = "a"\ntip_link = "b"\n'
    )
    _expect_error(tmp_path, text, "robot", "urdf", detail)


@pytest.mark.parametrize("key", ["urdf", "base_link", "tip_link"])
def test_a_urdf_field_in_a_dh_robot_is_an_error(tmp_path: Path, key: str) -> None:
    # The DH table was loaded and the field dropped: a file meant for a URDF arm (its
    # convention line forgotten) loaded as whatever DH rows it also held.
    text = GOOD.replace('length_unit = "m"', f'length_unit = "m"\n{key} = "arm.urdf"')
    _expect_error(tmp_path, text, "robot", key, "belongs to convention = \"urdf\", not 'dh'")


@pytest.mark.parametrize("field", ["a", "alpha", "lower"])
def test_an_integer_beyond_float64_is_an_error_naming_its_field(tmp_path: Path, field: str) -> None:
    # float() of a 401-digit TOML integer raised a raw OverflowError (exit 3 in the CLI).
    text = GOOD.replace("a = 1.0", "a = 1.0" if field != "a" else "") + f"{field} = 1{'0' * 400}\n"
    if field == "lower":
        text += "upper = 1.0\n"
    _expect_error(tmp_path, text, "robot.joints[0]", field, "an integer of 401 digits")


def test_a_zero_angle_tolerance_names_its_own_field(tmp_path: Path) -> None:
    text = GOOD + '\n[[targets]]\nname = "t"\nposition = [0.5, 0, 0]\nangle_tolerance = 0\n'
    _expect_error(tmp_path, text, "targets[0]", "angle_tolerance", "must be positive")


def test_documented_toml_example_loads(tmp_path: Path) -> None:
    doc = (Path(__file__).resolve().parent.parent / "docs" / "problems.md").read_text()
    blocks = re.findall(r"```toml\n(.*?)```", doc, flags=re.S)
    assert blocks
    for k, block in enumerate(blocks):
        path = tmp_path / f"example{k}.toml"
        path.write_text(block)
        problem = load_problem(path)
        assert problem.robot.dof >= 1
    robot = problem.robot
    assert_close(robot.upper, [math.pi, 0.75 * math.pi], atol=1e-15)
    assert_close(robot.fk([0.0, 0.0])[:3, 3], [2.0, 0.0, 0.0], atol=1e-15)


# ---------------------------------------------------------------------- library bugs
# These fail on the current optik/problems.py (fixes in the final report).
def test_duplicate_path_name(tmp_path: Path) -> None:
    path = '[[paths]]\nname = "p"\npositions = [[1, 2, 3]]\n'
    _expect_error(tmp_path, GOOD + path + path, "paths[1]", "name", "duplicate path")


def test_non_positive_path_tolerance(tmp_path: Path) -> None:
    text = GOOD + '[[paths]]\nname = "p"\npositions = [[1, 2, 3]]\ntolerance = 0.0\n'
    _expect_error(tmp_path, text, "paths[0]", "tolerance", "must be positive")


def test_urdf_error_is_reported_under_urdf_field(tmp_path: Path) -> None:
    urdf = (PROBLEMS_DIR / "panda.urdf").resolve()
    text = (
        f'[robot]\nname = "u"\nconvention = "urdf"\nsource = "s"\nurdf = "{urdf}"\n'
        'base_link = "panda_link0"\ntip_link = "panda_hnd"\n'
    )
    _expect_error(tmp_path, text, "robot", "urdf", "link 'panda_hnd' not in the URDF")
