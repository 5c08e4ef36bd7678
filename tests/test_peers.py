"""Peer IK libraries (optik.peers) and ``optik report --peers``.

The report runs every peer the test extra installs on the UR5 and the Panda; the test
re-verifies each peer row from the joint vectors the run returns, with its own FK error
formulas, against targets it draws itself.
"""

from __future__ import annotations

import importlib.util
import json
import math
import os
from pathlib import Path

import numpy as np
import pytest
from conftest import load, robot_of

from optik.cli import build_parser, main
from optik.cli._common import urdf_problem
from optik.cli._report import config_from_args
from optik.compare import RunConfig, peer_solver, random_configurations
from optik.errors import OptikError
from optik.model import Robot
from optik.peers import (
    PEERS,
    PeerUnavailable,
    UnknownPeerError,
    available_peers,
    get_peer,
    peer_names,
)
from optik.peers._base import fk_mismatch, wrap_into_limits
from optik.peers._chain import ROOT_LINK, TOOL_LINK, urdf_text
from optik.peers.rtb import RTBPeer
from optik.problems import PROBLEMS_DIR
from optik.report import make_report

# The import names of the peers the test extra installs (pyproject.toml).
_MODULES = {
    "rtb": "roboticstoolbox",
    "ikpy": "ikpy",
    "pink": "pink",
    "eaik": "eaik",
    "pybullet": "pybullet",
}
MISSING = [n for n, m in _MODULES.items() if importlib.util.find_spec(m) is None]
# CI installs the test extra: there a missing peer is a failure, never a skip.
needs_peers = pytest.mark.skipif(
    bool(MISSING) and not os.environ.get("CI"),
    reason=f"peer libraries not installed here: {MISSING} (pip install -e '.[test]')",
)
TOL = 1e-6
N = 3


def _rotation_angle(R: np.ndarray) -> float:
    """Angle of a rotation from its quaternion's vector and scalar parts (an own formula)."""
    w = math.sqrt(max(0.0, 1.0 + float(np.trace(R)))) / 2.0
    v = np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]]) / 4.0
    return 2.0 * math.atan2(float(np.linalg.norm(v)), w) if w > 0 else math.pi


def _reference_verdict(robot: Robot, q: np.ndarray, T_target: np.ndarray) -> bool:
    T = robot.fk(q)
    position = float(np.linalg.norm(T[:3, 3] - T_target[:3, 3]))
    angle = _rotation_angle(T_target[:3, :3].T @ T[:3, :3])
    inside = bool(np.all(q >= robot.lower - 1e-12) and np.all(q <= robot.upper + 1e-12))
    return position <= TOL and angle <= TOL and inside


