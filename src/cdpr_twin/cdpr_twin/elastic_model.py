"""Elastic-cable robot simulation: the plant's `elastic` fidelity.

Each cable is a unilateral spring–damper of stiffness EA / l between its drum and the
end-effector (it can go slack, never push); motors carry viscous and Coulomb friction.
Integrated by semi-implicit Euler with sub-steps inside each control period.
"""
from __future__ import annotations

import numpy as np

from cdpr_control.kinematics import cable_vectors
from cdpr_control.robot import Robot
from cdpr_control.statics import static_tensions


class ElasticCableRobot:

    def __init__(self, robot: Robot, position_m, substeps: int, axial_stiffness_n: float,
                 damping_n_s_m: float, coulomb_friction_nm: float,
                 coulomb_velocity_rad_s: float):
        self.robot = robot
        self.substeps = int(substeps)
        self.axial_stiffness_n = axial_stiffness_n
        self.damping_n_s_m = damping_n_s_m
        self.coulomb_friction_nm = coulomb_friction_nm
        self.coulomb_velocity_rad_s = coulomb_velocity_rad_s
        self.position_m = np.array(position_m, dtype=float)
        self.velocity_m_s = np.zeros(3)
        self.attached = np.ones(robot.cable_count, dtype=bool)
        # Start in equilibrium: each cable stretched by its static tension.
        tension = np.maximum(static_tensions(robot, self.position_m, self.attached), 0.0)
        _, d = cable_vectors(robot.exit_points_m, self.position_m)
        unstretched = d / (1.0 + tension / axial_stiffness_n)
        radius = robot.motor.drum_radius_m
        self.angle_rad = (unstretched - robot.cable_length_offset_m) / radius
        self.angular_velocity_rad_s = np.zeros(robot.cable_count)
        self.tension_n = tension

    def break_cables(self, cables) -> None:
        for index in cables:
            self.attached[index] = False

    def cable_tensions(self):
        """Tensions (N) of the current state, and the unit vectors u_i (m × 3) they act along."""
        robot = self.robot
        radius = robot.motor.drum_radius_m
        u, d = cable_vectors(robot.exit_points_m, self.position_m)
        length = robot.cable_length_offset_m + radius * self.angle_rad
        stretch = d - length
        stretch_rate = -(u @ self.velocity_m_s) - radius * self.angular_velocity_rad_s
        tension = (self.axial_stiffness_n / length) * stretch + self.damping_n_s_m * stretch_rate
        tension = np.where((stretch > 0.0) & self.attached, np.maximum(tension, 0.0), 0.0)
        return tension, u

    def step(self, torque_nm: np.ndarray, period_s: float) -> None:
        robot = self.robot
        motor = robot.motor
        h = period_s / self.substeps
        for _ in range(self.substeps):
            tension, u = self.cable_tensions()
            acceleration = (tension @ u) / robot.mass_kg + robot.gravity_m_s2
            friction = (motor.viscous_friction_nm_s_rad * self.angular_velocity_rad_s
                        + self.coulomb_friction_nm
                        * np.tanh(self.angular_velocity_rad_s / self.coulomb_velocity_rad_s))
            angular_acceleration = (torque_nm - friction + motor.drum_radius_m * tension) / motor.inertia_kg_m2
            self.velocity_m_s = self.velocity_m_s + h * acceleration
            self.position_m = self.position_m + h * self.velocity_m_s
            self.angular_velocity_rad_s = self.angular_velocity_rad_s + h * angular_acceleration
            self.angle_rad = self.angle_rad + h * self.angular_velocity_rad_s
        self.tension_n = self.cable_tensions()[0]
