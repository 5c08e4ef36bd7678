"""A wheel built from the checkout carries compiled kernels: first calls compile nothing.

The wheel is built as ``pip install .`` builds it (the build hook ``hatch_build.py`` runs
``optik._warmup``), installed into a folder of its own, and a fresh process then makes
the first ``solve_ik`` on the Puma 560 (closed form) and the Panda (numeric), the first
``solve_ik_batch``, and the Panda's closed form with joint 7 held. The answers are
checked here from forward kinematics, and the process must have compiled no kernel:
every one came from the wheel. Times are reported by ``benchmarks/bench_first_call.py``,
never asserted.
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
from scipy.spatial.transform import Rotation

import optik

CHECKOUT = Path(__file__).resolve().parent.parent

FIRST_CALLS = """
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
    "package": optik.__file__,
    "puma": [a.status, a.solver, a.q.tolist()],
    "panda": [b.status, b.solver, b.q.tolist()],
    "batch": [c.success.tolist(), c.q.tolist()],
    "held": [d.status, d.solver, d.q.tolist()],
    "closed_form_batch": [e.success.tolist(), e.iterations.tolist(), e.q.tolist()],
    "compiled": compiled,
}))
"""


def _pose_errors(robot: optik.Robot, q: np.ndarray, T: np.ndarray) -> tuple[float, float]:
    """Position error (m) and rotation angle (rad, scipy's) of FK(q) against T."""
    F = robot.fk(q)
    angle = Rotation.from_matrix(F[:3, :3].T @ T[:3, :3]).magnitude()
    return float(np.linalg.norm(F[:3, 3] - T[:3, 3])), float(angle)


@pytest.mark.slow
def test_a_wheel_built_from_the_checkout_ships_every_kernel_of_the_first_calls(
    tmp_path: Path,
) -> None:
    env = {k: v for k, v in os.environ.items() if k not in ("NUMBA_CACHE_DIR", "OPTIK_WARMUP")}
    # The groups behind the calls checked here (the whole warm-up is the README's install).
    env["OPTIK_WARMUP_GROUPS"] = "closed_forms,numeric,batch,held_joint"
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
        [sys.executable, "-c", FIRST_CALLS],
        env={**env, "PYTHONPATH": str(target)},
        capture_output=True, text=True, check=True, cwd=tmp_path,
    )  # fmt: skip
    out = json.loads(done.stdout.strip().splitlines()[-1])
    assert out["package"].startswith(str(target))
    assert out["compiled"] == []  # every kernel came from the wheel

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
