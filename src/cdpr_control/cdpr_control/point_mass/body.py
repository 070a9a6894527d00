"""The point mass: an end-effector of 3 translations, its pose the position p (m).

Its equations are this room's modules (kinematics, statics, dynamics, substeps:
docs/design.md §4); this class is what the rest of the stack calls them by.
"""
from __future__ import annotations

import numpy as np

from cdpr_control.geometry.motions import motion_from_settled
from cdpr_control.geometry.rotation import IDENTITY
from cdpr_control.model.body import Body
from cdpr_control.model.reference_table import tick_times
from cdpr_control.point_mass import substeps
from cdpr_control.point_mass.dynamics import NO_FORCE, direct_dynamics, motion_terms
from cdpr_control.point_mass.kinematics import forward_kinematics, inverse_kinematics, structure_matrix
from cdpr_control.point_mass.statics import holding_torque_nm, static_tensions

NO_POINTS = np.empty((0, 3))
NO_POINTS.setflags(write=False)
# NO_FORCE as the kernel takes it
NO_FORCE_ROW = np.zeros(3)
NO_FORCE_ROW.flags.writeable = False


class PointMass(Body):
    """A point mass: every cable ends at its position; it has no orientation."""

    kind = 'point_mass'
    degrees_of_freedom = 3
    # four cables: three hold its 3 DOF after one breaks
    minimum_cables = 4
    has_orientation = False
    home_orientation = None

    def numbers(self) -> np.ndarray:
        return np.empty(0)

    def cable_ends_m(self, position_m, orientation, cable_count: int) -> np.ndarray:
        return np.broadcast_to(np.asarray(position_m, dtype=float), (cable_count, 3))

    def orientation_from(self, section, key: str):
        return None

    def structure_matrix(self, robot, position_m, orientation) -> np.ndarray:
        return structure_matrix(robot, position_m)[0]

    def pose_of_angles(self, robot, angles_rad, cables=None, start=None, iterations=None):
        # closed form, then a few refining steps: no start or step count to choose
        return forward_kinematics(robot, np.asarray(angles_rad, dtype=float), cables), None

    def poses_of_angles(self, robot, angles_rad, cables=None, hints=None):
        # forward_kinematics takes one set of angles or a stack of them alike
        return forward_kinematics(robot, np.asarray(angles_rad, dtype=float), cables), None

    def orientation_error_rad(self, orientation, target) -> float:
        return 0.0

    def motion_terms(self, robot, poses, twists, twist_rates):
        return motion_terms(robot, poses, twists, twist_rates)

    def direct_dynamics(self, robot, pose, twist, torque_nm, joint_velocity_rad_s, attached=None,
                        external_wrench=None, kernel: str = 'compiled'):
        return direct_dynamics(robot, pose, twist, torque_nm, joint_velocity_rad_s, attached, external_wrench, kernel)

    def holding_torques_nm(self, robot, position_m, orientation, attached=None) -> np.ndarray:
        return holding_torque_nm(robot, position_m,
                                 np.ones(robot.cable_count, dtype=bool) if attached is None else attached)

    def unbalanced_force_n(self, robot, orientation, twist, acceleration, pulled) -> np.ndarray:
        return robot.mass_kg * (acceleration - robot.gravity_m_s2) - pulled

    def motion(self, motion):
        return motion_from_settled(motion)

    def reference_poses(self, robot, motion, period_s: float):
        path = motion_from_settled(motion).trajectory
        return path.sample(tick_times(period_s, path.duration_s))[0], None

    def check_goal(self, goal_m) -> None:
        """Any position is a goal; the schedule checks it against the workspace."""

    def outline_m(self, robot, position_m, orientation) -> np.ndarray:
        return NO_POINTS

    def rigid_cables(self, robot, kernel: str, retaut_tolerance_m: float) -> 'RigidCables':
        return RigidCables(robot, kernel, retaut_tolerance_m)

    def load_kernels(self) -> None:
        substeps.kernel().load_all()


class RigidCables:
    """The point mass's part of the rigid model (Body.rigid_cables): substeps.rigid_substeps
    on the position and velocity, the pose's and twist's first three entries."""

    def __init__(self, robot, kernel: str, retaut_tolerance_m: float):
        self.robot = robot
        self.kernel = substeps.kernel(kernel).load_all()
        self.constants = substeps.constants_of(robot, retaut_tolerance_m=retaut_tolerance_m)
        self.exits = np.array(robot.exit_points_m, dtype=float)
        self.offsets = np.array(robot.cable_length_offset_m, dtype=float)
        # the cables' directions at the model's position, which its next sub-step starts from
        # (the model's state, kept here as only this kernel takes it)
        self.directions = np.empty((robot.cable_count, 4))

    def start(self, position_m, orientation):
        """The identity, θ (rad) at p and the static tensions (N) of every cable there."""
        self.kernel.cable_directions(self.exits, position_m, self.directions)
        return IDENTITY, inverse_kinematics(self.robot, position_m), static_tensions(self.robot, position_m,
                                                                                     self.robot.cable_mask())

    def substeps(self, count, h, attached, torque_nm, external_force_n, pose, twist, angle, speed, tension,
                 taut) -> None:
        self.kernel.rigid_substeps(count, h, self.constants, self.exits, self.offsets, attached,
                                   np.ascontiguousarray(torque_nm, dtype=float),
                                   NO_FORCE_ROW if external_force_n is NO_FORCE
                                   else np.array(external_force_n, dtype=float),
                                   pose[:3], twist[:3], angle, speed, tension, taut, self.directions)
