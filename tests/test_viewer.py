"""The browser viewer (optik.viewer, ``optik view``): its Python API, and a real browser.

The browser test runs Debian's headless Chromium against a viewer served in-process,
drives it over the Chrome DevTools Protocol (a websocket, with the ``websockets`` package
that viser depends on) and reads the page back: a screenshot with the robot differs from
one with it hidden where the robot's joints project, and a drag of the target gizmo with
the mouse changes the joint values the page reports, to a q whose forward kinematics
reaches the new target. WebGL in headless Chromium needs SwiftShader
(``--use-angle=swiftshader --enable-unsafe-swiftshader``); without a GPU it is otherwise
refused.
"""

from __future__ import annotations

import base64
import io
import json
import math
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
import urllib.request
from collections.abc import Callable, Iterator
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest
from conftest import ROOT, assert_close, reference_fk, robot_of, time_limit

from optik.analytic import analytic_ik
from optik.errors import OptikError
from optik.planning import plan_path
from optik.viewer import STATUS_COLORS, Viewer, stick_points

CHROMIUM_FLAGS = (
    "--headless=new",
    "--no-sandbox",  # CI runs as root
    "--disable-gpu",
    "--use-angle=swiftshader",  # WebGL on the CPU ...
    "--enable-unsafe-swiftshader",  # ... which Chromium otherwise refuses without a GPU
    "--no-first-run",
    "--no-default-browser-check",
    "--disable-extensions",
    "--hide-scrollbars",
    "--mute-audio",
)
WIDTH, HEIGHT = 1100, 700


def wait_for(predicate: Callable[[], Any], timeout: float, what: str) -> Any:
    deadline = time.monotonic() + timeout
    while True:
        value = predicate()
        if value is not None and value is not False:  # predicates return bool or a value
            return value
        if time.monotonic() > deadline:
            raise AssertionError(f"timed out after {timeout} s waiting for {what}")
        time.sleep(0.05)


# ---------------------------------------------------------------------- the browser
def chromium_binary() -> str | None:
    for name in ("chromium", "chromium-browser", "google-chrome"):
        found = shutil.which(name)
        if found:
            return found
    return "/usr/bin/chromium" if os.access("/usr/bin/chromium", os.X_OK) else None


class Chromium:
    """Headless Chromium driven over the DevTools protocol (one page)."""

    def __init__(self, binary: str) -> None:
        from websockets.sync.client import connect

        self.profile = tempfile.mkdtemp(prefix="optik-chromium-")
        self.process = subprocess.Popen(
            [
                binary,
                *CHROMIUM_FLAGS,
                f"--window-size={WIDTH},{HEIGHT}",
                "--remote-debugging-port=0",  # the port is written to DevToolsActivePort
                f"--user-data-dir={self.profile}",
                "about:blank",
            ],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )
        port_file = Path(self.profile) / "DevToolsActivePort"
        wait_for(lambda: port_file.exists() and port_file.stat().st_size > 0, 20, "Chromium")
        port = port_file.read_text().split()[0]
        with urllib.request.urlopen(f"http://127.0.0.1:{port}/json/list", timeout=10) as r:
            page = next(t for t in json.load(r) if t["type"] == "page")
        self.ws = connect(page["webSocketDebuggerUrl"], max_size=None, open_timeout=10)
        self.calls = 0

    def call(self, method: str, **params: Any) -> dict[str, Any]:
        self.calls += 1
        self.ws.send(json.dumps({"id": self.calls, "method": method, "params": params}))
        while True:
            message = json.loads(self.ws.recv(timeout=60))
            if message.get("id") == self.calls:
                assert "error" not in message, f"{method}: {message['error']}"
                return dict(message["result"])

    def evaluate(self, expression: str) -> Any:
        result = self.call("Runtime.evaluate", expression=expression, returnByValue=True)
        return result["result"].get("value")

    def screenshot(self) -> np.ndarray:
        from PIL import Image

        data = base64.b64decode(self.call("Page.captureScreenshot", format="png")["data"])
        return np.asarray(Image.open(io.BytesIO(data)).convert("RGB")).astype(np.int16)

    def mouse(self, kind: str, x: float, y: float, buttons: int) -> None:
        self.call(
            "Input.dispatchMouseEvent",
            type=kind,
            x=float(x),
            y=float(y),
            button="left",
            buttons=buttons,
            clickCount=1 if kind != "mouseMoved" else 0,
        )

    def close(self) -> None:
        self.ws.close()
        self.process.terminate()
        self.process.wait(timeout=10)
        shutil.rmtree(self.profile, ignore_errors=True)


