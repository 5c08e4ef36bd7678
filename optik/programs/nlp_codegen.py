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
  ``sqpmethod`` with its QP solver (DAQP): the SQP loop, the QP and the functions in one
  C function) and loads it with ``casadi.external``. It leaves out what CasADi's C++
  solver does around the numbers on every function call: a timing of each call with
  ``std::clock()``, which is a system call (``clock_gettime(CLOCK_PROCESS_CPUTIME_ID)``,
  1-2 µs here, about 70 per Panda solve). The Panda's solve of at most 8 SQP iterations
  takes about 50 µs compiled whole against 180 µs on the compiled functions (measured,
  the same iterates to the last bit). The generated code reports no statistics, so it is
  instrumented (:func:`instrument`): the loop's iteration count and its own convergence
  test are kept per thread and read back through one exported function.

Ipopt takes an iteration callback compiled to C (:func:`compiled_monitor`): it counts the
iterations (so a solve needs no ``stats()``, which costs 70 µs per Ipopt solve for its
per-iteration history) and stops Ipopt at the first iterate whose objective is below a
threshold set per solve (the task's tolerances, see
:func:`optik.solvers.casadi_nlp.stop_objective`).

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

import contextlib
import ctypes
import hashlib
import os
import re
import shutil
import signal
import string
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
    "Monitor",
    "cache_dir",
    "compiled_monitor",
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


MAX_CODE_BYTES = 2_000_000
"""Largest C code (bytes) compiled; larger programs run on CasADi's SX functions.
Measured: the ``sqpmethod`` solver of a pose is 0.13 MB of C for the Panda, 0.7-0.8 MB
for a chain of 20 joints (compiled in 5-12 s), 2 MB at about 35 joints (``ipopt``'s
functions at about 40), 4.1-4.5 MB for 60 joints (15-56 s) and 13 MB for 120 joints; a
200-joint chain's compile ran past 10 minutes."""

COMPILE_TIMEOUT_S = 600.0
"""Longest compile (s) before it is stopped (and the solver runs on the SX functions)."""


def _compile(
    source: Path, target: Path, compiler: str, flags: tuple[str, ...], libs: tuple[str, ...] = ()
) -> None:
    """Compile ``source`` into ``target`` atomically (a temporary file, then a rename).

    ``libs`` (linker arguments) follow the source, where a linker that drops libraries
    not yet needed (``--as-needed``) still links them. A compile that overruns
    :data:`COMPILE_TIMEOUT_S`, or whose caller is interrupted, is stopped with the
    processes it started (:func:`_stop_tree`): stopping the driver alone (``cc``) left its
    compiler proper (``cc1``) running. It stays in the caller's process group, so that a
    signal to that group (a terminal's Ctrl-C, ``timeout``) reaches it too.
    """
    target.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{target.stem}.", suffix=".so", dir=target.parent)
    os.close(fd)
    command = [compiler, *flags, str(source), "-o", tmp, "-lm", *libs]
    try:
        process = subprocess.Popen(
            command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
        )
        try:
            out, err = process.communicate(timeout=COMPILE_TIMEOUT_S)
        except BaseException:
            _stop_tree(process.pid)
            process.wait()
            raise
        if process.returncode != 0:
            raise subprocess.CalledProcessError(process.returncode, command, out, err)
        os.replace(tmp, target)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def _stop_tree(pid: int) -> None:
    """Kill process ``pid`` and its descendants (found in ``/proc``; elsewhere ``pid`` alone).

    ``pid`` is stopped first, so that it starts no other process while its tree is read.
    """
    with contextlib.suppress(ProcessLookupError):
        os.kill(pid, signal.SIGSTOP)
    for child in [*_descendants(pid), pid]:
        with contextlib.suppress(ProcessLookupError):
            os.kill(child, signal.SIGKILL)


