"""Rigid-cable simulation of a platform robot (6 DOF): the digital twin's model of it, and
the plant's `rigid` fidelity for it (docs/platform.md)."""
from __future__ import annotations

import numpy as np

from cdpr_control.platform import substeps as platform_substeps
from cdpr_control.platform import kinematics as pose_kinematics
from cdpr_control.point_mass.dynamics import NO_FORCE
from cdpr_control.platform.dynamics import wrench_at_origin
from cdpr_control.model.robot import Robot
from cdpr_control.geometry.rotation import normalised

from cdpr_twin.models.rigid_model import RETAUT_TOLERANCE_M

class RigidPlatform:
    """State: pose (p, q), twist (v, ω), motors θ, θ̇ (rad, rad/s); taut cables tie θ to
    the pose.

    Each step integrates the Newton–Euler direct dynamics (cdpr_control.platform.dynamics) by
    semi-implicit Euler in `substeps` (cdpr_control.platform.substeps.rigid_substeps, run
    by its `kernel`): twist first, then the pose with it (the orientation turned by the
    rotation vector h ω). A cable is taut while attached, not paid out beyond the
    straight-line length and pulling; otherwise its motor spins freely. After each
    sub-step the taut motors are put back on the kinematic constraint. As RigidCableRobot,
    a step replaces the state arrays rather than writing into them.
    """

    def __init__(self, robot: Robot, position_m, orientation=None, substeps: int = 1, kernel: str = 'compiled'):
        """At rest at the pose (p, `orientation`: the platform's home one when None)."""
        self.robot = robot
        self.substeps = int(substeps)
        self.kernel = platform_substeps.kernel(kernel).load_all()
        self.exits, self.attachments, self.offsets = platform_substeps.geometry_of(robot)
        self.constants = platform_substeps.constants_of(robot, retaut_tolerance_m=RETAUT_TOLERANCE_M)
        self.position_m = np.array(position_m, dtype=float)
        self.orientation = normalised(robot.body.home_orientation if orientation is None else orientation)
        self.velocity_m_s = np.zeros(3)
        self.platform_angular_velocity_rad_s = np.zeros(3)
        self.angle_rad = pose_kinematics.inverse_kinematics(robot, self.position_m, self.orientation)
        self.angular_velocity_rad_s = np.zeros(robot.cable_count)
        self.drums_locked = False
        self.attached = np.ones(robot.cable_count, dtype=bool)
        self.taut = self.attached.copy()
        self.tension_n = np.zeros(robot.cable_count)

    def break_cables(self, cables) -> None:
        """Detach the 0-based `cables` for good."""
        for index in cables:
            self.attached[index] = False

    def step(self, torque_nm, period_s: float, substeps: int | None = None, external_force_n=NO_FORCE) -> None:
        """Apply `torque_nm` (N·m) for `period_s` (s), in `substeps` (default: the model's),
        and `external_force_n` (N, world frame) at the platform's origin."""
        if self.drums_locked:
            self.velocity_m_s, self.platform_angular_velocity_rad_s = np.zeros(3), np.zeros(3)
            self.angular_velocity_rad_s = np.zeros(self.robot.cable_count)
            return
        robot = self.robot
        substeps = substeps or self.substeps
        pose = np.concatenate([self.position_m, self.orientation])
        twist = np.concatenate([self.velocity_m_s, self.platform_angular_velocity_rad_s])
        angle, speed = self.angle_rad.copy(), self.angular_velocity_rad_s.copy()
        tension, taut = np.empty(robot.cable_count), np.empty(robot.cable_count)
        self.kernel.rigid_substeps(substeps, period_s / substeps, self.constants, self.exits,
                                   self.attachments, self.offsets,
                                   self.attached.astype(float), np.array(torque_nm, dtype=float),
                                   wrench_at_origin(external_force_n),
                                   pose, twist, angle, speed, tension, taut)
        self.position_m, self.orientation = pose[:3], pose[3:]
        self.velocity_m_s, self.platform_angular_velocity_rad_s = twist[:3], twist[3:]
        self.angle_rad, self.angular_velocity_rad_s = angle, speed
        self.tension_n, self.taut = tension, taut != 0.0
