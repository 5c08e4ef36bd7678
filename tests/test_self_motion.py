"""Closed forms whose pair conditions degenerate: both matrices singular, or one equation.

The angle pairs of ``M (cos a, sin a) = v0 + N (cos b, sin b)`` (the general arm's and the
three-inner-parallel kind's step) when no quartic separates them, and the Unitree Z1
(``three_parallel``, from example-robot-data's URDF) at configurations where its two
pair conditions coincide: a self-motion, every ``q1`` of an arc reaching the pose.

References independent of the closed form: the residual of the system written out here,
pinocchio's FK of the URDF, the configuration each pose came from, and scipy's least
squares over the other joints with ``q1`` held.
"""

from __future__ import annotations

import importlib.metadata
import math
import re
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from conftest import axes_urdf_robot, joint_distance, poe_fk, reference_fk
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

from optik import Robot, solve_ik
from optik.analytic import analytic_ik, analytic_ik_batch, family_of
from optik.analytic._angle_pairs import angle_pairs, pair_continuum

ROOTS = (1e-12, 1e-12, 1e-9, 1e-9)
"""``(trig_tol, eps, free_tol, reach_tol)``, the closed forms' values."""
SYSTEM_TOL = 1e-12
FK_TOL = 1e-9


def _miss(M: np.ndarray, v0: np.ndarray, N: np.ndarray, a: float, b: float) -> float:
    return float(
        np.max(np.abs(M @ (math.cos(a), math.sin(a)) - v0 - N @ (math.cos(b), math.sin(b))))
    )


def _pairs(M: np.ndarray, v0: np.ndarray, N: np.ndarray, ref_a: float, ref_b: float) -> np.ndarray:
    angles = np.full((2, 4), np.nan)
    count = angle_pairs(tuple(M.ravel()), tuple(v0), tuple(N.ravel()), ref_a, ref_b, ROOTS, angles)
    return angles[:, :count].T


def _wrapped(x: float) -> float:
    return math.atan2(math.sin(x), math.cos(x))


def test_regular_systems_give_pairs_that_solve_them() -> None:
    rng = np.random.default_rng(3)
    for _ in range(200):
        M, N = rng.normal(size=(2, 2)), rng.normal(size=(2, 2))
        a0, b0 = rng.uniform(-math.pi, math.pi, 2)
        v0 = M @ (math.cos(a0), math.sin(a0)) - N @ (math.cos(b0), math.sin(b0))
        pairs = _pairs(M, v0, N, 0.0, 0.0)
        assert 1 <= len(pairs) <= 4
        assert max(_miss(M, v0, N, a, b) for a, b in pairs) < SYSTEM_TOL
        assert min(abs(_wrapped(a - a0)) + abs(_wrapped(b - b0)) for a, b in pairs) < 1e-7


def _reference_pairs(M: np.ndarray, v0: np.ndarray, N: np.ndarray, u: np.ndarray) -> list:
    """Every pair of a system with ``M``'s columns along ``u``: the roots ``b`` of
    ``l . (v0 + N u_b) = 0`` (``l`` normal to ``u``) by sign changes on a fine grid and
    brentq, then ``a`` from ``M``'s larger row by arccos."""
    from scipy.optimize import brentq

    normal = np.array([-u[1], u[0]])

    def g(t: float) -> float:
        return float(normal @ (v0 + N @ (math.cos(t), math.sin(t))))

    grid = np.linspace(-math.pi, math.pi, 2001)
    values = [g(t) for t in grid]
    pairs = []
    k = int(np.argmax(np.abs(M).sum(axis=1)))
    for t0, t1, g0, g1 in zip(grid[:-1], grid[1:], values[:-1], values[1:], strict=True):
        if g0 == 0.0 or g0 * g1 < 0.0:
            b = brentq(g, t0, t1, xtol=1e-15) if g0 != 0.0 else t0
            rhs = (v0 + N @ (math.cos(b), math.sin(b)))[k]
            r = np.linalg.norm(M[k])
            if abs(rhs) <= r:
                phi, psi = math.atan2(M[k, 1], M[k, 0]), math.acos(rhs / r)
                pairs += [(phi + psi, b), (phi - psi, b)]
    return pairs


