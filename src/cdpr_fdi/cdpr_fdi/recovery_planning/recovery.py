"""Where the end-effector goes after a cable failure, and whether it can (paper §3.2,
docs/design.md §5): what every recovery strategy (recovery_strategies/), the markers and
the run reports share.

The safe target of a point mass is SP, the barycentre of the residual static-equilibrium
workspace's cross-section at recovery.safe_height_m (or recovery.safe_points_m per
cable), or where the remaining cables cannot hold it within their bounds, the barycentre
of the section where they can (held_safe_point), at the nearest height where there is
one; a platform's is
its safe pose (cdpr_control.platform.safe_pose). Both are found ahead of time for every
single break by the strategies (find_safe_targets).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from cdpr_control.model.robot import Robot
from cdpr_control.platform.safe_pose import SafePose, safe_pose
from cdpr_control.point_mass.workspace import held_safe_point, sew_cross_section


class RecoveryInfeasible(RuntimeError):
    """The remaining cables cannot hold the end-effector, or take it to its safe target."""


@dataclass(frozen=True)
class SafeTarget:
    """Where a recovery takes the end-effector: its position (m), its orientation (a unit
    quaternion; None for a point mass, which has none), and the residual workspace's
    section at that height (n × 3, m) as it is known: the outline of a point mass's
    residual SEW, a convex polygon in order (`outline_m`), or the points of the grid a
    platform's safe pose was found on, its section not convex in general
    (`section_points_m`); the other None."""

    position_m: np.ndarray
    orientation: np.ndarray | None
    outline_m: np.ndarray | None
    section_points_m: np.ndarray | None


def safe_target(robot: Robot, config, attached: np.ndarray) -> SafeTarget:
    """The safe target after the `attached` cables are left, with `config` the robot's
    RecoveryConfig: a platform's safe pose (`safe_pose_for`), a point mass's SP
    (`safe_point_for`); RecoveryInfeasible where there is none."""
    return SAFE_TARGETS[robot.body.kind](robot, config, attached)


def point_mass_target(robot: Robot, config, attached: np.ndarray) -> SafeTarget:
    position = safe_point_for(robot, config, attached)
    return SafeTarget(position, None, at_height(sew_cross_section(robot, attached, position[2]), position[2]), None)


def platform_target(robot: Robot, config, attached: np.ndarray) -> SafeTarget:
    pose = safe_pose_for(robot, config, attached)
    return SafeTarget(pose.position_m, pose.orientation, None, at_height(pose.section_m, pose.position_m[2]))


def at_height(points_xy: np.ndarray, height_m: float) -> np.ndarray:
    """Points (n × 2, m) of a horizontal section as points in space (n × 3) at `height_m`."""
    return np.column_stack([points_xy, np.full(len(points_xy), height_m)])


def safe_point_for(robot: Robot, config, attached: np.ndarray) -> np.ndarray:
    """SP (m): the configured point of a single broken cable, else the barycentre of the
    residual SEW cross-section at the safe height; a platform's, the position of its safe
    pose (`safe_pose_for`)."""
    broken = np.flatnonzero(~attached) + 1
    if broken.size == 1 and int(broken[0]) in config.safe_points_m:
        return config.safe_points_m[int(broken[0])].copy()
    return SAFE_POINTS[robot.body.kind](robot, config, attached)


def residual_barycentre(robot: Robot, config, attached: np.ndarray) -> np.ndarray:
    """A point mass's SP: the barycentre of the residual SEW's section at the safe height,
    or where the remaining cables cannot hold the end-effector there within [τ_min,
    τ_max], of the section where they can, sampled on a platform's grid
    (`safe_pose_grid_m`; held_safe_point): no move ends at a point no tensions hold; where
    they hold it nowhere at the safe height, the same at the nearest height above
    table_height_m where they do."""
    try:
        return held_safe_point(robot, attached, config.safe_height_m, config.safe_pose_grid_m, config.table_height_m)
    except ValueError as err:
        raise RecoveryInfeasible(f'no residual workspace at z = {config.safe_height_m} m: {err}') from None


def safe_pose_for(robot: Robot, config, attached: np.ndarray) -> SafePose:
    """A platform's safe pose after its `attached` cables are left (cdpr_control.platform.safe_pose)
    at recovery.safe_height_m; RecoveryInfeasible where there is none."""
    try:
        return safe_pose(robot, attached, config.safe_height_m, config.safe_pose_turns_deg, config.safe_pose_grid_m)
    except ValueError as err:
        raise RecoveryInfeasible(str(err)) from None


# The safe target, and SP, of each body (Body.kind)
SAFE_TARGETS = {'point_mass': point_mass_target, 'platform': platform_target}
SAFE_POINTS = {'point_mass': residual_barycentre,
               'platform': lambda robot, config, attached: safe_pose_for(robot, config, attached).position_m}


def find_safe_targets(robot: Robot, config) -> None:
    """The safe target after each single break, found now (cdpr_control.platform.safe_pose
    and cdpr_control.point_mass.workspace keep them, or why there is none), so that naming
    a cable does not search: ~0.2 s a cable on the shipped platform, ~0.1 s a point mass's
    grid where the paper's SP is not held, which a realtime supervisor cannot spend
    between two ticks."""
    for cable in range(robot.cable_count):
        try:
            safe_target(robot, config, robot.cable_mask([cable]))
        except RecoveryInfeasible:
            pass     # said when that cable is named


def check_recoverable(robot: Robot, attached: np.ndarray) -> None:
    """RecoveryInfeasible unless as many cables remain as the end-effector has degrees of
    freedom."""
    freedom = robot.degrees_of_freedom
    if np.count_nonzero(attached) < freedom:
        raise RecoveryInfeasible(f'{np.count_nonzero(attached)} cables left: {freedom} DOF need {freedom}')
