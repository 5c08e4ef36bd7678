"""The kernel warm-up: workers' numba caches merged into a package's ``__pycache__``.

The merge is checked on a small package of its own (two signatures of one kernel,
compiled by two processes into separate cache folders, as ``optik._warmup.warm`` runs
them): a fresh process then loads both from the merged cache and compiles nothing.
"""

from __future__ import annotations

import json
import os
import pickle
import stat
import subprocess
import sys
import textwrap
from pathlib import Path
from typing import Any

import pytest

from optik._warmup import (
    FIRST,
    GROUPS,
    GROUPS_ENV,
    LAST,
    OPTIONAL,
    WarmReport,
    _count_entries,
    groups_from_environment,
    merge_caches,
    parse_groups,
    plan_stages,
    run_groups,
)
from optik.cli import main
from optik.errors import KernelCacheWarning, OptikError
from optik.problems import load_problem

CHECKOUT = Path(__file__).resolve().parent.parent

TOY = textwrap.dedent(
    """
    import numba

    @numba.njit(cache=True)
    def twice(x):
        return 2 * x
    """
)

# Calls ``twice`` with the given argument, then prints the dispatcher's cache statistics.
CALL = textwrap.dedent(
    """
    import json, sys
    from toy.kernels import twice
    value = twice(int(sys.argv[1]) if sys.argv[2] == "int" else float(sys.argv[1]))
    print(json.dumps({
        "value": value,
        "misses": sum(twice.stats.cache_misses.values()),
        "hits": sum(twice.stats.cache_hits.values()),
    }))
    """
)


def _call(root: Path, value: str, kind: str, cache: Path | None) -> dict[str, float]:
    env = {k: v for k, v in os.environ.items() if k != "NUMBA_CACHE_DIR"}
    env["PYTHONPATH"] = str(root)
    if cache is not None:
        env["NUMBA_CACHE_DIR"] = str(cache)
    done = subprocess.run(
        [sys.executable, "-c", CALL, value, kind],
        env=env,
        capture_output=True,
        text=True,
        check=True,
    )
    return dict(json.loads(done.stdout))


@pytest.fixture
def toy(tmp_path: Path) -> Path:
    package = tmp_path / "src" / "toy"
    package.mkdir(parents=True)
    (package / "__init__.py").write_text("")
    (package / "kernels.py").write_text(TOY)
    return package


def test_two_workers_caches_merge_into_one_that_a_fresh_process_loads(
    toy: Path, tmp_path: Path
) -> None:
    root = toy.parent
    first, second = tmp_path / "worker0", tmp_path / "worker1"
    # Each worker compiles its own signature of the same kernel into its own folder.
    assert _call(root, "3", "int", first) == {"value": 6, "misses": 1, "hits": 0}
    assert _call(root, "1.5", "float", second) == {"value": 3.0, "misses": 1, "hits": 0}
    # Both numbered their data file 1: copied side by side they would clash.
    assert sorted(p.name for p in first.rglob("*.nbc")) == sorted(
        p.name for p in second.rglob("*.nbc")
    )

    assert merge_caches([first, second], toy, root) == 2
    cached = sorted(p.name for p in (toy / "__pycache__").glob("kernels.twice*"))
    assert len([n for n in cached if n.endswith(".nbc")]) == 2
    assert len([n for n in cached if n.endswith(".nbi")]) == 1

    # A fresh process without NUMBA_CACHE_DIR finds both in the package's own cache.
    assert _call(root, "4", "int", None) == {"value": 8, "misses": 0, "hits": 1}
    assert _call(root, "2.5", "float", None) == {"value": 5.0, "misses": 0, "hits": 1}

    # Merging again adds nothing and keeps one file per signature.
    assert merge_caches([first, second], toy, root) == 0
    assert sorted(p.name for p in (toy / "__pycache__").glob("kernels.twice*")) == cached
    # What the warm-up reports as compiled: each worker's signature, and both merged.
    assert (_count_entries(first), _count_entries(second)) == (1, 1)
    assert _count_entries(toy / "__pycache__") == 2


