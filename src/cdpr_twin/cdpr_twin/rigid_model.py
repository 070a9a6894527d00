"""Rigid-cable robot simulation: the digital twin's model, and the plant's `rigid` fidelity."""
from __future__ import annotations

import numpy as np

from cdpr_control.dynamics import NO_FORCE, RigidDirectDynamics
from cdpr_control.kinematics import cable_directions, inverse_kinematics
from cdpr_control.robot import Robot
from cdpr_control.rotation import IDENTITY
from cdpr_control.statics import static_tensions

# A slack cable whose motor has wound in to within this much of the straight-line
# length is taut again (m).
RETAUT_TOLERANCE_M = 1e-9


class RigidCableRobot:
    """State p, ṗ (m, m/s) and θ, θ̇ (rad, rad/s); taut cables tie θ to p.

    Each step integrates the direct dynamics by semi-implicit Euler in `substeps`. A
    cable is taut while attached, not paid out beyond the straight-line length, and
    pulling (non-negative tension); otherwise its motor spins freely. After each
    sub-step the taut motors are put back on the kinematic constraint, so the model
    does not drift. A step replaces the state arrays rather than writing into them.
    """

    # a point mass has no orientation to tell: the identity, as a platform's model has one
    orientation = IDENTITY

    def __init__(self, robot: Robot, position_m, substeps: int = 1):
        self.robot = robot
        self.substeps = int(substeps)
        self.position_m = np.array(position_m, dtype=float)
        self.velocity_m_s = np.zeros(3)
        self.angle_rad = inverse_kinematics(robot, self.position_m)
        self.angular_velocity_rad_s = np.zeros(robot.cable_count)
        # A brake holds every drum still; taut rigid cables then hold the end-effector.
        self.drums_locked = False
        self.attached = np.ones(robot.cable_count, dtype=bool)
        self.tension_n = static_tensions(robot, self.position_m, self.attached)
        self.taut = self.attached.copy()
        self.dynamics = RigidDirectDynamics(robot)
        self.exit_points_m = robot.exit_points_m.tolist()
        self.cable_length_offset_m = robot.cable_length_offset_m.tolist()
        # The cable directions at the end of the last sub-step are those the next one
        # starts from: kept with the position they belong to.
        self.directions_at: tuple | None = None
        self.directions: list = []

    def break_cables(self, cables) -> None:
        """Detach the 0-based `cables` for good."""
        for index in cables:
            self.attached[index] = False

    def step(self, torque_nm: np.ndarray, period_s: float, external_force_n=NO_FORCE) -> None:
        """Apply `torque_nm` (N·m) for `period_s` (s), and `external_force_n` (N, world
        frame) on the end-effector.

        Plain floats throughout: a sub-step on numpy arrays of m ≈ 4 entries spends its
        time in numpy's per-call overhead, not in the arithmetic.
        """
        if self.drums_locked:
            self.velocity_m_s = np.zeros(3)
            self.angular_velocity_rad_s = np.zeros(self.robot.cable_count)
            return
        radius = self.robot.motor.drum_radius_m
        h = period_s / self.substeps
        torque = np.asarray(torque_nm, dtype=float).tolist()
        external = tuple(external_force_n)
        position = tuple(self.position_m.tolist())
        vx, vy, vz = self.velocity_m_s.tolist()
        angle = self.angle_rad.tolist()
        speed = self.angular_velocity_rad_s.tolist()
        attached = self.attached.tolist()
        offsets = self.cable_length_offset_m
        for _ in range(self.substeps):
            directions = (self.directions if position == self.directions_at
                          else cable_directions(self.exit_points_m, position))
            candidates = [on and offset + radius * theta <= d + RETAUT_TOLERANCE_M
                          for on, offset, theta, (_, _, _, d)
                          in zip(attached, offsets, angle, directions)]
            (ax, ay, az), theta_ddot, tension, taut = self.dynamics.accelerations(
                directions, (vx, vy, vz), torque, speed, candidates, external)
            vx, vy, vz = vx + h * ax, vy + h * ay, vz + h * az
            px, py, pz = position
            position = (px + h * vx, py + h * vy, pz + h * vz)
            directions = cable_directions(self.exit_points_m, position)
            next_angle, next_speed = [], []
            for (ux, uy, uz, d), offset, is_taut, theta, w, a in zip(
                    directions, offsets, taut, angle, speed, theta_ddot):
                if is_taut:
                    # on the kinematic constraint: l = d, θ̇ = −uᵀ ṗ / ρ
                    theta = (d - offset) / radius
                    w = -(ux * vx + uy * vy + uz * vz) / radius
                else:
                    w += h * a
                    theta += h * w
                next_angle.append(theta)
                next_speed.append(w)
            angle, speed = next_angle, next_speed
            self.directions, self.directions_at = directions, position
        self.position_m = np.array(position)
        self.velocity_m_s = np.array((vx, vy, vz))
        self.angle_rad = np.array(angle)
        self.angular_velocity_rad_s = np.array(speed)
        self.tension_n = np.array(tension)
        self.taut = np.array(taut)
