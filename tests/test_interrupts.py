"""Ctrl-C reaches the caller as ``KeyboardInterrupt``, from compiled kernels and backends.

A ``KeyboardInterrupt`` that lands while a numba kernel boxes its result comes out of the
call as ``SystemError`` (its cause the interrupt), and Ipopt's callback reported one the
same way, which the solver loop then took for a backend failure and returned as a status.
The calls run in a child process: the interrupt is the process's own (``interrupt_main``).
"""

import subprocess
import sys

import pytest

from optik._interrupts import reraise_interrupt, wrapped_interrupt

INTERRUPTED = """
import _thread
import threading
import time

import numpy as np

import optik

panda = optik.load_problem("panda").robot
ur5 = optik.load_problem("ur5").robot
centre, radius = panda.reach_sphere
far = panda.fk(panda.mid_limits)
far[:3, 3] = centre + [0.97 * radius, 0.0, 0.0]  # out of reach, no proof: runs to its deadline
path = np.stack([panda.fk(panda.mid_limits + 0.002 * k) for k in range(150)])
rng = np.random.default_rng(5)
qs = ur5.lower + (ur5.upper - ur5.lower) * rng.uniform(0.2, 0.8, (20000, 6))
poses = ur5.fk(qs)
calls = {
    "solve_ik dls": lambda: optik.solve_ik(panda, far, solver="dls", timeout_s=5.0),
    "solve_ik ipopt": lambda: optik.solve_ik(panda, far, solver="casadi:ipopt", timeout_s=5.0),
    "plan_path": lambda: optik.plan_path(panda, path),
    "analytic_ik_batch": lambda: optik.analytic_ik_batch(ur5, poses),
}
for name, call in calls.items():
    started = time.perf_counter()
    call()  # compiled and built first; its time sets when the interrupt comes
    delay = min((time.perf_counter() - started) / 3.0, 0.3)
    for _ in range(3):
        timer = threading.Timer(delay, _thread.interrupt_main)
        timer.start()
        try:
            call()
            time.sleep(2.0)  # a call that ended first meets the interrupt here
            outcome = "swallowed"
        except KeyboardInterrupt:
            outcome = "KeyboardInterrupt"
        except BaseException as exc:
            outcome = type(exc).__name__
        timer.join()
        print(name, "|", outcome)
"""


def test_ctrl_c_inside_kernels_and_backends_is_a_keyboard_interrupt() -> None:
    done = subprocess.run(
        [sys.executable, "-c", INTERRUPTED], capture_output=True, text=True, timeout=900
    )
    assert done.returncode == 0, done.stderr
    outcomes = [line.split(" | ") for line in done.stdout.splitlines() if " | " in line]
    assert len(outcomes) == 12, done.stdout
    assert {outcome for _, outcome in outcomes} == {"KeyboardInterrupt"}, done.stdout


def test_a_wrapped_interrupt_is_found_along_causes_and_contexts() -> None:
    try:
        try:
            raise KeyboardInterrupt
        except KeyboardInterrupt as interrupt:
            raise SystemError("returned a result with an exception set") from interrupt
    except SystemError as exc:
        wrapped = exc
    assert isinstance(wrapped_interrupt(wrapped), KeyboardInterrupt)
    with pytest.raises(KeyboardInterrupt):
        reraise_interrupt(wrapped)

    try:
        try:
            raise ValueError("a backend's own failure")
        except ValueError:
            raise RuntimeError("while handling it") from None
    except RuntimeError as exc:
        plain = exc
    assert wrapped_interrupt(plain) is None
    reraise_interrupt(plain)  # nothing wrapped: returns


def test_the_command_line_exits_130_for_an_interrupt_a_kernel_wrapped(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    # What numba hands back when Ctrl-C lands as a kernel boxes its result.
    def interrupted(*args: object, **kwargs: object) -> None:
        try:
            raise KeyboardInterrupt
        except KeyboardInterrupt as interrupt:
            raise SystemError("returned a result with an exception set") from interrupt

    import optik.cli._solve
    from optik.cli import main

    monkeypatch.setattr(optik.cli._solve, "solve_ik", interrupted)
    assert main(["solve", "ur5", "--position", "0.3", "0.1", "0.4"]) == 130
    err = capsys.readouterr().err
    assert "optik: interrupted" in err and "internal error" not in err