@pytest.fixture(scope="module")
def chromium() -> Iterator[Chromium]:
    binary = chromium_binary()
    if binary is None:
        reason = "no Chromium binary (chromium, chromium-browser, google-chrome) on PATH"
        # CI installs Chromium (.ci/run): there a missing browser is a failure, not a skip.
        assert not os.environ.get("CI"), reason
        print(f"SKIP browser test: {reason}", file=sys.stderr)
        pytest.skip(reason)
    browser = Chromium(binary)
    yield browser
    browser.close()


# The joint values the page reports: the text input in the row labelled "q (rad, m)"
# (viser draws a label and its input side by side in one flex row).
Q_TEXT_JS = """(() => {
  const label = [...document.querySelectorAll('label')]
    .find(l => l.textContent.trim() === 'q (rad, m)');
  const row = label && label.closest('.mantine-Flex-root');
  const input = row && row.querySelector('input');
  return input ? input.value : null;
})()"""


def page_q(browser: Chromium) -> np.ndarray | None:
    text = browser.evaluate(Q_TEXT_JS)
    if not text:
        return None
    return np.array([float(v) for v in text.split(",")])


def project(camera: Any, points: np.ndarray) -> np.ndarray:
    """Pixels (k, 2) of world points (k, 3) in the client's camera (OpenCV convention)."""
    w, x, y, z = camera.wxyz
    R = np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )
    p_camera = (points - camera.position) @ R  # R^T (p - t), row-wise
    f = 0.5 * camera.image_height / math.tan(0.5 * camera.fov)
    u = 0.5 * camera.image_width + f * p_camera[:, 0] / p_camera[:, 2]
    v = 0.5 * camera.image_height + f * p_camera[:, 1] / p_camera[:, 2]
    return np.stack([u, v], axis=1)


def grab_point(
    browser: Chromium, camera: Any, T: np.ndarray, arrow: float
) -> tuple[int, np.ndarray, np.ndarray]:
    """An axis of the gizmo at ``T`` whose arrow shows on the canvas (not under the panel).

    Returns the axis (0 x, 1 y, 2 z) and the pixels of the gizmo's centre and of the point
    0.8 of the way along that arrow.
    """
    for axis in range(3):
        ends = np.array([T[:3, 3], T[:3, 3] + 0.8 * arrow * T[:3, axis]])
        centre, tip = project(camera, ends)
        if np.linalg.norm(tip - centre) < 15:  # the arrow points at the camera
            continue
        u, v = tip
        on_canvas = browser.evaluate(
            f"(document.elementFromPoint({u}, {v}) || {{}}).tagName === 'CANVAS'"
        )
        if on_canvas:
            return axis, centre, tip
    raise AssertionError("no arrow of the target gizmo shows on the canvas")


def settled_state(viewer: Viewer, quiet_s: float = 0.6) -> tuple[np.ndarray, np.ndarray] | None:
    """``(target, q)`` once no pose has arrived for ``quiet_s`` and no solve runs."""
    with viewer._lock:  # target and q together: a solve holds the lock throughout
        before = (viewer.target, viewer.q, viewer._following)
    time.sleep(quiet_s)
    with viewer._lock:
        after = (viewer.target, viewer.q, viewer._following)
    if before[2] or after[2] or not np.array_equal(before[0], after[0]):
        return None
    return after[0], after[1]


def stable_screenshot(browser: Chromium, timeout: float = 20.0) -> np.ndarray:
    """A screenshot once two in a row agree (the scene fades in; nodes arrive)."""
    previous = browser.screenshot()
    deadline = time.monotonic() + timeout
    while True:
        time.sleep(0.3)
        shot = browser.screenshot()
        if np.array_equal(shot, previous) or time.monotonic() > deadline:
            return shot
        previous = shot


