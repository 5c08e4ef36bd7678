"""optik: optimization-based inverse kinematics for robot arms.

IK written as least-norm and least-squares programs with hard joint limits, checked
against closed forms, with analytic IK as the warm start.
"""

# First: kernels defined by the imports below get a cache stamp of all kernel sources.
from optik import _kernel_cache  # noqa: F401  isort: skip

# Then: a user who cannot write beside the sources still loads the kernels shipped there.
from optik import _shipped_kernels  # noqa: F401  isort: skip
from optik._version import __version__
from optik.analytic import AnalyticBatch, analytic_ik, analytic_ik_batch
from optik.campaign import base_placement, capability_map
from optik.diffik import diff_ik
from optik.errors import OptikError
from optik.ik import IKBatchResult, IKResult, solve_ik, solve_ik_all, solve_ik_batch
from optik.linalg import generalized_inverse, least_squares, min_norm
from optik.model import DHJoint, Joint, Mimic, Robot
from optik.planning import PathPlan, plan_path
from optik.poses import (
    as_target_pose,
    pose,
    to_position_rotation,
    to_quat_wxyz,
    to_quat_xyzw,
    to_rotation,
    to_rpy,
)
from optik.problems import Problem, Target, load_problem
from optik.reachability import Reachability, reachability
from optik.solvers import available_solvers
from optik.trajectory import Trajectory, TrajectorySegment
from optik.trig import solve_trig

__all__ = [
    "AnalyticBatch",
    "DHJoint",
    "IKBatchResult",
    "IKResult",
    "Joint",
    "Mimic",
    "OptikError",
    "PathPlan",
    "Problem",
    "Reachability",
    "Robot",
    "Target",
    "Trajectory",
    "TrajectorySegment",
    "__version__",
    "analytic_ik",
    "analytic_ik_batch",
    "as_target_pose",
    "available_solvers",
    "base_placement",
    "capability_map",
    "diff_ik",
    "generalized_inverse",
    "least_squares",
    "load_problem",
    "min_norm",
    "plan_path",
    "pose",
    "reachability",
    "solve_ik",
    "solve_ik_all",
    "solve_ik_batch",
    "solve_trig",
    "to_position_rotation",
    "to_quat_wxyz",
    "to_quat_xyzw",
    "to_rotation",
    "to_rpy",
]
