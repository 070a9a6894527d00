"""Rigid-cable robot simulation, whatever its body: the digital twin's model, and the
plant's `rigid` fidelity (docs/platform.md for a platform's)."""
from __future__ import annotations

import numpy as np

from cdpr_control.point_mass.dynamics import NO_FORCE
from cdpr_control.model.robot import Robot

# A slack cable whose motor has wound in to within this much of the straight-line
# length is taut again (m).
RETAUT_TOLERANCE_M = 1e-9


class RigidModel:
    """State: pose (p m, q: the identity for a point mass), twist (v m/s, ω rad/s: ω zero
    for a point mass), motors θ, θ̇ (rad, rad/s); taut cables tie θ to the pose.

    Each step integrates the body's direct dynamics by semi-implicit Euler in `substeps`
    (its rigid sub-steps, Body.rigid_cables, run by its `kernel`). A cable is taut while
    attached, not paid out beyond the straight-line length, and pulling (non-negative
    tension); otherwise its motor spins freely. After each sub-step the taut motors are
    put back on the kinematic constraint, so the model does not drift. A step replaces the
    state arrays rather than writing into them.
    """

    def __init__(self, robot: Robot, position_m, orientation=None, substeps: int = 1, kernel: str = 'compiled'):
        """At rest at the pose (p, `orientation`: the body's home one when None)."""
        self.robot = robot
        self.substeps = int(substeps)
        self.cables = robot.body.rigid_cables(robot, kernel, RETAUT_TOLERANCE_M)
        position_m = np.array(position_m, dtype=float)
        orientation, self.angle_rad, self.tension_n = self.cables.start(position_m, orientation)
        self.pose = np.concatenate([position_m, orientation])
        self.twist = np.zeros(6)
        self.angular_velocity_rad_s = np.zeros(robot.cable_count)
        # A brake holds every drum still; taut rigid cables then hold the end-effector.
        self.drums_locked = False
        # 1.0 for yes, 0.0 for no per cable, as the kernels take and give them
        self.attached_mask = np.ones(robot.cable_count)
        self.taut_mask = np.ones(robot.cable_count)

    def break_cables(self, cables) -> None:
        """Detach the 0-based `cables` for good."""
        for index in cables:
            self.attached_mask[index] = 0.0

    def step(self, torque_nm: np.ndarray, period_s: float, substeps: int | None = None,
             external_force_n=NO_FORCE) -> None:
        """Apply `torque_nm` (N·m) for `period_s` (s), in `substeps` (default: the
        model's), and `external_force_n` (N, world frame) at the end-effector (a
        platform's origin)."""
        if self.drums_locked:
            self.twist = np.zeros(6)
            self.angular_velocity_rad_s = np.zeros(self.robot.cable_count)
            return
        m = self.robot.cable_count
        substeps = substeps or self.substeps
        pose, twist = self.pose.copy(), self.twist.copy()
        angle, speed = self.angle_rad.copy(), self.angular_velocity_rad_s.copy()
        tension, taut = np.empty(m), np.empty(m)
        self.cables.substeps(substeps, period_s / substeps, self.attached_mask, torque_nm, external_force_n,
                             pose, twist, angle, speed, tension, taut)
        self.pose, self.twist = pose, twist
        self.angle_rad, self.angular_velocity_rad_s = angle, speed
        self.tension_n, self.taut_mask = tension, taut

    # The masks as bools, and the pose's and twist's parts: views, as a step replaces the arrays.
    attached = property(lambda self: self.attached_mask != 0.0, doc='Which cables are still attached (bool).')
    taut = property(lambda self: self.taut_mask != 0.0, doc='Which cables are taut (bool).')
    position_m = property(lambda self: self.pose[:3])
    orientation = property(lambda self: self.pose[3:], doc='Unit quaternion (w, x, y, z); a point mass: identity.')
    velocity_m_s = property(lambda self: self.twist[:3])
    platform_angular_velocity_rad_s = property(lambda self: self.twist[3:])
