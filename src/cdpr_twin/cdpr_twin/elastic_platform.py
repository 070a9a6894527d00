"""Elastic-cable simulation of a platform robot (6 DOF): the plant's `elastic` fidelity for
it (docs/platform.md).

Each cable is a unilateral spring–damper of stiffness EA / l from its exit point to its
attachment point on the platform (it can go slack, never push), l = l_0 + ρ θ its
unstretched length; motors carry viscous and Coulomb friction (smoothed by tanh). The
platform obeys Newton–Euler at its frame's origin (cdpr_control.pose_dynamics.rigid_body):
M (a, α) + h = W τ + w_g + w_ext. Integrated by semi-implicit Euler in sub-steps: the
velocities with the tensions of the sub-step's start, then the pose and the angles with
the new velocities, then the tensions of the end.
"""
from __future__ import annotations

import numpy as np

from cdpr_control import pose_kinematics
from cdpr_control.pose_dynamics import rigid_body_at, wrench_at_origin
from cdpr_control.pose_statics import static_tensions
from cdpr_control.dynamics import NO_FORCE
from cdpr_control.robot import Robot
from cdpr_control.rotation import from_rotation_vector, normalised, product, rotation_matrix


class ElasticPlatform:
    """State: pose (p, q), twist (v, ω), motors θ, θ̇; tensions τ (N) follow from it.

    It starts in equilibrium at rest: each cable stretched by the tension that holds the
    platform there (the minimum-norm tensions within the cable bounds).
    """

    def __init__(self, robot: Robot, position_m, orientation, config):
        """At the pose (p, `orientation`: the platform's home one when None). `config`: the
        plant's PlantConfig (sub-steps, the cables' EA and damping, the Coulomb friction's
        smoothing); the Coulomb friction is the robot's motors' static friction."""
        self.robot = robot
        self.config = config
        self.position_m = np.array(position_m, dtype=float)
        self.orientation = normalised(robot.platform.home_orientation if orientation is None else orientation)
        self.velocity_m_s = np.zeros(3)
        self.platform_angular_velocity_rad_s = np.zeros(3)
        self.drums_locked = False
        self.attached = np.ones(robot.cable_count, dtype=bool)
        tension = static_tensions(robot, self.position_m, self.orientation)
        _, d, _ = pose_kinematics.cable_vectors(robot, self.position_m, self.orientation)
        unstretched = d / (1.0 + tension / config.axial_stiffness_n)
        self.angle_rad = (unstretched - robot.cable_length_offset_m) / robot.motor.drum_radius_m
        self.angular_velocity_rad_s = np.zeros(robot.cable_count)
        self.tension_n = self.spring_tensions(self.position_m, self.orientation, self.velocity_m_s,
                                              self.platform_angular_velocity_rad_s, self.angle_rad,
                                              self.angular_velocity_rad_s)[0]

    def break_cables(self, cables) -> None:
        """Detach the 0-based `cables` for good."""
        for index in cables:
            self.attached[index] = False
        self.tension_n = np.where(self.attached, self.tension_n, 0.0)

    def spring_tensions(self, position, orientation, velocity, omega, angle, speed):
        """(τ (N), W (6 × m), R) of a state: EA / l · stretch + damping · stretch rate, never
        negative, 0 for a detached cable."""
        robot = self.robot
        rotation = rotation_matrix(orientation)
        u, d, r = pose_kinematics.cable_geometry(robot, position, rotation)
        structure = pose_kinematics.structure_of(u, r)
        radius = robot.motor.drum_radius_m
        length = robot.cable_length_offset_m + radius * angle
        # the cable's stretch rate: its end on the platform moves with ḋ = −Wᵀ (v, ω), its
        # drum pays out ρ θ̇
        rate = pose_kinematics.length_rates(structure, np.concatenate([velocity, omega])) - radius * speed
        pull = (self.config.axial_stiffness_n / length) * (d - length) + self.config.damping_n_s_m * rate
        tension = np.where(self.attached & (d > length) & (pull > 0.0), pull, 0.0)
        return tension, structure, rotation

    def step(self, torque_nm, period_s: float, substeps: int | None = None, external_force_n=NO_FORCE) -> None:
        """Apply `torque_nm` (N·m) for `period_s` (s), in `substeps` (default: the model's),
        and `external_force_n` (N, world frame) at the platform's origin."""
        external_wrench = wrench_at_origin(external_force_n)
        robot, motor = self.robot, self.robot.motor
        substeps = substeps or self.config.substeps
        h = period_s / substeps
        torque = np.asarray(torque_nm, dtype=float)
        position, orientation = self.position_m, self.orientation
        velocity, omega = self.velocity_m_s, self.platform_angular_velocity_rad_s
        angle, speed = self.angle_rad, self.angular_velocity_rad_s
        tension, structure, rotation = self.spring_tensions(position, orientation, velocity, omega, angle, speed)
        for _ in range(substeps):
            body = rigid_body_at(robot, rotation, omega)
            wrench = structure @ tension + body.weight_wrench - body.velocity_terms
            if external_wrench is not None:
                wrench = wrench + external_wrench
            accelerations = np.linalg.solve(body.mass_matrix, wrench)
            velocity = velocity + h * accelerations[:3]
            omega = omega + h * accelerations[3:]
            position = position + h * velocity
            orientation = normalised(product(from_rotation_vector(h * omega), orientation))
            if self.drums_locked:
                speed = np.zeros(robot.cable_count)
            else:
                friction = (motor.viscous_friction_nm_s_rad * speed
                            + motor.static_friction_nm * np.tanh(speed / self.config.coulomb_velocity_rad_s))
                speed = speed + h * (torque - friction + motor.drum_radius_m * tension) / motor.inertia_kg_m2
                angle = angle + h * speed
            tension, structure, rotation = self.spring_tensions(position, orientation, velocity, omega, angle,
                                                                speed)
        self.position_m, self.orientation = position, orientation
        self.velocity_m_s, self.platform_angular_velocity_rad_s = velocity, omega
        self.angle_rad, self.angular_velocity_rad_s = angle, speed
        self.tension_n = tension
