"""The API reference: every documented function and method states its arguments.

docs/api.md lists the public API as mkdocstrings ``::: dotted.name`` entries; each
function, and each public method of each class, with parameters must have a Google-style
``Args:`` section naming every one of them (``self``, ``cls``, ``*args`` and ``**kwargs``
aside).
"""

from __future__ import annotations

import importlib
import inspect
import re
from collections.abc import Callable
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parent.parent
API = ROOT / "docs" / "api.md"

_ARGS_SECTION = re.compile(r"^Args:\n((?:[ \t]+.*\n?|\n)*)", re.M)
# An argument entry: ``name: ...`` or ``name (type): ...``, indented one level.
_ARG_ENTRY = re.compile(r"^ {4}(\w+)[^:\n]*:", re.M)


def api_names(text: str) -> list[str]:
    """The dotted names of the ``:::`` entries of an API page."""
    return re.findall(r"^::: ([\w.]+)", text, re.M)


def resolve(name: str) -> Any:
    """The object a dotted name refers to: the longest importable module, then attributes."""
    parts = name.split(".")
    for i in range(len(parts), 0, -1):
        try:
            obj: Any = importlib.import_module(".".join(parts[:i]))
        except ImportError:
            continue
        for part in parts[i:]:
            obj = getattr(obj, part)
        return obj
    raise ImportError(f"{name}: no importable module")


def undocumented(fn: Callable[..., Any]) -> list[str]:
    """The parameters of ``fn`` its docstring's ``Args:`` section does not name."""
    try:
        signature = inspect.signature(fn)
    except (TypeError, ValueError):  # a builtin without a signature: nothing to check
        return []
    params = [
        p.name
        for p in signature.parameters.values()
        if p.name not in ("self", "cls") and p.kind not in (p.VAR_POSITIONAL, p.VAR_KEYWORD)
    ]
    if not params:
        return []
    section = _ARGS_SECTION.search(inspect.getdoc(fn) or "")
    documented = set(_ARG_ENTRY.findall(section.group(1))) if section else set()
    return [p for p in params if p not in documented]


def _callables(name: str, obj: Any) -> list[tuple[str, Callable[..., Any]]]:
    """``obj`` itself if it is a function; a class's public methods (its own, not inherited)."""
    if not inspect.isclass(obj):
        return [(name, obj)] if callable(obj) else []
    out = []
    for attr, value in vars(obj).items():
        if attr.startswith("_"):
            continue
        if isinstance(value, (staticmethod, classmethod)):
            value = value.__func__
        if inspect.isfunction(value):
            out.append((f"{name}.{attr}", value))
    return out


def api_gaps(names: list[str]) -> list[str]:
    """One line per documented function or method with parameters missing from ``Args:``."""
    gaps = []
    for name in names:
        for qualname, fn in _callables(name, resolve(name)):
            missing = undocumented(fn)
            if missing:
                gaps.append(f"{qualname}: {', '.join(missing)}")
    return gaps


def test_every_api_function_documents_its_arguments() -> None:
    names = api_names(API.read_text(encoding="utf-8"))
    assert len(names) > 50, "docs/api.md lists fewer entries than expected"
    gaps = api_gaps(names)
    assert not gaps, "arguments missing from Args: sections:\n" + "\n".join(gaps)


def _no_args(a: float, b: float) -> float:
    """Sum of two numbers (no Args section)."""
    return a + b


def _one_arg_missing(a: float, *rest: float, b: float = 0.0, **extra: float) -> float:
    """Sum of numbers.

    Args:
        a: the first, m.

    Returns:
        The sum.
    """
    return a + b


def _all_args(a: float, b: float) -> float:
    """Sum of two numbers.

    Args:
        a: the first, m.
        b (float): the second, m.
    """
    return a + b


def test_check_finds_missing_arguments() -> None:
    assert undocumented(_no_args) == ["a", "b"]
    # *rest and **extra need no entry; b does; a line of Returns: is not an argument.
    assert undocumented(_one_arg_missing) == ["b"]
    assert undocumented(_all_args) == []
