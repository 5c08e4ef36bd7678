"""The nonlinear IK program's solvers as compiled C, cached on disk.

CasADi evaluates an SX function in its virtual machine; the same function generated as C
and compiled runs several times faster (the Panda's ``sqpmethod`` solve: 1.25 ms with
the SX functions, 0.38 ms compiled, measured). Two forms:

- :func:`compiled_nlpsol` generates the C code of every function a solver calls
  (``Function.generate_dependencies``: objective, gradient, Hessian of the Lagrangian,
  ...), compiles it once into a shared library with the machine's C compiler, and builds
  the solver on it (``casadi.nlpsol(name, plugin, "<library>.so", options)``). Ipopt runs
  this way.
- :func:`compiled_solver` generates the *whole* solver as C (CasADi's code generation of
  ``sqpmethod`` with its QP solver ``qrqp``: the SQP loop, the QP and the functions in one
  C function) and loads it with ``casadi.external``. It leaves out what CasADi's C++
  solver does around the numbers on every function call: a timing of each call with
  ``std::clock()``, which is a system call (``clock_gettime(CLOCK_PROCESS_CPUTIME_ID)``,
  1-2 µs here, about 70 per Panda solve). The Panda's solve of at most 8 SQP iterations
  takes about 50 µs compiled whole against 180 µs on the compiled functions (measured,
  the same iterates to the last bit). The generated code reports no statistics, so it is
  instrumented (:func:`instrument`): the loop's iteration count and its own convergence
  test are kept per thread and read back through one exported function.

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

import ctypes
import hashlib
import os
import re
import shutil
import subprocess
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Final

import casadi

__all__ = [
    "COMPILE_FLAGS",
    "MAX_THREADS",
    "CompileReport",
    "CompiledSolver",
    "cache_dir",
    "compiled_nlpsol",
    "compiled_solver",
    "find_compiler",
    "instrument",
]

#: Flags of the C compiler. ``-O1`` compiles the Panda's functions in about half the time
#: of ``-O2`` for the same solve time (measured); ``-fPIC -shared`` make a loadable library.
COMPILE_FLAGS: Final[tuple[str, ...]] = ("-O1", "-fPIC", "-shared")

#: Threads that may run one whole compiled solver at the same time. Its generated code
#: keeps one memory slot per caller (``CASADI_MAX_NUM_THREADS``); every
#: ``casadi.FunctionBuffer`` holds one slot for its lifetime and does not check that one
#: is left (an exhausted pool crashes), so callers bound their buffers below this
#: (:class:`CompiledSolver` is the only owner of buffers).
MAX_THREADS: Final[int] = 64

#: The exported function of an instrumented solver library (see :func:`instrument`).
INFO_SYMBOL: Final[str] = "optik_solve_info"

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


def _compile(source: Path, target: Path, compiler: str, flags: tuple[str, ...]) -> None:
    """Compile ``source`` into ``target`` atomically (a temporary file, then a rename)."""
    target.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{target.stem}.", suffix=".so", dir=target.parent)
    os.close(fd)
    try:
        subprocess.run(
            [compiler, *flags, str(source), "-o", tmp, "-lm"],
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
    compiler, refusal = _compiler_or_reason()
    if compiler is None:
        return solver, CompileReport(False, 0.0, False, refusal)
    try:
        # The program (the oracle "nlp") and the functions the solver calls (nlp_fg,
        # nlp_hess_l, ...), as one C file: what Function.generate_dependencies writes, but
        # returned as text (that method writes only into the working directory).
        generator = casadi.CodeGenerator(f"{name}.c")
        generator.add(solver.oracle())
        for function in solver.get_function():
            generator.add(solver.get_function(function))
        target, cached = _library(name, generator.dump(), compiler, COMPILE_FLAGS)
        built = casadi.nlpsol(name, plugin, str(target), options)
    except (OSError, RuntimeError, subprocess.SubprocessError) as exc:
        return solver, _failed(exc, start)
    return built, CompileReport(True, time.perf_counter() - start, cached, str(target))


def _compiler_or_reason() -> tuple[str | None, str]:
    """The C compiler, or ``None`` and why code generation is not used."""
    if os.environ.get(NO_CODEGEN_ENV, "") not in ("", "0"):
        return None, f"{NO_CODEGEN_ENV} is set"
    compiler = find_compiler()
    if compiler is None:
        return None, "no C compiler found (set CC)"
    return compiler, ""


def _failed(exc: BaseException, start: float) -> CompileReport:
    detail = getattr(exc, "stderr", None) or str(exc)
    return CompileReport(
        False, time.perf_counter() - start, False, f"code generation failed: {detail}"[:400]
    )


def _library(name: str, code: str, compiler: str, flags: tuple[str, ...]) -> tuple[Path, bool]:
    """The shared library of C ``code`` in the cache: ``(path, found on disk)``.

    Named by the SHA-256 of the code, the CasADi version, the compiler and its flags.
    """
    data = code.encode()
    digest = hashlib.sha256()
    for part in (data, _casadi_version(), compiler.encode(), *(f.encode() for f in flags)):
        digest.update(part)
        digest.update(b"\0")
    target = cache_dir() / f"{name}_{digest.hexdigest()[:24]}.so"
    if target.is_file():
        return target, True
    with tempfile.TemporaryDirectory(prefix="optik_nlp_") as tmp:
        source = Path(tmp) / f"{name}.c"
        source.write_bytes(data)
        _compile(source, target, compiler, flags)
    return target, False


# The SQP loop's convergence test in CasADi's generated sqpmethod code, e.g.
# ``if (iter_count >= 0 && pr_inf < 1e-10 && du_inf < 1e-10) break;``: evaluated at the
# top of every iteration, before the iteration limit and the step-size test.
_CONVERGENCE_TEST = re.compile(
    r"^(?P<indent>[ \t]*)if \((?P<test>iter_count >= \d+ && pr_inf < [^&]+ && du_inf < [^)]+)\)"
    r" break;$",
    re.MULTILINE,
)


def instrument(code: str) -> str | None:
    """CasADi's generated ``sqpmethod`` code that also reports how its last solve ended.

    Before its convergence test, each SQP iteration stores the iteration count and the
    test's outcome in two thread-local variables; the exported ``optik_solve_info()``
    returns ``2 * iterations + converged`` of the calling thread's last solve (the
    ``iter_count`` and ``success`` of ``casadi.nlpsol``'s ``stats()``). Every exit of
    the loop follows that test except a failed function evaluation, which the solver
    reports as an error. Returns ``None`` when the test is not found exactly once (a
    CasADi whose generated code reads otherwise): then the solver is not compiled whole.
    """
    matches = list(_CONVERGENCE_TEST.finditer(code))
    if len(matches) != 1:
        return None
    match = matches[0]
    indent, test = match.group("indent"), match.group("test")
    counted = (
        f"{indent}optik_iterations = iter_count;\n"
        f"{indent}optik_converged = ({test});\n"
        f"{indent}if (optik_converged) break;"
    )
    header = (
        "/* optik: how the calling thread's last solve ended. */\n"
        "static _Thread_local long long optik_iterations = 0;\n"
        "static _Thread_local int optik_converged = 0;\n"
    )
    footer = (
        f"\nCASADI_SYMBOL_EXPORT long long {INFO_SYMBOL}(void) {{\n"
        "  return 2 * optik_iterations + optik_converged;\n}\n"
    )
    return header + code[: match.start()] + counted + code[match.end() :] + footer


@dataclass(frozen=True, eq=False)
class CompiledSolver:
    """A whole solver compiled to C (:func:`compiled_solver`).

    Attributes:
        function: the solver as a ``casadi.Function`` (``casadi.external``), with the
            inputs and outputs of ``casadi.nlpsol``; call it through ``buffer()`` (at most
            :data:`MAX_THREADS` - 1 buffers at a time).
        path: the shared library.
    """

    function: casadi.Function
    path: Path
    _info: Any

    def last_solve(self) -> tuple[int, bool]:
        """``(iterations, converged)`` of the calling thread's last solve."""
        info = int(self._info())
        return info >> 1, bool(info & 1)


