"""Figures (matplotlib, the ``report`` extra): joint paths, reachability slices.

Every function writes one image file and returns its path; the figure is closed.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from optik._pyplot import pyplot
from optik.drawing import save_figure
from optik.errors import OptikError

if TYPE_CHECKING:
    from optik.model import Robot
    from optik.planning import PathPlan
    from optik.reachability import Reachability

_FLAG_STYLE = {
    "discontinuity": ("tab:red", "x", "discontinuity"),
    "near_singular": ("tab:orange", "^", "near singular"),
    "outside_limits": ("tab:purple", "s", "outside limits"),
    "unreachable": ("black", "o", "unreachable"),
    "not_found": ("tab:gray", "d", "not found (no proof)"),
}


@dataclass
class PlanFigure:
    """The figure of :func:`plan_figure` and its parts (for tests and further drawing).

    Attributes:
        figure: the matplotlib figure.
        path_axes: the 3-D panel (``None`` without a robot).
        joint_axes: one panel per joint, in ``q`` order.
        arm_waypoints: the waypoints at which the arm is drawn in the 3-D panel.
    """

    figure: Any
    path_axes: Any
    joint_axes: list[Any]
    arm_waypoints: list[int]


def plot_plan(plan: PathPlan, path: Path, robot: Robot | None = None) -> Path:
    """The plan's figure (:func:`plan_figure`), written whole to ``path``."""
    from optik.drawing import save_figure

    return save_figure(plan_figure(plan, robot).figure, path, 110.0)


