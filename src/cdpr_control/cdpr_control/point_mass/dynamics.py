"""The point mass's motion terms (for model.dynamics' inverse dynamics) and its rigid
direct dynamics (docs/design.md §4).

Motor i:        J θ̈_i = −b θ̇_i + c_i + ρ τ_i
End-effector:   m_e p̈ = S τ + m_e g
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from cdpr_control.point_mass import substeps as point_mass_substeps
from cdpr_control.point_mass.kinematics import joint_acceleration, joint_velocity, structure_matrix, structure_matrix_rate
from cdpr_control.model.dynamics import DirectDynamics, MotionTerms
from cdpr_control.model.robot import Robot

# No force on the end-effector but its weight and the cables' (N, world frame).
NO_FORCE = (0.0, 0.0, 0.0)


def motion_terms(robot: Robot, positions_m, velocities_m_s, accelerations_m_s2) -> MotionTerms:
    """MotionTerms of each row of the positions, velocities and accelerations (n × 3): S,
    the lengths, the wrench w = m_e p̈ − m_e g, θ̇ = −Sᵀ ṗ / ρ and θ̈ = −(Sᵀ p̈ + Ṡᵀ ṗ) / ρ."""
    radius = robot.motor.drum_radius_m
    structure, lengths = structure_matrix(robot, positions_m)
    rate = structure_matrix_rate(structure, lengths, velocities_m_s)
    return MotionTerms(structure, lengths, robot.mass_kg * (accelerations_m_s2 - robot.gravity_m_s2),
                       joint_velocity(structure, velocities_m_s, radius),
                       joint_acceleration(structure, rate, velocities_m_s, accelerations_m_s2, radius))


def direct_dynamics(robot: Robot, position_m, velocity_m_s, torque_nm, joint_velocity_rad_s,
                    attached=None, external_wrench=None, kernel: str = 'compiled') -> DirectDynamics:
    """Accelerations under torques c for a rigid-cable robot.

    Taut cables obey (m_e I + (J/ρ²) S Sᵀ) p̈ = m_e g − (J/ρ²) S Ṡᵀ ṗ − (b/ρ²) S Sᵀ ṗ − (1/ρ) S c.
    A cable whose implied tension would be negative goes slack and leaves S (the most
    negative first, until all remaining tensions are non-negative); the motors of slack
    and detached cables spin freely, J θ̈ = −b θ̇ + c, from `joint_velocity_rad_s`.
    `external_wrench`, a force (N, world frame), acts on the end-effector besides.
    Solved by point_mass_substeps' `kernel`.
    """
    m = robot.cable_count
    candidates = np.ones(m) if attached is None else np.asarray(attached, dtype=float)
    solver = point_mass_substeps.kernel(kernel)
    directions = np.empty((m, 4))
    solver.cable_directions(np.array(robot.exit_points_m, dtype=float), np.array(position_m, dtype=float),
                            directions)
    acceleration, theta_ddot, tension, taut = np.empty(3), np.empty(m), np.empty(m), np.empty(m)
    solver.direct_dynamics(point_mass_substeps.constants_of(robot), directions,
                           np.array(velocity_m_s, dtype=float), np.array(torque_nm, dtype=float),
                           np.array(joint_velocity_rad_s, dtype=float), candidates,
                           np.zeros(3) if external_wrench is None else np.array(external_wrench, dtype=float),
                           acceleration, theta_ddot, tension, taut)
    return DirectDynamics(acceleration, theta_ddot, tension, taut != 0.0)