def test_a_stale_index_is_replaced_not_extended(toy: Path, tmp_path: Path) -> None:
    root = toy.parent
    cache = tmp_path / "worker0"
    _call(root, "3", "int", cache)
    merge_caches([cache], toy, root)
    index = next((toy / "__pycache__").glob("*.nbi"))
    with open(index, "rb") as f:
        version = pickle.load(f)
        stamp, overloads = pickle.loads(f.read())
    # The source changes: the index left behind names code of the old source.
    stale = pickle.dumps(version) + pickle.dumps(("another source", overloads))
    index.write_bytes(stale)
    assert merge_caches([cache], toy, root) == 1
    with open(index, "rb") as f:
        pickle.load(f)
        assert pickle.loads(f.read())[0] == stamp
    assert _call(root, "5", "int", None) == {"value": 10, "misses": 0, "hits": 1}


def test_merged_files_are_readable_by_every_user(toy: Path, tmp_path: Path) -> None:
    # The wheel ships these files: a private (0600) file would leave other users of a
    # system-wide install without the kernels.
    worker = tmp_path / "worker"
    assert _call(toy.parent, "3", "int", worker)["misses"] == 1
    old = os.umask(0o022)
    try:
        assert merge_caches([worker], toy, toy.parent) == 1
    finally:
        os.umask(old)
    merged = list((toy / "__pycache__").glob("kernels.twice*"))
    assert len(merged) == 2
    assert all(stat.S_IMODE(path.stat().st_mode) == 0o644 for path in merged)


def test_the_merge_names_the_workers_folders_as_numba_does(toy: Path, tmp_path: Path) -> None:
    # Nothing compiled: nothing merged, no folder created.
    assert merge_caches([tmp_path / "empty"], toy, toy.parent) == 0
    assert not (toy / "__pycache__").exists()


@pytest.mark.parametrize("processes", [1, 2, 3, 5, 8])
def test_every_group_runs_once_whatever_the_number_of_processes(processes: int) -> None:
    stages = plan_stages(processes)
    planned = [name for stage in stages for worker in stage for name in worker]
    assert sorted(planned) == sorted(GROUPS)
    assert len(set(planned)) == len(planned)
    assert all(len(stage) <= max(processes, 1) for stage in stages)
    if processes > 1:  # the report runs last, on what the first stage compiled
        last = {name for worker in LAST for name in worker}
        assert {name for worker in stages[-1] for name in worker} == last
        assert last.isdisjoint(n for w in FIRST for n in w)
    if processes == 2:  # as planned
        assert stages == [list(FIRST), list(LAST)]


@pytest.mark.parametrize("processes", [1, 2, 3])
def test_a_subset_of_groups_runs_those_alone_in_their_stages(processes: int) -> None:
    stages = plan_stages(processes, ["batch", "closed_forms", "report"])
    planned = [name for stage in stages for worker in stage for name in worker]
    assert sorted(planned) == ["batch", "closed_forms", "report"]
    assert all(worker for stage in stages for worker in stage)
    if processes > 1:  # the report still runs after what the first stage compiled
        assert stages[-1] == [("report",)]
    assert plan_stages(processes, ["kinematics"]) == [[("kinematics",)]]
    with pytest.raises(ValueError, match="unknown warm-up groups"):
        plan_stages(processes, ["closed_forms", "no-such-group"])


def test_unknown_groups_are_refused() -> None:
    with pytest.raises(ValueError, match="unknown warm-up groups"):
        run_groups(["closed_forms", "no-such-group"])


def test_the_command_refuses_fewer_than_one_process(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["warmup", "--processes", "0"]) == 2
    assert "--processes must be at least 1" in capsys.readouterr().err