def test_browser_draws_the_robot_and_follows_a_dragged_target(chromium: Chromium) -> None:
    robot = robot_of("puma560")
    q_start = np.array([0.3, 0.8, -2.2, 0.4, 0.6, 0.2])  # the arm bent: reach to spare
    with Viewer(robot, port=0, q=q_start) as viewer:
        assert viewer.host == "127.0.0.1"
        chromium.call("Page.navigate", url=viewer.url)
        shown = wait_for(lambda: page_q(chromium), 30, "the page's joint values")
        assert_close(shown, q_start, atol=5e-7, what="q reported before any move")

        # The robot is drawn: hiding it changes the pixels where its joints project.
        with_robot = stable_screenshot(chromium)
        viewer.set_robot_visible(False)

        def robot_hidden() -> np.ndarray | None:
            # Waited for, not slept on: a late message would leave the robot in the shot.
            shot = stable_screenshot(chromium)
            changed = np.any(np.abs(with_robot - shot) > 24, axis=2)
            return changed if changed.sum() > 500 else None

        changed = wait_for(robot_hidden, 30, "more than 500 pixels to change as the robot hides")
        viewer.set_robot_visible(True)
        camera = wait_for(lambda: page_client(viewer), 30, "the page's client").camera
        scale = with_robot.shape[0] / camera.image_height  # device pixels per CSS pixel
        joints = stick_points(robot, q_start)
        pixels = project(camera, joints) * scale
        rows, cols = np.nonzero(changed)
        for point, (u, v) in zip(joints, pixels, strict=True):
            nearest = float(np.min(np.hypot(cols - u, rows - v)))
            assert nearest < 12, f"nothing drawn within 12 px of joint {point} at ({u}, {v})"

        # A drag of one of the gizmo's arrows with the mouse: the page sends the new pose,
        # the solver follows, and the page reports the new joint values.
        T_before = viewer.target
        arrow = 0.3 * viewer._size  # the gizmo's scale: its arrows' length (m)
        axis, (u0, v0), (u1, v1) = grab_point(chromium, camera, T_before, arrow)
        grab = (u1, v1)  # on the arrow, 0.8 of its length from the gizmo's centre
        chromium.mouse("mouseMoved", *grab, buttons=0)
        chromium.mouse("mousePressed", *grab, buttons=1)
        for k in range(1, 6):  # drag along the arrow by a quarter of its projected length
            drag = (grab[0] + 0.05 * k * (u1 - u0), grab[1] + 0.05 * k * (v1 - v0))
            chromium.mouse("mouseMoved", *drag, buttons=1)
            time.sleep(0.05)
        chromium.mouse("mouseReleased", *drag, buttons=0)
        wait_for(
            lambda: bool(np.linalg.norm(viewer.target[:3, 3] - T_before[:3, 3]) > 1e-3),
            15,
            "the dragged target to reach the server",
        )

        def settled_and_shown() -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
            # The drag's last pose may reach the server after a quiet spell (a loaded
            # machine): the state counts as settled once the page shows its solved q and
            # no pose arrived meanwhile.
            settled = settled_state(viewer)
            if settled is None:
                return None
            q = page_q(chromium)
            if q is None or np.max(np.abs(q - settled[1])) >= 1e-6:
                return None
            with viewer._lock:
                if not np.array_equal(viewer.target, settled[0]):
                    return None
            return settled[0], settled[1], q

        T_after, q_after, q_page = wait_for(
            settled_and_shown, 40, "the drag to end and the page to show its solved q"
        )
        # The drag moved the target along the gizmo's arrow, not elsewhere.
        shift = T_after[:3, 3] - T_before[:3, 3]
        assert float(shift @ T_before[:3, axis]) > 0.9 * np.linalg.norm(shift), shift
        assert viewer.result is not None and viewer.result.success, viewer.result
        assert np.max(np.abs(q_page - q_start)) > 1e-3, "the joint values did not change"
        assert_close(q_page, q_after, atol=5e-7, what="page vs viewer q")
        T_fk = reference_fk(robot, q_page)
        assert_close(T_fk[:3, 3], T_after[:3, 3], atol=1e-5, what="FK position of the page's q")
        assert_close(T_fk[:3, :3], T_after[:3, :3], atol=1e-5, what="FK rotation of the page's q")


# ---------------------------------------------------------------------- the Python API
def random_inside(robot: Any, rng: np.random.Generator) -> np.ndarray:
    """A configuration well inside the limits (continuous joints: within one turn)."""
    lo = np.where(np.isfinite(robot.lower), robot.lower, -math.pi)
    hi = np.where(np.isfinite(robot.upper), robot.upper, math.pi)
    return lo + (0.25 + 0.5 * rng.random(robot.dof)) * (hi - lo)


