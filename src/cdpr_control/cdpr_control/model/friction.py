"""The motors' Coulomb friction as the control stack models it."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from cdpr_control.config import Section
from cdpr_control.model.robot import Robot


@dataclass(frozen=True)
class FrictionModel:
    """Coulomb friction torque (N·m), reached smoothly over `smoothing_rad_s`, raised near
    standstill by a break-away excess (N·m) fading over the Stribeck speed (rad/s)."""

    coulomb_nm: float
    smoothing_rad_s: float
    breakaway_nm: float = 0.0
    stribeck_speed_rad_s: float = 1.0

    @classmethod
    def of_robot(cls, robot: Robot, control: Section, coulomb_nm: float | None = None) -> 'FrictionModel':
        """The motors' static friction (robot.motor), unless `coulomb_nm` or the control
        section's `coulomb_friction_nm` (a settled run's: 0 on the rigid plant, which is the
        twin's friction-free model, or as calibrated) says otherwise."""
        if coulomb_nm is None:
            coulomb_nm = control.number('coulomb_friction_nm', robot.motor.static_friction_nm,
                                        non_negative=True)
        return cls(float(coulomb_nm), control.number('coulomb_smoothing_rad_s', positive=True))

    @classmethod
    def of_twin(cls, twin: Section, control: Section) -> 'FrictionModel | None':
        """The friction the twin models (`twin.coulomb_friction_nm`, and its break-away
        `twin.breakaway_friction_nm` over `twin.stribeck_speed_rad_s`); None for none."""
        coulomb_nm = twin.number('coulomb_friction_nm', non_negative=True)
        breakaway_nm = twin.number('breakaway_friction_nm', non_negative=True)
        stribeck = twin.number('stribeck_speed_rad_s', positive=True)
        if not (coulomb_nm or breakaway_nm):
            return None
        return cls(coulomb_nm, control.number('coulomb_smoothing_rad_s', positive=True), breakaway_nm, stribeck)

    def torque_nm(self, angular_velocity_rad_s: np.ndarray) -> np.ndarray:
        """The torque friction takes from a motor turning at `angular_velocity_rad_s`."""
        if self.breakaway_nm:
            standstill = np.exp(-(angular_velocity_rad_s / self.stribeck_speed_rad_s) ** 2)
            return (self.coulomb_nm + self.breakaway_nm * standstill) * np.tanh(angular_velocity_rad_s / self.smoothing_rad_s)
        if self.coulomb_nm == 0.0:
            return np.zeros_like(angular_velocity_rad_s)
        return self.coulomb_nm * np.tanh(angular_velocity_rad_s / self.smoothing_rad_s)
