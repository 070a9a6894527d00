"""Rigid-cable simulation of a platform robot (6 DOF): the digital twin's model of it, and
the plant's `rigid` fidelity for it (docs/platform.md)."""
from __future__ import annotations

import numpy as np

from cdpr_control import pose_dynamics, pose_kinematics
from cdpr_control.dynamics import NO_FORCE
from cdpr_control.robot import Robot
from cdpr_control.rotation import from_rotation_vector, normalised, product

from .rigid_model import RETAUT_TOLERANCE_M


class RigidPlatform:
    """State: pose (p, q), twist (v, ω), motors θ, θ̇ (rad, rad/s); taut cables tie θ to
    the pose.

    Each step integrates the Newton–Euler direct dynamics (cdpr_control.pose_dynamics) by
    semi-implicit Euler in `substeps`: twist first, then the pose with it (the orientation
    turned by the rotation vector h ω). A cable is taut while attached, not paid out
    beyond the straight-line length and pulling; otherwise its motor spins freely. After
    each sub-step the taut motors are put back on the kinematic constraint. As
    RigidCableRobot, a step replaces the state arrays rather than writing into them.
    """

    def __init__(self, robot: Robot, position_m, orientation=None, substeps: int = 1):
        """At rest at the pose (p, `orientation`: the platform's home one when None)."""
        self.robot = robot
        self.substeps = int(substeps)
        self.position_m = np.array(position_m, dtype=float)
        self.orientation = normalised(robot.platform.home_orientation if orientation is None else orientation)
        self.velocity_m_s = np.zeros(3)
        self.platform_angular_velocity_rad_s = np.zeros(3)
        self.angle_rad = pose_kinematics.inverse_kinematics(robot, self.position_m, self.orientation)
        self.angular_velocity_rad_s = np.zeros(robot.cable_count)
        self.drums_locked = False
        self.attached = np.ones(robot.cable_count, dtype=bool)
        self.taut = self.attached.copy()
        self.tension_n = np.zeros(robot.cable_count)

    def break_cables(self, cables) -> None:
        """Detach the 0-based `cables` for good."""
        for index in cables:
            self.attached[index] = False

    def step(self, torque_nm, period_s: float, substeps: int | None = None, external_force_n=NO_FORCE) -> None:
        """Apply `torque_nm` (N·m) for `period_s` (s), in `substeps` (default: the model's),
        and `external_force_n` (N, world frame) at the platform's origin."""
        if self.drums_locked:
            self.velocity_m_s, self.platform_angular_velocity_rad_s = np.zeros(3), np.zeros(3)
            self.angular_velocity_rad_s = np.zeros(self.robot.cable_count)
            return
        robot = self.robot
        radius = robot.motor.drum_radius_m
        substeps = substeps or self.substeps
        h = period_s / substeps
        torque = np.asarray(torque_nm, dtype=float)
        external_wrench = pose_dynamics.wrench_at_origin(external_force_n)
        position, orientation = self.position_m, self.orientation
        velocity, omega = self.velocity_m_s, self.platform_angular_velocity_rad_s
        angle, speed = self.angle_rad, self.angular_velocity_rad_s
        _, lengths, _ = pose_kinematics.cable_vectors(robot, position, orientation)
        for _ in range(substeps):
            candidates = self.attached & (robot.cable_length_offset_m + radius * angle
                                          <= lengths + RETAUT_TOLERANCE_M)
            motion = pose_dynamics.direct_dynamics(robot, position, orientation, velocity, omega, torque, speed,
                                                   candidates, external_wrench)
            velocity = velocity + h * motion.acceleration_m_s2
            omega = omega + h * motion.angular_acceleration_rad_s2
            position = position + h * velocity
            orientation = normalised(product(from_rotation_vector(h * omega), orientation))
            taut = motion.taut
            speed = speed + h * motion.joint_acceleration_rad_s2
            angle = angle + h * speed
            # on the kinematic constraint: l = d, θ̇ = ḋ / ρ (the lengths are the next
            # sub-step's too)
            u, lengths, r = pose_kinematics.cable_vectors(robot, position, orientation)
            angle[taut] = ((lengths - robot.cable_length_offset_m) / radius)[taut]
            speed[taut] = (pose_kinematics.length_rates(pose_kinematics.structure_of(u, r),
                                                        np.concatenate([velocity, omega])) / radius)[taut]
            self.tension_n, self.taut = motion.tension_n, taut
        self.position_m, self.orientation = position, orientation
        self.velocity_m_s, self.platform_angular_velocity_rad_s = velocity, omega
        self.angle_rad, self.angular_velocity_rad_s = angle, speed