def test_the_command_says_how_many_kernels_it_compiled_and_how_many_were_new(
    capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    # A cache that held all but one kernel: 71 compiled, 1 new (it printed "1 kernels
    # compiled and cached"). The warm-up itself is stood in for: it takes a minute.
    import optik._warmup

    def warm(**options: object) -> WarmReport:
        assert options["processes"] == 3
        return WarmReport(kernels=1, seconds=57.06, stages=[], compiled=71)

    monkeypatch.setattr(optik._warmup, "warm", warm)
    assert main(["warmup", "--processes", "3"]) == 0
    assert capsys.readouterr().out == "71 kernels compiled in 57.1 s, 1 of them new to the cache\n"


def test_a_second_warm_up_finds_every_kernel_cached_and_runs_no_worker(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    # A second `optik warmup` compiled every kernel again (118 s, as the first): each
    # worker compiles into a fresh folder of its own. A probe now finds them cached.
    import optik._warmup

    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path / "cache"))
    first = optik._warmup.warm(processes=1, groups=["kinematics"])
    assert first.compiled > 0 and first.kernels == first.compiled and not first.cached
    second = optik._warmup.warm(processes=1, groups=["kinematics"])
    assert second.cached and second.compiled == second.kernels == 0
    assert main(["warmup", "--processes", "1", "--groups", "kinematics"]) == 0
    assert capsys.readouterr().out.startswith(
        "every kernel of the groups is cached already: none compiled ("
    )
    # Another cache (empty): the probe meets a compilation at once.
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path / "empty")}
    assert not optik._warmup.cached_already(["kinematics"], env)
    assert optik._warmup.cached_already(["kinematics"], dict(os.environ))


def test_a_merge_into_a_numba_cache_dir_serves_processes_that_use_it(
    toy: Path, tmp_path: Path
) -> None:
    root = toy.parent
    worker, shared = tmp_path / "worker0", tmp_path / "shared"
    _call(root, "3", "int", worker)
    assert merge_caches([worker], toy, shared, cache_dir=True) == 1
    assert not (toy / "__pycache__").exists()
    assert _call(root, "6", "int", shared) == {"value": 12, "misses": 0, "hits": 1}


def test_the_command_line_says_once_when_it_compiles_on_a_terminal() -> None:
    import io

    import numba

    from optik.cli import COMPILE_NOTICE, say_when_compiling

    class Terminal(io.StringIO):
        def isatty(self) -> bool:
            return True

    terminal, pipe = Terminal(), io.StringIO()
    say_when_compiling(terminal)
    say_when_compiling(terminal)  # registered once per stream
    say_when_compiling(pipe)  # not a terminal: silent
    numba.njit(lambda x: x + 1)(1)  # fresh functions: they compile
    numba.njit(lambda x: x + 2)(1)
    assert terminal.getvalue() == COMPILE_NOTICE + "\n"
    assert pipe.getvalue() == ""


def test_the_build_requires_what_the_warm_up_imports() -> None:
    # The wheel's build hook imports optik in the build's environment: every core
    # dependency must be a build requirement too, with the same bounds.
    try:
        import tomllib
    except ModuleNotFoundError:  # Python 3.10
        import tomli as tomllib  # type: ignore[no-redef]

    data = tomllib.loads((Path(__file__).resolve().parent.parent / "pyproject.toml").read_text())
    requires = set(data["build-system"]["requires"])
    assert set(data["project"]["dependencies"]) <= requires
    hook = data["tool"]["hatch"]["build"]["targets"]["wheel"]["hooks"]["custom"]
    assert hook == {"path": "hatch_build.py"}


@pytest.mark.parametrize("processes", [1, 2, 3])
def test_optional_groups_run_only_when_named_and_last(processes: int) -> None:
    """``held_joint`` and ``axes_arms`` are not the install's; named, they join the last
    stage (after the closed forms' pieces they share), one per worker in turn."""
    default = [name for stage in plan_stages(processes) for w in stage for name in w]
    assert not set(OPTIONAL) & set(default)
    named = [*GROUPS, *OPTIONAL]
    stages = plan_stages(processes, named)
    planned = [name for stage in stages for worker in stage for name in worker]
    assert sorted(planned) == sorted(named)
    if processes == 2:
        assert stages[-1] == [("report", "held_joint"), ("closed_form_batches", "axes_arms")]
    assert plan_stages(processes, ["axes_arms"]) == [[("axes_arms",)]]