@needs_peers
def test_report_runs_every_peer_on_ur5_and_panda_and_each_success_re_verifies(
    tmp_path: Path,
) -> None:
    assert not MISSING, f"the test extra's peers are not installed: {MISSING}"
    config = RunConfig(
        problems=("ur5", "panda"),
        solvers=("auto",),
        n=N,
        seed=3,
        tol=TOL,
        timeout_s=0.5,
        closed_form_configs=0,
        seeds=False,
        peers=peer_names(),
    )
    report = make_report(config, tmp_path / "rep", progress=False)

    # One row per (problem, peer) of the table, in every output.
    assert [(p.problem, p.peer) for p in report.peers] == [
        (problem, peer) for problem in ("ur5", "panda") for peer in peer_names()
    ]
    markdown = report.markdown.read_text(encoding="utf-8")
    text = report.summary_text()
    html = report.index.read_text(encoding="utf-8")
    for p in report.peers:
        line = next(x for x in markdown.splitlines() if x.startswith(f"| {p.problem} | {p.peer} |"))
        assert (p.reason or p.notes[0]).replace("|", "\\|") in line
        assert any(x.split()[:2] == [p.problem, p.peer] for x in text.splitlines())
    assert 'id="peers"' in html

    # EAIK has no 7-joint solver: the Panda's row says so; every other peer ran.
    by_key = {(p.problem, p.peer): p for p in report.peers}
    eaik_panda = by_key["panda", "eaik"]
    assert not eaik_panda.ran and eaik_panda.n == 0 and "7" in eaik_panda.reason
    ran = [p for p in report.peers if p is not eaik_panda]
    assert all(p.ran and p.n == N for p in ran), [(p.peer, p.reason) for p in ran]

    # Re-verify every peer row: our targets, our FK error formulas, the run's joint vectors.
    rows = [r for r in report.stats.rows if r.solver.startswith("peer:")]
    assert len(rows) == N * len(ran)
    for problem in ("ur5", "panda"):
        robot = load(problem).robot
        targets = robot.fk(random_configurations(robot, problem, N, 3))
        for row in (r for r in rows if r.problem == problem):
            k = int(row.target[1:])
            q = report.stats.answers.get(row.key())
            ours = q is not None and _reference_verdict(robot, q, targets[k])
            assert row.success == ours, (row.solver, row.target, row.status, row.message)
            assert row.status == (
                "converged" if ours else ("rejected" if q is not None else "no_answer")
            )
    # The well-behaved peers solve these targets (a report of all-failures would pass above).
    for name in ("rtb", "pink", "ikpy"):
        for problem in ("ur5", "panda"):
            assert by_key[problem, name].success_rate == 1.0, (problem, name)
    assert by_key["ur5", "eaik"].success_rate == 1.0


