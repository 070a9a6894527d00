"""What a platform's recoveries share (steered.py, braked.py): the platform's state where
they take over, the first row eased in from the torques commanded at the naming, and
`PlatformRecovery`, their common part; and what they prepare before a cable breaks.
"""
from __future__ import annotations

import numpy as np

from cdpr_control.platform import substeps as platform_substeps
from cdpr_control.platform.kinematics import joint_velocity
from cdpr_control.model.reference_table import ReferenceTable
from cdpr_control.geometry.pose_trajectories import PoseSample
from cdpr_control.model.robot import Robot
from cdpr_control.geometry.rotation import normalised
from cdpr_control.tension_distribution import LoweredFloor, TensionDistribution, make_tension_distribution
from cdpr_msgs_py.contract import RECOVERY_MOVE, VERDICT_DELAY_TICKS

from ..recovery_planning.recovery import find_safe_targets, safe_pose_for
from ..detection.wrench_balance import placement
from .base import Naming, StartedRecovery


def prepare_platform(robot: Robot, config) -> None:
    """What a platform's recovery needs from the naming on, when there is no time to load
    (or compile) or search: the kernels its steps run on, and the safe pose after each
    single break (find_safe_targets)."""
    platform_substeps.kernel().load_all()
    find_safe_targets(robot, config)


def named_state(naming: Naming):
    """The recovery's pose tracker (Naming.named_pose) and (position m, orientation,
    velocity m/s, angular velocity rad/s) of the platform as the remaining cables place
    and move it on the naming tick (wrench_balance.placement)."""
    tracker, pose = naming.named_pose()
    return tracker, moving_state(naming.robot, naming.angle_rad, naming.angular_velocity_rad_s, naming.attached,
                                 pose)


def moving_state(robot: Robot, angle_rad, angular_velocity_rad_s, attached: np.ndarray, pose):
    """(position m, orientation, velocity m/s, angular velocity rad/s) of the platform at
    `pose`, its twist from the `attached` cables' motor speeds (wrench_balance.placement)."""
    position, orientation, twist, _ = placement(robot, angle_rad, angular_velocity_rad_s, attached, pose)
    return position, orientation, twist[:3], twist[3:]


def after_the_naming_tick(robot: Robot, attached: np.ndarray, position_m, orientation, velocity_m_s,
                          angular_velocity_rad_s, command_nm, period_s: float) -> PoseSample:
    """The platform's state on the tick its recovery takes over, VERDICT_DELAY_TICKS
    periods after the naming tick's (p, q, v, ω): the torques `command_nm` commanded on
    the naming tick move it over the first period, and the controller's nominal answer of
    the tick after, not known here, is taken as the same (the rigid model's direct
    dynamics, a period at a time by semi-implicit Euler as the steered approach's rows
    are, platform_substeps.move). A recovery's plans start there — planned from the
    naming state with their own motion over those periods, the drives chased the
    difference at the takeover (docs/platform.md). Its accelerations are zero (the plans
    set their own)."""
    pose = np.concatenate([np.asarray(position_m, dtype=float), normalised(orientation)])
    twist = np.concatenate([np.asarray(velocity_m_s, dtype=float), np.asarray(angular_velocity_rad_s, dtype=float)])
    for _ in range(VERDICT_DELAY_TICKS):
        speed = joint_velocity(robot, pose[:3], pose[3:], twist[:3], twist[3:])
        commanded = robot.body.direct_dynamics(robot, pose, twist, command_nm, speed, attached)
        platform_substeps.kernel().move(pose, twist, commanded.twist_rate, period_s)
    zero = np.zeros(3)
    return PoseSample(pose[:3].copy(), pose[3:].copy(), twist[:3].copy(), twist[3:].copy(), zero, zero)


def ease_in(table: ReferenceTable, command_nm: np.ndarray, step_share: float, attached: np.ndarray,
            drum_radius_m: float) -> None:
    """The first row the controller tracks (row 0, the tick after the naming) takes
    `step_share` of the step from `command_nm` to its feed-forward, the next row the rest:
    a step in torque rings elastic cables, and half of it rings them half as much
    (docs/platform.md)."""
    held = (1.0 - step_share) * (command_nm - table.feedforward_nm[0]) * attached
    table.feedforward_nm[0] += held
    table.tension_n[0] -= held / drum_radius_m


class PlatformRecovery(StartedRecovery):
    """What a platform's recoveries share (braked.PoseRecovery, steered.PoseApproach): the
    safe pose of the `attached` cables left (recovery.safe_pose_for; RecoveryInfeasible
    where there is none), the recovery's distribution with its margin above τ_min, lowered
    where a pose needs it, the mode and the ticks each phase began on (the first row of a
    plan is the tick after the naming's); the safe orientation in the supervisor's
    summary."""

    def __init__(self, robot: Robot, config, distribution: TensionDistribution,
                 period_s: float, attached: np.ndarray, start_tick: int):
        safe = safe_pose_for(robot, config, attached)
        super().__init__()
        self.robot = robot
        self.config = config
        self.period_s = period_s
        self.attached = np.asarray(attached, dtype=bool).copy()
        self.safe_point_m = safe.position_m
        self.safe_orientation = safe.orientation
        self.safe_margin_n = safe.tension_margin_n
        self.margin = make_tension_distribution(
            distribution.name, distribution.tension_min_n + config.plan_tension_margin_n, distribution.tension_max_n)
        self.lowered = LoweredFloor(self.margin, robot.tension_min_n)
        self.mode = RECOVERY_MOVE
        self.phase_ticks = {RECOVERY_MOVE: start_tick}
        self.first_tick = start_tick + VERDICT_DELAY_TICKS

    def summary(self) -> dict:
        """StartedRecovery's, and the safe orientation, a unit quaternion (w, x, y, z)."""
        return {**super().summary(), 'safe_orientation': self.safe_orientation.tolist()}
