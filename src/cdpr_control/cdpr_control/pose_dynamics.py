"""Rigid-body dynamics of a platform on m cables with their motors (docs/platform.md).

Newton–Euler of the platform at its frame's origin p, with the centre of mass c
(world offset c_w = R c), inertia I_w = R I_c Rᵀ about it, twist (v, ω) and its rate
(a, α), all in the world frame:

    M(x) (a, α) + h(x, ẋ) = W τ + w_g + w_ext
    M = [[m I, −m [c_w]×], [m [c_w]×, I_w − m [c_w]×²]]
    h = [m ω × (ω × c_w) ; ω × (I_w ω) + m c_w × (ω × (ω × c_w))]
    w_g = [m g ; c_w × m g]

Motor i, as for the point mass: J θ̈_i = −b θ̇_i + c_i + ρ τ_i, with (pose_kinematics)
θ̈ = (−Wᵀ (a, α) + κ) / ρ. Rigid taut cables then give

    (M + (J/ρ²) W Wᵀ) (a, α) = w_g + w_ext − h + W ((J/ρ²) κ + (b/ρ) θ̇ − c/ρ),

and a cable whose tension comes out negative is slack and leaves W. A point mass is the
case c = 0, I_c = 0, b_i = 0, where these reduce to docs/design.md §4.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .pose_kinematics import cable_geometry, length_accelerations, length_rates, structure_of, velocity_product
from .robot import Robot
from .rotation import rotation_matrix, skew
from .tension_distribution import InfeasibleTensionError, TensionDistribution


@dataclass
class PlatformInverseDynamics:
    """Torques c (N·m) and the joint motion and tensions (N) they produce."""

    torque_nm: np.ndarray
    tension_n: np.ndarray
    joint_velocity_rad_s: np.ndarray
    joint_acceleration_rad_s2: np.ndarray


@dataclass
class PlatformDirectDynamics:
    """(a, α) (m/s², rad/s²), θ̈ (rad/s²), tensions (N) and which cables are taut."""

    acceleration_m_s2: np.ndarray
    angular_acceleration_rad_s2: np.ndarray
    joint_acceleration_rad_s2: np.ndarray
    tension_n: np.ndarray
    taut: np.ndarray


@dataclass
class RigidBody:
    """The platform's mass matrix M (6 × 6), velocity terms h (6) and weight wrench w_g (6)
    at a pose and twist, about the platform frame's origin."""

    mass_matrix: np.ndarray
    velocity_terms: np.ndarray
    weight_wrench: np.ndarray


def rigid_body(robot: Robot, orientation, angular_velocity_rad_s) -> RigidBody:
    return rigid_body_at(robot, rotation_matrix(orientation), angular_velocity_rad_s)


def rigid_body_at(robot: Robot, rotation: np.ndarray, angular_velocity_rad_s) -> RigidBody:
    """rigid_body for the platform's rotation matrix R."""
    mass = robot.mass_kg
    offset = rotation @ robot.platform.centre_of_mass_m
    inertia = rotation @ robot.platform.inertia_kg_m2 @ rotation.T
    cross = skew(offset)
    turn = skew(angular_velocity_rad_s)
    omega = np.asarray(angular_velocity_rad_s, dtype=float)
    mass_matrix = np.empty((6, 6))
    mass_matrix[:3, :3] = mass * np.eye(3)
    mass_matrix[:3, 3:] = -mass * cross
    mass_matrix[3:, :3] = mass * cross
    mass_matrix[3:, 3:] = inertia - mass * cross @ cross
    centripetal = turn @ (turn @ offset)
    velocity_terms = np.concatenate([mass * centripetal, turn @ (inertia @ omega) + mass * cross @ centripetal])
    weight = mass * robot.gravity_m_s2
    return RigidBody(mass_matrix, velocity_terms, np.concatenate([weight, cross @ weight]))