def test_the_optional_groups_warm_the_families_they_name() -> None:
    """Each group's robot is solved by the family whose kernels it is meant to compile."""
    from optik._warmup import axes_arm_robot, rrp_wrist_robot
    from optik.analytic import family_of, free_joint_reason

    assert family_of(axes_arm_robot()).name == "spherical_axes"
    assert family_of(rrp_wrist_robot()).name == "rrp_wrist"
    panda = load_problem("panda").robot
    assert free_joint_reason(panda, panda.joint_names[6]) == ""


def test_the_command_refuses_an_unknown_group(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["warmup", "--groups", "closed_forms,no-such-group"]) == 2
    err = capsys.readouterr().err
    assert "unknown warm-up groups ['no-such-group']" in err and "axes_arms" in err


@pytest.mark.parametrize("given", [",", "", ",,"])
def test_the_command_refuses_groups_that_name_none(
    given: str, capsys: pytest.CaptureFixture[str]
) -> None:
    # "--groups ," compiled nothing and reported success.
    assert main(["warmup", "--groups", given]) == 2
    assert "--groups: no group named" in capsys.readouterr().err


def test_group_names_may_have_spaces_and_must_name_known_groups() -> None:
    assert parse_groups(" kinematics , rrp_wrist,", "--groups") == ["kinematics", "rrp_wrist"]
    with pytest.raises(OptikError, match=r"^--groups: no group named in ' , '$"):
        parse_groups(" , ", "--groups")
    with pytest.raises(OptikError, match=r"^\$X: unknown warm-up groups \['junk'\]; known: \["):
        parse_groups("kinematics,junk", "$X")


