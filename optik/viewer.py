"""An interactive 3-D viewer in the browser: the robot, a target to drag, branches, plans.

:class:`Viewer` serves a local page with `viser <https://viser.studio>`_ (the optional
``viewer`` extra) that shows the robot as a stick figure drawn from
:meth:`optik.Robot.frames`: links between consecutive joint origins, a cylinder on every
joint axis (orange: revolute, purple: prismatic, as in :mod:`optik.drawing`) and the
base, link and tool frames (x red, y green, z blue). A transform gizmo is the IK target:
while it is dragged, :func:`optik.solve_ik` follows it live from the current
configuration (warm start), in the task mode of the GUI's dropdown (``pose``, ``axis``:
the tool's z axis along the target's, ``position``). The panel reports the joint values,
the result's status and errors, steps through every closed-form branch of the current
target (:func:`optik.analytic_ik`) and plays a plan (:func:`optik.plan_path`) back along
its path, its flagged waypoints coloured.

Everything the page does is also a method, so the viewer can be driven from Python (and
tests): :meth:`Viewer.set_q`, :meth:`Viewer.set_target` (the same code path as a drag),
:meth:`Viewer.set_mode`, :meth:`Viewer.next_branch`, :meth:`Viewer.load_plan`,
:meth:`Viewer.show_waypoint`, :meth:`Viewer.close`.

Units: SI (m, rad) everywhere, as in the rest of optik; the page shows joint values in rad
(revolute) or m (prismatic).
"""

from __future__ import annotations

import contextlib
import io
import math
import threading
import time
from collections.abc import Callable, Iterator
from typing import Any

import numpy as np

from optik._checks import FloatArray, check_bool, check_choice, check_int, check_real
from optik._closing import Closing
from optik._viewer_checks import check_bindable, dragged_pose
from optik.analytic import analytic_ik, family_of
from optik.drawing import joint_frames, link_points
from optik.errors import AnalyticIKError, OptikError
from optik.ik import IKResult, solve_ik
from optik.model import Robot
from optik.planning import PathPlan
from optik.poses import as_target_pose, to_quat_wxyz
from optik.solvers import available_solvers

VIEW_MODES = ("pose", "axis", "position")
"""Task modes of the viewer's dropdown (``axis``: the tool's z axis along the target's)."""

DEFAULT_TIMEOUT_S = 0.25
"""Wall-time budget (s) of one live solve, so that dragging stays responsive."""

STATUS_COLORS: dict[str, tuple[int, int, int]] = {
    "ok": (40, 160, 70),
    "discontinuity": (245, 130, 20),
    "near_singular": (200, 170, 0),
    "outside_limits": (150, 60, 200),
    "unreachable": (220, 30, 40),
    "not_found": (120, 120, 120),
}
"""RGB colour of a plan waypoint by its status (:data:`optik.planning.PLAN_STATUSES`)."""

_LINK_COLOR = (90, 95, 110)
_REVOLUTE_COLOR = (240, 150, 40)
_PRISMATIC_COLOR = (148, 103, 189)  # matplotlib's tab:purple, as optik.drawing
_PLAY_PERIOD_S = 0.1  # playback: one waypoint per 0.1 s


def _viser() -> Any:
    """The viser module, or an error that says how to install it."""
    try:
        import viser
    except ImportError as exc:
        raise OptikError("the viewer needs viser: pip install 'optik[viewer]'") from exc
    return viser


@contextlib.contextmanager
def _quiet() -> Iterator[None]:
    """Silence viser's own banner and shutdown line (the caller prints the URL)."""
    with contextlib.redirect_stdout(io.StringIO()):
        yield


def q_text(q: FloatArray) -> str:
    """Joint values as the page shows them: ``+0.123456, -1.000000`` (rad or m)."""
    return ", ".join(f"{v:+.6f}" for v in q)


def result_text(result: IKResult) -> str:
    """One line (Markdown) for an IK result: status, solver, errors, time."""
    line = (
        f"**{result.status}** · {result.solver or '-'} · position error "
        f"{result.position_error:.2e} m · orientation error {result.orientation_error:.2e} "
        f"rad · {1e3 * result.time_s:.1f} ms"
    )
    if not result.success and result.message:
        line += f"  \n{result.message}"
    return line


