"""Compiled kernels ship in a wheel, and the warm-up covers the first calls.

Two checks together give the promise of ``pip install .`` (a wheel whose build hook,
``hatch_build.py``, runs ``optik._warmup``): the first ``solve_ik`` on the Puma 560
(closed form) and the Panda (numeric), the first ``solve_ik_batch``, and the Panda's
closed form with joint 7 held compile no kernel.

- The warm-up's groups cover those calls: in a fresh process, after the groups' calls,
  the first calls add no compiled signature to any kernel, whether numba compiles it or
  loads it from a cache (so a cache left by other tests cannot hide a missing one).
- A wheel built from the checkout carries what its warm-up compiled, and a fresh process
  using the installed wheel loads it: with the small ``kinematics`` group, the Panda's
  forward kinematics, Jacobian and frames compile nothing.

The answers are checked here from forward kinematics. Times are reported by
``benchmarks/bench_first_call.py``, never asserted.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest
from conftest import assert_close
from scipy.spatial.transform import Rotation

import optik

CHECKOUT = Path(__file__).resolve().parent.parent

#: The warm-up groups behind the first calls (``held_joint`` is optional: named here, as a
#: user who wants the Panda's held-joint closed form warmed names it).
FIRST_CALL_GROUPS = ("closed_forms", "numeric", "batch", "held_joint")

#: Records every signature a kernel gains from here on, compiled or loaded from a cache.
RECORD_NEW_SIGNATURES = """
from numba.core.dispatcher import Dispatcher

added = []
_add_overload = Dispatcher.add_overload

def _recording(self, cres):
    added.append(f"{self.py_func.__module__}.{self.py_func.__qualname__}{cres.signature}")
    return _add_overload(self, cres)

Dispatcher.add_overload = _recording
"""

FIRST_CALLS = """
import json
import numpy as np
import optik

puma = optik.load_problem("puma560").robot
panda = optik.load_problem("panda").robot
T_puma = puma.fk(np.radians([20.0, 60.0, -120.0, 30.0, 40.0, 10.0]))
T_panda = panda.fk(np.array([0.3, -0.4, 0.2, -2.0, 0.1, 1.6, 0.5]))
rng = np.random.default_rng(0)
Q = rng.uniform(panda.lower, panda.upper, size=(32, panda.dof))
a = optik.solve_ik(puma, T_puma)
b = optik.solve_ik(panda, T_panda)
c = optik.solve_ik_batch(panda, panda.fk(Q))
d = optik.solve_ik(panda, T_panda, frozen={"panda_joint7": 0.5})
Q_puma = rng.uniform(puma.lower, puma.upper, size=(32, puma.dof))
e = optik.solve_ik_batch(puma, puma.fk(Q_puma))
print(json.dumps({
    "puma": [a.status, a.solver, a.q.tolist()],
    "panda": [b.status, b.solver, b.q.tolist()],
    "batch": [c.success.tolist(), c.q.tolist()],
    "held": [d.status, d.solver, d.q.tolist()],
    "closed_form_batch": [e.success.tolist(), e.iterations.tolist(), e.q.tolist()],
    "added": added,
}))
"""

#: The ``kinematics`` group's calls, from the installed wheel.
KINEMATICS_CALLS = """
import json
import numpy as np
from numba.core import event
import optik

compiled = []

class Compiles(event.Listener):
    def on_start(self, ev):
        compiled.append(ev.data["dispatcher"].py_func.__qualname__)

    def on_end(self, ev):
        pass

