"""The rigid platform: an end-effector of 3 rotations + 3 translations, its pose the
position p (m) of its frame's origin and the unit quaternion q (w, x, y, z) of its
orientation (docs/platform.md).

Its equations are this room's modules (kinematics, statics, dynamics, motion,
substeps, safe_pose, steered_approach); this class is what the rest of the stack calls
them by.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from cdpr_control.config import Section
from cdpr_control.geometry.motions import motion_from_settled
from cdpr_control.geometry.rotation import difference, normalised, rotation_matrix
from cdpr_control.model.body import Body
from cdpr_control.platform import substeps
from cdpr_control.model.reference_table import sampled
from cdpr_control.platform.dynamics import direct_dynamics, motion_terms, rigid_body, wrench_at_origin
from cdpr_control.platform.kinematics import (forward_kinematics, forward_kinematics_rows, inverse_kinematics,
                                              wrench_matrix)
from cdpr_control.platform.motion import pose_motion_from_settled, with_turn
from cdpr_control.platform.statics import static_tensions

# An inertia tensor this far from symmetric (relative) is a typing mistake.
SYMMETRY_TOLERANCE = 1e-9


@dataclass(frozen=True)
class Platform(Body):
    """A rigid platform: cable i is attached at b_i; the centre of mass c and the inertia
    tensor about it, all in the platform frame, whose origin is the platform's position p.
    `home_orientation` is the unit quaternion (w, x, y, z) of the home pose."""

    attachment_points_m: np.ndarray
    centre_of_mass_m: np.ndarray
    inertia_kg_m2: np.ndarray
    home_orientation: np.ndarray

    kind = 'platform'
    degrees_of_freedom = 6
    # six taut cables with gravity, and one more to lose one
    minimum_cables = 7
    has_orientation = True

    def __post_init__(self):
        for array in (self.attachment_points_m, self.centre_of_mass_m, self.inertia_kg_m2,
                      self.home_orientation):
            array.setflags(write=False)

    def numbers(self) -> np.ndarray:
        return np.concatenate([self.attachment_points_m.ravel(), self.centre_of_mass_m,
                               self.inertia_kg_m2.ravel(), self.home_orientation])

    def cable_ends_m(self, position_m, orientation, cable_count: int) -> np.ndarray:
        return position_m + self.attachment_points_m @ rotation_matrix(orientation).T

    def orientation_from(self, section: Section, key: str):
        return section.vector(key, 4, self.home_orientation.tolist())

    def structure_matrix(self, robot, position_m, orientation) -> np.ndarray:
        return wrench_matrix(robot, position_m, orientation)[0]

    def pose_of_angles(self, robot, angles_rad, cables=None, start=None, iterations=None):
        return forward_kinematics(robot, angles_rad, cables, start, iterations)

    def orientation_error_rad(self, orientation, target) -> float:
        return float(np.linalg.norm(difference(target, orientation)))

    def poses_of_angles(self, robot, angles_rad, cables=None, hints=None):
        return forward_kinematics_rows(robot, np.asarray(angles_rad, dtype=float), cables, hints)

    def motion_terms(self, robot, poses, twists, twist_rates):
        return motion_terms(robot, poses, twists, twist_rates)

    def direct_dynamics(self, robot, pose, twist, torque_nm, joint_velocity_rad_s, attached=None,
                        external_wrench=None, kernel: str = 'compiled'):
        return direct_dynamics(robot, pose, twist, torque_nm, joint_velocity_rad_s, attached, external_wrench, kernel)

    def holding_torques_nm(self, robot, position_m, orientation, attached=None) -> np.ndarray:
        return -robot.motor.drum_radius_m * static_tensions(robot, position_m, orientation, attached)

    def unbalanced_force_n(self, robot, orientation, twist, acceleration, pulled) -> np.ndarray:
        body = rigid_body(robot, orientation, twist[3:])
        return (body.mass_matrix @ acceleration - body.free_wrench - pulled)[:3]

    def motion(self, motion):
        return with_turn(motion_from_settled(motion), motion, self.home_orientation)

    def reference_poses(self, robot, motion, period_s: float):
        sample = sampled(pose_motion_from_settled(motion, self.home_orientation).pose_trajectory, period_s)
        return sample.position_m, sample.orientation

    def check_goal(self, goal_m) -> None:
        raise ValueError('a platform takes no goal positions yet: a move needs its orientation too')

    def outline_m(self, robot, position_m, orientation) -> np.ndarray:
        """Its origin joined to each attachment point at the pose (2m × 3)."""
        ends = self.cable_ends_m(position_m, orientation, robot.cable_count)
        return np.array([point for end in ends for point in (position_m, end)])

    def rigid_cables(self, robot, kernel: str, retaut_tolerance_m: float) -> 'RigidCables':
        return RigidCables(robot, kernel, retaut_tolerance_m)

    def load_kernels(self) -> None:
        substeps.kernel().load_all()


class RigidCables:
    """The platform's part of the rigid model (Body.rigid_cables): substeps.rigid_substeps
    on the whole pose and twist, an external force acting at the platform's origin."""

    def __init__(self, robot, kernel: str, retaut_tolerance_m: float):
        self.robot = robot
        self.kernel = substeps.kernel(kernel).load_all()
        self.exits, self.attachments, self.offsets = substeps.geometry_of(robot)
        self.constants = substeps.constants_of(robot, retaut_tolerance_m=retaut_tolerance_m)

    def start(self, position_m, orientation):
        """q (the home orientation when None), θ (rad) at the pose, and no tensions yet."""
        robot = self.robot
        orientation = normalised(robot.body.home_orientation if orientation is None else orientation)
        return (orientation, inverse_kinematics(robot, position_m, orientation),
                np.zeros(robot.cable_count))

    def substeps(self, count, h, attached, torque_nm, external_force_n, pose, twist, angle, speed, tension,
                 taut) -> None:
        self.kernel.rigid_substeps(count, h, self.constants, self.exits, self.attachments, self.offsets,
                                   attached, np.array(torque_nm, dtype=float), wrench_at_origin(external_force_n),
                                   pose, twist, angle, speed, tension, taut)