def _descendants(pid: int) -> list[int]:
    """The processes below ``pid`` (Linux ``/proc``; empty where there is none)."""
    parents: dict[int, int] = {}
    for stat in Path("/proc").glob("[0-9]*/stat"):
        with contextlib.suppress(OSError, IndexError, ValueError):
            # The command name, in parentheses, may hold spaces: the fields follow it.
            parents[int(stat.parent.name)] = int(stat.read_text().rsplit(")", 1)[1].split()[1])
    found, frontier = [], [pid]
    while frontier:
        below = [child for child, parent in parents.items() if parent in frontier]
        found += below
        frontier = below
    return found


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


def _library(
    name: str, code: str, compiler: str, flags: tuple[str, ...], libs: tuple[str, ...] = ()
) -> tuple[Path, bool]:
    """The shared library of C ``code`` in the cache: ``(path, found on disk)``.

    Named by the SHA-256 of the code, the CasADi version, the compiler, its flags and the
    libraries linked (``libs``, as :func:`_compile` takes them).
    """
    data = code.encode()
    if len(data) > MAX_CODE_BYTES:
        raise RuntimeError(
            f"its C code ({len(data) / 1e6:.1f} MB) is larger than optik compiles "
            f"({MAX_CODE_BYTES / 1e6:.0f} MB; the compiler would take minutes)"
        )
    digest = hashlib.sha256()
    arguments = (*flags, *libs)
    for part in (data, _casadi_version(), compiler.encode(), *(f.encode() for f in arguments)):
        digest.update(part)
        digest.update(b"\0")
    target = cache_dir() / f"{name}_{digest.hexdigest()[:24]}.so"
    if target.is_file():
        return target, True
    with tempfile.TemporaryDirectory(prefix="optik_nlp_") as tmp:
        source = Path(tmp) / f"{name}.c"
        source.write_bytes(data)
        _compile(source, target, compiler, flags, libs)
    return target, False


def _qp_library(code: str) -> tuple[tuple[str, ...], tuple[str, ...]]:
    """The compiler flags and linker arguments of the QP solver that ``code`` calls.

    CasADi's generated code of a ``daqp`` QP includes DAQP's header and calls its
    library; CasADi's wheel ships both (``casadi/include/daqp``, ``libdaqp.so``). Code
    of CasADi's own ``qrqp`` needs neither.
    """
    if "<daqp/" not in code:
        return (), ()
    folder = Path(casadi.__file__).resolve().parent
    return (f"-I{folder / 'include'}",), (f"-L{folder}", "-ldaqp", f"-Wl,-rpath,{folder}")


# The SQP loop's convergence test in CasADi's generated sqpmethod code, e.g.
# ``if (iter_count >= 0 && pr_inf < 1e-10 && du_inf < 1e-10) break;``: evaluated at the
# top of every iteration, before the iteration limit and the step-size test.
_CONVERGENCE_TEST = re.compile(
    r"^(?P<indent>[ \t]*)if \((?P<test>iter_count >= \d+ && pr_inf < [^&]+ && du_inf < [^)]+)\)"
    r" break;$",
    re.MULTILINE,
)


# The memory pool of each generated function: ``int casadi_f4_checkout(void) {`` and
# ``void casadi_f4_release(int mem) {`` (names of the form casadi_f<N>).
_POOL_FUNCTION = re.compile(
    r"^(?P<kind>int|void) (?P<name>casadi_f\d+)_(?P<op>checkout|release)"
    r"\((?P<args>void|int mem)\) \{$",
    re.MULTILINE,
)