def test_a_peer_that_is_not_installed_is_a_row_with_its_reason(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(RTBPeer, "module", "optik_no_such_module")
    info = {p.name: p for p in available_peers()}["rtb"]
    assert not info.installed and "optik_no_such_module" in info.reason
    config = RunConfig(
        problems=("planar_2r",),
        solvers=("auto",),
        n=1,
        closed_form_configs=0,
        seeds=False,
        peers=("rtb",),
    )
    report = make_report(config, tmp_path / "rep", progress=False)
    (row,) = report.peers
    assert not row.ran and "import optik_no_such_module failed" in row.reason
    assert "pip install roboticstoolbox-python" in row.reason
    assert row.reason in report.markdown.read_text(encoding="utf-8")
    assert not [r for r in report.stats.rows if r.solver == peer_solver("rtb")]


def test_bad_peer_names_exit_2_listing_the_valid_ones(capsys: pytest.CaptureFixture[str]) -> None:
    for value in ("rtb,nope", ","):
        with pytest.raises(SystemExit) as exit_info:
            main(["report", "--peers", value, "--out", "unused"])
        assert exit_info.value.code == 2
        err = capsys.readouterr().err
        assert "--peers" in err and "valid names: rtb,ikpy,pink,eaik,pybullet" in err
    with pytest.raises(UnknownPeerError, match="valid names: rtb, ikpy"):
        get_peer("nope")
    with pytest.raises(OptikError, match="unknown peer 'nope'"):
        RunConfig(problems=("ur5",), solvers=("auto",), peers=("nope",))


def test_registry_holds_one_adapter_per_peer() -> None:
    assert peer_names() == ("rtb", "ikpy", "pink", "eaik", "pybullet")
    assert {name: cls.name for name, cls in PEERS.items()} == {n: n for n in peer_names()}
    assert [p.name for p in available_peers()] == list(peer_names())


def test_adapter_options_are_keywords_stored_as_their_kind_of_number() -> None:
    peer = get_peer("pink", tol=1e-5, seed=np.int64(7), max_iter=12.0, restarts=np.int64(3))
    assert (peer.tol, peer.seed, peer.max_iter, peer.restarts) == (1e-5, 7, 12, 3)
    assert [type(v) for v in (peer.seed, peer.max_iter, peer.restarts)] == [int, int, int]
    assert json.loads(json.dumps(peer.settings()))["max_iter"] == 12
    assert get_peer("rtb", tol=1e-4).rtb_tol == pytest.approx(0.5e-8)  # ½·tol² by default
    assert get_peer("rtb", rtb_tol=1e-6).rtb_tol == 1e-6
    with pytest.raises(TypeError):
        PEERS["ikpy"](1e-6, 0, None, 10)  # options are keywords only
    for bad in ({"tol": 0.0}, {"tol": math.inf}, {"timeout_s": -1.0}):
        with pytest.raises(OptikError, match=next(iter(bad))):
            get_peer("ikpy", **bad)


@pytest.mark.parametrize("name", ["ur5", "panda", "stanford_arm", "jumbo_spherical_arm"])
def test_written_urdf_is_optiks_chain(name: str, rng: np.random.Generator) -> None:
    robot = robot_of(name)
    back = Robot.from_urdf(urdf_text(robot, "test"), ROOT_LINK, TOOL_LINK)
    assert back.dof == robot.dof
    np.testing.assert_array_equal(back.lower, robot.lower)
    np.testing.assert_array_equal(back.upper, robot.upper)
    assert fk_mismatch(back.fk, robot) < 1e-12


def test_fk_mismatch_finds_a_wrong_model_and_the_check_refuses_it() -> None:
    robot = robot_of("ur5")

    def wrong(q: np.ndarray) -> np.ndarray:
        T = robot.fk(q)
        T[0, 3] += 1e-8  # 10 nm off: above the 1e-9 bound
        return T

    assert 9e-9 < fk_mismatch(wrong, robot) < 1.1e-8
    assert fk_mismatch(lambda q: np.zeros((3, 4)), robot) == math.inf
    peer = get_peer("eaik")
    with pytest.raises(PeerUnavailable, match=r"FK differs from optik's by 1\.00e-08"):
        peer.check_fk(wrong, robot, "a wrong model")


def test_wrap_into_limits_moves_by_whole_turns_nearest_the_reference() -> None:
    lower, upper = np.array([-np.pi, -2 * np.pi]), np.array([np.pi, 2 * np.pi])
    q = np.array([3 * np.pi - 0.1, 0.5])
    out = wrap_into_limits(q, lower, upper, np.array([0.0, -5.0]))
    assert out is not None
    np.testing.assert_allclose(out, [np.pi - 0.1, 0.5 - 2 * np.pi])
    np.testing.assert_allclose(np.cos(out), np.cos(q))
    assert wrap_into_limits(np.array([2.0]), np.array([-0.5]), np.array([0.5]), np.zeros(1)) is None


@needs_peers
def test_peers_run_on_a_urdf_robot(tmp_path: Path) -> None:
    problem = urdf_problem(str(PROBLEMS_DIR / "panda.urdf"), "panda_link0", "panda_hand")
    config = RunConfig(
        problems=(problem,),
        solvers=("auto",),
        n=2,
        seed=1,
        tol=TOL,
        timeout_s=0.5,
        closed_form_configs=0,
        seeds=False,
        peers=("rtb", "pink"),
    )
    report = make_report(config, tmp_path / "rep", progress=False)
    assert [(p.peer, p.ran, p.n) for p in report.peers] == [("rtb", True, 2), ("pink", True, 2)]
    targets = problem.robot.fk(random_configurations(problem.robot, problem.name, 2, 1))
    rows = [r for r in report.stats.rows if r.solver.startswith("peer:")]
    assert len(rows) == 4
    for row in rows:
        q = report.stats.answers[row.key()]
        assert row.success and _reference_verdict(problem.robot, q, targets[int(row.target[1:])])


def test_cli_peers_option_reaches_the_run_configuration() -> None:
    args = build_parser().parse_args(["report", "--quick", "--peers", "eaik, rtb,eaik"])
    assert config_from_args(args).peers == ("eaik", "rtb")
    args = build_parser().parse_args(["report", "--problems", "ur5", "--peers", "pybullet"])
    assert config_from_args(args).peers == ("pybullet",)
    assert config_from_args(build_parser().parse_args(["report"])).peers == ()
