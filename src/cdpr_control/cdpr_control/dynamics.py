"""Inverse and rigid direct dynamics of the cable robot (docs/design.md §4).

Motor i:        J θ̈_i = −b θ̇_i + c_i + ρ τ_i
End-effector:   m_e p̈ = S τ + m_e g
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .kinematics import (cable_directions, joint_acceleration, joint_velocity, structure_matrix,
                         structure_matrix_rate)
from .linalg3 import solve3_floats
from .robot import Robot
from .tension_distribution import InfeasibleTensionError, TensionDistribution

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
                    attached=None) -> DirectDynamics:
    """Accelerations under torques c for a rigid-cable robot.

    Taut cables obey (m_e I + (J/ρ²) S Sᵀ) p̈ = m_e g − (J/ρ²) S Ṡᵀ ṗ − (b/ρ²) S Sᵀ ṗ − (1/ρ) S c.
    A cable whose implied tension would be negative goes slack and leaves S (the most
    negative first, until all remaining tensions are non-negative); the motors of slack
    and detached cables spin freely, J θ̈ = −b θ̇ + c, from `joint_velocity_rad_s`.
    """
    if attached is None:
        attached = np.ones(robot.cable_count, dtype=bool)
    directions = cable_directions(robot.exit_points_m.tolist(),
                                  np.asarray(position_m, dtype=float).tolist())
    acceleration, theta_ddot, tension, taut = RigidDirectDynamics(robot).accelerations(
        directions, np.asarray(velocity_m_s, dtype=float).tolist(),
        np.asarray(torque_nm, dtype=float).tolist(),
        np.asarray(joint_velocity_rad_s, dtype=float).tolist(),
        np.asarray(attached, dtype=bool).tolist())
    return DirectDynamics(np.array(acceleration), np.array(theta_ddot), np.array(tension),
                          np.array(taut, dtype=bool))


class RigidDirectDynamics:
    """direct_dynamics on plain floats, for the loops that call it every sub-step.

    The twin and the rigid plant evaluate it once per sub-step on a handful of cables,
    where numpy's per-call overhead outweighs the arithmetic several times; the robot's
    constants are unpacked once, here.
    """

    def __init__(self, robot: Robot):
        motor = robot.motor
        self.mass_kg = robot.mass_kg
        self.weight_n = tuple((robot.mass_kg * robot.gravity_m_s2).tolist())
        self.inertia_kg_m2 = motor.inertia_kg_m2
        self.friction_nm_s_rad = motor.viscous_friction_nm_s_rad
        self.radius_m = motor.drum_radius_m
        # J/ρ² (kg): a motor's inertia as the cable feels it
        self.reflected_mass_kg = motor.inertia_kg_m2 / motor.drum_radius_m ** 2

    def accelerations(self, directions, velocity_m_s, torque_nm, joint_velocity_rad_s, candidates,
                      external_force_n=NO_FORCE):
        """p̈ (m/s², a 3-tuple), and per cable θ̈ (rad/s²), τ (N) and taut flags (lists).

        `directions` holds (u_x, u_y, u_z, d_i) per cable (kinematics.cable_directions) and
        `candidates` flags the cables that may be taut; `external_force_n` acts on the
        end-effector besides its weight (a push: the plant's, never the twin's); every
        argument is plain floats.
        """
        inertia, friction, radius = self.inertia_kg_m2, self.friction_nm_s_rad, self.radius_m
        radius_squared = radius * radius
        mass, reflected = self.mass_kg, self.reflected_mass_kg
        vx, vy, vz = velocity_m_s
        speed_squared = vx * vx + vy * vy + vz * vz
        # Per cable, ṗ·u_i (m/s) and ṗ·u̇_i = ((u_i·ṗ)² − |ṗ|²) / d_i (m/s², u̇_i of
        # docs/design.md §4); the motor law then gives τ_i = −(J/ρ²) u_i·p̈ − pull_i,
        # pull_i (N) free of p̈.
        cable_speed, cable_rate, pull = [], [], []
        for (ux, uy, uz, d), c in zip(directions, torque_nm):
            speed = ux * vx + uy * vy + uz * vz
            rate = (speed * speed - speed_squared) / d
            cable_speed.append(speed)
            cable_rate.append(rate)
            pull.append((inertia * rate + friction * speed) / radius_squared + c / radius)
        taut = list(candidates)
        wx, wy, wz = self.weight_n
        if external_force_n is not NO_FORCE:
            wx, wy, wz = wx + external_force_n[0], wy + external_force_n[1], wz + external_force_n[2]
        while True:
            sxx = sxy = sxz = syy = syz = szz = 0.0
            fx = fy = fz = 0.0
            for (ux, uy, uz, _), is_taut, p in zip(directions, taut, pull):
                if is_taut:
                    sxx += ux * ux
                    sxy += ux * uy
                    sxz += ux * uz
                    syy += uy * uy
                    syz += uy * uz
                    szz += uz * uz
                    fx += ux * p
                    fy += uy * p
                    fz += uz * p
            mxy, mxz, myz = reflected * sxy, reflected * sxz, reflected * syz
            ax, ay, az = solve3_floats(
                ((mass + reflected * sxx, mxy, mxz), (mxy, mass + reflected * syy, myz),
                 (mxz, myz, mass + reflected * szz)),
                (wx - fx, wy - fy, wz - fz))
            theta_ddot, tension = [], []
            # The cable of the most negative tension goes slack, and the taut set is solved again.
            most_negative, slack = 0.0, -1
            for i, ((ux, uy, uz, _), is_taut, c, w) in enumerate(
                    zip(directions, taut, torque_nm, joint_velocity_rad_s)):
                if is_taut:
                    theta_ddot_i = -(ax * ux + ay * uy + az * uz + cable_rate[i]) / radius
                    tension_i = (inertia * theta_ddot_i - friction * cable_speed[i] / radius
                                 - c) / radius
                    if tension_i < most_negative:
                        most_negative, slack = tension_i, i
                else:
                    theta_ddot_i = (c - friction * w) / inertia
                    tension_i = 0.0
                theta_ddot.append(theta_ddot_i)
                tension.append(tension_i)
            if slack < 0:
                return (ax, ay, az), theta_ddot, tension, taut
            taut[slack] = False
