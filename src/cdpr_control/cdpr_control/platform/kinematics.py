"""Kinematics of a rigid platform on m cables (docs/platform.md; DESIGN §9).

Pose x = (p, q): the position p of the platform frame's origin (m) and the unit
quaternion q of its orientation (rotation.py). Attachment point b_i (platform frame) is
at p + r_i in the world, r_i = R(q) b_i; the cable runs from it to the exit point A_i:
l_i = A_i − p − r_i, length d_i = |l_i|, unit u_i = l_i / d_i.

Wrench matrix W (6 × m), column i = [u_i ; r_i × u_i]: the force and the moment about p
that a unit tension in cable i applies. Twist (v, ω), world frame: ḋ_i = −u_iᵀ (v + ω × r_i),
i.e. ḋ = −Wᵀ (v, ω); with l_i = l_i0 + ρ θ_i, θ̇ = −Wᵀ (v, ω) / ρ.
"""
from __future__ import annotations

import numpy as np

from cdpr_control.platform import substeps as platform_substeps
from cdpr_control.model.body import KinematicsError
from cdpr_control.model.pose_tracking import PoseTracker
from cdpr_control.model.robot import Robot
from cdpr_control.geometry.rotation import cross_rows, normalised, rotation_matrix

# Forward kinematics: Gauss–Newton on the six pose coordinates until every cable's
# length is met to FK_TOLERANCE_M, or the step is below FK_STEP_TOLERANCE (m, rad): the
# least-squares pose of lengths that carry noise and stretch; at most FK_ITERATIONS.
FK_ITERATIONS = 30
FK_TOLERANCE_M = 1e-12
FK_STEP_TOLERANCE = 1e-11
# The least-squares pose whose lengths are still off by more than this (m) fits the
# lengths of no pose: they are inconsistent (a stale angle, a broken cable counted).
# Resolver noise and the cables' stretch leave up to a few tenths of a millimetre.
FK_RESIDUAL_LIMIT_M = 1e-3
# A recorded run read offline has no tick's budget: a row that does not converge in
# FK_ITERATIONS steps from the row before gets this many from each better start.
FK_READ_ITERATIONS = 200


def cable_vectors(robot: Robot, position_m, orientation) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(u: m × 3 unit vectors platform → exit point, d: m lengths (m), r: m × 3 attachment
    points relative to p, world frame) at the pose (p, q)."""
    return cable_geometry(robot, position_m, rotation_matrix(orientation))


def cable_geometry(robot: Robot, position_m, rotation: np.ndarray):
    """cable_vectors for the platform's rotation matrix R."""
    r = robot.body.attachment_points_m @ rotation.T
    cable = robot.exit_points_m - position_m - r
    d = np.sqrt(np.einsum('ij,ij->i', cable, cable))
    return cable / d[:, None], d, r


def structure_of(u: np.ndarray, r: np.ndarray) -> np.ndarray:
    """W (6 × m) from the cables' unit vectors and attachment points (m × 3 each)."""
    return np.concatenate([u, cross_rows(r, u)], axis=1).T


def wrench_matrix(robot: Robot, position_m, orientation) -> tuple[np.ndarray, np.ndarray]:
    """W (6 × m) and the cable lengths d (m) at the pose (p, q)."""
    u, d, r = cable_vectors(robot, position_m, orientation)
    return structure_of(u, r), d


def inverse_kinematics(robot: Robot, position_m, orientation) -> np.ndarray:
    """Motor angles θ (rad) that put the platform at the pose (p, q)."""
    _, d, _ = cable_vectors(robot, position_m, orientation)
    return (d - robot.cable_length_offset_m) / robot.motor.drum_radius_m


def length_rates(structure: np.ndarray, twist) -> np.ndarray:
    """ḋ = −Wᵀ (v, ω) (m/s, one per cable), `twist` the six (v, ω)."""
    return -(twist @ structure)


def length_accelerations(structure: np.ndarray, velocity_product_m_s2: np.ndarray, accelerations) -> np.ndarray:
    """d̈ = −Wᵀ (a, α) + κ (m/s², one per cable), `accelerations` the six (a, α), κ
    `velocity_product`'s."""
    return velocity_product_m_s2 - accelerations @ structure


def joint_velocity(robot: Robot, position_m, orientation, velocity_m_s, angular_velocity_rad_s) -> np.ndarray:
    """θ̇ = ḋ / ρ (rad/s)."""
    structure, _ = wrench_matrix(robot, position_m, orientation)
    return (length_rates(structure, np.concatenate([velocity_m_s, angular_velocity_rad_s]))
            / robot.motor.drum_radius_m)


def joint_acceleration(robot: Robot, position_m, orientation, velocity_m_s, angular_velocity_rad_s,
                       acceleration_m_s2, angular_acceleration_rad_s2) -> np.ndarray:
    """θ̈ = d̈ / ρ (rad/s²)."""
    u, d, r = cable_vectors(robot, position_m, orientation)
    return length_accelerations(structure_of(u, r), velocity_product(u, d, r, velocity_m_s, angular_velocity_rad_s),
                                np.concatenate([acceleration_m_s2, angular_acceleration_rad_s2])
                                ) / robot.motor.drum_radius_m


