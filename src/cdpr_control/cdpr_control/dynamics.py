"""Inverse and rigid direct dynamics of the cable robot (DESIGN §4).

Motor i:        J θ̈_i = −b θ̇_i + c_i + ρ τ_i
End-effector:   m_e p̈ = S τ + m_e g
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .linalg3 import solve3
from .kinematics import joint_acceleration, joint_velocity, structure_matrix, structure_matrix_rate
from .robot import Robot
from .tension_distribution import InfeasibleTensionError, TensionDistribution


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
    """
    if attached is None:
        attached = np.ones(robot.cable_count, dtype=bool)
    motor = robot.motor
    structure, lengths = structure_matrix(robot, position_m)
    rate = structure_matrix_rate(structure, lengths, velocity_m_s)
    wrench = robot.mass_kg * (acceleration_m_s2 - robot.gravity_m_s2)
    tension = np.zeros(robot.cable_count)
    try:
        tension[attached] = tension_distribution.distribute(structure[:, attached], wrench)
    except InfeasibleTensionError as err:
        raise err.at(position_m) from None
    theta_dot = joint_velocity(structure, velocity_m_s, motor.drum_radius_m)
    theta_ddot = joint_acceleration(structure, rate, velocity_m_s, acceleration_m_s2,
                                    motor.drum_radius_m)
    theta_dot[~attached] = 0.0
    theta_ddot[~attached] = 0.0
    torque = (motor.inertia_kg_m2 * theta_ddot + motor.viscous_friction_nm_s_rad * theta_dot
              - motor.drum_radius_m * tension)
    return InverseDynamics(torque, tension, theta_dot, theta_ddot)


def direct_dynamics(robot: Robot, position_m, velocity_m_s, torque_nm, joint_velocity_rad_s,
                    attached=None) -> DirectDynamics:
    """Accelerations under torques c for a rigid-cable robot.

    Taut cables obey (m_e I + (J/ρ²) S Sᵀ) p̈ = m_e g − (J/ρ²) S Ṡᵀ ṗ − (b/ρ²) S Sᵀ ṗ − (1/ρ) S c.
    A cable whose implied tension would be negative goes slack and leaves S (the most
    negative first, until all remaining tensions are non-negative); the motors of slack
    and detached cables spin freely, J θ̈ = −b θ̇ + c, from `joint_velocity_rad_s`.
    """
    torque_nm = np.asarray(torque_nm, dtype=float)
    joint_velocity_rad_s = np.asarray(joint_velocity_rad_s, dtype=float)
    if attached is None:
        attached = np.ones(robot.cable_count, dtype=bool)
    motor = robot.motor
    inertia, friction, radius = motor.inertia_kg_m2, motor.viscous_friction_nm_s_rad, motor.drum_radius_m
    structure, lengths = structure_matrix(robot, position_m)
    rate = structure_matrix_rate(structure, lengths, velocity_m_s)
    taut = np.array(attached, dtype=bool)
    mass_matrix_base = robot.mass_kg * np.eye(3)
    weight = robot.mass_kg * robot.gravity_m_s2
    tension = np.zeros(robot.cable_count)
    while True:
        s = structure[:, taut]
        cable_speed = velocity_m_s @ s
        cable_rate = velocity_m_s @ rate[:, taut]
        mass_matrix = mass_matrix_base + (inertia / radius ** 2) * (s @ s.T)
        force = weight - s @ ((inertia * cable_rate + friction * cable_speed) / radius ** 2
                              + torque_nm[taut] / radius)
        acceleration = solve3(mass_matrix, force)
        theta_ddot_taut = -(acceleration @ s + cable_rate) / radius
        tension_taut = (inertia * theta_ddot_taut - friction * cable_speed / radius
                        - torque_nm[taut]) / radius
        if tension_taut.size == 0 or np.min(tension_taut) >= 0.0:
            break
        taut[np.flatnonzero(taut)[np.argmin(tension_taut)]] = False
    theta_ddot = (torque_nm - friction * joint_velocity_rad_s) / inertia
    theta_ddot[taut] = theta_ddot_taut
    tension[taut] = tension_taut
    return DirectDynamics(acceleration, theta_ddot, tension, taut)
