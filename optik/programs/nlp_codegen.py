"""The nonlinear IK program's functions as compiled C, cached on disk.

CasADi evaluates an SX function in its virtual machine; the same function generated as C
and compiled runs several times faster (the Panda's ``sqpmethod`` solve: 1.25 ms with
the SX functions, 0.38 ms compiled, measured). :func:`compiled_nlpsol` generates the C
code of every function a solver calls (``Function.generate_dependencies``: objective,
gradient, Hessian of the Lagrangian, ...), compiles it once into a shared library with
the machine's C compiler, and builds the solver on it
(``casadi.nlpsol(name, plugin, "<library>.so", options)``).

The library's name is the SHA-256 of the generated C code, the CasADi version and the
compiler command, so it is specific to the robot (its chain constants are in the code),
the mode and the plugin, and every process finds the one compiled before. The cache
directory is ``$OPTIK_CACHE_DIR/casadi`` (default ``$XDG_CACHE_HOME/optik/casadi``, else
``~/.cache/optik/casadi``); a library is compiled to a temporary file and renamed into
place, so a reader never sees half of one. Without a C compiler (``$CC``, else ``cc``,
``gcc`` or ``clang`` on the ``PATH``), or when compiling or loading fails, the solver is
built on the SX functions as before and the reason is kept.
"""

from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Final

import casadi

__all__ = ["COMPILE_FLAGS", "CompileReport", "cache_dir", "compiled_nlpsol", "find_compiler"]

#: Flags of the C compiler. ``-O1`` compiles the Panda's functions in about half the time
#: of ``-O2`` for the same solve time (measured); ``-fPIC -shared`` make a loadable library.
COMPILE_FLAGS: Final[tuple[str, ...]] = ("-O1", "-fPIC", "-shared")

_FLAGS_BYTES: Final[tuple[bytes, ...]] = tuple(flag.encode() for flag in COMPILE_FLAGS)

#: Environment variable that turns code generation off (``OPTIK_NO_CODEGEN=1``).
NO_CODEGEN_ENV: Final[str] = "OPTIK_NO_CODEGEN"


@dataclass(frozen=True)
class CompileReport:
    """How a solver's functions were built.

    Attributes:
        compiled: whether the solver runs compiled C (else CasADi's SX virtual machine).
        seconds: time spent generating, compiling and loading (s); a library found in
            the cache costs only the generation and the load.
        cached: the library was found on disk (compiled by an earlier call or process).
        detail: the library's path, or why the SX functions are used.
    """

    compiled: bool
    seconds: float
    cached: bool
    detail: str


def _casadi_version() -> bytes:
    return str(getattr(casadi, "__version__", "?")).encode()


def cache_dir() -> Path:
    """Where compiled libraries are kept (see the module docstring)."""
    root = os.environ.get("OPTIK_CACHE_DIR")
    if root:
        return Path(root) / "casadi"
    xdg = os.environ.get("XDG_CACHE_HOME")
    base = Path(xdg) if xdg else Path.home() / ".cache"
    return base / "optik" / "casadi"


def find_compiler() -> str | None:
    """The C compiler to use: ``$CC``, else the first of ``cc``, ``gcc``, ``clang`` found."""
    env = os.environ.get("CC")
    if env:
        return shutil.which(env) or None
    for name in ("cc", "gcc", "clang"):
        path = shutil.which(name)
        if path:
            return path
    return None


def _compile(source: Path, target: Path, compiler: str) -> None:
    """Compile ``source`` into ``target`` atomically (a temporary file, then a rename)."""
    target.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{target.stem}.", suffix=".so", dir=target.parent)
    os.close(fd)
    try:
        subprocess.run(
            [compiler, *COMPILE_FLAGS, str(source), "-o", tmp, "-lm"],
            check=True,
            capture_output=True,
            text=True,
            timeout=600,
        )
        os.replace(tmp, target)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def compiled_nlpsol(
    name: str, plugin: str, solver: casadi.Function, options: dict[str, Any]
) -> tuple[casadi.Function, CompileReport]:
    """``solver`` rebuilt on its functions compiled to C, or ``solver`` itself on failure.

    Args:
        name: name of the new solver.
        plugin: its ``nlpsol`` plugin.
        solver: the solver built on SX expressions (``casadi.nlpsol``).
        options: the options ``solver`` was built with.

    Returns:
        The solver to use and how it was built (never raises for a build failure).
    """
    start = time.perf_counter()
    if os.environ.get(NO_CODEGEN_ENV, "") not in ("", "0"):
        return solver, CompileReport(False, 0.0, False, f"{NO_CODEGEN_ENV} is set")
    compiler = find_compiler()
    if compiler is None:
        return solver, CompileReport(False, 0.0, False, "no C compiler found (set CC)")
    try:
        # The program (the oracle "nlp") and the functions the solver calls (nlp_fg,
        # nlp_hess_l, ...), as one C file: what Function.generate_dependencies writes, but
        # returned as text (that method writes only into the working directory).
        generator = casadi.CodeGenerator(f"{name}.c")
        generator.add(solver.oracle())
        for function in solver.get_function():
            generator.add(solver.get_function(function))
        code = generator.dump().encode()
        digest = hashlib.sha256()
        for part in (code, _casadi_version(), compiler.encode(), *_FLAGS_BYTES):
            digest.update(part)
            digest.update(b"\0")
        target = cache_dir() / f"{name}_{digest.hexdigest()[:24]}.so"
        cached = target.is_file()
        if not cached:
            with tempfile.TemporaryDirectory(prefix="optik_nlp_") as tmp:
                source = Path(tmp) / f"{name}.c"
                source.write_bytes(code)
                _compile(source, target, compiler)
        built = casadi.nlpsol(name, plugin, str(target), options)
    except (OSError, RuntimeError, subprocess.SubprocessError) as exc:
        detail = getattr(exc, "stderr", None) or str(exc)
        return solver, CompileReport(
            False, time.perf_counter() - start, False, f"code generation failed: {detail}"[:400]
        )
    return built, CompileReport(True, time.perf_counter() - start, cached, str(target))