def _locked_pools(code: str) -> str:
    """``code`` whose memory pools are taken and given back under a lock per function.

    CasADi's generated checkout and release keep a static stack without a lock, and the
    SQP loop checks out its QP solver's memory on every iteration (DAQP's), so two
    threads solving at once could take the same memory: each function gets a mutex.
    """

    def locked(match: re.Match[str]) -> str:
        kind, name, op, args = match.group("kind", "name", "op", "args")
        lock = f"optik_pool_lock_{name}"
        inner = f"{name}_{op}_unlocked"
        call = f"{inner}()" if op == "checkout" else f"{inner}(mem)"
        body = (
            f"  int got;\n  pthread_mutex_lock(&{lock});\n  got = {call};\n"
            f"  pthread_mutex_unlock(&{lock});\n  return got;\n"
            if kind == "int"
            else f"  pthread_mutex_lock(&{lock});\n  {call};\n  pthread_mutex_unlock(&{lock});\n"
        )
        return (
            f"static {kind} {inner}({args});\n"
            f"{kind} {name}_{op}({args}) {{\n{body}}}\n"
            f"static {kind} {inner}({args}) {{"
        )

    names = sorted({match.group("name") for match in _POOL_FUNCTION.finditer(code)})
    locks = "".join(
        f"static pthread_mutex_t optik_pool_lock_{name} = PTHREAD_MUTEX_INITIALIZER;\n"
        for name in names
    )
    return "#include <pthread.h>\n" + locks + _POOL_FUNCTION.sub(locked, code)


def instrument(code: str) -> str | None:
    """CasADi's generated ``sqpmethod`` code that also reports how its last solve ended.

    Before its convergence test, each SQP iteration stores the iteration count and the
    test's outcome in two thread-local variables; the exported ``optik_solve_info()``
    returns ``2 * iterations + converged`` of the calling thread's last solve (the
    ``iter_count`` and ``success`` of ``casadi.nlpsol``'s ``stats()``). Every exit of
    the loop follows that test except a failed function evaluation, which the solver
    reports as an error. Every generated memory pool is taken and given back under a
    lock (:func:`_locked_pools`). Returns ``None`` when the test is not found exactly once (a
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
    code = code[: match.start()] + counted + code[match.end() :]
    return header + _locked_pools(code) + footer


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
        solver: a ``sqpmethod`` solver whose QP solver CasADi generates code for (DAQP,
            qrqp).

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
        extra_flags, libs = _qp_library(code)
        target, cached = _library(name, code, compiler, (*flags, *extra_flags), libs)
        function = casadi.external(name, str(target))
        info = getattr(ctypes.CDLL(str(target)), INFO_SYMBOL)
        info.restype = ctypes.c_longlong
        info.argtypes = []
    except (OSError, RuntimeError, AttributeError, subprocess.SubprocessError) as exc:
        return None, _failed(exc, start)
    report = CompileReport(True, time.perf_counter() - start, cached, str(target))
    return CompiledSolver(function, target, info), report


# CasADi's C API of external functions (the symbols casadi.external reads), for a
# function with casadi.nlpsol's outputs as inputs: what an iteration callback takes.
_MONITOR_SOURCE = string.Template(
    r"""/* optik: an iteration callback of casadi.nlpsol, compiled (optik.programs.nlp_codegen).
   Counts the calls and returns 1 (stop) once the objective is at most the threshold of
   the calling thread's solve (optik_monitor_start). */
#include <math.h>
#define casadi_int long long int
#define casadi_real double

static _Thread_local long long optik_calls = 0;
static _Thread_local int optik_stopped = 0;
static _Thread_local double optik_stop_objective = -1.0;

static const casadi_int sp_x[] = {$nx, 1, 0, $nx, $rows_x};
static const casadi_int sp_p[] = {$np, 1, 0, $np, $rows_p};
static const casadi_int sp_scalar[] = {1, 1, 0, 1, 0};
static const casadi_int sp_empty[] = {0, 1, 0, 0};
static const char* names_in[] = {"x", "f", "g", "lam_x", "lam_g", "lam_p"};

