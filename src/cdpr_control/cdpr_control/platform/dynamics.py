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

from cdpr_control.platform import substeps as platform_substeps
from cdpr_control.model.dynamics import DirectDynamics, MotionTerms
from cdpr_control.model.robot import Robot
from cdpr_control.geometry.rotation import rotation_matrix


@dataclass
class RigidBody:
    """The platform's mass matrix M (6 × 6) and the wrench w_g − h (6) its weight and its
    velocity terms apply, at a pose and twist, about the platform frame's origin."""

    mass_matrix: np.ndarray
    free_wrench: np.ndarray


def rigid_body(robot: Robot, orientation, angular_velocity_rad_s, kernel: str = 'compiled') -> RigidBody:
    """M and w_g − h (module docstring) at the orientation and angular velocity (rad/s),
    by platform_substeps' `kernel`."""
    mass_matrix, free = np.empty((6, 6)), np.empty(6)
    platform_substeps.kernel(kernel).rigid_body(
        platform_substeps.constants_of(robot), rotation_matrix(orientation),
        np.concatenate([np.zeros(3), angular_velocity_rad_s]), mass_matrix, free)
    return RigidBody(mass_matrix, free)


def motion_terms(robot: Robot, poses, twists, accelerations) -> MotionTerms:
    """MotionTerms (model.dynamics) of each row of the poses (n × 7: p, q), twists (n × 6:
    v, ω) and their rates (n × 6: a, α), by platform_substeps.motion_rows: the wrench
    M (a, α) + h − w_g (module docstring)."""
    rows, m = len(poses), robot.cable_count
    columns, lengths, wrench = np.empty((rows, m, 6)), np.empty((rows, m)), np.empty((rows, 6))
    joint_velocity, joint_acceleration = np.empty((rows, m)), np.empty((rows, m))
    exits, attachments, _ = platform_substeps.geometry_of(robot)
    platform_substeps.kernel().motion_rows(
        platform_substeps.constants_of(robot), exits, attachments, *(np.ascontiguousarray(figure, dtype=float)
                                                                     for figure in (poses, twists, accelerations)),
        columns, lengths, wrench, joint_velocity, joint_acceleration)
    return MotionTerms(np.swapaxes(columns, 1, 2), lengths, wrench, joint_velocity, joint_acceleration)


def direct_dynamics(robot: Robot, pose, twist, torque_nm, joint_velocity_rad_s, attached=None,
                    external_wrench=None, kernel: str = 'compiled') -> DirectDynamics:
    """(a, α) at the pose (p, q) and twist (v, ω) under motor torques c with rigid cables: the attached cables that stay taut
    pull (module docstring); one whose tension comes out negative goes slack and the
    rest are solved again, the most negative first. The motor of a slack or detached
    cable spins freely: J θ̈ = −b θ̇ + c. Solved by platform_substeps' `kernel`."""
    m = robot.cable_count
    acceleration, joint_acceleration, tension, taut = np.empty(6), np.empty(m), np.empty(m), np.empty(m)
    exits, attachments, _ = platform_substeps.geometry_of(robot)
    platform_substeps.kernel(kernel).direct_dynamics(
        platform_substeps.constants_of(robot), exits, attachments,
        np.array(pose, dtype=float), np.array(twist, dtype=float),
        np.array(torque_nm, dtype=float), np.array(joint_velocity_rad_s, dtype=float),
        np.ones(m) if attached is None else np.array(attached, dtype=float),
        np.zeros(6) if external_wrench is None else np.array(external_wrench, dtype=float),
        acceleration, joint_acceleration, tension, taut)
    return DirectDynamics(acceleration, joint_acceleration, tension, taut != 0.0)


def wrench_at_origin(force_n) -> np.ndarray:
    """A force (N, world frame) applied at the platform frame's origin as a wrench
    (force, moment about the origin)."""
    return np.concatenate([np.asarray(force_n, dtype=float), np.zeros(3)])
