"""``solve_ik`` with frozen joints answers with the closed form where one exists.

A seven-joint arm with exactly one joint frozen, whose other six fit the held-joint form
(the Panda's joint 7, the iiwa's joint 3), is solved by ``analytic_ik(free_joint=...)``:
the answer is a branch (solver ``"analytic"``), and an empty set of branches is a proof,
cross-checked by a short numeric search. A six-joint arm with a family takes a branch
whose frozen joint matches the value to rounding. References are independent of the
closed form: the robot's FK, the configuration a pose came from, and a numeric search
that does not start from the closed form (``warm_start="q0"``).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pybullet_data  # the test extra: its absence is a failure, not a skip
import pytest
from conftest import FakeClock

import optik
from optik import Robot, load_problem
from optik._clock import budget_clock, excluded_seconds
from optik.analytic import free_joint_reason, held_joint
from optik.errors import OptikError
from optik.spatial import rotation_angle

IIWA_URDF = Path(pybullet_data.getDataPath()) / "kuka_iiwa" / "model.urdf"
PANDA = load_problem("panda").robot
Q7 = "panda_joint7"
FK_TOL = 1e-10


@pytest.fixture(scope="module")
def iiwa() -> Robot:
    return Robot.from_urdf(IIWA_URDF, "lbr_iiwa_link_0", "lbr_iiwa_link_7")


def _reaches(robot: Robot, q: np.ndarray, T: np.ndarray, tol: float = FK_TOL) -> bool:
    reached = robot.fk(q)
    position = float(np.linalg.norm(reached[:3, 3] - T[:3, 3]))
    return position <= tol and rotation_angle(reached[:3, :3].T @ T[:3, :3]) <= tol


def test_free_joint_reason_names_the_joints_with_a_closed_form(iiwa: Robot) -> None:
    assert free_joint_reason(PANDA, Q7) == ""
    # The iiwa: joints 1, 3, 5, 7; not the elbow, nor 2 or 6 (held at 0 they align two
    # of the other axes: a degenerate six).
    held = [n for n in iiwa.joint_names if not free_joint_reason(iiwa, n)]
    assert held == [f"lbr_iiwa_joint_{k}" for k in (1, 3, 5, 7)]
    assert "does not change the distance" in free_joint_reason(iiwa, "lbr_iiwa_joint_4")
    assert "are parallel" in free_joint_reason(iiwa, "lbr_iiwa_joint_2")
    assert "the other six joints" in free_joint_reason(PANDA, "panda_joint3")
    puma = load_problem("puma560").robot
    assert free_joint_reason(puma, puma.joint_names[0])  # six joints: nothing to hold
    with pytest.raises(OptikError, match="free_joint must name a joint"):
        free_joint_reason(PANDA, "elbow")
    with pytest.raises(OptikError, match=r"robot must be an optik\.Robot"):
        free_joint_reason("panda", Q7)  # type: ignore[arg-type]


def test_the_held_joint_setup_is_not_counted_against_a_timeout(
    fake_clock: FakeClock, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Finding the form around a joint (tens of ms, once per robot and joint) is a robot's
    one-time setup: the budget clock of ``timeout_s`` stops while it runs."""
    # The search "takes" 1 s of the test's clock (no load on the machine moves it), and
    # the budget clock must not see any of it.
    find = held_joint.free_joint.free_joint_plan
    searches: list[int] = []

    def slow_find(robot: Robot, k: int) -> object:
        searches.append(k)
        plan = find(robot, k)
        fake_clock.advance(1.0)
        return plan

    monkeypatch.setattr(held_joint.free_joint, "free_joint_plan", slow_find)
    fresh = load_problem("panda").robot  # a new Robot: nothing cached
    wall, budget, excluded = fake_clock.now, budget_clock(), excluded_seconds()
    assert free_joint_reason(fresh, Q7) == ""
    assert searches == [6]  # the search ran, here
    assert fake_clock.now - wall == pytest.approx(1.0, abs=1e-9)
    assert excluded_seconds() - excluded == pytest.approx(1.0, abs=1e-9)
    assert budget_clock() - budget == pytest.approx(0.0, abs=1e-9)


def test_panda_with_q7_frozen_answers_with_a_branch() -> None:
    rng = np.random.default_rng(31)
    for q in rng.uniform(PANDA.lower, PANDA.upper, (40, 7)):
        T = PANDA.fk(q)
        res = optik.solve_ik(PANDA, T, frozen={Q7: float(q[6])})
        assert (res.success, res.solver, res.status) == (True, "analytic", "converged")
        assert res.q[6] == q[6]
        assert PANDA.within_limits(res.q) and _reaches(PANDA, res.q, T)