@pytest.mark.parametrize(
    ("value", "message"), [("junk", "unknown warm-up groups"), (",", "no group named")]
)
def test_a_bad_groups_variable_is_one_line_before_anything_compiles(
    value: str,
    message: str,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:
    # It was a 17-line traceback called an internal error (exit 3); "," compiled every group.
    import optik._warmup

    def no_stage(*args: object) -> None:
        raise AssertionError("a worker started")

    monkeypatch.setattr(optik._warmup, "_run_stage", no_stage)
    monkeypatch.setenv(GROUPS_ENV, value)
    assert main(["warmup"]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"optik: error: ${GROUPS_ENV}: {message}") and err.count("\n") == 1
    monkeypatch.setenv(GROUPS_ENV, "  ")  # blank: unset
    assert groups_from_environment() is None


def test_an_unwritable_cache_folder_is_refused_before_anything_compiles(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    # It compiled every kernel first, then failed in the merge as an internal error.
    import optik._warmup

    def no_stage(*args: object) -> None:
        raise AssertionError("a worker started")

    monkeypatch.setattr(optik._warmup, "_run_stage", no_stage)
    a_file = tmp_path / "cache"
    a_file.write_text("x")
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(a_file))
    assert main(["warmup", "--groups", "kinematics"]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"optik: error: cannot write the kernels into {a_file}: ")
    assert "NUMBA_CACHE_DIR" in err.splitlines()[0]


def test_a_package_numba_cannot_write_beside_is_warmed_into_the_users_cache(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    # numba reads a package's __pycache__ only where it can write it; elsewhere it keeps
    # the user's kernels in ~/.cache/numba (XDG_CACHE_HOME): the warm-up fills that one.
    import optik._warmup

    merged: list[tuple[Path, bool]] = []

    def merge(caches: object, package: Path, destination: Path, *, cache_dir: bool) -> int:
        merged.append((destination, cache_dir))
        return 0

    monkeypatch.delenv("NUMBA_CACHE_DIR", raising=False)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    monkeypatch.setattr(optik._warmup, "_writable", lambda package: False)
    monkeypatch.setattr(optik._warmup, "_run_stage", lambda *args: None)
    monkeypatch.setattr(optik._warmup, "_count_entries", lambda cache: 0)
    monkeypatch.setattr(optik._warmup, "merge_caches", merge)
    optik._warmup.warm(processes=1, groups=["kinematics"])
    assert merged[-1] == (tmp_path / "xdg" / "numba", True)
    assert (tmp_path / "xdg" / "numba").is_dir()


def _children(pid: int) -> list[int]:
    """Processes whose parent is ``pid`` (Linux /proc)."""
    found = []
    for stat_file in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat_file.read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        if int(fields[1]) == pid:
            found.append(int(stat_file.parent.name))
    return found


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="needs Linux /proc")
def test_a_terminated_warm_up_stops_its_workers_and_leaves_no_scratch(tmp_path: Path) -> None:
    # SIGTERM to the command alone ended it at once; its workers compiled on for a minute
    # and re-created the scratch folder that it had removed.
    import signal
    import time

    env = {**os.environ, "TMPDIR": str(tmp_path), "NUMBA_CACHE_DIR": str(tmp_path / "cache")}
    command = [sys.executable, "-m", "optik", "warmup", "--groups", "kinematics,rrp_wrist"]
    parent = subprocess.Popen(command, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    try:
        deadline = time.monotonic() + 60.0
        while len(workers := _children(parent.pid)) < 2:
            assert parent.poll() is None and time.monotonic() < deadline
            time.sleep(0.05)
        parent.send_signal(signal.SIGTERM)
        assert parent.wait(timeout=30.0) == 128 + signal.SIGTERM
    finally:
        if parent.poll() is None:
            parent.kill()
    for worker in workers:
        assert (
            not Path(f"/proc/{worker}").exists()
            or "Z" in Path(f"/proc/{worker}/stat").read_text().rsplit(")", 1)[1].split()[0]
        )
    assert not list(tmp_path.glob("optik-warmup-*"))


def test_without_a_writable_cache_place_kernels_compile_in_memory_with_a_warning(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    # numba raised "no locator available" at the first kernel's definition: import optik
    # failed for a service user without a home folder on a read-only install.
    from numba.core import caching

    from optik import _numba

    assert _numba._can_cache()
    monkeypatch.setattr(caching.CacheImpl, "_locator_classes", [])
    with pytest.warns(KernelCacheWarning, match="Set NUMBA_CACHE_DIR"):
        assert not _numba._can_cache()


class _App:
    """hatchling's Application, as the hook uses it."""

    def __init__(self) -> None:
        self.lines: list[str] = []

    def display_info(self, text: str) -> None:
        self.lines.append(text)

    display_warning = display_info


def _hook(tmp_path: Path, app: _App) -> Any:
    import importlib.util

    spec = importlib.util.spec_from_file_location("hatch_build", CHECKOUT / "hatch_build.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module.WarmKernelsHook(str(CHECKOUT), {}, None, None, str(tmp_path), "wheel", app=app)


@pytest.mark.parametrize("value", ["0", "false", "No", " off "])
def test_the_build_ships_no_kernels_when_the_warm_up_is_off(
    value: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("OPTIK_WARMUP", value)
    app = _App()
    build_data: dict[str, Any] = {"force_include": {}}
    _hook(tmp_path, app).initialize("standard", build_data)
    assert build_data == {"force_include": {}}
    assert app.lines == ["OPTIK_WARMUP is off: the wheel ships no compiled kernels"]


def test_the_build_stops_on_a_bad_groups_variable(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    # The wheel was built without kernels and the warning showed only with pip -v.
    monkeypatch.delenv("OPTIK_WARMUP", raising=False)
    monkeypatch.setenv(GROUPS_ENV, "junk")
    with pytest.raises(RuntimeError, match=r"refused its settings: .*unknown warm-up groups"):
        _hook(tmp_path, _App()).initialize("standard", {"force_include": {}})