event.register("numba:compile", Compiles())
panda = optik.load_problem("panda").robot
q = np.array([0.3, -0.4, 0.2, -2.0, 0.1, 1.6, 0.5])
Q = np.stack([q, -0.5 * q])
T, J = panda.fk_jacobian(Q)
print(json.dumps({
    "package": optik.__file__,
    "fk": panda.fk(q).tolist(),
    "jacobian": panda.jacobian(q).tolist(),
    "fk_batch": panda.fk(Q).tolist(),
    "fk_jacobian": [T.tolist(), J.tolist()],
    "frames": np.asarray(panda.frames(q)).tolist(),
    "compiled": compiled,
}))
"""


def _pose_errors(robot: optik.Robot, q: np.ndarray, T: np.ndarray) -> tuple[float, float]:
    """Position error (m) and rotation angle (rad, scipy's) of FK(q) against T."""
    F = robot.fk(q)
    angle = Rotation.from_matrix(F[:3, :3].T @ T[:3, :3]).magnitude()
    return float(np.linalg.norm(F[:3, 3] - T[:3, 3])), float(angle)


def test_the_warm_up_groups_cover_the_first_calls() -> None:
    script = (
        "from optik._warmup import run_groups\n"
        f"run_groups({list(FIRST_CALL_GROUPS)!r})\n" + RECORD_NEW_SIGNATURES + FIRST_CALLS
    )
    env = {k: v for k, v in os.environ.items() if k != "OPTIK_WARMUP_GROUPS"}
    done = subprocess.run(
        [sys.executable, "-c", script], env=env, capture_output=True, text=True, check=True
    )
    out = json.loads(done.stdout.strip().splitlines()[-1])
    assert out["added"] == []  # every signature of the first calls came from the groups

    puma = optik.load_problem("puma560").robot
    panda = optik.load_problem("panda").robot
    status, solver, q = out["puma"]
    T = puma.fk(np.radians([20.0, 60.0, -120.0, 30.0, 40.0, 10.0]))
    assert (status, solver) == ("converged", "analytic")
    assert max(_pose_errors(puma, np.array(q), T)) < 1e-9
    status, solver, q = out["panda"]
    T = panda.fk(np.array([0.3, -0.4, 0.2, -2.0, 0.1, 1.6, 0.5]))
    assert status == "converged"
    assert max(_pose_errors(panda, np.array(q), T)) < 1e-6
    assert np.all(panda.lower <= q) and np.all(np.array(q) <= panda.upper)
    rng = np.random.default_rng(0)
    Q = rng.uniform(panda.lower, panda.upper, size=(32, panda.dof))
    status, solver, q = out["held"]  # the Panda's closed form with joint 7 held
    assert (status, solver) == ("converged", "analytic") and q[6] == 0.5
    assert max(_pose_errors(panda, np.array(q), T)) < 1e-9
    success, iterations, answers = out["closed_form_batch"]  # the Puma's closed form
    Q_puma = rng.uniform(puma.lower, puma.upper, size=(32, puma.dof))
    assert all(success) and not any(iterations)
    for q_answer, q_source in zip(answers, Q_puma, strict=True):
        assert max(_pose_errors(puma, np.array(q_answer), puma.fk(q_source))) < 1e-9
    success, answers = out["batch"]
    assert sum(success) >= 31
    for ok, q_answer, q_source in zip(success, answers, Q, strict=True):
        if ok:
            assert max(_pose_errors(panda, np.array(q_answer), panda.fk(q_source))) < 1e-6


@pytest.mark.slow
def test_a_wheel_built_from_the_checkout_ships_the_kernels_its_warm_up_compiled(
    tmp_path: Path,
) -> None:
    env = {k: v for k, v in os.environ.items() if k not in ("NUMBA_CACHE_DIR", "OPTIK_WARMUP")}
    # One small group (15 s of compilation): shipping and loading do not depend on which
    # kernels (the groups' coverage of the first calls is checked above).
    env["OPTIK_WARMUP_GROUPS"] = "kinematics"
    wheels = tmp_path / "wheels"
    # This environment has the build's requirements (the build hook imports optik).
    subprocess.run(
        [sys.executable, "-m", "pip", "wheel", "-q", "--no-deps", "--no-build-isolation",
         "-w", str(wheels), str(CHECKOUT)],
        env=env, check=True, cwd=tmp_path,
    )  # fmt: skip
    (wheel,) = wheels.glob("optik-*.whl")
    assert "-none-any" not in wheel.name  # machine code for this Python and platform
    with zipfile.ZipFile(wheel) as archive:
        shipped = [n for n in archive.namelist() if n.endswith((".nbi", ".nbc"))]
    assert any("/__pycache__/" in n for n in shipped)

    target = tmp_path / "site"
    subprocess.run(
        [sys.executable, "-m", "pip", "install", "-q", "--no-deps", "--target", str(target),
         str(wheel)],
        env=env, check=True, cwd=tmp_path,
    )  # fmt: skip
    done = subprocess.run(
        [sys.executable, "-c", KINEMATICS_CALLS],
        env={**env, "PYTHONPATH": str(target)},
        capture_output=True, text=True, check=True, cwd=tmp_path,
    )  # fmt: skip
    out = json.loads(done.stdout.strip().splitlines()[-1])
    assert out["package"].startswith(str(target))
    assert out["compiled"] == []  # every kernel came from the wheel

    # The shipped machine code computes what this process compiled for itself; the
    # Jacobian also matches central differences of the pose.
    panda = optik.load_problem("panda").robot
    q = np.array([0.3, -0.4, 0.2, -2.0, 0.1, 1.6, 0.5])
    Q = np.stack([q, -0.5 * q])
    T, J = panda.fk_jacobian(Q)
    assert_close(out["fk"], panda.fk(q), what="fk")
    assert_close(out["jacobian"], panda.jacobian(q), what="jacobian")
    assert_close(out["fk_batch"], panda.fk(Q), what="batch fk")
    assert_close(out["fk_jacobian"][0], T, what="fk_jacobian poses")
    assert_close(out["fk_jacobian"][1], J, what="fk_jacobian Jacobians")
    assert_close(out["frames"], panda.frames(q), what="frames")
    assert_close(out["jacobian"], _central_jacobian(panda, q), atol=1e-7, what="differences")


def _central_jacobian(robot: optik.Robot, q: np.ndarray, h: float = 1e-6) -> np.ndarray:
    """Geometric Jacobian (6, dof) by central differences of ``robot.fk``: linear velocity
    from the position, angular from ``R(q + h e) R(q - h e)^T`` (small-angle vee)."""
    columns = []
    for j in range(robot.dof):
        step = np.zeros(robot.dof)
        step[j] = h
        plus, minus = robot.fk(q + step), robot.fk(q - step)
        R = plus[:3, :3] @ minus[:3, :3].T
        omega = 0.5 * np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])
        columns.append(np.concatenate([(plus[:3, 3] - minus[:3, 3]), omega]) / (2 * h))
    return np.array(columns).T
