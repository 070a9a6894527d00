"""The robot model: geometry, end-effector and motors of a cable-suspended robot.

Described in YAML (section `robot`, see config/robots/paper_robot.yaml of cdpr_bringup;
read by cdpr_control.setup.robot_file), separate from the analyses and controllers that
use it. The end-effector's body (model/body.py) is a point mass or a rigid platform.
"""
from __future__ import annotations

import hashlib
from dataclasses import dataclass, field

import numpy as np

from cdpr_control.model.body import Body

# Hex digits of Robot.fingerprint(): 2^64 robots before two share one by chance.
FINGERPRINT_DIGITS = 16


@dataclass(frozen=True)
class Motor:
    """One winch: motor, drum and the friction the model knows about."""

    inertia_kg_m2: float
    drum_radius_m: float
    viscous_friction_nm_s_rad: float
    static_friction_nm: float
    nominal_torque_nm: float
    nominal_speed_rad_s: float
    torque_limit_nm: float


@dataclass(frozen=True)
class Robot:
    """A cable-suspended robot with m cables whose end-effector is `body`: a point mass
    (3 DOF) or a rigid platform (6 DOF: position and orientation).

    Cable i runs from exit point A_i to the end-effector (to its attachment point b_i on a
    platform); indices are 0-based in code (motor_1 is index 0). Joint angle θ_i grows as
    cable i pays out: l_i = l_i0 + ρ θ_i with θ = 0 at the home pose (`home_position_m`,
    and the body's `home_orientation`).
    """

    name: str
    exit_points_m: np.ndarray
    mass_kg: float
    gravity_m_s2: np.ndarray
    motor: Motor
    tension_min_n: float
    tension_max_n: float
    workspace_min_m: np.ndarray
    workspace_max_m: np.ndarray
    home_position_m: np.ndarray
    body: Body
    cable_length_offset_m: np.ndarray = field(init=False)

    def __post_init__(self):
        offset = np.linalg.norm(self.exit_points_m - self.cable_ends_m(
            self.home_position_m, self.body.home_orientation), axis=1)
        object.__setattr__(self, 'cable_length_offset_m', offset)
        for array in (self.exit_points_m, self.gravity_m_s2, self.workspace_min_m,
                      self.workspace_max_m, self.home_position_m, offset):
            array.setflags(write=False)

    def cable_ends_m(self, position_m, orientation) -> np.ndarray:
        """Where each cable ends on the end-effector at the pose (m × 3, world frame): the
        point mass's position, or a platform's attachment points p + R(q) b_i."""
        return self.body.cable_ends_m(position_m, orientation, self.cable_count)

    @property
    def cable_count(self) -> int:
        return self.exit_points_m.shape[0]

    @property
    def degrees_of_freedom(self) -> int:
        return self.body.degrees_of_freedom

    @property
    def weight_wrench_n(self) -> np.ndarray:
        """External wrench w_e = m_e g on the end-effector (N)."""
        return self.mass_kg * self.gravity_m_s2

    def fingerprint(self) -> str:
        """A short hash of everything the model of this robot is made of (geometry, mass,
        motors, tension bounds), not of its name or how its file is written: what a
        calibration made on it is bound to."""
        numbers = np.concatenate([
            self.exit_points_m.ravel(), [self.mass_kg], self.gravity_m_s2,
            [getattr(self.motor, name) for name in Motor.__dataclass_fields__],
            [self.tension_min_n, self.tension_max_n], self.workspace_min_m,
            self.workspace_max_m, self.home_position_m, self.body.numbers()])
        text = ','.join(f'{value:.9g}' for value in numbers)
        return hashlib.sha256(text.encode()).hexdigest()[:FINGERPRINT_DIGITS]

    def cable_mask(self, broken=()) -> np.ndarray:
        """Boolean mask of the cables still attached, given 0-based broken indices."""
        mask = np.ones(self.cable_count, dtype=bool)
        for index in broken:
            if not 0 <= index < self.cable_count:
                raise IndexError(f'cable index {index} outside 0..{self.cable_count - 1}')
            mask[index] = False
        return mask