def shown_q(viewer: Viewer) -> np.ndarray:
    """The joint values of the panel's text element, parsed."""
    return np.array([float(v) for v in viewer._q_text.value.split(",")])


@pytest.fixture(scope="module")
def puma_viewer() -> Iterator[Viewer]:
    with Viewer(robot_of("puma560"), port=0) as viewer:
        yield viewer


def page_client(viewer: Viewer) -> Any:
    """The page's client handle (its ``.camera``), or ``None`` until the server lists it.

    The page can show its joint values a moment before the server registers its client.
    """
    clients = list(viewer._server.get_clients().values())
    return clients[0] if clients else None


def test_the_opening_view_holds_the_whole_arm_and_its_target(chromium: Chromium) -> None:
    """The camera aimed above the base: the Puma at mid-limits stands tall, and its tool
    (with the target gizmo the user grabs) was above the page."""
    robot = robot_of("puma560")
    with Viewer(robot, port=0) as viewer:
        chromium.call("Page.navigate", url=viewer.url)
        wait_for(lambda: page_q(chromium), 30, "the page's joint values")
        aim = np.array(viewer._server.initial_camera.look_at)

        def aimed() -> Any:
            # The page reports its camera a moment after it applies the opening view.
            client = page_client(viewer)
            if client is None:
                return None
            camera = client.camera
            return camera if np.allclose(camera.look_at, aim, atol=1e-6) else None

        camera = wait_for(aimed, 30, "the page's camera to take the opening view")
        points = np.vstack([stick_points(robot, viewer.q), viewer.target[:3, 3]])
        u, v = project(camera, points).T
        margin = 0.05 * camera.image_height
        assert np.all((u > margin) & (u < camera.image_width - margin)), u
        assert np.all((v > margin) & (v < camera.image_height - margin)), v


def test_the_page_is_served_on_localhost_and_close_frees_the_port() -> None:
    viewer = Viewer(robot_of("planar_2r"), port=0)
    port = viewer.port
    assert viewer.host == "127.0.0.1" and port > 0
    assert viewer.url == f"http://127.0.0.1:{port}/"
    with urllib.request.urlopen(viewer.url, timeout=10) as response:
        assert b"<title>Viser</title>" in response.read()
    viewer.close()
    viewer.close()  # idempotent
    with pytest.raises(OSError):
        urllib.request.urlopen(viewer.url, timeout=5)


@pytest.mark.parametrize("mode", ["pose", "position", "axis"])
def test_a_target_move_solves_ik_in_the_mode_of_the_dropdown(
    puma_viewer: Viewer, mode: str, rng: np.random.Generator
) -> None:
    robot = puma_viewer.robot
    puma_viewer._mode_box.value = mode  # what choosing in the page's dropdown does
    assert puma_viewer.mode == mode
    T = reference_fk(robot, random_inside(robot, rng))
    puma_viewer.set_q(random_inside(robot, rng))  # start elsewhere
    q_before = puma_viewer.q
    result = puma_viewer.set_target(T)
    assert result is not None and result.success, result
    q = puma_viewer.q
    assert np.max(np.abs(q - q_before)) > 1e-3
    assert_close(shown_q(puma_viewer), q, atol=5e-7, what="q on the panel")
    assert "converged" in puma_viewer._status.content
    T_q = reference_fk(robot, q)
    assert_close(T_q[:3, 3], T[:3, 3], atol=1e-6, what="tool position")
    if mode == "pose":
        assert_close(T_q[:3, :3], T[:3, :3], atol=1e-6, what="tool rotation")
    if mode == "axis":  # the tool's z axis along the target's
        assert float(T_q[:3, 2] @ T[:3, 2]) > 1 - 1e-9
    assert_close(puma_viewer.target, T, atol=0.0, what="target")
    assert_close(puma_viewer._gizmo.position, T[:3, 3], atol=1e-12, what="gizmo position")