def platform_from_section(platform: Section, cable_count: int) -> Platform:
    """A Platform from a robot's `platform` section; ConfigError, naming the key, for
    attachment points that do not match the cables, or an inertia tensor no rigid body has."""
    attachment = platform.matrix('attachment_points_m', 3)
    if attachment.shape[0] != cable_count:
        raise platform.error('attachment_points_m', f'must list one point per cable ({cable_count}), '
                             f'got {attachment.shape[0]}')
    inertia = platform.matrix('inertia_kg_m2', 3)
    if inertia.shape != (3, 3) or not np.allclose(inertia, inertia.T, rtol=0.0,
                                                  atol=SYMMETRY_TOLERANCE * np.abs(inertia).max()):
        raise platform.error('inertia_kg_m2', f'must be a symmetric 3 × 3 tensor, got {inertia.tolist()}')
    principal = np.linalg.eigvalsh(inertia)
    if principal[0] <= 0.0 or principal[2] > principal[0] + principal[1] + SYMMETRY_TOLERANCE * principal[2]:
        raise platform.error('inertia_kg_m2', f'has principal moments {principal.round(6).tolist()}: '
                             'a rigid body\'s are positive and each at most the sum of the other two')
    try:
        home = normalised(platform.vector('home_orientation', 4, [1.0, 0.0, 0.0, 0.0]))
    except ValueError:
        raise platform.error('home_orientation', 'must be a quaternion (w, x, y, z) of non-zero norm') from None
    return Platform(attachment_points_m=attachment,
                    centre_of_mass_m=platform.vector('centre_of_mass_m', 3, [0.0, 0.0, 0.0]),
                    inertia_kg_m2=inertia, home_orientation=home)