def test_two_singular_matrices_give_every_pair() -> None:
    """Rank 1 each, the system rank 2: ``l^T M = 0`` leaves one equation in ``b``."""
    rng = np.random.default_rng(4)
    for _ in range(200):
        u, w = rng.normal(size=2), rng.normal(size=2)
        M, N = np.outer(u, rng.normal(size=2)), np.outer(w, rng.normal(size=2))
        a0, b0 = rng.uniform(-math.pi, math.pi, 2)
        v0 = M @ (math.cos(a0), math.sin(a0)) - N @ (math.cos(b0), math.sin(b0))
        assert not pair_continuum(tuple(M.ravel()), tuple(v0), tuple(N.ravel()))
        pairs = _pairs(M, v0, N, 0.3, -0.2)
        assert max(_miss(M, v0, N, a, b) for a, b in pairs) < SYSTEM_TOL
        expected = _reference_pairs(M, v0, N, u)
        assert len(pairs) == len(expected)
        for a, b in expected:
            assert min(abs(_wrapped(a - x)) + abs(_wrapped(b - y)) for x, y in pairs) < 1e-7


def test_one_equation_holds_a_at_its_reference() -> None:
    """The rows proportional (a curve of pairs): ``a`` takes ``ref_a`` where it can."""
    rng = np.random.default_rng(5)
    held = 0
    for _ in range(200):
        u = rng.normal(size=2)
        m, n = rng.normal(size=2), rng.normal(size=2)
        a0, b0 = rng.uniform(-math.pi, math.pi, 2)
        c = m @ (math.cos(a0), math.sin(a0)) - n @ (math.cos(b0), math.sin(b0))
        M, N, v0 = np.outer(u, m), np.outer(u, n), c * u
        assert pair_continuum(tuple(M.ravel()), tuple(v0), tuple(N.ravel()))
        ref_a = rng.uniform(-math.pi, math.pi)
        pairs = _pairs(M, v0, N, ref_a, 0.0)
        assert 1 <= len(pairs) <= 2
        assert max(_miss(M, v0, N, a, b) for a, b in pairs) < 1e-9
        reachable = abs(m @ (math.cos(ref_a), math.sin(ref_a)) - c) <= np.linalg.norm(n)
        if reachable:
            held += 1
            assert all(abs(_wrapped(a - ref_a)) < 1e-15 for a, _ in pairs)
    assert held > 50


# ------------------------------------------------------------------------ the Z1


def _z1_path() -> Path:
    dist = importlib.metadata.distribution("example-robot-data")  # the test extra
    path = Path(str(dist.locate_file("cmeel.prefix/share/example-robot-data/robots")))
    return path / "z1_description" / "urdf" / "z1.urdf"


@pytest.fixture(scope="module")
def z1() -> Robot:
    robot = Robot.from_urdf(_z1_path(), "link00", "link06")
    assert family_of(robot).name == "three_parallel"
    return robot


@pytest.fixture(scope="module")
def pinocchio_fk():
    model = pin.buildModelFromUrdf(str(_z1_path()))
    data = model.createData()
    frame = model.getFrameId("link06")

    def fk(q: np.ndarray) -> np.ndarray:
        full = np.zeros(model.nq)
        full[:6] = q  # joint1 .. joint6, then the gripper at 0
        pin.framesForwardKinematics(model, data, full)
        return np.asarray(data.oMf[frame].homogeneous)

    return fk


SELF_MOTION = [
    [0.8648512123864576, 1.193307366485286, -1.937867031719962, -0.7215125206020953,
     1.1804773630904115, 1.906720101111779],
    [-1.0212816257623467, 1.2384001471172754, -0.06545943824695775, 0.7296565886314073,
     0.4403653529847855, 1.2924559099086097],
    [-2.4138644916857697, 1.2775846662336523, -2.401715465199128, 0.540179844898437,
     -1.2872570378207433, -1.0579756041042578],
    [-0.9010684102651938, 1.478642106232688, -2.778318850891328, 0.15201725844951208,
     -1.1399336383808183, -1.6616583822901354],
]  # fmt: skip
"""In-limit configurations where the Z1's two pair conditions coincide (sigma_min(J) about
1e-16): the first two gave no branch at all, the last two none but for ``q1`` of an arc
away from mid-limits' ``q1 = 0``."""


