"""The joint-space reference of a platform's motion, tabulated at the control period."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import pose_dynamics, pose_kinematics
from .pose_trajectories import PoseTrajectory
from .robot import Robot
from .tension_distribution import TensionDistribution


@dataclass
class PoseReferenceTable:
    """Reference at t_k = k · period: pose (m, unit quaternion), twist (m/s, rad/s),
    θ_d (rad), θ̇_d (rad/s), c_ID (N·m) and the tensions it plans (N), a row per tick."""

    period_s: float
    position_m: np.ndarray
    orientation: np.ndarray
    velocity_m_s: np.ndarray
    angular_velocity_rad_s: np.ndarray
    angle_rad: np.ndarray
    joint_velocity_rad_s: np.ndarray
    feedforward_nm: np.ndarray
    tension_n: np.ndarray

    def __len__(self) -> int:
        return self.position_m.shape[0]


def tabulate_pose_reference(robot: Robot, tension_distribution: TensionDistribution,
                            trajectory: PoseTrajectory, period_s: float) -> PoseReferenceTable:
    """Sample `trajectory` every `period_s` from its start to its end and compute IK and the
    feed-forward; InfeasibleTensionError names the first pose no tensions hold."""
    rows = []
    for k in range(int(round(trajectory.duration_s / period_s)) + 1):
        sample = trajectory.sample(k * period_s)
        dynamics = pose_dynamics.inverse_dynamics(robot, tension_distribution, *sample.motion)
        rows.append((sample.position_m, sample.orientation, sample.velocity_m_s, sample.angular_velocity_rad_s,
                     pose_kinematics.inverse_kinematics(robot, sample.position_m, sample.orientation),
                     dynamics.joint_velocity_rad_s, dynamics.torque_nm, dynamics.tension_n))
    return PoseReferenceTable(period_s, *(np.array(column) for column in zip(*rows)))