def inverse_dynamics(robot: Robot, tension_distribution: TensionDistribution, position_m, orientation,
                     velocity_m_s, angular_velocity_rad_s, acceleration_m_s2, angular_acceleration_rad_s2,
                     attached=None, external_wrench=None) -> PlatformInverseDynamics:
    """Torques that make the platform follow the pose x, twist and its rate with the
    `attached` cables: the cables' wrench w = M (a, α) + h − w_g − w_ext is shared by
    `tension_distribution`, and c = J θ̈ + b θ̇ − ρ τ. A detached cable carries no tension
    and its motor is not tied to the platform: its figures are 0."""
    motor = robot.motor
    rotation = rotation_matrix(orientation)
    u, d, r = cable_geometry(robot, position_m, rotation)
    structure = structure_of(u, r)
    body = rigid_body_at(robot, rotation, angular_velocity_rad_s)
    accelerations = np.concatenate([acceleration_m_s2, angular_acceleration_rad_s2])
    wrench = body.mass_matrix @ accelerations + body.velocity_terms - body.weight_wrench
    if external_wrench is not None:
        wrench = wrench - external_wrench
    try:
        if attached is None:
            tension = tension_distribution.distribute(structure, wrench)
        else:
            tension = np.zeros(robot.cable_count)
            tension[attached] = tension_distribution.distribute(structure[:, attached], wrench)
    except InfeasibleTensionError as err:
        raise err.at(position_m, orientation) from None
    theta_dot = (length_rates(structure, np.concatenate([velocity_m_s, angular_velocity_rad_s]))
                 / motor.drum_radius_m)
    theta_ddot = length_accelerations(structure, velocity_product(u, d, r, velocity_m_s, angular_velocity_rad_s),
                                      accelerations) / motor.drum_radius_m
    if attached is not None:
        theta_dot[~attached] = 0.0
        theta_ddot[~attached] = 0.0
    torque = (motor.inertia_kg_m2 * theta_ddot + motor.viscous_friction_nm_s_rad * theta_dot
              - motor.drum_radius_m * tension)
    return PlatformInverseDynamics(torque, tension, theta_dot, theta_ddot)


def direct_dynamics(robot: Robot, position_m, orientation, velocity_m_s, angular_velocity_rad_s,
                    torque_nm, joint_velocity_rad_s, attached=None,
                    external_wrench=None) -> PlatformDirectDynamics:
    """(a, α) under motor torques c with rigid cables: the attached cables that stay taut
    pull (module docstring); one whose tension comes out negative goes slack and the
    rest are solved again, the most negative first. The motor of a slack or detached
    cable spins freely: J θ̈ = −b θ̇ + c."""
    motor = robot.motor
    inertia, damping, radius = motor.inertia_kg_m2, motor.viscous_friction_nm_s_rad, motor.drum_radius_m
    torque = np.asarray(torque_nm, dtype=float)
    theta_dot = np.asarray(joint_velocity_rad_s, dtype=float)
    rotation = rotation_matrix(orientation)
    u, d, r = cable_geometry(robot, position_m, rotation)
    structure = structure_of(u, r)
    kappa = velocity_product(u, d, r, velocity_m_s, angular_velocity_rad_s)
    body = rigid_body_at(robot, rotation, angular_velocity_rad_s)
    free = body.weight_wrench - body.velocity_terms
    if external_wrench is not None:
        free = free + external_wrench
    # a taut cable's tension as the motor's equation gives it, before the platform's part
    pull = (inertia / radius ** 2) * kappa + (damping / radius) * theta_dot - torque / radius
    taut = np.ones(robot.cable_count, dtype=bool) if attached is None else np.array(attached, dtype=bool)
    while True:
        taut_structure = structure[:, taut]
        accelerations = np.linalg.solve(
            body.mass_matrix + (inertia / radius ** 2) * taut_structure @ taut_structure.T,
            free + taut_structure @ pull[taut])
        tension = np.zeros(robot.cable_count)
        tension[taut] = pull[taut] - (inertia / radius ** 2) * (taut_structure.T @ accelerations)
        if not taut.any() or tension[taut].min() >= 0.0:
            break
        taut[np.argmin(np.where(taut, tension, np.inf))] = False
    theta_ddot = length_accelerations(structure, kappa, accelerations) / radius
    loose = ~taut
    theta_ddot[loose] = (-damping * theta_dot[loose] + torque[loose]) / inertia
    tension[loose] = 0.0
    return PlatformDirectDynamics(accelerations[:3], accelerations[3:], theta_ddot, tension, taut)


def wrench_at_origin(force_n) -> np.ndarray | None:
    """A force (N, world frame) applied at the platform frame's origin as a wrench
    (force, moment about the origin); None for no force."""
    force = np.asarray(force_n, dtype=float)
    return None if not force.any() else np.concatenate([force, np.zeros(3)])