def _singular(z1: Robot, q: np.ndarray) -> np.ndarray:
    """``q`` with ``q2`` moved until the Jacobian's smallest singular value vanishes."""

    def smallest(x: np.ndarray) -> list[float]:
        return [np.linalg.svd(z1.jacobian(np.r_[q[0], x, q[2:]]), compute_uv=False)[-1]]

    fit = least_squares(smallest, [q[1]], xtol=1e-15, ftol=1e-15, gtol=1e-15)
    return np.r_[q[0], fit.x, q[2:]]


def _assert_branches_reach(pinocchio_fk, branches: list[np.ndarray], T: np.ndarray) -> None:
    for b in branches:
        F = pinocchio_fk(b)
        assert np.linalg.norm(F[:3, 3] - T[:3, 3]) < FK_TOL
        assert Rotation.from_matrix(F[:3, :3].T @ T[:3, :3]).magnitude() < FK_TOL


def test_the_z1_self_motion_has_branches_and_the_reference_point(z1: Robot, pinocchio_fk) -> None:
    for q in map(np.array, SELF_MOTION):
        assert z1.within_limits(q)
        assert np.linalg.svd(z1.jacobian(q), compute_uv=False)[-1] < 1e-12
        T = pinocchio_fk(q)
        branches = analytic_ik(z1, T, within_limits=False)
        assert branches, "a reachable pose answered as unreachable"
        _assert_branches_reach(pinocchio_fk, branches, T)
        near = analytic_ik(z1, T, within_limits=False, q_ref=q)
        assert min(joint_distance(z1, b, q) for b in near) < 1e-9  # q_ref's own point
        batch = analytic_ik_batch(z1, T[None], within_limits=False, q_ref=q[None])
        assert batch.counts[0] == len(near)
        np.testing.assert_array_equal(batch.q[0, : len(near)], np.array(near))
        result = solve_ik(z1, T)
        assert result.status == "converged" and result.solver == "analytic"


def test_the_self_motion_is_an_arc_of_q1(z1: Robot) -> None:
    """Independent of the closed form: with ``q1`` held at a returned branch's value the
    other joints reach the pose (scipy), and at mid-limits' ``q1 = 0`` they do not: the
    branch is a point of the arc, not the reference's rounding."""
    q = np.array(SELF_MOTION[2])
    T = z1.fk(q)

    def residual(rest: np.ndarray, q1: float) -> np.ndarray:
        F = z1.fk(np.r_[q1, rest])
        turn = Rotation.from_matrix(F[:3, :3].T @ T[:3, :3]).as_rotvec()
        return np.r_[F[:3, 3] - T[:3, 3], 0.3 * turn]

    def best(q1: float) -> float:
        starts = [q[1:] + np.random.default_rng(i).normal(0.0, 0.5 * (i > 0), 5) for i in range(8)]
        fits = [least_squares(residual, s, args=(q1,), xtol=1e-15, ftol=1e-15) for s in starts]
        return min(float(np.linalg.norm(f.fun)) for f in fits)

    branches = analytic_ik(z1, T, within_limits=False)
    assert branches
    assert all(best(b[0]) < 1e-12 for b in branches)
    assert best(0.0) > 1e-4


