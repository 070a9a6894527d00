"""Rigid-cable robot simulation: the digital twin's model, and the plant's `rigid` fidelity."""
from __future__ import annotations

import numpy as np

from cdpr_control.dynamics import direct_dynamics
from cdpr_control.kinematics import cable_vectors, inverse_kinematics
from cdpr_control.robot import Robot
from cdpr_control.statics import static_tensions

# A slack cable whose motor has wound in to within this much of the straight-line
# length is taut again (m).
RETAUT_TOLERANCE_M = 1e-9


class RigidCableRobot:
    """State p, ṗ (m, m/s) and θ, θ̇ (rad, rad/s); taut cables tie θ to p.

    Each step integrates the direct dynamics by semi-implicit Euler in `substeps`. A
    cable is taut while attached, not paid out beyond the straight-line length, and
    pulling (non-negative tension); otherwise its motor spins freely. After each
    sub-step the taut motors are put back on the kinematic constraint, so the model
    does not drift.
    """

    def __init__(self, robot: Robot, position_m, substeps: int = 1):
        self.robot = robot
        self.substeps = int(substeps)
        self.position_m = np.array(position_m, dtype=float)
        self.velocity_m_s = np.zeros(3)
        self.angle_rad = inverse_kinematics(robot, self.position_m)
        self.angular_velocity_rad_s = np.zeros(robot.cable_count)
        self.attached = np.ones(robot.cable_count, dtype=bool)
        self.tension_n = static_tensions(robot, self.position_m, self.attached)
        self.taut = self.attached.copy()

    def break_cables(self, cables) -> None:
        """Detach the 0-based `cables` for good."""
        for index in cables:
            self.attached[index] = False

    def step(self, torque_nm: np.ndarray, period_s: float) -> None:
        robot = self.robot
        radius = robot.motor.drum_radius_m
        h = period_s / self.substeps
        for _ in range(self.substeps):
            u, d = cable_vectors(robot.exit_points_m, self.position_m)
            paid_out = robot.cable_length_offset_m + radius * self.angle_rad
            candidates = self.attached & (paid_out <= d + RETAUT_TOLERANCE_M)
            result = direct_dynamics(robot, self.position_m, self.velocity_m_s, torque_nm,
                                     self.angular_velocity_rad_s, candidates)
            self.velocity_m_s = self.velocity_m_s + h * result.acceleration_m_s2
            self.position_m = self.position_m + h * self.velocity_m_s
            self.angular_velocity_rad_s = self.angular_velocity_rad_s + h * result.joint_acceleration_rad_s2
            self.angle_rad = self.angle_rad + h * self.angular_velocity_rad_s
            taut = result.taut
            u, d = cable_vectors(robot.exit_points_m[taut], self.position_m)
            self.angle_rad[taut] = (d - robot.cable_length_offset_m[taut]) / radius
            self.angular_velocity_rad_s[taut] = -(u @ self.velocity_m_s) / radius
            self.tension_n = result.tension_n
            self.taut = taut
