"""Joint-space PD + inverse-dynamics feed-forward controller and its modes (paper Fig. 2)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .config import Section
from .robot import Robot

NOMINAL = 'NOMINAL'
RECOVERY_TENSION = 'RECOVERY_TENSION'
RECOVERY_MOVE = 'RECOVERY_MOVE'
SAFE_HOLD = 'SAFE_HOLD'
FAULT = 'FAULT'
MODES = (NOMINAL, RECOVERY_TENSION, RECOVERY_MOVE, SAFE_HOLD, FAULT)


@dataclass(frozen=True)
class PdGains:
    """Joint PD gains: stiffness (N·m/rad) and damping (N·m·s/rad)."""

    stiffness_nm_rad: float
    damping_nm_s_rad: float

    @classmethod
    def from_bandwidth(cls, robot: Robot, frequency_hz: float, damping_ratio: float) -> 'PdGains':
        """Gains placing a joint loaded by J + m_e ρ² at `frequency_hz` with `damping_ratio`."""
        inertia = robot.motor.inertia_kg_m2 + robot.mass_kg * robot.motor.drum_radius_m ** 2
        omega = 2.0 * np.pi * frequency_hz
        return cls(inertia * omega ** 2, 2.0 * damping_ratio * inertia * omega)

    @classmethod
    def from_section(cls, robot: Robot, control: Section) -> 'PdGains':
        return cls.from_bandwidth(robot, control.number('pd_natural_frequency_hz', positive=True),
                                  control.number('pd_damping_ratio', positive=True))


@dataclass
class JointReference:
    """What the controller tracks: θ_d (rad), θ̇_d (rad/s) and the feed-forward c_ID (N·m)."""

    angle_rad: np.ndarray
    angular_velocity_rad_s: np.ndarray
    feedforward_nm: np.ndarray

    def at_rest(self) -> 'JointReference':
        return JointReference(self.angle_rad.copy(), np.zeros_like(self.angular_velocity_rad_s),
                              self.feedforward_nm.copy())


class JointController:
    """c = c_ID + K_p (θ_d − θ) + K_d (θ̇_d − θ̇), within the torque limit, per mode.

    NOMINAL and RECOVERY_MOVE track a joint reference (the trajectory's, or the
    recovery's); RECOVERY_TENSION applies tension setpoints t as c = −ρ t + b θ̇;
    SAFE_HOLD and FAULT hold the last reference at rest. A motor whose cable is broken
    gets zero torque in every mode: freed of its load it would ring under loaded gains.
    """

    def __init__(self, robot: Robot, gains: PdGains):
        self.robot = robot
        self.gains = gains
        self.torque_limit_nm = robot.motor.torque_limit_nm
        self.mode = NOMINAL
        self.broken = np.zeros(robot.cable_count, dtype=bool)
        self.tension_setpoint_n: np.ndarray | None = None
        self.hold: JointReference | None = None

    def set_mode(self, mode: str) -> None:
        if mode not in MODES:
            raise ValueError(f'unknown mode {mode!r}; one of {", ".join(MODES)}')
        self.mode = mode

    def set_broken(self, cables) -> None:
        """Mark the 0-based `cables` as broken (their motors get zero torque from now on)."""
        for index in cables:
            self.broken[index] = True

    def set_tension_setpoint(self, tensions_n: np.ndarray) -> None:
        self.tension_setpoint_n = np.asarray(tensions_n, dtype=float)

    def feedback(self, angle_rad, angular_velocity_rad_s, reference: JointReference) -> np.ndarray:
        """The PD part c_FB (N·m)."""
        return (self.gains.stiffness_nm_rad * (reference.angle_rad - angle_rad)
                + self.gains.damping_nm_s_rad
                * (reference.angular_velocity_rad_s - angular_velocity_rad_s))

    def command(self, angle_rad, angular_velocity_rad_s, reference: JointReference | None) -> np.ndarray:
        """Motor torques c (N·m) for the measured θ, θ̇ in the current mode."""
        if self.mode == RECOVERY_TENSION and self.tension_setpoint_n is not None:
            torque = (-self.robot.motor.drum_radius_m * self.tension_setpoint_n
                      + self.robot.motor.viscous_friction_nm_s_rad * angular_velocity_rad_s)
        else:
            if self.mode in (SAFE_HOLD, FAULT) or reference is None:
                if self.hold is None:
                    self.hold = (reference or JointReference(
                        np.asarray(angle_rad, float), np.zeros(self.robot.cable_count),
                        np.zeros(self.robot.cable_count))).at_rest()
                reference = self.hold
            else:
                self.hold = None
            torque = reference.feedforward_nm + self.feedback(angle_rad, angular_velocity_rad_s,
                                                              reference)
        torque = np.clip(torque, -self.torque_limit_nm, self.torque_limit_nm)
        torque[self.broken] = 0.0
        return torque