def test_the_panel_controls_drive_the_viewer(puma_viewer: Viewer) -> None:
    robot = puma_viewer.robot
    puma_viewer._mode_box.value = "position"
    assert puma_viewer._gizmo.disable_rotations  # a point target: translation arrows only
    puma_viewer._mode_box.value = "pose"
    assert not puma_viewer._gizmo.disable_rotations
    # A joint slider moves that joint alone.
    q = puma_viewer.q
    puma_viewer._sliders[1].value = 1.25
    expected = q.copy()
    expected[1] = 1.25
    assert_close(puma_viewer.q, expected, atol=0.0, what="q after the slider")
    assert_close(shown_q(puma_viewer), expected, atol=5e-7, what="q on the panel")
    # "target to tool" puts the target on the tool; the solver dropdown picks the solver.
    puma_viewer._to_tool.value = True
    assert_close(puma_viewer.target, reference_fk(robot, expected), atol=1e-12)
    puma_viewer._solver_box.value = "dls"
    assert puma_viewer.result is not None and puma_viewer.result.solver == "dls"
    assert puma_viewer.result.success
    puma_viewer._solver_box.value = "auto"
    with pytest.raises(OptikError, match="playing"):
        puma_viewer.play("yes")


def test_a_position_keeps_the_target_orientation(puma_viewer: Viewer) -> None:
    puma_viewer.set_mode("pose")
    T0 = puma_viewer.robot.fk(puma_viewer.q)
    puma_viewer.set_target(T0)
    p = T0[:3, 3] + np.array([0.0, 0.0, -0.05])
    result = puma_viewer.set_target(p)
    assert result is not None and result.success, result
    assert_close(puma_viewer.target[:3, 3], p, atol=0.0, what="position")
    assert_close(puma_viewer.target[:3, :3], T0[:3, :3], atol=0.0, what="rotation kept")


def test_an_unreachable_target_keeps_q_and_shows_the_status(puma_viewer: Viewer) -> None:
    puma_viewer.set_mode("pose")
    q_before = puma_viewer.q
    T = np.eye(4)
    T[:3, 3] = (5.0, 0.0, 0.5)  # beyond the reach sphere (radius about 1 m)
    result = puma_viewer.set_target(T)
    assert result is not None and result.status == "unreachable"
    assert_close(puma_viewer.q, q_before, atol=0.0, what="q kept")
    assert "unreachable" in puma_viewer._status.content


def test_branches_step_through_every_closed_form_branch(
    puma_viewer: Viewer, rng: np.random.Generator
) -> None:
    robot = puma_viewer.robot
    puma_viewer.set_mode("pose")
    T = reference_fk(robot, random_inside(robot, rng))
    puma_viewer.set_target(T)
    # The viewer wraps its branches nearest the q it shows (joint 6 spans more than 2 pi):
    # so must the reference, whatever q an earlier test left on the shared viewer.
    expected = analytic_ik(robot, T, q_ref=puma_viewer.q)
    assert len(expected) >= 2
    shown = []
    for _ in expected:
        q = puma_viewer.next_branch(+1)
        assert q is not None
        assert_close(puma_viewer.q, q, atol=0.0, what="q shown")
        assert_close(reference_fk(robot, q), T, atol=1e-9, what="branch FK")
        shown.append(q)
    # Every branch once: each shown q is one of analytic_ik's, and all are distinct.
    for q in expected:
        assert sum(np.max(np.abs(q - s)) < 1e-9 for s in shown) == 1
    again = puma_viewer.next_branch(+1)  # wraps around to the first
    assert again is not None and np.max(np.abs(again - shown[0])) < 1e-12
    back = puma_viewer.next_branch(-1)
    assert back is not None and np.max(np.abs(back - shown[-1])) < 1e-12
    puma_viewer._branch_buttons[1].value = True  # the page's "next branch" button
    assert_close(puma_viewer.q, shown[0], atol=0.0, what="after the button")
    assert "branch **1** of" in puma_viewer._branch_text.content


def test_a_robot_without_closed_form_reports_it_on_the_page() -> None:
    with Viewer(robot_of("panda"), port=0) as viewer:
        assert "no closed form" in viewer._branch_text.content
        q_before = viewer.q
        viewer._branch_buttons[1].value = True  # the page's "next branch" button
        assert viewer._status.content.startswith("**error**")
        assert "closed-form" in viewer.error
        assert_close(viewer.q, q_before, atol=0.0)


