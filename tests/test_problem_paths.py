"""load_problem and load_robot on paths the system cannot look up, and a missing source."""

from __future__ import annotations

from pathlib import Path

import pytest

from optik.errors import ProblemFileError
from optik.problems import load_problem, load_robot


@pytest.mark.parametrize("path", ["x" * 5000, "x" * 300 + ".toml", "a\0b.toml", "x" * 252])
@pytest.mark.parametrize("load", [load_problem, load_robot])
def test_an_unusable_path_is_a_problem_file_error(path: str, load: object) -> None:
    with pytest.raises(ProblemFileError, match="file not found"):
        load(path)  # type: ignore[operator]


def test_a_misspelled_built_in_name_lists_the_built_ins() -> None:
    with pytest.raises(ProblemFileError) as info:
        load_problem("pumma560")
    message = str(info.value)
    assert "file not found" in message and "did you mean 'puma560'?" in message
    assert "built-in problems: " in message and "planar_2r" in message
    with pytest.raises(ProblemFileError) as info:
        load_problem("no/such/dir.toml")  # a path, not a name: no list
    assert "built-in problems" not in str(info.value)


def test_load_robot_needs_no_source_and_load_problem_does(tmp_path: Path) -> None:
    file = tmp_path / "r.toml"
    file.write_text(
        '[robot]\nname = "r"\n[[robot.joints]]\na = 1.0\nlower = -1.0\nupper = 1.0\n',
        encoding="utf-8",
    )
    problem = load_robot(file)
    assert problem.source == f"robot file {file}" and problem.robot.dof == 1
    with pytest.raises(ProblemFileError, match="'source'"):
        load_problem(file)