def test_singular_poses_made_here_keep_their_source(z1: Robot, pinocchio_fk) -> None:
    rng = np.random.default_rng(11)
    lo, hi = z1.lower, z1.upper
    checked = 0
    for q in rng.uniform(lo, hi, (40, 6)):
        q = _singular(z1, q)
        if not z1.within_limits(q) or np.linalg.svd(z1.jacobian(q), compute_uv=False)[-1] > 1e-10:
            continue
        checked += 1
        T = pinocchio_fk(q)
        branches = analytic_ik(z1, T, within_limits=False)
        assert branches
        _assert_branches_reach(pinocchio_fk, branches, T)
        # Singular to about 1e-13 (not to rounding): the quartic's points of the near
        # curve, the nearest within a millirad of the source.
        near = analytic_ik(z1, T, within_limits=False, q_ref=q)
        assert min(joint_distance(z1, b, q) for b in near) < 1e-3
        batch = analytic_ik_batch(z1, T[None], within_limits=False)
        assert batch.counts[0] == len(branches)
    assert checked >= 10


def _scaled_z1(scale: float, directory: Path) -> Path:
    """The Z1's URDF with every origin's offset (m) times ``scale`` (angles unchanged)."""
    text = _z1_path().read_text()

    def times(match: re.Match[str]) -> str:
        values = " ".join(repr(scale * float(v)) for v in match.group(1).split())
        return f'xyz="{values}"'

    path = directory / f"z1_x{scale:g}.urdf"
    path.write_text(re.sub(r'xyz="([^"]*)"', times, text))
    return path


@pytest.mark.parametrize("scale", [1.0, 1000.0])
def test_poses_just_off_the_self_motion_keep_their_isolated_branches(
    scale: float, tmp_path: Path
) -> None:
    """1e-10 to 3e-9 rad off a self-motion the branches are isolated: the quartic's, not
    the curve's point at the reference (up to 1e-9 of the arm's size off, which at 1000
    times the Z1's size the FK check refused: no branch at all). Checked against the FK
    check's tolerance (1e-9, times the arm's size in position) by pinocchio."""
    path = _scaled_z1(scale, tmp_path)
    robot = Robot.from_urdf(path, "link00", "link06")
    model = pin.buildModelFromUrdf(str(path))
    data, frame = model.createData(), model.getFrameId("link06")
    for source in map(np.array, SELF_MOTION):
        for offset in (0.0, 1e-10, 3e-10, 1e-9, 3e-9):
            q = source + np.array([0.0, 0.0, offset, 0.0, 0.0, 0.0])
            pin.framesForwardKinematics(model, data, np.r_[q, 0.0])
            T = np.asarray(data.oMf[frame].homogeneous)
            branches = analytic_ik(robot, T, within_limits=False)
            assert branches, f"scale {scale}, offset {offset}: no branch"
            for b in branches:
                pin.framesForwardKinematics(model, data, np.r_[b, 0.0])
                F = np.asarray(data.oMf[frame].homogeneous)
                assert np.linalg.norm(F[:3, 3] - T[:3, 3]) < FK_TOL * scale
                assert Rotation.from_matrix(F[:3, :3].T @ T[:3, :3]).magnitude() < FK_TOL


WRIST_ALONG = [
    [0.2549474485108041, 0.8583048789745089, -2.576031298837515, -1.5087586319112658,
     1.5707963267948966, 0.9545097610370683],
    [-1.0358110292452987, 2.80473760828029, -2.565636103171732, -0.2130943157977201,
     -1.5707963267948966, 1.1697045460711353],
]  # fmt: skip
"""q5 = +-pi/2 (beyond the Z1's q5 limits): axis 6 along axes 2-4, so q6 is free in its
subproblem but turns the elbow's target; at mid-limits' q6 the elbow falls short."""


def test_axis_6_along_the_parallel_axes(z1: Robot, pinocchio_fk) -> None:
    for q in map(np.array, WRIST_ALONG):
        T = pinocchio_fk(q)
        for q_ref in (None, q, q + 1.0):
            branches = analytic_ik(z1, T, within_limits=False, q_ref=q_ref)
            assert branches, "a reachable pose answered as unreachable"
            _assert_branches_reach(pinocchio_fk, branches, T)
            refs = None if q_ref is None else q_ref[None]
            batch = analytic_ik_batch(z1, T[None], within_limits=False, q_ref=refs)
            assert batch.counts[0] == len(branches)
        # Reached only outside the limits: not "unreachable".
        assert solve_ik(z1, T).status == "outside_limits"