def test_a_plan_plays_back_with_its_flags_coloured() -> None:
    robot = robot_of("planar_2r")
    points = np.array([(1.0 + 0.2 * k, 0.2, 0.0) for k in range(8)])  # leaves the reach
    plan = plan_path(robot, points, mode="position")
    assert "ok" in plan.status and "unreachable" in plan.status
    with Viewer(robot, port=0) as viewer:
        viewer.load_plan(plan)
        colors = np.asarray(viewer._plan_nodes[0].colors)
        expected = np.array([STATUS_COLORS[s] for s in plan.status])
        assert_close(colors, expected, atol=0.0, what="waypoint colours")
        assert_close(viewer._plan_nodes[0].points, points, atol=1e-6, what="waypoints")
        solved = np.flatnonzero(plan.solved)
        unsolved = np.flatnonzero(~plan.solved)
        for k in solved:
            viewer._waypoint.value = int(k)  # the page's slider
            assert_close(viewer.q, plan.q[k], atol=0.0, what=f"q at waypoint {k}")
            assert_close(viewer.target[:3, 3], points[k], atol=1e-12)
        q_last = viewer.q
        viewer.show_waypoint(int(unsolved[0]))
        assert_close(viewer.q, q_last, atol=0.0, what="an unsolved waypoint keeps q")
        assert "unreachable" in viewer._waypoint_text.content
        viewer.show_waypoint(0)
        viewer._play.value = True  # the page's play checkbox
        wait_for(lambda: int(viewer._waypoint.value) >= 2, 10, "playback to advance")
        viewer.play(False)
        assert viewer._play.value is False


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"port": -1}, "port"),
        ({"port": 65536}, "port"),
        ({"port": True}, "port"),
        ({"port": "8080"}, "port"),
        ({"host": ""}, "host"),
        ({"host": "1.2.3.4"}, "host"),  # not this machine's: viser waited forever
        ({"host": "bad host!"}, "host"),
        ({"q": [0.0]}, "q"),
        ({"q": [0.0, 10.0]}, "q"),
        ({"q": [0.0, math.nan]}, "q"),
        ({"mode": "orientation"}, "mode"),
        ({"solver": "nope"}, "solver"),
        ({"timeout_s": 0.0}, "timeout_s"),
    ],
)
def test_bad_arguments_raise_optik_errors_naming_them(kwargs: dict[str, Any], match: str) -> None:
    with pytest.raises(OptikError, match=match):
        Viewer(robot_of("planar_2r"), **kwargs).close()


def test_a_malformed_drag_from_the_page_is_an_error_line(puma_viewer: Viewer) -> None:
    """A gizmo update with a bad position or quaternion: shown, never raised."""
    q_before = puma_viewer.q
    for position, wxyz in (
        ([math.nan, 0.0, 0.0], [1.0, 0.0, 0.0, 0.0]),
        ([0.1, 0.0, 0.3, 0.0], [1.0, 0.0, 0.0, 0.0]),
        ([0.1, 0.0, 0.3], [1.0, 0.0, 0.0]),
        ([0.1, 0.0, 0.3], [0.0, 0.0, 0.0, 0.0]),
    ):
        event = SimpleNamespace(target=SimpleNamespace(position=position, wxyz=wxyz))
        puma_viewer._on_drag(event)
        assert "dragged target" in puma_viewer.error
        assert_close(puma_viewer.q, q_before, atol=0.0, what="q after a malformed drag")
    # Entries of 1e308 overflow a plain norm; scaled first, the quaternion is (1, 1, 0, 0).
    target = puma_viewer.robot.fk(puma_viewer.robot.mid_limits)
    huge = SimpleNamespace(position=target[:3, 3].tolist(), wxyz=[1e308, 1e308, 0.0, 0.0])
    puma_viewer._on_drag(SimpleNamespace(target=huge))
    expected = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])
    assert_close(puma_viewer.target[:3, :3], expected, atol=1e-12, what="normalised drag")


def test_a_waypoint_slider_value_out_of_range_shows_the_nearest_waypoint() -> None:
    """viser stored int(1e300) on an integer slider, which no page could then load."""
    robot = robot_of("planar_2r")
    plan = plan_path(robot, np.array([(1.0 + 0.1 * k, 0.2, 0.0) for k in range(4)]))
    with Viewer(robot, port=0) as viewer:
        viewer.load_plan(plan)
        for sent, shown in ((1e300, 3), (-5.0, 0), (2.4, 2), (math.nan, 0), (math.inf, 0)):
            viewer._waypoint.value = sent  # the page's slider
            assert viewer._waypoint.value == float(shown)
            assert f"waypoint {shown + 1} of 4" in viewer._waypoint_text.content


