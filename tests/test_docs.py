"""Documentation that runs: every Python block of the guides, and the CLI reference."""

from __future__ import annotations

import re
import sys
from collections.abc import Callable
from pathlib import Path

import pytest

from optik.cli import build_parser

ROOT = Path(__file__).resolve().parent.parent
GUIDES = ["docs/getting-started.md", "docs/planning.md", "docs/tasks.md", "docs/your-robot.md"]


def _python_blocks(path: Path) -> list[str]:
    return re.findall(r"```python\n(.*?)```", path.read_text(encoding="utf-8"), flags=re.S)


def _floats(text: str) -> list[float]:
    return [float(v) for v in text.split()]


PRINTED: dict[str, dict[str, Callable[[str], bool]]] = {
    "docs/getting-started.md": {
        "print(result.status, result.solver)": lambda out: out == "converged analytic",
        "print(result.position_error, result.orientation_error)": lambda out: all(
            0.0 <= v < 1e-6 for v in _floats(out)
        ),
        "print(optik.solve_ik(robot, far).status)": lambda out: out == "unreachable",
        "print(len(every))": lambda out: out == "8",
        'print(plan.summary()["solved"], plan.largest_step)': lambda out: (
            out.split()[0] == "21" and float(out.split()[1]) < 0.1
        ),
    },
    "docs/planning.md": {
        'print(full.summary()["discontinuity"], free.summary()["ok"])': lambda out: out == "21 22",
    },
    "docs/tasks.md": {
        "print(place.status, place.position_error, aim.position_error)": lambda out: (
            round(1e3 * _floats(out.split(maxsplit=1)[1])[0]) == 3
            and round(1e2 * _floats(out.split(maxsplit=1)[1])[1]) == 36
        ),
        "print(np.linalg.norm(free.q - home), np.linalg.norm(homely.q - home))": lambda out: (
            _floats(out)[1] < _floats(out)[0]
        ),
        "print(five.status)": lambda out: set(re.findall(r"'(\w+)'", out)) == {"ok"},
    },
    "docs/your-robot.md": {
        "print(robot)": lambda out: out == "Robot(name='panda', dof=7, joints='RRRRRRR')",
        "print(held.success, held.q[6])": lambda out: out == "True 0.3",
    },
}
"""What the guides say a ``print`` shows (in its comment), per statement: checked."""


@pytest.mark.parametrize("doc", GUIDES)
def test_guide_code_blocks_run_in_order(
    doc: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.chdir(tmp_path)  # blocks may write files; keep them out of the repository
    blocks = _python_blocks(ROOT / doc)
    assert blocks, f"{doc} has no python block"
    namespace: dict[str, object] = {"__name__": "__doc__"}
    printed: dict[str, str] = {}
    for code in blocks:  # later blocks build on earlier ones, as a reader would run them
        lines = code.splitlines()

        def record(*values: object, sep: str = " ", _lines: list[str] = lines, **_: object) -> None:
            caller = sys._getframe(1)
            statement = _lines[caller.f_lineno - 1].split("  #")[0].strip()
            printed[statement] = sep.join(str(v) for v in values)

        namespace["print"] = record
        exec(compile(code, doc, "exec"), namespace)
    for statement, holds in PRINTED.get(doc, {}).items():
        assert statement in printed, f"{doc}: no longer prints {statement}"
        assert holds(printed[statement]), f"{doc}: {statement} printed {printed[statement]!r}"


def test_cli_reference_documents_every_command_and_option() -> None:
    text = (ROOT / "docs" / "cli.md").read_text(encoding="utf-8")
    parser = build_parser()
    subparsers = next(a for a in parser._actions if a.__class__.__name__ == "_SubParsersAction")
    for name, sub in subparsers.choices.items():  # type: ignore[attr-defined]
        assert f"optik {name}" in text, f"docs/cli.md lacks `optik {name}`"
        for action in sub._actions:
            for flag in action.option_strings:
                if flag.startswith("--") and flag != "--help":
                    assert flag in text, f"docs/cli.md lacks {flag} of `optik {name}`"