NEAR_ALONG_ARMS = {
    "seed21": (
        [[-0.9134206980042605, -0.395868078217272, -0.0946102167103174],
         [0.9032286609397678, -0.025339689238585827, -0.428410884789644],
         [0.9032286609397678, -0.025339689238585827, -0.428410884789644],
         [0.9032286609397678, -0.025339689238585827, -0.428410884789644],
         [-0.6086124832155612, -0.5641387900420846, 0.5579769447244582],
         [0.9692719280356376, 0.22168285305269692, -0.10662383497367817]],
        [[-0.30731740051636697, 0.38558173644368204, 0.18851827928109935],
         [0.0644474783036758, -0.24596199677156497, 0.0008340665421671866],
         [-0.04409961053412835, 0.2677605334844466, 0.03734908319961415],
         [0.47542377430188854, -0.23234572596544453, 0.14133076782312876],
         [0.14965271323573673, -0.2593015619442543, -0.35437981394130486],
         [0.3040738500976839, 0.15523214141443178, -0.04875155550371681],
         [0.11831021958136545, -0.20260320863529468, 0.07150446061457094]],
        [-1.618228011250746, -0.004090155754958413, -0.8567456129893563, -1.648731103917061,
         -0.6617028254446833, -1.60051374269513],
    ),
    "seed22": (
        [[0.9658141242442534, 0.058244431752900255, 0.2526077266832666],
         [-0.277185693655236, 0.6442504737236593, -0.7128179419316734],
         [-0.277185693655236, 0.6442504737236593, -0.7128179419316734],
         [-0.277185693655236, 0.6442504737236593, -0.7128179419316734],
         [0.7629552849629879, 0.31565874196032534, 0.564144300486206],
         [-0.7619124330715182, -0.38668782162947646, 0.5195786494213264]],
        [[-0.3461107760237983, -0.10903011495481445, 0.057898416625246404],
         [-0.3939301728367635, 0.24482575917924335, -0.03091468186972795],
         [-0.19266032253905163, -0.22958662247510914, 0.6062064818649023],
         [0.05076850478631665, -0.26937796177887346, -0.2861946897121853],
         [0.551347329140022, -0.17350526896299, 0.35661122755970465],
         [0.42698216435196895, -0.6973204069037421, 0.4052924680488905],
         [-0.06252963971331643, -0.3252385764805109, -0.1631527343977792]],
        [0.7804260244690879, 0.7831628387010414, 2.743178013193864, 1.3824610464647211,
         -2.3368335121124946, 1.1364237454352701],
    ),
    "seed23 (read backwards)": (
        [[0.84518279196137, -0.48834344794515, 0.21722505615473017],
         [-0.7302253590919655, 0.13587609605909245, -0.6695585198164162],
         [0.6628978920225723, 0.4414594290905623, 0.6047147734420459],
         [0.6628978920225723, 0.4414594290905623, 0.6047147734420459],
         [0.6628978920225723, 0.4414594290905623, 0.6047147734420459],
         [-0.9676784656965365, -0.17165020330183947, -0.18475549987384524]],
        [[-0.09196736458637092, 0.07696549376025617, -0.08815681650773984],
         [-0.10641253949663051, -0.18504454576114504, 0.02687534007182662],
         [-0.4032498002419907, 0.015655469792333006, 0.39300771970455933],
         [-0.23007386365015628, -0.013617521410046012, 0.8451627049452729],
         [-0.2978023229282869, -0.4863424572635604, -0.12804273947397682],
         [0.5420813941134506, 0.6105346535352273, -0.3647961789391559],
         [0.17104217654110118, 0.0013564294029404754, -0.17651122663060442]],
        [-1.798409178012705, 2.311797470165354, -1.1090952419149014, -1.2448221387732317,
         -0.04733193734072838, 1.729195611339403],
    ),
}  # fmt: skip
"""Random three-inner arms (axes 2-4 parallel; seed23's 3-5, read backwards) whose axis 6 q5
turns onto the parallel axes, each with a configuration on that self-motion (q2, q3, q4 and
q6 move along it). The quartic returns its (q1, q5) as a double root, off by about
sqrt(eps): axis 6 is then not exactly along the parallel axes, q6 came out of an
ill-conditioned subproblem, and the elbow fell short (no branch, without a reference or from
a far one). Only q5 (q2 read backwards) moves the pose off the self-motion (the others move
it along another): 1e-8 rad off, the solutions are isolated points 1.5 rad along the curve
from where the grid of q6 met it. On seed23, 1e-10 rad off, a grid value of q6 lies within
1e-12 m of a zero of the elbow target's height mismatch (the search along q6 must still
bracket it)."""
NEAR_ALONG_OFFSETS = [(0, 0.0), *((j, e) for e in (1e-10, 1e-8, 1e-6) for j in range(6))]
"""(joint, offset in rad) moving the source configuration."""
OFF_CURVE_MATCH = 1e-5
"""How near (rad) a branch must come to a source moved 1e-8 rad or more off the
self-motion by q5, where the curve's points miss the pose by more than the FK check
allows (at 1e-10 they pass it, and any of them is an answer). The pose's conditioning
(a singular value about 1e-9) lets FK round-trip a configuration 1e-6 rad along the
curve."""