int optik_monitor_casadi_int_size(void) { return (int) sizeof(casadi_int); }
int optik_monitor_casadi_real_size(void) { return (int) sizeof(casadi_real); }
casadi_int optik_monitor_n_in(void) { return 6; }
casadi_int optik_monitor_n_out(void) { return 1; }
const char* optik_monitor_name_in(casadi_int i) { return i >= 0 && i < 6 ? names_in[i] : 0; }
const char* optik_monitor_name_out(casadi_int i) { return i == 0 ? "ret" : 0; }
const casadi_int* optik_monitor_sparsity_in(casadi_int i) {
  switch (i) {
    case 0: case 3: return sp_x;
    case 1: return sp_scalar;
    case 2: case 4: return sp_empty;
    case 5: return sp_p;
    default: return 0;
  }
}
const casadi_int* optik_monitor_sparsity_out(casadi_int i) { return i == 0 ? sp_scalar : 0; }
int optik_monitor_work(casadi_int* sz_arg, casadi_int* sz_res, casadi_int* sz_iw,
                       casadi_int* sz_w) {
  if (sz_arg) *sz_arg = 6;
  if (sz_res) *sz_res = 1;
  if (sz_iw) *sz_iw = 0;
  if (sz_w) *sz_w = 0;
  return 0;
}
int optik_monitor(const casadi_real** arg, casadi_real** res, casadi_int* iw, casadi_real* w,
                  int mem) {
  /* The objective comes only with Ipopt's full callback: without it, never stop. */
  double f = arg[1] ? arg[1][0] : INFINITY;
  optik_calls += 1;
  optik_stopped = f <= optik_stop_objective;
  if (res[0]) res[0][0] = optik_stopped;
  return 0;
}
void optik_monitor_start(double stop_objective) {
  optik_calls = 0;
  optik_stopped = 0;
  optik_stop_objective = stop_objective;
}
long long optik_monitor_info(void) { return 2 * optik_calls + optik_stopped; }
"""
)


@dataclass(frozen=True, eq=False)
class Monitor:
    """An iteration callback compiled to C (:func:`compiled_monitor`).

    Attributes:
        function: the callback (``casadi.external``), for ``nlpsol``'s
            ``iteration_callback`` option.
        path: the shared library.
    """

    function: casadi.Function
    path: Path
    _start: Any
    _info: Any

    def start(self, stop_objective: float) -> None:
        """Arm the calling thread's next solve: stop at an objective <= ``stop_objective``.

        A negative value never stops (the callback only counts).
        """
        self._start(stop_objective)

    def last_solve(self) -> tuple[int, bool]:
        """``(iterations, stopped)`` of the calling thread's last solve.

        Ipopt calls back once per iteration and once before the first, so the count is
        ``stats()["iter_count"]``.
        """
        info = int(self._info())
        return max((info >> 1) - 1, 0), bool(info & 1)


def compiled_monitor(nx: int, n_parameters: int) -> tuple[Monitor | None, CompileReport]:
    """The iteration callback of a program with ``nx`` variables and ``n_parameters``.

    Returns:
        The monitor, or ``None`` with the reason in the report (no compiler,
        ``OPTIK_NO_CODEGEN``, a failing compiler); never raises for a build failure.
    """
    start = time.perf_counter()
    compiler, refusal = _compiler_or_reason()
    if compiler is None:
        return None, CompileReport(False, 0.0, False, refusal)
    code = _MONITOR_SOURCE.substitute(
        nx=nx,
        np=n_parameters,
        rows_x=", ".join(str(i) for i in range(nx)),
        rows_p=", ".join(str(i) for i in range(n_parameters)),
    )
    try:
        target, cached = _library(
            f"optik_monitor_{nx}_{n_parameters}", code, compiler, COMPILE_FLAGS
        )
        function = casadi.external("optik_monitor", str(target))
        library = ctypes.CDLL(str(target))
        start_solve = library.optik_monitor_start
        start_solve.restype = None
        start_solve.argtypes = [ctypes.c_double]
        info = library.optik_monitor_info
        info.restype = ctypes.c_longlong
        info.argtypes = []
    except (OSError, RuntimeError, AttributeError, subprocess.SubprocessError) as exc:
        return None, _failed(exc, start)
    report = CompileReport(True, time.perf_counter() - start, cached, str(target))
    return Monitor(function, target, start_solve, info), report
