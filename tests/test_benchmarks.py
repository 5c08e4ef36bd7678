"""The benchmark harness: interleaved runs of two trees, and the scripts' ``--json`` figures.

The harness is exercised on fake source trees whose ``optik`` package only says which tree
it is and which figure to report in each run, so that the order of the runs, the exclusion
of the warm-up and every statistic can be checked against values worked out by hand.
"""

from __future__ import annotations

import importlib.util
import json
import math
import os
import statistics
import subprocess
import sys
from pathlib import Path
from types import ModuleType

import pytest

ROOT = Path(__file__).resolve().parent.parent
BENCH = ROOT / "benchmarks"


def _load(name: str) -> ModuleType:
    spec = importlib.util.spec_from_file_location(f"_bench_{name}", BENCH / f"{name}.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # dataclasses look their module up there
    spec.loader.exec_module(module)
    return module


interleave = _load("interleave")
record = _load("_record")

# A benchmark script stand-in: it reports, as its one figure, the value of its tree's
# optik.VALUES indexed by how many runs of that tree came before (the log counts them).
FAKE_SCRIPT = """
import sys
from pathlib import Path
sys.path.insert(0, {bench!r})
import _record
import optik
args = sys.argv[1:]
out = Path(args[args.index("--json") + 1])
tree = Path(optik.__file__).resolve().parent.parent.name
log = Path({log!r})
k = sum(line.split()[0] == tree for line in log.read_text().splitlines()) if log.exists() else 0
with log.open("a") as f:
    f.write(tree + " " + " ".join(args[:-2]) + "\\n")
meta = _record.optik_source()
if getattr(optik, "ELSEWHERE", False):
    meta["optik_path"] = "/nonexistent/optik"
figure = _record.metric("r: solve", "single", optik.VALUES[k] * 1e-6, 10,
                        success_rate=1.0, mean_iterations=optik.ITERATIONS)
_record.write_json(out, "fake", meta, [figure])
"""


def _fake_setup(tmp_path: Path, old: list[float], new: list[float], new_extra: str = "") -> Path:
    for name, values, extra in (("old", old, ""), ("new", new, new_extra)):
        package = tmp_path / name / "optik"
        package.mkdir(parents=True)
        (package / "__init__.py").write_text(f"VALUES = {values!r}\nITERATIONS = 4.0\n{extra}\n")
    scripts = tmp_path / "scripts"
    scripts.mkdir()
    source = FAKE_SCRIPT.format(bench=str(BENCH), log=str(tmp_path / "runs.log"))
    for script in ("bench_ik.py", "bench_analytic.py"):
        (scripts / script).write_text(source)
    return scripts


def _harness(tmp_path: Path, scripts: Path, *extra: str) -> int:
    return int(
        interleave.main(
            [
                "--old", str(tmp_path / "old"),
                "--new", str(tmp_path / "new"),
                "--scripts", str(scripts),
                "--bench", "ik",
                "--python", sys.executable,
                "--json", str(tmp_path / "out.json"),
                *extra,
            ]
        )
    )  # fmt: skip


def _runs(tmp_path: Path) -> list[str]:
    return [line.split()[0] for line in (tmp_path / "runs.log").read_text().splitlines()]


def test_runs_alternate_after_one_warm_up_per_tree_and_the_figures_are_paired_by_round(
    tmp_path: Path,
) -> None:
    # Warm-up figures (99) must be left out; rounds: old 1, 3, 2 and new 2, 3.3, 2.2.
    scripts = _fake_setup(tmp_path, old=[99.0, 1.0, 3.0, 2.0], new=[99.0, 2.0, 3.3, 2.2])
    assert _harness(tmp_path, scripts, "--rounds", "3") == 0
    assert _runs(tmp_path) == ["old", "new"] * 4
    (row,) = json.loads((tmp_path / "out.json").read_text())["figures"]
    assert row["old_us"] == pytest.approx([1.0, 3.0, 2.0])
    assert row["new_us"] == pytest.approx([2.0, 3.3, 2.2])
    assert row["old_median_us"] == pytest.approx(2.0)
    assert row["new_median_us"] == pytest.approx(2.2)
    assert row["ratio"] == pytest.approx(1.1)
    assert (row["ratio_min"], row["ratio_max"]) == pytest.approx((1.1, 2.0))
    assert row["best_ratio"] == pytest.approx(2.0)
    assert row["verdict"] == "SLOWER"
    assert row["answers"] == "same"


def test_abba_order_flips_every_other_round(tmp_path: Path) -> None:
    scripts = _fake_setup(tmp_path, old=[1.0] * 4, new=[1.0] * 4)
    assert _harness(tmp_path, scripts, "--rounds", "3", "--order", "abba") == 0
    assert _runs(tmp_path) == ["old", "new", "old", "new", "new", "old", "old", "new"]
    (row,) = json.loads((tmp_path / "out.json").read_text())["figures"]
    assert row["ratio"] == pytest.approx(1.0)
    assert row["verdict"] == "within"


def test_round_order_flips_only_in_abba() -> None:
    assert interleave.round_order(3, "alternate") == [("old", "new")] * 3
    assert interleave.round_order(3, "abba") == [("old", "new"), ("new", "old"), ("old", "new")]
    with pytest.raises(ValueError, match="order"):
        interleave.round_order(2, "random")


def test_faster_new_tree_and_changed_answers_are_reported(tmp_path: Path) -> None:
    scripts = _fake_setup(tmp_path, [1.0, 10.0, 10.0], [1.0, 9.0, 9.0], "ITERATIONS = 5.0")
    assert _harness(tmp_path, scripts, "--rounds", "2") == 0
    (row,) = json.loads((tmp_path / "out.json").read_text())["figures"]
    assert row["ratio"] == pytest.approx(0.9)
    assert row["verdict"] == "faster"
    assert row["answers"] == "mean_iterations 4.0 -> 5.0"


def test_peers_stay_out_unless_asked_and_extra_options_come_last(tmp_path: Path) -> None:
    scripts = _fake_setup(tmp_path, old=[1.0] * 3, new=[1.0] * 3)
    assert _harness(tmp_path, scripts, "--rounds", "1", "--extra", "ik=--batch-n 7") == 0
    line = (tmp_path / "runs.log").read_text().splitlines()[-1]
    assert "--no-peers" in line.split()
    assert line.endswith("--no-peers --batch-n 7")
    (tmp_path / "runs.log").unlink()
    assert _harness(tmp_path, scripts, "--rounds", "1", "--peers") == 0
    assert "--peers" in (tmp_path / "runs.log").read_text().splitlines()[-1].split()


def test_a_run_that_imported_optik_from_outside_its_tree_stops_the_comparison(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    scripts = _fake_setup(tmp_path, old=[1.0] * 3, new=[1.0] * 3, new_extra="ELSEWHERE = True")
    assert _harness(tmp_path, scripts, "--rounds", "1") == 1
    assert "imported optik from /nonexistent/optik" in capsys.readouterr().err
    assert not (tmp_path / "out.json").exists()


def test_a_folder_without_optik_is_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    scripts = _fake_setup(tmp_path, old=[1.0] * 3, new=[1.0] * 3)
    (tmp_path / "empty").mkdir()
    code = interleave.main(
        ["--old", str(tmp_path / "old"), "--new", str(tmp_path / "empty"),
         "--scripts", str(scripts), "--python", sys.executable]
    )  # fmt: skip
    assert code == 2
    assert "no optik/__init__.py" in capsys.readouterr().err


def test_a_failing_run_names_its_log(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    scripts = _fake_setup(tmp_path, old=[1.0] * 3, new=[1.0] * 3)
    (scripts / "bench_ik.py").write_text("raise SystemExit('broken benchmark')\n")
    assert _harness(tmp_path, scripts, "--rounds", "1") == 1
    err = capsys.readouterr().err
    assert "exited with 1" in err and "broken benchmark" in err


def test_load_above_the_core_count_is_flagged() -> None:
    assert interleave.load_warning(1.9, 2) == ""
    assert "reached 3.10 on 2 cores" in interleave.load_warning(3.1, 2)


def test_metric_turns_nan_into_null_so_the_file_stays_valid_json(tmp_path: Path) -> None:
    figure = record.metric("x", "batch", 2e-6, 5, runs_s=[math.nan, 1e-6], success_rate=math.nan)
    assert figure["success_rate"] is None and figure["runs_s"] == [None, 1e-6]
    record.write_json(tmp_path / "f.json", "s", {}, [figure])
    assert json.loads((tmp_path / "f.json").read_text())["metrics"] == [figure]
    with pytest.raises(ValueError, match="kind"):
        record.metric("x", "sometimes", 1.0, 1)


def test_git_commit_names_the_checkout_and_whether_its_optik_changed(tmp_path: Path) -> None:
    assert record.git_commit(tmp_path) == "?"  # not a checkout
    git = ["git", "-c", "user.name=t", "-c", "user.email=t@t", "-c", "commit.gpgsign=false"]
    (tmp_path / "optik").mkdir()
    (tmp_path / "optik" / "__init__.py").write_text("")
    (tmp_path / "notes.txt").write_text("")
    for cmd in (["init", "-q"], ["add", "."], ["commit", "-q", "-m", "one"]):
        subprocess.run([*git, *cmd], cwd=tmp_path, check=True, capture_output=True)
    rev = subprocess.check_output(["git", "rev-parse", "--short", "HEAD"], cwd=tmp_path, text=True)
    rev = rev.strip()
    (tmp_path / "notes.txt").write_text("a change outside optik/")
    assert record.git_commit(tmp_path) == rev
    (tmp_path / "optik" / "__init__.py").write_text("X = 1\n")
    assert record.git_commit(tmp_path) == rev + "+dirty"
    # The harness names its trees with the same function.
    assert interleave.git_commit(tmp_path) == rev + "+dirty"


def _run_script(script: str, tmp_path: Path, *args: str) -> dict[str, object]:
    out = tmp_path / f"{script}.json"
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    run = subprocess.run(
        [sys.executable, str(BENCH / script), *args, "--json", str(out)],
        cwd=tmp_path,
        env=env,
        check=True,
        capture_output=True,
        text=True,
    )
    (tmp_path / "out.txt").write_text(run.stdout)
    data: dict[str, object] = json.loads(out.read_text())
    assert data["meta"]["optik_path"] == str(ROOT / "optik")  # type: ignore[index]
    return data


def test_bench_analytic_json_figures(tmp_path: Path) -> None:
    data = _run_script(
        "bench_analytic.py", tmp_path,
        "--robots", "ur5", "--single", "4", "--batch", "30", "--repeat", "3", "--no-peers",
    )  # fmt: skip
    figures = {m["name"]: m for m in data["metrics"]}  # type: ignore[attr-defined]
    assert set(figures) == {
        "ur5: analytic_ik (limits, FK-verified)",
        "ur5: analytic_ik (no limits, FK-verified)",
        "ur5: analytic_ik_batch, N = 30",
    }
    for m in figures.values():
        assert m["seconds_per_query"] == statistics.median(m["runs_s"]) > 0
    assert figures["ur5: analytic_ik_batch, N = 30"]["kind"] == "batch"
    assert figures["ur5: analytic_ik_batch, N = 30"]["n"] == 30


def test_bench_analytic_urdf_arm_beside_eaik(tmp_path: Path) -> None:
    # A maker's URDF arm, against EAIK's UrdfRobot of the same file (both in the test extra).
    data = _run_script(
        "bench_analytic.py", tmp_path,
        "--robots", "urdf:kinova", "--single", "5", "--batch", "20", "--repeat", "3",
    )  # fmt: skip
    figures = {m["name"]: m for m in data["metrics"]}  # type: ignore[attr-defined]
    assert set(figures) == {
        "urdf:kinova: analytic_ik (limits, FK-verified)",
        "urdf:kinova: analytic_ik (no limits, FK-verified)",
        "urdf:kinova: analytic_ik_batch, N = 20",
        "urdf:kinova: EAIK IK (no limits, not verified)",
        "urdf:kinova: EAIK IK, then reading .Q and .is_LS",
        "urdf:kinova: EAIK IK_batched, 1 thread, N = 20",
    }
    for m in figures.values():
        assert len(m["runs_s"]) == 3 and m["seconds_per_query"] > 0
    printed = (tmp_path / "out.txt").read_text()
    # Eight exact branches per pose in both libraries (the Jaco 2's spherical wrist).
    assert (
        "urdf:kinova: branch count (optik without limits vs EAIK exact solutions) "
        "equal on 5/5 poses"
    ) in printed


def test_bench_ik_json_figures(tmp_path: Path) -> None:
    data = _run_script(
        "bench_ik.py", tmp_path,
        "--robots", "ur5", "-n", "3", "--solvers", "auto", "--no-q0-variants", "--no-peers",
        "--batch-n", "6", "--threads", "1", "--batch-repeat", "3",
    )  # fmt: skip
    figures = {m["name"]: m for m in data["metrics"]}  # type: ignore[attr-defined]
    assert set(figures) == {"ur5: optik auto", "ur5: optik solve_ik_batch (1 thread)"}
    single, batch = figures["ur5: optik auto"], figures["ur5: optik solve_ik_batch (1 thread)"]
    assert (single["kind"], single["n"], single["success_rate"]) == ("single", 3, 1.0)
    assert single["seconds_per_query"] > 0
    assert (batch["kind"], batch["n"], len(batch["runs_s"])) == ("batch", 6, 3)
    assert batch["seconds_per_query"] == pytest.approx(statistics.median(batch["runs_s"]))
