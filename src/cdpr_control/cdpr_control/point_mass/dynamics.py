"""Inverse and rigid direct dynamics of the cable robot (docs/design.md §4).

Motor i:        J θ̈_i = −b θ̇_i + c_i + ρ τ_i
End-effector:   m_e p̈ = S τ + m_e g
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from cdpr_control.point_mass import substeps as point_mass_substeps
from cdpr_control.point_mass.kinematics import joint_acceleration, joint_velocity, structure_matrix, structure_matrix_rate
from cdpr_control.model.robot import Robot
from cdpr_control.tension_distribution import InfeasibleTensionError, TensionDistribution

# No force on the end-effector but its weight and the cables' (N, world frame).
NO_FORCE = (0.0, 0.0, 0.0)


@dataclass
class InverseDynamics:
    """Torques c (N·m) and the joint motion and tensions (N) they produce."""

    torque_nm: np.ndarray
    tension_n: np.ndarray
    joint_velocity_rad_s: np.ndarray
    joint_acceleration_rad_s2: np.ndarray


@dataclass
class DirectDynamics:
    """p̈ (m/s²), θ̈ (rad/s²), tensions (N) and which cables are taut."""

    acceleration_m_s2: np.ndarray
    joint_acceleration_rad_s2: np.ndarray
    tension_n: np.ndarray
    taut: np.ndarray


def inverse_dynamics(robot: Robot, tension_distribution: TensionDistribution,
                     position_m, velocity_m_s, acceleration_m_s2, attached=None) -> InverseDynamics:
    """Torques that make the end-effector follow (p, ṗ, p̈) with the `attached` cables.

    w = m_e p̈ − m_e g is shared among the attached cables by `tension_distribution`;
    c = J θ̈ + b θ̇ − ρ τ. A detached (broken) cable carries no tension and its motor
    is not tied to p: its torque, velocity and acceleration are reported as 0.
    p, ṗ, p̈ are one pose (3,) or a stack (n × 3), which gives rows (n × m) of each figure;
    an infeasible pose names its position (the first of a stack).
    """
    if attached is None:
        attached = np.ones(robot.cable_count, dtype=bool)
    motor = robot.motor
    position_m = np.asarray(position_m, dtype=float)
    structure, lengths = structure_matrix(robot, position_m)
    rate = structure_matrix_rate(structure, lengths, velocity_m_s)
    wrench = robot.mass_kg * (acceleration_m_s2 - robot.gravity_m_s2)
    tension = np.zeros(lengths.shape)
    distribute = (tension_distribution.distribute if position_m.ndim == 1
                  else tension_distribution.distribute_rows)
    try:
        tension[..., attached] = distribute(structure[..., attached], wrench)
    except InfeasibleTensionError as err:
        raise err.at(position_m if err.row is None else position_m[err.row]) from None
    theta_dot = joint_velocity(structure, velocity_m_s, motor.drum_radius_m)
    theta_ddot = joint_acceleration(structure, rate, velocity_m_s, acceleration_m_s2,
                                    motor.drum_radius_m)
    theta_dot[..., ~attached] = 0.0
    theta_ddot[..., ~attached] = 0.0
    torque = (motor.inertia_kg_m2 * theta_ddot + motor.viscous_friction_nm_s_rad * theta_dot
              - motor.drum_radius_m * tension)
    return InverseDynamics(torque, tension, theta_dot, theta_ddot)


def direct_dynamics(robot: Robot, position_m, velocity_m_s, torque_nm, joint_velocity_rad_s,
                    attached=None, kernel: str = 'compiled') -> DirectDynamics:
    """Accelerations under torques c for a rigid-cable robot.

    Taut cables obey (m_e I + (J/ρ²) S Sᵀ) p̈ = m_e g − (J/ρ²) S Ṡᵀ ṗ − (b/ρ²) S Sᵀ ṗ − (1/ρ) S c.
    A cable whose implied tension would be negative goes slack and leaves S (the most
    negative first, until all remaining tensions are non-negative); the motors of slack
    and detached cables spin freely, J θ̈ = −b θ̇ + c, from `joint_velocity_rad_s`.
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
                           np.array(joint_velocity_rad_s, dtype=float), candidates, np.zeros(3),
                           acceleration, theta_ddot, tension, taut)
    return DirectDynamics(acceleration, theta_ddot, tension, taut != 0.0)
