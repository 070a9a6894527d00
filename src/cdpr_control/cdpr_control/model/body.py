"""The end-effector's body: what every analysis asks of it, whichever it is.

A robot's body is a point mass (3 translations: the pose is the position p) or a rigid
platform (3 rotations + 3 translations: the pose is p and the unit quaternion q of its
orientation). Each is a class of its own room (`cdpr_control.point_mass`,
`cdpr_control.platform`) that implements this interface; nothing outside those rooms asks
which one a robot has. A pose is passed as (position m, orientation), the orientation
None for a body that has none. `robot` below is the Robot (model/robot.py) whose body
it is, `section` a config Section, `distribution` a TensionDistribution.
"""
from __future__ import annotations

from abc import ABC, abstractmethod

import numpy as np


class KinematicsError(ValueError):
    """The cable lengths admit no pose of the end-effector."""


class Body(ABC):
    """The interface of an end-effector's body (module docstring)."""

    # Names the body's implementations in other packages (the plants, cdpr_twin.models.plant).
    kind: str
    degrees_of_freedom: int
    # cables the robot needs to keep every degree of freedom after one breaks
    minimum_cables: int
    # the pose has an orientation part (a unit quaternion w, x, y, z): what a pose's
    # figures, rows and message carry besides the position
    has_orientation: bool
    # the orientation of the home pose (None for a body without one)
    home_orientation: np.ndarray | None

    @abstractmethod
    def numbers(self) -> np.ndarray:
        """Every number the body is made of, for the robot's fingerprint."""

    @abstractmethod
    def cable_ends_m(self, position_m, orientation, cable_count: int) -> np.ndarray:
        """Where each cable ends on the end-effector at the pose (m × 3, world frame)."""

    @abstractmethod
    def orientation_from(self, section, key: str):
        """The orientation `section` gives under `key` (the home one where it gives none);
        None for a body without one."""

    @abstractmethod
    def structure_matrix(self, robot, position_m, orientation) -> np.ndarray:
        """The structure (wrench) matrix (dof × m) at the pose: column i the wrench a unit
        tension of cable i applies."""

    @abstractmethod
    def pose_of_angles(self, robot, angles_rad, cables=None, start=None, iterations=None):
        """(position m, orientation) where the motor angles of `cables` (boolean mask;
        all when None) put the end-effector: forward kinematics, from the pose `start`
        (home when None) in at most `iterations` steps (the body's default when None), for
        a body whose forward kinematics iterates; KinematicsError where it finds none. A
        recovery finds its poses through model.pose_tracking.PoseTracker, which falls
        back where this does not converge."""

    @abstractmethod
    def orientation_error_rad(self, orientation, target) -> float:
        """The angle (rad) from the orientation `target` to `orientation` (0 for a body
        without one)."""

    @abstractmethod
    def poses_of_angles(self, robot, angles_rad, cables=None, hints=None):
        """(positions n × 3, orientations n × 4 or None) of each row of a stack of motor
        angles (n × m), as a recorded run is read; `hints` (positions, orientations) a
        pose per row to fall back on where a body's iteration needs a better start (the
        twin's, for the measured angles)."""

    @abstractmethod
    def motion_terms(self, robot, poses, twists, twist_rates):
        """model.dynamics.MotionTerms of each row of the poses (n × 3, or n × 7 with the
        orientation), twists and their rates (n × dof): what the inverse dynamics of
        either body is computed from."""

    @abstractmethod
    def direct_dynamics(self, robot, pose, twist, torque_nm, joint_velocity_rad_s, attached=None,
                        external_wrench=None, kernel: str = 'compiled'):
        """model.dynamics.DirectDynamics at the pose and twist under the motor torques
        (N·m), the motors at `joint_velocity_rad_s`, with the `attached` cables (all when
        None) and `external_wrench` (dof: N, and N·m for a platform) besides, rigid cables."""

    @abstractmethod
    def holding_torques_nm(self, robot, position_m, orientation, attached=None) -> np.ndarray:
        """c = −ρ t (N·m): the motor torques whose static tensions t of the `attached`
        cables (all when None) hold the end-effector still at the pose."""

    @abstractmethod
    def unbalanced_force_n(self, robot, orientation, twist, acceleration, pulled) -> np.ndarray:
        """The force (N, 3) on the end-effector that its motion (`twist` and its rate
        `acceleration`, dof each), its weight and the cables' wrench `pulled` (dof) leave
        unexplained: what a push or a contact applies."""

    @abstractmethod
    def motion(self, motion):
        """The reference motion (geometry.motions.Motion) of the settled `motion` section
        for this body: its path, and for a platform its turn."""

    @abstractmethod
    def reference_poses(self, robot, motion, period_s: float):
        """(positions n × 3, orientations n × 4 or None) of the settled `motion` at every
        tick, as the trajectory generator tabulates them, to the bit."""

    @abstractmethod
    def check_goal(self, goal_m) -> None:
        """ValueError, saying why, where this body takes no goal position."""

    @abstractmethod
    def outline_m(self, robot, position_m, orientation) -> np.ndarray:
        """The body drawn as line segments at the pose (2k × 3 points, m; none for a
        point, whose marker is its sphere)."""

    @abstractmethod
    def rigid_cables(self, robot, kernel: str, retaut_tolerance_m: float):
        """The body's part of the rigid-cable model (cdpr_twin.models.rigid_model), its
        `kernel` (KERNELS) loaded: `start(position_m, orientation)` gives the start pose's
        orientation (the home one when None; the identity for a point mass), motor angles
        (rad) and tensions (N); `substeps(count, h, attached, torque_nm, external_force_n,
        pose, twist, angle, speed, tension, taut)` runs the body's rigid sub-steps on the
        model's arrays (pose: p, q; twist: v, ω), updating them in place."""

    @abstractmethod
    def load_kernels(self) -> None:
        """The compiled functions the body's models step with, loaded now."""
