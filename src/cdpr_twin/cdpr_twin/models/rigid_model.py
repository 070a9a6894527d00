"""Rigid-cable robot simulation: the digital twin's model, and the plant's `rigid` fidelity."""
from __future__ import annotations

import numpy as np

from cdpr_control.point_mass import substeps as point_mass_substeps
from cdpr_control.point_mass.dynamics import NO_FORCE
from cdpr_control.point_mass.kinematics import inverse_kinematics
from cdpr_control.model.robot import Robot
from cdpr_control.geometry.rotation import IDENTITY
from cdpr_control.point_mass.statics import static_tensions

# A slack cable whose motor has wound in to within this much of the straight-line
# length is taut again (m).
RETAUT_TOLERANCE_M = 1e-9
# NO_FORCE as the kernel takes it
NO_FORCE_ROW = np.zeros(3)
NO_FORCE_ROW.flags.writeable = False


class RigidCableRobot:
    """State p, ṗ (m, m/s) and θ, θ̇ (rad, rad/s); taut cables tie θ to p.

    Each step integrates the direct dynamics by semi-implicit Euler in `substeps`
    (cdpr_control.point_mass.substeps.rigid_substeps, run by its `kernel`). A cable is
    taut while attached, not paid out beyond the straight-line length, and pulling
    (non-negative tension); otherwise its motor spins freely. After each sub-step the
    taut motors are put back on the kinematic constraint, so the model does not drift. A
    step replaces the state arrays rather than writing into them.
    """

    # a point mass has no orientation to tell: the identity, as a platform's model has one
    orientation = IDENTITY

    def __init__(self, robot: Robot, position_m, substeps: int = 1, kernel: str = 'compiled'):
        self.robot = robot
        self.substeps = int(substeps)
        self.kernel = point_mass_substeps.kernel(kernel).load_all()
        self.constants = point_mass_substeps.constants_of(robot, retaut_tolerance_m=RETAUT_TOLERANCE_M)
        self.exits = np.array(robot.exit_points_m, dtype=float)
        self.offsets = np.array(robot.cable_length_offset_m, dtype=float)
        self.position_m = np.array(position_m, dtype=float)
        self.velocity_m_s = np.zeros(3)
        self.angle_rad = inverse_kinematics(robot, self.position_m)
        self.angular_velocity_rad_s = np.zeros(robot.cable_count)
        # A brake holds every drum still; taut rigid cables then hold the end-effector.
        self.drums_locked = False
        self.attached_mask = np.ones(robot.cable_count)    # 1.0 while attached, as the kernel takes it
        self.tension_n = static_tensions(robot, self.position_m, self.attached)
        self.taut_mask = np.ones(robot.cable_count)
        # the cables' directions at position_m, which the next sub-step starts from
        self.directions = np.empty((robot.cable_count, 4))
        self.kernel.cable_directions(self.exits, self.position_m, self.directions)

    def break_cables(self, cables) -> None:
        """Detach the 0-based `cables` for good."""
        for index in cables:
            self.attached_mask[index] = 0.0

    @property
    def attached(self) -> np.ndarray:
        """Which cables are still attached (bool per cable)."""
        return self.attached_mask != 0.0

    def step(self, torque_nm: np.ndarray, period_s: float, substeps: int | None = None,
             external_force_n=NO_FORCE) -> None:
        """Apply `torque_nm` (N·m) for `period_s` (s), in `substeps` (default: the
        model's), and `external_force_n` (N, world frame) on the end-effector."""
        if self.drums_locked:
            self.velocity_m_s = np.zeros(3)
            self.angular_velocity_rad_s = np.zeros(self.robot.cable_count)
            return
        m = self.robot.cable_count
        substeps = substeps or self.substeps
        position, velocity = self.position_m.copy(), self.velocity_m_s.copy()
        angle, speed = self.angle_rad.copy(), self.angular_velocity_rad_s.copy()
        tension, taut = np.empty(m), np.empty(m)
        self.kernel.rigid_substeps(substeps, period_s / substeps, self.constants, self.exits, self.offsets,
                                   self.attached_mask, np.ascontiguousarray(torque_nm, dtype=float),
                                   NO_FORCE_ROW if external_force_n is NO_FORCE
                                   else np.array(external_force_n, dtype=float),
                                   position, velocity, angle, speed, tension, taut, self.directions)
        self.position_m, self.velocity_m_s = position, velocity
        self.angle_rad, self.angular_velocity_rad_s = angle, speed
        self.tension_n, self.taut_mask = tension, taut

    @property
    def taut(self) -> np.ndarray:
        """Which cables are taut (bool per cable)."""
        return self.taut_mask != 0.0