def test_bad_calls_raise_optik_errors_naming_the_argument(puma_viewer: Viewer) -> None:
    with pytest.raises(OptikError, match="target"):
        puma_viewer.set_target(np.full((4, 4), math.nan))
    with pytest.raises(OptikError, match="q"):
        puma_viewer.set_q(puma_viewer.robot.upper + 1.0)
    with pytest.raises(OptikError, match="mode"):
        puma_viewer.set_mode("sideways")
    with pytest.raises(OptikError, match="plan"):
        puma_viewer.load_plan("plan.json")
    with pytest.raises(OptikError, match="no plan"):
        puma_viewer.show_waypoint(0)
    with pytest.raises(OptikError, match="robot"):
        Viewer("puma560")


# ---------------------------------------------------------------------- the command
def test_optik_view_prints_its_url_serves_the_page_and_stops_on_ctrl_c() -> None:
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    # One fresh interpreter for two checks: importing optik, its CLI and optik.viewer
    # leaves viser unimported (exit 5 if not), then the command runs.
    code = (
        "import sys, optik, optik.cli, optik.viewer\n"
        "if 'viser' in sys.modules: sys.exit(5)\n"
        "sys.exit(optik.cli.main(sys.argv[1:]))"
    )
    process = subprocess.Popen(
        [sys.executable, "-c", code, "view", "planar_2r", "--port", "0", "--mode", "position"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=env,
    )
    try:
        assert process.stdout is not None
        line = process.stdout.readline()
        if not line:  # the process ended: exit 5 is viser imported by `import optik`
            raise AssertionError(f"no URL; exit {process.wait(30)}: {process.stderr.read()}")
        assert line.startswith("optik view: planar_2r at http://127.0.0.1:"), line
        url = line.split(" at ")[1].split()[0]
        with urllib.request.urlopen(url, timeout=10) as response:
            assert b"<title>Viser</title>" in response.read()
        process.send_signal(signal.SIGINT)
        out, err = process.communicate(timeout=30)
    finally:
        if process.poll() is None:
            process.kill()
    assert process.returncode == 0, err
    assert "optik view: stopped" in out
    assert "Traceback" not in err


def test_optik_view_plays_a_problem_path_and_stops_on_sigterm(
    capsys: pytest.CaptureFixture[str],
) -> None:
    from optik.cli import main

    original = signal.getsignal(signal.SIGTERM)

    def terminate() -> None:  # once the command handles SIGTERM, send it
        wait_for(lambda: signal.getsignal(signal.SIGTERM) is not original, 60, "the handler")
        os.kill(os.getpid(), signal.SIGTERM)

    threading.Thread(target=terminate, daemon=True).start()
    argv = ["view", "dobot_magician", "--problem-path", "table2", "--mode", "position"]
    assert main([*argv, "--port", "0"]) == 0
    out = capsys.readouterr().out
    assert "dobot_magician: plan of 3 waypoints" in out, out
    assert "optik view: stopped" in out
    assert signal.getsignal(signal.SIGTERM) is original


def test_optik_view_names_an_unknown_problem_path(capsys: pytest.CaptureFixture[str]) -> None:
    from optik.cli import main

    assert main(["view", "dobot_magician", "--problem-path", "nope", "--port", "0"]) == 2
    assert "paths: table2" in capsys.readouterr().err


def test_optik_view_rejects_a_bad_port_as_a_usage_error() -> None:
    from optik.cli import main

    with pytest.raises(SystemExit) as exit_info:
        main(["view", "planar_2r", "--port", "70000"])
    assert exit_info.value.code == 2


def test_a_port_with_every_higher_port_taken_is_refused_not_a_hang() -> None:
    """viser moves on from a taken port; past 65535 its server thread failed and the
    process waited forever. Only 65535 itself was checked."""
    import socket

    held = []
    try:
        for port in (65534, 65535):
            s = socket.socket()
            try:
                s.bind(("127.0.0.1", port))
            except OSError:  # taken already: the case under test
                s.close()
                continue
            s.listen()
            held.append(s)
        with time_limit(20.0), pytest.raises(OptikError, match="ports 65534 to 65535"):
            Viewer(robot_of("planar_2r"), port=65534).close()
    finally:
        for s in held:
            s.close()
