"""The joint-space reference of a platform's motion, tabulated at the control period."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import pose_dynamics
from .pose_trajectories import PoseTrajectory
from .reference import ReferenceTable
from .robot import Robot
from .tension_distribution import TensionDistribution


@dataclass
class PoseReferenceTable(ReferenceTable):
    """A platform's reference (ReferenceTable's rows, θ̇_d its angular_velocity_rad_s), and
    per tick its orientation (unit quaternion), its angular velocity ω (rad/s, world
    frame) and the tensions the feed-forward plans (N)."""

    orientation: np.ndarray
    platform_angular_velocity_rad_s: np.ndarray
    tension_n: np.ndarray


def tabulate_pose_reference(robot: Robot, tension_distribution: TensionDistribution,
                            trajectory: PoseTrajectory, period_s: float, attached=None) -> PoseReferenceTable:
    """Sample `trajectory` every `period_s` from its start to its end and compute IK and the
    feed-forward with the `attached` cables (all when None; a detached one's figures 0),
    every row at once; InfeasibleTensionError names the first pose no tensions hold."""
    sample = trajectory.sample(np.arange(int(round(trajectory.duration_s / period_s)) + 1) * period_s)
    dynamics = pose_dynamics.inverse_dynamics(robot, tension_distribution, *sample.motion, attached=attached)
    return PoseReferenceTable(period_s, sample.position_m, sample.velocity_m_s, dynamics.joint_angle_rad,
                              dynamics.joint_velocity_rad_s, dynamics.torque_nm, sample.orientation,
                              sample.angular_velocity_rad_s, dynamics.tension_n)