def velocity_product(u: np.ndarray, d: np.ndarray, r: np.ndarray, velocity_m_s,
                     angular_velocity_rad_s) -> np.ndarray:
    """κ (m/s², one per cable), the part of d̈ the twist makes without any acceleration:
    κ_i = s_iᵀ (I − u_i u_iᵀ) s_i / d_i − u_iᵀ (ω × (ω × r_i)), s_i = v + ω × r_i the
    attachment point's velocity (the derivative of ḋ_i = −u_iᵀ s_i); computed by
    platform_substeps, whose kernels use it."""
    kappa = np.empty(d.shape[0])
    platform_substeps.kernel().velocity_product(np.array(u, dtype=float), np.array(d, dtype=float),
                                                np.array(r, dtype=float),
                                                np.concatenate([velocity_m_s, angular_velocity_rad_s]), kappa)
    return kappa


def forward_kinematics(robot: Robot, angles_rad, cables=None, start=None,
                       iterations: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The pose (p, q) whose cable lengths are those of the motor angles of `cables`
    (boolean mask; at least 6), by Gauss–Newton from `start` (a pose; the home pose when
    None): each step solves Wᵀ δ = d(x) − l in the least-squares sense for δ = (δp, δφ),
    moves p by δp and turns q by the rotation vector δφ. It stops when every length is
    met to FK_TOLERANCE_M or the step is below FK_STEP_TOLERANCE (the least-squares pose
    of lengths with noise); KinematicsError after `iterations` steps (FK_ITERATIONS where
    None; a recovery's fallback takes more, model.pose_tracking), or when the
    lengths are then still off by more than FK_RESIDUAL_LIMIT_M. Where the cables used
    lose rank on the way, the step is damped (Levenberg–Marquardt). Solved by
    platform_substeps.forward_kinematics."""
    used = np.ones(robot.cable_count) if cables is None else np.array(cables, dtype=bool).astype(float)
    used_count = np.count_nonzero(used)
    if used_count < 6:
        raise KinematicsError(f'forward kinematics of a platform needs 6 cables, got {used_count}')
    lengths = robot.cable_length_offset_m + robot.motor.drum_radius_m * np.asarray(angles_rad, dtype=float)
    position, orientation = ((robot.home_position_m, robot.body.home_orientation) if start is None
                             else start)
    pose = np.concatenate([position, normalised(orientation)])
    exits, attachments, _ = platform_substeps.geometry_of(robot)
    steps = FK_ITERATIONS if iterations is None else int(iterations)
    taken = platform_substeps.kernel().forward_kinematics(exits, attachments, lengths, used, pose, steps,
                                                          FK_TOLERANCE_M, FK_STEP_TOLERANCE)
    if taken == -1:
        raise KinematicsError(f'forward kinematics did not converge in {steps} Gauss–Newton steps')
    if taken == -2:
        raise KinematicsError('forward kinematics: the cable lengths are not numbers')
    position, orientation = pose[:3], pose[3:]
    _, d, _ = cable_vectors(robot, position, orientation)
    worst = np.max(np.abs(d - lengths)[used != 0.0])
    if worst > FK_RESIDUAL_LIMIT_M:
        raise KinematicsError(f'the cable lengths fit no pose: at the closest, one is off by '
                              f'{worst * 1000:.3f} mm')
    return position, orientation


def forward_kinematics_rows(robot: Robot, angles_rad, cables=None, hints=None) -> tuple[np.ndarray, np.ndarray]:
    """`forward_kinematics` of each row of a stack of angles (n × m), as a recorded run is
    read: (positions n × 3, orientations n × 4), each row started from the row before's pose
    (the first from home), as a node follows the platform tick by tick. A row that does not
    converge there falls back as a recovery's pose does (model.pose_tracking), on
    FK_READ_ITERATIONS steps: near a pose where one direction is barely held (the smallest
    singular value of W a five-hundredth of the largest), the cables' stretch moves the
    least-squares pose millimetres a tick, and from the row before Gauss–Newton may need
    more than FK_ITERATIONS steps; `hints` (positions n × 3, orientations n × 4), a pose
    per row to retry from too (the twin's: a drawn platform's first measured row, far
    from home, was met from home in no number of steps)."""
    angles = np.asarray(angles_rad, dtype=float)
    used = np.ones(robot.cable_count, dtype=bool) if cables is None else cables
    tracker = PoseTracker(robot, used, FK_READ_ITERATIONS)
    positions, orientations = np.empty((len(angles), 3)), np.empty((len(angles), 4))
    for row, row_angles in enumerate(angles):
        hint = None if hints is None else (hints[0][row], hints[1][row])
        positions[row], orientations[row] = tracker.pose(row_angles, hint)
    return positions, orientations