@pytest.mark.parametrize("arm", sorted(NEAR_ALONG_ARMS))
def test_axis_6_nearly_along_the_parallel_axes(arm: str, tmp_path: Path) -> None:
    H, P, source = (np.array(x) for x in NEAR_ALONG_ARMS[arm])
    robot = axes_urdf_robot(H, P, tmp_path / "arm.urdf")
    assert family_of(robot).name == "three_parallel"
    off_curve = 1 if "backwards" in arm else 4  # the joint that turns axis 6 off h
    for joint, offset in NEAR_ALONG_OFFSETS:
        q = source.copy()
        q[joint] += offset
        T = poe_fk(H, P, q)
        for q_ref in (None, q + np.array([2.0, -2.2, 1.9, -2.4, 2.1, -1.7])):
            branches = analytic_ik(robot, T, within_limits=False, q_ref=q_ref)
            assert branches, f"joint {joint} + {offset}: no branch"
            for b in branches:
                F = poe_fk(H, P, b)
                assert np.linalg.norm(F[:3, 3] - T[:3, 3]) < FK_TOL
                assert Rotation.from_matrix(F[:3, :3].T @ T[:3, :3]).magnitude() < FK_TOL
            if joint == off_curve and offset >= 1e-8:
                nearest = min(joint_distance(robot, b, q) for b in branches)
                assert nearest < OFF_CURVE_MATCH, f"joint {joint} + {offset}: {nearest:.1e}"