def stick_points(robot: Robot, q: FloatArray) -> FloatArray:
    """(k, 3) points of the stick figure at ``q``: base, every joint and link origin, tool.

    Consecutive duplicates (a joint at its link frame's origin) are dropped; the same
    polyline as :func:`optik.drawing.arm_geometry`'s.
    """
    frames = robot.frames(q)
    return link_points(frames, joint_frames(robot, frames))


def _is_point(target: Any) -> bool:
    """Whether ``target`` is a 3-vector (a position without an orientation)."""
    if isinstance(target, dict | tuple) and not all(np.isscalar(v) for v in target):
        return False  # a mapping or a (p, R) pair
    try:
        return np.shape(target) == (3,)
    except (TypeError, ValueError):
        return False


def _cylinder_pose(T_axis: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Position and wxyz of a viser cylinder (its axis is local z) on a joint axis."""
    return T_axis[:3, 3], to_quat_wxyz(T_axis)


class Viewer(Closing):
    """A local web page that shows a robot and solves IK as its target is dragged.

    Args:
        robot: the robot to show.
        host: address to bind (default ``127.0.0.1``: this machine only).
        port: TCP port, 0 to 65535 (0: any free port); when it is taken, viser takes the
            next free one. :attr:`url` gives the address actually bound.
        q: initial configuration (dof,), rad or m (default mid-limits).
        mode: initial task mode, one of :data:`VIEW_MODES`.
        solver: initial solver name (``"auto"`` or one of :func:`optik.available_solvers`).
        timeout_s: wall-time budget (s) of each live solve.

    Raises:
        OptikError: viser is not installed, a bad argument (``port`` not an integer in
            range, ``q`` of the wrong shape or outside the limits, an unknown ``mode`` or
            ``solver``, a non-positive ``timeout_s``).
    """

    def __init__(
        self,
        robot: Robot,
        host: str = "127.0.0.1",
        port: int = 8080,
        *,
        q: Any = None,
        mode: str = "pose",
        solver: str = "auto",
        timeout_s: float = DEFAULT_TIMEOUT_S,
    ) -> None:
        if not isinstance(robot, Robot):
            raise OptikError(f"robot must be an optik.Robot, got {type(robot).__name__}")
        if not isinstance(host, str) or not host:
            raise OptikError(f"host must be a non-empty address string, got {host!r}")
        port = check_int("port", port, minimum=0, maximum=65535)
        self.robot = robot
        self._q = self._checked_q(robot.mid_limits if q is None else q, "q")
        self._mode = check_choice("mode", mode, VIEW_MODES)
        self._solvers = ("auto", *available_solvers())
        self._solver = check_choice("solver", solver, self._solvers)
        self._timeout_s = check_real("timeout_s", timeout_s, positive=True)
        self._lock = threading.RLock()
        # Set in a thread while it writes GUI values: viser runs the callbacks of a value
        # set from Python at once, in that thread, and they must not act on it again.
        self._local = threading.local()
        self._pending: FloatArray | None = None  # latest dragged target not yet solved
        self._following = False
        self._closed = False
        self._branches: list[FloatArray] = []
        self._branch = -1
        self._branch_target: FloatArray | None = None
        self._branch_of = "pose"  # the closed form's mode of the branches
        self._plan: PathPlan | None = None
        self._plan_nodes: list[Any] = []
        self._playing = threading.Event()
        self._stop = threading.Event()
        self.result: IKResult | None = None
        """The last live IK result (``None`` before the first solve)."""
        self.error: str = ""
        """The last error message shown on the page (empty when the last call worked)."""

        check_bindable(host, port)
        viser = _viser()
        with _quiet():
            self._server = viser.ViserServer(host=host, port=port, verbose=False)
        self._target = robot.fk(self._q)
        _, radius = robot.reach_sphere
        self._size = max(float(radius), 1e-3)  # scene scale (m)
        self._build_scene()
        self._build_gui()
        self._draw_robot()
        self._place_gizmo(self._target)
        self._player = threading.Thread(target=self._play_loop, name="optik-viewer", daemon=True)
        self._player.start()

    # ------------------------------------------------------------------ properties
    @property
    def host(self) -> str:
        """The address the server binds."""
        return str(self._server.get_host())

    @property
    def port(self) -> int:
        """The TCP port the server bound."""
        return int(self._server.get_port())

    @property
    def url(self) -> str:
        """The page's address, ``http://HOST:PORT/``."""
        host = self.host
        shown = f"[{host}]" if ":" in host else host
        return f"http://{shown}:{self.port}/"

    @property
    def q(self) -> FloatArray:
        """The configuration shown (dof,), rad or m (a copy)."""
        with self._lock:
            return self._q.copy()

    @property
    def target(self) -> FloatArray:
        """The target pose (4, 4), world frame, m (a copy)."""
        with self._lock:
            return self._target.copy()

    @property
    def mode(self) -> str:
        """The task mode of the live solve, one of :data:`VIEW_MODES`."""
        return self._mode

    @property
    def solver(self) -> str:
        """The solver name of the live solve."""
        return self._solver

    @property
    def branches(self) -> list[FloatArray]:
        """The closed-form branches of the last :meth:`solve_branches` (copies)."""
        with self._lock:
            return [b.copy() for b in self._branches]

    @property
    def plan(self) -> PathPlan | None:
        """The plan loaded by :meth:`load_plan`, or ``None``."""
        return self._plan

    # ------------------------------------------------------------------ scene
    def _build_scene(self) -> None:
        scene = self._server.scene
        size = self._size
        centre = self.robot.frames(self._q)[0, :3, 3]
        # Aimed at the middle of the arm as it starts, not above its base: a tall arm (the
        # Puma at mid-limits) had its tool, and the target on it, above the page.
        points = stick_points(self.robot, self._q)
        middle = 0.5 * (points.min(axis=0) + points.max(axis=0))
        with _quiet():
            camera = self._server.initial_camera
            camera.look_at = tuple(middle)
            camera.position = tuple(middle + size * np.array([1.2, -1.45, 1.0]))
            camera.up = (0.0, 0.0, 1.0)
        # Plain lights instead of viser's default environment map: prefiltering the map
        # stalls a software-rendered page (no GPU: a VM, a remote desktop, headless
        # Chromium) for seconds, and shadows add a pass for no information.
        scene.configure_environment_map(hdri=None)
        scene.configure_default_lights(enabled=True, cast_shadow=False)
        scene.add_light_hemisphere(
            "/light", sky_color=(255, 255, 255), ground_color=(120, 120, 130), intensity=1.5
        )
        scene.add_grid(
            "/grid",
            width=2.4 * size,
            height=2.4 * size,
            cell_size=size / 5.0,
            section_size=size,
            shadow_opacity=0.0,
            position=tuple(centre),
        )
        n = self.robot.chain.n
        self._links = scene.add_line_segments(
            "/robot/links",
            np.zeros((1, 2, 3)),
            colors=_LINK_COLOR,
            thickness=0.03 * size,
        )
        self._joint_nodes = [
            scene.add_cylinder(
                f"/robot/joint_{i}",
                radius=0.045 * size,
                height=0.14 * size,
                color=_PRISMATIC_COLOR if self.robot.chain.prismatic[i] else _REVOLUTE_COLOR,
                cast_shadow=False,
                receive_shadow=False,
            )
            for i in range(n)
        ]
        self._frame_nodes = [
            scene.add_frame(
                f"/robot/frame_{k}",
                axes_length=(0.2 if k in (0, n + 1) else 0.1) * size,
                axes_radius=(0.012 if k in (0, n + 1) else 0.007) * size,
            )
            for k in range(n + 2)
        ]
        self._gizmo = scene.add_transform_controls(
            "/target",
            scale=0.3 * size,
            depth_test=False,
            disable_rotations=self._mode == "position",  # a point has no orientation
        )
        self._gizmo.on_update(self._on_drag)

    def _draw_robot(self) -> None:
        """Move the scene's robot and the GUI's joint read-outs to ``self._q``."""
        q = self._q
        frames = self.robot.frames(q)
        axes = joint_frames(self.robot, frames)
        points = link_points(frames, axes)
        segments = np.stack([points[:-1], points[1:]], axis=1) if len(points) > 1 else None
        with self._server.atomic():
            if segments is not None:
                self._links.points = segments.astype(np.float32)
            for node, T in zip(self._joint_nodes, axes, strict=True):
                node.position, node.wxyz = _cylinder_pose(T)
            for node, T in zip(self._frame_nodes, frames, strict=True):
                node.position, node.wxyz = T[:3, 3], to_quat_wxyz(T)
        with self._from_python():
            self._q_text.value = q_text(q)
            for slider, value in zip(self._sliders, q, strict=True):
                slider.value = float(np.clip(value, slider.min, slider.max))

    @contextlib.contextmanager
    def _from_python(self) -> Iterator[None]:
        """GUI values set inside are the viewer's own: their callbacks do nothing."""
        self._local.syncing = True
        try:
            yield
        finally:
            self._local.syncing = False

    def _place_gizmo(self, T: FloatArray) -> None:
        self._gizmo.position = T[:3, 3]
        self._gizmo.wxyz = to_quat_wxyz(T)

    def set_robot_visible(self, visible: bool) -> None:
        """Show or hide the robot (links, joints, frames); the target stays.

        Args:
            visible: ``True`` to show the robot, ``False`` to hide it.
        """
        visible = check_bool("visible", visible)
        with self._lock:
            for node in (self._links, *self._joint_nodes, *self._frame_nodes):
                node.visible = visible

    # ------------------------------------------------------------------ GUI
    def _build_gui(self) -> None:
        gui = self._server.gui
        gui.add_markdown(f"**optik** · {self.robot.name} · {self.robot.dof} joints")
        with gui.add_folder("Target"):
            self._mode_box = gui.add_dropdown(
                "task", VIEW_MODES, initial_value=self._mode, hint="what the target constrains"
            )
            self._solver_box = gui.add_dropdown("solver", self._solvers, initial_value=self._solver)
            self._status = gui.add_markdown("drag the target")
            self._to_tool = gui.add_button("target to tool", hint="move the target onto the tool")
        with gui.add_folder("Joints"):
            self._q_text = gui.add_text(
                "q (rad, m)", q_text(self._q), disabled=True, hint="the joint values shown"
            )
            self._sliders = []
            for joint in self.robot.joints:
                lo, hi = joint.lower, joint.upper
                if not math.isfinite(lo) or not math.isfinite(hi):
                    lo, hi = -math.pi, math.pi  # a continuous joint: one turn
                self._sliders.append(
                    gui.add_slider(
                        joint.name,
                        min=float(lo),
                        max=float(hi),
                        step=1e-3,
                        initial_value=float(np.clip(0.5 * (lo + hi), lo, hi)),
                    )
                )
        with gui.add_folder("Closed-form branches"):
            self._branch_text = gui.add_markdown(self._branch_help())
            previous = gui.add_button("previous branch")
            following = gui.add_button("next branch")
            self._branch_buttons = (previous, following)
        self._plan_folder = gui.add_folder("Plan", visible=False)
        with self._plan_folder:
            # Float values: viser converts a client's value to the slider's initial type,
            # and int(1e300) cannot be sent to the next client (the page would not load).
            self._waypoint = gui.add_slider(
                "waypoint", min=0.0, max=1.0, step=1.0, initial_value=0.0
            )
            self._play = gui.add_checkbox("play", False)
            self._waypoint_text = gui.add_markdown("")

        self._mode_box.on_update(self._gui(lambda: self.set_mode(self._mode_box.value)))
        self._solver_box.on_update(self._gui(lambda: self.set_solver(self._solver_box.value)))
        self._to_tool.on_click(self._gui(lambda: self.set_target(self.robot.fk(self.q))))
        previous.on_click(self._gui(lambda: self.next_branch(-1)))
        following.on_click(self._gui(lambda: self.next_branch(+1)))
        for k, slider in enumerate(self._sliders):
            slider.on_update(self._gui(self._slider_moved(k)))
        self._waypoint.on_update(self._gui(self._waypoint_moved))
        self._play.on_update(self._gui(lambda: self.play(bool(self._play.value))))

    def _branch_help(self) -> str:
        try:
            family = family_of(self.robot)
        except OptikError as exc:
            return f"no closed form: {exc}"
        if family is None:
            return "no closed form for this robot"
        return f"family **{family.name}**: press next to solve the target"

    def _gui(self, action: Callable[[], Any]) -> Callable[[Any], None]:
        """A GUI callback running ``action``; an error is shown on the page, not raised."""

        def callback(_event: Any) -> None:
            if getattr(self._local, "syncing", False) or self._closed:
                return
            try:
                action()
            except OptikError as exc:
                self._show_error(str(exc))

        return callback

    def _slider_moved(self, k: int) -> Callable[[], None]:
        def moved() -> None:
            q = self.q
            q[k] = float(self._sliders[k].value)
            self.set_q(q)

        return moved

    def _waypoint_moved(self) -> None:
        """The waypoint slider from the page: the nearest waypoint, whatever was sent."""
        value = float(self._waypoint.value)
        with self._lock:
            last = 0 if self._plan is None else len(self._plan.status) - 1
        index = round(min(max(value, 0.0), float(last))) if math.isfinite(value) else 0
        self.show_waypoint(index)  # puts the slider back on the waypoint shown

    def _show_error(self, message: str) -> None:
        self.error = " ".join(message.split())
        self._status.content = f"**error** · {self.error}"

    # ------------------------------------------------------------------ state
    def _checked_q(self, q: Any, name: str) -> FloatArray:
        value = self.robot.check_q(q, name)
        if value.ndim != 1:
            raise OptikError(f"{name} must be one configuration ({self.robot.dof},)")
        if not self.robot.within_limits(value, tol=1e-9):
            raise OptikError(
                f"{name} lies outside the joint limits (largest excursion "
                f"{self.robot.limit_violation(value):.3g} rad or m)"
            )
        return np.array(value, dtype=float)

    def set_q(self, q: Any) -> None:
        """Show configuration ``q`` (dof,), rad or m (inside the limits).

        Args:
            q: one configuration (dof,), rad or m, inside the limits.

        Raises:
            OptikError: wrong shape, a non-finite entry, or a value outside the limits.
        """
        with self._lock:
            self._q = self._checked_q(q, "q")
            self._draw_robot()

    def set_mode(self, mode: str) -> IKResult | None:
        """Change the task mode (one of :data:`VIEW_MODES`) and solve the target again.

        Args:
            mode: the task mode, one of :data:`VIEW_MODES`.

        Raises:
            OptikError: an unknown mode.
        """
        with self._lock:
            self._mode = check_choice("mode", mode, VIEW_MODES)
            self._branch_target = None  # branches depend on the mode
            self._gizmo.disable_rotations = self._mode == "position"
            with self._from_python():
                self._mode_box.value = self._mode
            return self._follow(self._target)

    def set_solver(self, solver: str) -> IKResult | None:
        """Change the solver of the live solve and solve the target again.

        Args:
            solver: ``"auto"`` or the name of an available solver.

        Raises:
            OptikError: a name that is not ``"auto"`` nor an available solver.
        """
        with self._lock:
            self._solver = check_choice("solver", solver, self._solvers)
            with self._from_python():
                self._solver_box.value = self._solver
            return self._follow(self._target)

    def set_target(self, target: Any) -> IKResult | None:
        """Move the target gizmo to ``target`` and solve IK there, as a drag does.

        Args:
            target: world pose of the tool, any form of :func:`optik.as_target_pose`
                (a 4x4, a ``(p, R)`` pair, a mapping); a 3-vector (m) moves the target
                and keeps its orientation.

        Returns:
            The IK result (the robot moves to its ``q`` when it succeeds; otherwise it
            stays and the page shows the status).

        Raises:
            OptikError: a malformed target.
        """
        with self._lock:
            if _is_point(target):
                T = self._target.copy()
                T[:3, 3] = as_target_pose(target, "position")[:3, 3]
            else:
                T = as_target_pose(target, "pose")
            self._place_gizmo(T)
            return self._follow(T)

    def _on_drag(self, event: Any) -> None:
        """A gizmo update from the page: solve the latest pose, dropping stale ones."""
        if self._closed:
            return
        handle = event.target
        try:
            T = dragged_pose(handle.position, handle.wxyz)
        except OptikError as exc:  # a malformed update from the page
            self._show_error(str(exc))
            return
        with self._lock:
            self._pending = T
            if self._following:  # the thread already solving will take this one next
                return
            self._following = True
        while True:
            with self._lock:
                T_next, self._pending = self._pending, None
                if T_next is None or self._closed:
                    self._following = False
                    return
                try:
                    self._follow(T_next)
                except OptikError as exc:
                    self._show_error(str(exc))

    def _follow(self, T: FloatArray) -> IKResult | None:
        """Solve IK at ``T`` from the current q; move the robot when it succeeds."""
        self._target = T
        try:
            result = solve_ik(
                self.robot,
                T,
                mode=self._mode,
                solver=self._solver,
                q0=self._q,
                timeout_s=self._timeout_s,
            )
        except OptikError as exc:
            self._show_error(str(exc))
            return None
        self.result = result
        self.error = ""
        if result.success:
            self._q = np.array(result.q, dtype=float)
            self._draw_robot()
        self._status.content = result_text(result)
        return result

    # ------------------------------------------------------------------ branches
    def _branch_mode(self) -> str:
        """The closed form's mode for the viewer's: ``position`` or ``pose``, as it solves."""
        family = family_of(self.robot)
        if family is None:
            raise AnalyticIKError(f"robot {self.robot.name!r} has no closed-form IK family")
        wanted = "position" if self._mode == "position" else "pose"
        return wanted if wanted in family.modes else family.modes[0]

    def solve_branches(self) -> list[FloatArray]:
        """Every closed-form branch for the current target, inside the limits.

        The closed forms solve a full pose or a position: ``pose`` and ``axis`` use the
        target's full pose (a branch reaching the pose also satisfies the axis task),
        ``position`` its translation; a family that solves only one of the two (a planar
        arm: position; a 6R arm: pose) solves that one. Branches are ordered by distance
        to the current q.

        Raises:
            AnalyticIKError: the robot has no closed-form family.
        """
        with self._lock:
            mode = self._branch_mode()
            self._branches = analytic_ik(self.robot, self._target, mode, q_ref=self._q)
            self._branch = -1
            self._branch_target = self._target.copy()
            self._branch_of = mode
            if not self._branches:
                self._branch_text.content = (
                    f"no branch reaches the target ({mode}) inside the limits"
                )
            return self.branches

    def next_branch(self, step: int = 1) -> FloatArray | None:
        """Show the next (``step=+1``) or previous (``-1``) branch of the current target.

        The branches are solved again when the target or the mode changed since the last
        call. Returns the branch shown, or ``None`` when there is none.

        Args:
            step: how many branches to move by: ``+1`` next, ``-1`` previous; no unit.

        Raises:
            AnalyticIKError: as :meth:`solve_branches`.
        """
        step = check_int("step", step)
        with self._lock:
            stale = self._branch_target is None or not np.array_equal(
                self._branch_target, self._target
            )
            if stale:
                self.solve_branches()
                if step < 0:
                    self._branch = 0  # so that "previous" first shows the last branch
            if not self._branches:
                return None
            self._branch = (self._branch + step) % len(self._branches)
            q = self._branches[self._branch]
            self._q = q.copy()
            self._draw_robot()
            self._branch_text.content = (
                f"branch **{self._branch + 1}** of {len(self._branches)} "
                f"({self._branch_of}): {q_text(q)}"
            )
            return q.copy()

    # ------------------------------------------------------------------ plans
    def load_plan(self, plan: PathPlan) -> None:
        """Show a plan: its path (waypoints coloured by status), a slider over waypoints.

        Waypoints are drawn as points coloured by :data:`STATUS_COLORS` (green ``ok``,
        other colours flagged), joined by a line; the slider shows the robot at each
        solved waypoint and the target at its pose.

        Args:
            plan: the plan, for a robot with this viewer's number of joints.

        Raises:
            OptikError: not a :class:`optik.PathPlan`, or one with another number of joints.
        """
        if not isinstance(plan, PathPlan):
            raise OptikError(f"plan must be an optik.PathPlan, got {type(plan).__name__}")
        if plan.q.ndim != 2 or plan.q.shape[1] != self.robot.dof or len(plan.status) == 0:
            raise OptikError(
                f"plan has joint paths of shape {plan.q.shape}, expected (N >= 1, "
                f"{self.robot.dof}) for robot {self.robot.name!r}"
            )
        with self._lock:
            self.play(False)
            for node in self._plan_nodes:
                node.remove()
            self._plan = plan
            points = plan.poses[:, :3, 3]
            colors = np.array([STATUS_COLORS.get(s, (0, 0, 0)) for s in plan.status], np.uint8)
            scene = self._server.scene
            self._plan_nodes = [
                scene.add_point_cloud(
                    "/plan/waypoints",
                    points=points.astype(np.float32),
                    colors=colors,
                    point_size=0.025 * self._size,
                    point_shape="circle",
                    precision="float32",
                )
            ]
            if len(points) > 1:
                self._plan_nodes.append(
                    scene.add_line_segments(
                        "/plan/path",
                        np.stack([points[:-1], points[1:]], axis=1).astype(np.float32),
                        colors=(150, 150, 160),
                        thickness=0.005 * self._size,
                    )
                )
            with self._from_python():
                self._waypoint.max = float(max(len(plan.status) - 1, 1))
                self._waypoint.value = 0.0
            self._plan_folder.visible = True
            self.show_waypoint(0)

    def show_waypoint(self, index: int) -> None:
        """Show waypoint ``index`` of the loaded plan: the robot there, the target at it.

        An unsolved waypoint leaves the robot where it was; its status is shown.

        Args:
            index: the waypoint's index in the plan, in ``[0, N)``.

        Raises:
            OptikError: no plan loaded, or ``index`` out of range.
        """
        with self._lock:
            if self._plan is None:
                raise OptikError("no plan loaded: call load_plan(plan) first")
            plan = self._plan
            index = check_int("index", index, minimum=0, maximum=len(plan.status) - 1)
            self._target = plan.poses[index].copy()
            self._place_gizmo(self._target)
            if plan.solved[index]:
                self._q = self._checked_q(plan.q[index], f"plan.q[{index}]")
                self._draw_robot()
            step = plan.step[index]
            self._waypoint_text.content = (
                f"waypoint {index + 1} of {len(plan.status)}: **{plan.status[index]}**"
                + (f" · step {step:.3g} rad or m" if math.isfinite(step) else "")
            )
            with self._from_python():
                self._waypoint.value = float(index)

    def play(self, playing: bool = True) -> None:
        """Start or stop playing the loaded plan (one waypoint per 0.1 s, then again).

        Args:
            playing: ``True`` to start playing, ``False`` to stop.

        Raises:
            OptikError: ``playing`` with no plan loaded.
        """
        playing = check_bool("playing", playing)
        if playing and self._plan is None:
            raise OptikError("no plan loaded: call load_plan(plan) first")
        if playing:
            self._playing.set()
        else:
            self._playing.clear()
        with self._from_python():
            self._play.value = playing

    def _play_loop(self) -> None:
        while not self._stop.is_set():
            if not self._playing.wait(timeout=0.2):
                continue
            time.sleep(_PLAY_PERIOD_S)
            with self._lock:
                if self._plan is None or not self._playing.is_set() or self._closed:
                    continue
                nxt = (int(self._waypoint.value) + 1) % len(self._plan.status)
                self.show_waypoint(nxt)

    # ------------------------------------------------------------------ lifetime
    def close(self) -> None:
        """Stop the server and the playback thread (idempotent)."""
        with self._lock:
            if self._closed:
                return
            self._closed = True
        self._stop.set()
        self._playing.clear()
        self._player.join(timeout=2.0)
        with _quiet():
            self._server.stop()
