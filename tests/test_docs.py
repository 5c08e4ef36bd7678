"""Documentation that runs: every Python block of the guides, and the CLI reference."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from optik.cli import build_parser

ROOT = Path(__file__).resolve().parent.parent
GUIDES = ["docs/getting-started.md", "docs/planning.md", "docs/tasks.md", "docs/your-robot.md"]


def _python_blocks(path: Path) -> list[str]:
    return re.findall(r"```python\n(.*?)```", path.read_text(encoding="utf-8"), flags=re.S)


@pytest.mark.parametrize("doc", GUIDES)
def test_guide_code_blocks_run_in_order(
    doc: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.chdir(tmp_path)  # blocks may write files; keep them out of the repository
    blocks = _python_blocks(ROOT / doc)
    assert blocks, f"{doc} has no python block"
    namespace: dict[str, object] = {"__name__": "__doc__"}
    for code in blocks:  # later blocks build on earlier ones, as a reader would run them
        exec(compile(code, doc, "exec"), namespace)


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