def plan_figure(plan: PathPlan, robot: Robot | None = None, arms: int = 5) -> PlanFigure:
    """The figure of a plan: its joint paths and, with a robot, the arm along the path.

    One panel per joint (planned value, limit bands, flagged waypoints) and, with a robot,
    a 3-D panel: the Cartesian path, its flagged waypoints in colour and the arm at up to
    ``arms`` solved waypoints (fainter to stronger along the path).

    Args:
        plan: the plan.
        robot: the robot the plan was made for: adds limit bands and the 3-D panel, and
            plots revolute joints in degrees (default: joint panels only, each joint's
            values as they are, rad or m).
        arms: most solved waypoints at which the arm is drawn; no unit.
    """
    plt = pyplot()
    dof = plan.q.shape[1]
    cols = 2 if dof > 3 else 1
    rows = math.ceil(dof / cols)
    extra = 1 if robot is not None else 0
    height = max(2.1 * rows, 5.8 if robot is not None else 0.0)
    fig = plt.figure(figsize=(6.5 * cols + 6.5 * extra, height))
    # A spacer column after the 3-D panel: its z label stands clear of the joint panels.
    ratios = [6.0, 0.5] * extra + [6.5] * cols
    grid = fig.add_gridspec(rows, cols + 2 * extra, width_ratios=ratios)
    axes: list[list[Any]] = [[None] * cols for _ in range(rows)]
    for r in range(rows):
        for c in range(cols):
            share = axes[0][0] if (r, c) != (0, 0) else None
            axes[r][c] = fig.add_subplot(grid[r, c + 2 * extra], sharex=share)
    index = np.arange(len(plan.status))
    names = plan.joint_names or tuple(f"q{i + 1}" for i in range(dof))
    for j in range(rows * cols):
        ax = axes[j // cols][j % cols]
        if j >= dof:
            ax.axis("off")
            continue
        if robot is None:  # the joint's kind is not known: its values as they are
            scale, unit = 1.0, "rad or m"
        elif robot.joints[j].kind == "prismatic":
            scale, unit = 1.0, "m"
        else:
            scale, unit = 180.0 / math.pi, "deg"
        ax.plot(index, plan.q[:, j] * scale, color="tab:blue", lw=1.4, label="planned")
        if robot is not None:
            lo, hi = robot.lower[j] * scale, robot.upper[j] * scale
            if math.isfinite(lo):
                span = hi - lo
                ax.axhspan(lo - 0.15 * span, lo, color="tab:red", alpha=0.12, lw=0)
                ax.axhspan(hi, hi + 0.15 * span, color="tab:red", alpha=0.12, lw=0)
                ax.axhline(lo, color="tab:red", lw=0.8)
                ax.axhline(hi, color="tab:red", lw=0.8)
        solved = ~np.isnan(plan.q[:, j])
        for status, (colour, marker, label) in _FLAG_STYLE.items():
            flagged = np.array([s == status for s in plan.status])
            on_path = flagged & solved
            if on_path.any():
                ax.scatter(
                    index[on_path],
                    plan.q[on_path, j] * scale,
                    c=colour,
                    marker=marker,
                    s=24,
                    label=label,
                    zorder=3,
                )
            off_path = flagged & ~solved
            if off_path.any():
                # Unsolved waypoints have no joint value: mark them along the panel's foot.
                ax.scatter(
                    index[off_path],
                    np.full(off_path.sum(), 0.04),
                    c=colour,
                    marker=marker,
                    s=18,
                    label=label,
                    zorder=3,
                    transform=ax.get_xaxis_transform(),
                    clip_on=False,
                )
        ax.set_ylabel(f"{names[j]} ({unit})")
        ax.grid(True, alpha=0.3)
    # Every waypoint, solved or not, on the shared axis: the unsolved ones' marks (in axes
    # coordinates along the foot) do not widen the data limits themselves.
    axes[0][0].set_xlim(-0.5, max(len(index) - 0.5, 0.5))
    for c in range(cols):
        # Each column's lowest panel (above an empty slot when dof is odd) has the axis.
        last = max(r for r in range(rows) if r * cols + c < dof)
        axes[last][c].set_xlabel("waypoint")
        for r in range(last):
            axes[r][c].tick_params(labelbottom=False)
    handles, labels = axes[0][0].get_legend_handles_labels()
    if robot is not None:
        from matplotlib.patches import Patch

        handles.append(Patch(color="tab:red", alpha=0.3))
        labels.append("outside joint limits")
    summary = plan.summary()
    fig.suptitle(
        f"Joint path: {summary['solved']}/{summary['waypoints']} waypoints solved, "
        f"largest step {summary['largest_step']:.3g} (bound {plan.max_joint_step:g}; rad or m)",
        y=0.99,
        fontsize=11,
    )
    fig.legend(
        handles,
        labels,
        loc="upper center",
        bbox_to_anchor=(0.5, 0.955),
        ncol=min(len(labels), 5),
        frameon=False,
        fontsize=9,
    )
    path_axes, drawn = (None, []) if robot is None else _path_panel(fig, grid, plan, robot, arms)
    fig.tight_layout(rect=(0, 0, 1, 0.9))
    return PlanFigure(fig, path_axes, [axes[j // cols][j % cols] for j in range(dof)], drawn)


def _path_panel(
    fig: Any, grid: Any, plan: PathPlan, robot: Robot, arms: int
) -> tuple[Any, list[int]]:
    """The 3-D panel of :func:`plan_figure`: path, flags and the arm at a few waypoints."""
    from optik.drawing import draw_robot, extent_points, set_equal_3d

    ax = fig.add_subplot(grid[:, 0], projection="3d")
    P = plan.poses[:, :3, 3]
    ax.plot(P[:, 0], P[:, 1], P[:, 2], "--", color="0.35", lw=1.2, label="Cartesian path")
    for status, (colour, marker, label) in _FLAG_STYLE.items():
        flagged = np.array([s == status for s in plan.status])
        if flagged.any():
            ax.scatter(
                P[flagged, 0],
                P[flagged, 1],
                P[flagged, 2],
                c=colour,
                marker=marker,
                s=30,
                label=label,
                depthshade=False,
                zorder=6,
            )
    solved = np.flatnonzero(plan.solved)
    chosen: set[int] = set()
    if len(solved) and arms > 0:
        chosen = {int(solved[round(i)]) for i in np.linspace(0, len(solved) - 1, arms)}
    # Both sides of the first branch switches, where a picture helps most.
    jumps = [k for k, s in enumerate(plan.status) if s == "discontinuity"][:2]
    chosen |= {i for k in jumps for i in (k - 1, k) if plan.solved[i]}
    picks = sorted(chosen)
    extent = [P]
    for n, k in enumerate(picks):
        last = n == len(picks) - 1
        g = draw_robot(
            ax,
            robot,
            plan.q[k],
            colour="tab:blue",
            alpha=0.3 + 0.7 * (n + 1) / len(picks),
            joint_axes=last,
            frames=last,
            label="arm at waypoints " + ", ".join(map(str, picks)) if last else None,
        )
        extent.append(extent_points(g))
    set_equal_3d(ax, np.concatenate(extent))
    ax.view_init(elev=22.0, azim=-58.0)
    ax.legend(loc="upper left", fontsize=8, frameon=False)
    ax.set_title(f"{robot.name}: path and arm", fontsize=10)
    return ax, picks


def plot_reachability(
    result: Reachability, path: Path, axis: str = "z", value: float | None = None
) -> Path:
    """Points within a thin slab around the plane ``axis = value``, reachable or not."""
    plt = pyplot()
    k = "xyz".index(axis) if axis in ("x", "y", "z") else -1
    if k < 0:
        raise OptikError(f"axis must be 'x', 'y' or 'z', got {axis!r}")
    P = result.points
    level = float(np.median(P[:, k])) if value is None else float(value)
    spread = float(np.ptp(P[:, k])) if len(P) else 0.0
    slab = np.abs(P[:, k] - level) <= max(0.02 * spread, 1e-9)
    a, b = [i for i in range(3) if i != k]
    fig, ax = plt.subplots(figsize=(5.5, 5.0))
    for mask, colour, label in (
        (slab & result.reachable, "tab:green", "reachable inside limits"),
        (slab & ~result.reachable & ~result.proven_unreachable, "tab:gray", "not reached"),
        (slab & result.proven_unreachable, "black", "beyond reach (proven)"),
    ):
        ax.scatter(P[mask, a], P[mask, b], s=6, c=colour, label=label)
    ax.set_xlabel(f"{'xyz'[a]} (m)")
    ax.set_ylabel(f"{'xyz'[b]} (m)")
    ax.set_aspect("equal")
    ax.grid(True, alpha=0.3)
    ax.legend(loc="upper right", fontsize=8)
    ax.set_title(f"Reachability, slice {axis} = {level:.3g} m")
    fig.tight_layout()
    return save_figure(fig, path)


def plot_planar_trajectory(
    robot: Robot, trajectory: np.ndarray, target: np.ndarray, path: Path, every: int | None = None
) -> Path:
    """A planar arm's IK trajectory, as in seed 003's figure.

    Args:
        robot: a planar arm (joint frames in the xy plane).
        trajectory: (K, dof) joint vectors visited by the iteration.
        target: (3,) or (2,) target position, m.
        path: image file to write.
        every: draw the arm every ``every`` iterations (default: about 12 drawings).
    """
    plt = pyplot()
    K = len(trajectory)
    step = every or max(K // 12, 1)
    fig, ax = plt.subplots(figsize=(5.5, 5.5))
    for k in range(0, K, step):
        points = robot.frames(trajectory[k])[:, :2, 3]
        ax.plot(points[:, 0], points[:, 1], "--", color="gray", alpha=0.35, lw=1)
    tip = np.array([robot.fk(q)[:2, 3] for q in trajectory[:: max(step // 10, 1)]])
    ax.plot(tip[:, 0], tip[:, 1], color="tab:orange", lw=1.2, label="tool path")
    final = robot.frames(trajectory[-1])[:, :2, 3]
    colours = ["tab:blue", "tab:green", "tab:purple", "tab:brown"]
    for i in range(len(final) - 2):
        ax.plot(
            final[i : i + 2, 0],
            final[i : i + 2, 1],
            "o-",
            color=colours[i % 4],
            lw=2.5,
            label=f"link {i + 1} (final)",
        )
    ax.plot(target[0], target[1], "rx", markersize=11, mew=2, label="target")
    ax.set_aspect("equal")
    ax.grid(True, alpha=0.3)
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_title(f"IK trajectory: {K - 1} iterations, arm drawn every {step}")
    ax.legend(loc="lower right", fontsize=8)
    fig.tight_layout()
    return save_figure(fig, path)
