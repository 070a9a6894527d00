"""Inverse dynamics of either body: the motor torques that make the end-effector follow a
motion (docs/design.md §4, docs/platform.md); and what the direct dynamics give.

A pose is (p, q) — 3 numbers for a point mass, 7 for a platform —, its twist (v, ω) and
the twist's rate (a, α) have as many entries as the body has degrees of freedom (3 or 6).
The body gives, per pose, its structure matrix S (dof × m), the wrench the cables must
apply, M (a, α) + h − w_g, and the joint motion θ̇, θ̈ of taut cables (Body.motion_terms);
the tensions that apply it are shared by a TensionDistribution, and each motor's torque
follows from J θ̈_i = −b θ̇_i + c_i + ρ τ_i.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from cdpr_control.tension_distribution import InfeasibleTensionError, TensionDistribution


@dataclass
class MotionTerms:
    """Per row of a motion (n poses with their twists and twist rates): S (n × dof × m), the
    cable lengths d (m), the wrench the cables must apply (N, and N·m for a platform), and
    the joint motion θ̇ (rad/s) and θ̈ (rad/s²) of taut cables."""

    structure: np.ndarray
    length_m: np.ndarray
    wrench_n: np.ndarray
    joint_velocity_rad_s: np.ndarray
    joint_acceleration_rad_s2: np.ndarray


@dataclass
class InverseDynamics:
    """Torques c (N·m), the tensions (N) they produce, and the joint motion: θ (rad, the
    pose's inverse kinematics), θ̇ (rad/s) and θ̈ (rad/s²)."""

    torque_nm: np.ndarray
    tension_n: np.ndarray
    joint_angle_rad: np.ndarray
    joint_velocity_rad_s: np.ndarray
    joint_acceleration_rad_s2: np.ndarray


@dataclass
class DirectDynamics:
    """The twist's rate (a, α) (m/s², and rad/s² for a platform), θ̈ (rad/s²), the tensions
    (N) and which cables are taut, under given motor torques (Body.direct_dynamics)."""

    twist_rate: np.ndarray
    joint_acceleration_rad_s2: np.ndarray
    tension_n: np.ndarray
    taut: np.ndarray

    @property
    def acceleration_m_s2(self) -> np.ndarray:
        return self.twist_rate[:3]

    @property
    def angular_acceleration_rad_s2(self) -> np.ndarray:
        """α (rad/s²): no entries for a point mass."""
        return self.twist_rate[3:]


def inverse_dynamics(robot, distribution: TensionDistribution, pose, twist, twist_rate, attached=None,
                     external_wrench=None, nan_where_infeasible: bool = False) -> InverseDynamics:
    """Torques that make the end-effector follow the pose, twist and its rate with the
    `attached` cables (all when None): the cables' wrench, less `external_wrench` (what
    a push applies), is shared by `distribution`, and c = J θ̈ + b θ̇ − ρ τ. A detached
    (broken) cable carries no tension and its motor is not tied to the end-effector: its
    figures are 0. Of one pose, or of each row of stacks (a tabulated motion at once);
    InfeasibleTensionError names the first pose no tensions within the bounds pull (with
    `nan_where_infeasible`, such rows' tensions and torques are NaN instead)."""
    motor = robot.motor
    single = np.ndim(pose) == 1
    poses = np.atleast_2d(np.asarray(pose, dtype=float))
    terms = robot.body.motion_terms(robot, poses, np.atleast_2d(twist), np.atleast_2d(twist_rate))
    wrench = terms.wrench_n if external_wrench is None else terms.wrench_n - external_wrench
    theta_dot, theta_ddot = terms.joint_velocity_rad_s, terms.joint_acceleration_rad_s2
    angle = (terms.length_m - robot.cable_length_offset_m) / motor.drum_radius_m
    distribute = distribution.distribute_each if nan_where_infeasible else distribution.distribute_rows
    try:
        if attached is None:
            tension = distribute(terms.structure, wrench)
        else:
            tension = np.zeros(theta_dot.shape)
            tension[:, attached] = distribute(terms.structure[:, :, attached], wrench)
    except InfeasibleTensionError as err:
        where = poses[err.row]
        err = err if attached is None else err.of_cables(np.flatnonzero(attached))
        raise err.at(where[:3], where[3:] if where.size > 3 else None) from None
    if attached is not None:
        for figure in (angle, theta_dot, theta_ddot):
            figure[:, ~attached] = 0.0
    torque = (motor.inertia_kg_m2 * theta_ddot + motor.viscous_friction_nm_s_rad * theta_dot
              - motor.drum_radius_m * tension)
    figures = (torque, tension, angle, theta_dot, theta_ddot)
    return InverseDynamics(*(figure[0] for figure in figures) if single else figures)