SHARED_CURVE_ARM = (
    [[-0.527570490976133, -0.39134071804074727, 0.7540038590448689],
     [-0.416184450431515, -0.7551608291458944, -0.5064806268187395],
     [0.3488919628736591, -0.7476523210599816, 0.5650578776159021],
     [0.3488919628736591, -0.7476523210599816, 0.5650578776159021],
     [0.3488919628736591, -0.7476523210599816, 0.5650578776159021],
     [0.5887857441443594, -0.42365578283952643, -0.6883655461736888]],
    [[-0.2493157150916446, 0.13025441210446456, -0.402545333698324],
     [0.14401412290141455, -0.5311583816699552, 0.32899478586667497],
     [0.08165632551720597, 0.40695654994115926, -0.2131390308651374],
     [-0.6283420953659046, -0.41087704523302476, -0.0727790947619123],
     [0.5891518901652342, 0.17154721642745563, 0.3935620868436906],
     [-0.26332462346694296, -0.15948518238637485, -0.09988380595703707],
     [0.35081588879740283, -0.16943347200854242, -0.08727429789450097]],
)  # fmt: skip
"""A random three-inner arm read backwards (axes 3-5 parallel) whose axes 2 and 6 can lie on
one line: the two pair conditions then share a curve (q2 and q6 turn together) though
their rows are not proportional, and the quartic vanishes identically."""
SHARED_CURVE_CONFIGS = [
    ([2.413767891531119, -0.8426043524207758, 2.3169605412471377, -0.848295647581689,
      -2.6135888318985887, 2.2969180652150447], 0, 0.0),
    ([-2.312115774504842, -1.9490307890066114, 2.3169605412471403, -0.8482956475816916,
      -2.613588831898589, -1.5082363180401803], 0, 1e-6),
    # One of the curve's pairs puts axis 6 along the parallel axes; the search along q6
    # then finds no branch the elbow reaches (subproblem 4 degenerates on the curve), and
    # the pairs with their own q6 answer.
    ([-2.312115774504842, -1.9490307890066114, 2.3169605412471403, -0.8482956475816916,
      -2.613588831898589, -1.5082363180401803], 3, 1e-6),
]  # fmt: skip
COAXIAL_GENERAL_ARM = [
    (0.3, 0.9, 0.35, 0.1),
    (0.3, 0.9, 0.0, 0.2),
    (0.12, 1.2, 0.07, -0.1),
    (0.0, -math.pi / 2, 0.4, 0.0),
    (0.0, math.pi / 2, 0.0, 0.0),
    (0.0, 0.0, 0.1, 0.0),
]
"""A general arm and spherical wrist, DH ``(a, alpha, d, theta)``, with a1 = a2, alpha1 =
alpha2 and d2 = 0: at q2 = pi - theta2 axis 3 lies on axis 1 and they turn together."""
COAXIAL_CONFIGS = [
    ([-1.000465900874718, 2.941592653589793, -1.2475651654693112, 1.8433390356326553,
      0.7295747297263411, 1.3510009863960848], 0, 0.0),
    ([-2.2268205789224567, 2.941592653589793, -1.6702412467002667, 1.5881644326947866,
      2.7796101140916507, -2.398339712549303], 2, 1e-12),
    ([0.02005521043148173, 2.941592653589793, 1.9897652433805684, -0.14673138395342233,
      1.6662161137366196, -1.610759263434022], 0, 1e-6),
]  # fmt: skip


def _assert_answered(robot: Robot, fk, q: np.ndarray) -> None:
    """Without a reference and from a far one: branches that reach ``robot.fk(q)`` (checked
    by ``fk``; the target's rounding decides whether the old quartic found anything)."""
    T = robot.fk(q)
    assert np.abs(fk(q) - T).max() < 1e-14
    for q_ref in (None, q + np.array([2.0, -2.2, 1.9, -2.4, 2.1, -1.7])):
        branches = analytic_ik(robot, T, within_limits=False, q_ref=q_ref)
        assert branches, "a reachable pose answered as unreachable"
        for b in branches:
            F = fk(b)
            assert np.linalg.norm(F[:3, 3] - T[:3, 3]) < FK_TOL
            assert Rotation.from_matrix(F[:3, :3].T @ T[:3, :3]).magnitude() < FK_TOL


def test_conditions_that_share_a_curve_without_proportional_rows(tmp_path: Path) -> None:
    H, P = (np.array(x) for x in SHARED_CURVE_ARM)
    robot = axes_urdf_robot(H, P, tmp_path / "arm.urdf")
    assert family_of(robot).name == "three_parallel"
    for source, joint, offset in SHARED_CURVE_CONFIGS:
        q = np.array(source)
        q[joint] += offset
        _assert_answered(robot, lambda x: poe_fk(H, P, x), q)


def test_a_general_arm_whose_third_axis_can_lie_on_the_first() -> None:
    rows = [
        {"a": a, "alpha": al, "d": d, "theta": th, "lower": -3.1, "upper": 3.1}
        for a, al, d, th in COAXIAL_GENERAL_ARM
    ]
    robot = Robot.from_dh(rows)
    assert family_of(robot).name == "spherical_axes"
    for source, joint, offset in COAXIAL_CONFIGS:
        q = np.array(source)
        q[joint] += offset
        _assert_answered(robot, lambda x: reference_fk(robot, x), q)