def compiled_solver(solver: casadi.Function) -> tuple[CompiledSolver | None, CompileReport]:
    """``solver`` (a ``casadi.nlpsol``) generated whole as C, compiled and loaded.

    The compiled function and its library take the solver's name.

    Args:
        solver: a ``sqpmethod`` solver with ``qrqp`` as its QP solver (CasADi generates
            code for those).

    Returns:
        The compiled solver, or ``None`` with the reason in the report (no compiler,
        ``OPTIK_NO_CODEGEN``, code CasADi cannot generate or :func:`instrument` cannot
        read, a failing compiler); never raises for a build failure.
    """
    start = time.perf_counter()
    compiler, refusal = _compiler_or_reason()
    if compiler is None:
        return None, CompileReport(False, 0.0, False, refusal)
    name = solver.name()
    try:
        generator = casadi.CodeGenerator(f"{name}.c")
        generator.add(solver)
        code = instrument(generator.dump())
        if code is None:
            return None, CompileReport(
                False,
                time.perf_counter() - start,
                False,
                "code generation failed: the generated SQP loop has no convergence test "
                "to instrument",
            )
        flags = (*COMPILE_FLAGS, f"-DCASADI_MAX_NUM_THREADS={MAX_THREADS}")
        target, cached = _library(name, code, compiler, flags)
        function = casadi.external(name, str(target))
        info = getattr(ctypes.CDLL(str(target)), INFO_SYMBOL)
        info.restype = ctypes.c_longlong
        info.argtypes = []
    except (OSError, RuntimeError, AttributeError, subprocess.SubprocessError) as exc:
        return None, _failed(exc, start)
    report = CompileReport(True, time.perf_counter() - start, cached, str(target))
    return CompiledSolver(function, target, info), report