def test_every_branch_and_the_source_among_the_answers(iiwa: Robot) -> None:
    """``solve_ik_all`` returns every in-limit branch: the pose's own configuration too."""
    rng = np.random.default_rng(32)
    for robot, k in ((PANDA, 6), (iiwa, 2)):
        name = robot.joint_names[k]
        for q in rng.uniform(robot.lower, robot.upper, (10, 7)):
            T = robot.fk(q)
            answers = optik.solve_ik_all(robot, T, k=16, frozen={name: float(q[k])})
            assert answers and all(r.solver == "analytic" for r in answers)
            for r in answers:
                assert r.q[k] == q[k] and _reaches(robot, r.q, T)
            nearest = min(float(np.max(np.abs(r.q - q))) for r in answers)
            assert nearest < 1e-8


def test_the_nearest_answer_is_the_branch_nearest_q0() -> None:
    rng = np.random.default_rng(33)
    q = rng.uniform(PANDA.lower, PANDA.upper)
    T = PANDA.fk(q)
    frozen = {Q7: float(q[6])}
    answers = optik.solve_ik_all(PANDA, T, k=16, frozen=frozen)
    for q0 in rng.uniform(PANDA.lower, PANDA.upper, (5, 7)):
        q0[6] = q[6]
        res = optik.solve_ik(PANDA, T, q0=q0, frozen=frozen)
        distances = [float(np.linalg.norm(r.q - q0)) for r in answers]
        assert np.linalg.norm(res.q - q0) == pytest.approx(min(distances), abs=1e-9)


def test_no_branch_with_the_joint_there_is_a_cross_checked_proof() -> None:
    """A pose whose q7 is turned far away: the closed form finds no branch, the result
    says why, and a numeric search that does not start from it finds nothing either."""
    rng = np.random.default_rng(34)
    proofs = 0
    for q in rng.uniform(PANDA.lower, PANDA.upper, (40, 7)):
        q[3] = -0.15  # near full stretch: few q7 values reach the pose
        T = PANDA.fk(q)
        other = q[6] - 2.5 if q[6] > 0 else q[6] + 2.5
        res = optik.solve_ik(PANDA, T, frozen={Q7: other})
        if res.success:
            assert res.q[6] == other and _reaches(PANDA, res.q, T, 1e-6)
            continue
        assert res.solver == "analytic" and res.status in ("unreachable", "outside_limits")
        assert f"closed form with {Q7!r} at" in res.message
        proofs += 1
        if proofs <= 4:
            searched = optik.solve_ik(PANDA, T, frozen={Q7: other}, warm_start="q0", restarts=30)
            assert not searched.success
    assert proofs >= 4


def test_a_margin_makes_the_closed_form_a_start_not_a_proof() -> None:
    """With ``limit_margin`` the box is narrower than the limits: branches outside it
    start a numeric search instead of proving anything, and answers keep the margin."""
    rng = np.random.default_rng(35)
    margin = 0.05
    finite = np.isfinite(PANDA.upper - PANDA.lower)
    for q in rng.uniform(PANDA.lower + 0.2, PANDA.upper - 0.2, (15, 7)):
        T = PANDA.fk(q)
        res = optik.solve_ik(PANDA, T, frozen={Q7: float(q[6])}, limit_margin=margin)
        assert res.success and res.q[6] == q[6]
        inner = np.arange(7) != 6
        assert np.all(res.q[inner & finite] >= PANDA.lower[inner & finite] + margin - 1e-12)
        assert np.all(res.q[inner & finite] <= PANDA.upper[inner & finite] - margin + 1e-12)
    # The source configuration just inside a limit: the margin excludes it; never a proof.
    q = PANDA.mid_limits.copy()
    q[3] = PANDA.upper[3] - 0.01
    res = optik.solve_ik(PANDA, PANDA.fk(q), frozen={Q7: float(q[6])}, limit_margin=margin)
    assert res.status not in ("unreachable", "outside_limits") or res.solver != "analytic"


def test_warm_start_q0_and_two_frozen_joints_search_numerically() -> None:
    rng = np.random.default_rng(36)
    q = rng.uniform(PANDA.lower, PANDA.upper)
    T = PANDA.fk(q)
    plain = optik.solve_ik(PANDA, T, frozen={Q7: float(q[6])}, warm_start="q0")
    assert plain.solver == "dls" and plain.success and plain.q[6] == q[6]
    two = {Q7: float(q[6]), "panda_joint1": float(q[0])}
    both = optik.solve_ik(PANDA, T, frozen=two)
    assert both.solver == "dls" and both.success
    assert both.q[6] == q[6] and both.q[0] == q[0]


def test_a_six_joint_family_takes_the_branch_holding_the_frozen_joint() -> None:
    """The branch recovers the frozen joint to rounding only: it is taken (the joint set
    to the value exactly), not left to a numeric search."""
    puma = load_problem("puma560").robot
    rng = np.random.default_rng(37)
    for k in (0, 5):
        name = puma.joint_names[k]
        for q in rng.uniform(puma.lower, puma.upper, (30, 6)):
            T = puma.fk(q)
            res = optik.solve_ik(puma, T, frozen={name: float(q[k])})
            assert (res.success, res.solver) == (True, "analytic")
            assert res.q[k] == q[k] and _reaches(puma, res.q, T, 1e-9)
