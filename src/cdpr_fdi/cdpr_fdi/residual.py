"""What the supervisor reads off the motors: torque residuals and sensorless tensions.

r = c − c_DT (docs/design.md §5). A motor obeys J θ̈ = −b θ̇ − f_c sgn(θ̇) + c + ρ τ, so over one
control period the tension its cable pulled with is
τ̂ = (J θ̈ + b θ̇ + f_c sgn(θ̇) − c) / ρ, with θ̈ from two resolver speeds: a freed motor
(eq. 18) shows τ̂ ≈ 0. The Coulomb term is smoothed as the drives' friction is.

Friction is known only at the two sampled speeds: over the period it took every value
between the two (friction grows with speed), so τ̂ is really an interval. It is narrow
for a motor turning steadily and wide for one whose speed crosses zero — which a freed
motor, held by its own controller, does.
"""
from __future__ import annotations

import numpy as np

from cdpr_control.friction import FrictionModel
from cdpr_control.robot import Motor


def sensorless_tensions(motor: Motor, friction: FrictionModel, applied_torque_nm: np.ndarray,
                        speed_before_rad_s: np.ndarray, speed_after_rad_s: np.ndarray,
                        period_s: float) -> np.ndarray:
    """τ̂ (N) over one period in which `applied_torque_nm` took the motors between two speeds.

    Friction is evaluated at the speed the period started with, as the drive integrates it.
    """
    return _tensions(motor, friction.torque_nm(speed_before_rad_s), applied_torque_nm,
                     speed_before_rad_s, speed_after_rad_s, period_s)


def _tensions(motor: Motor, friction_before_nm: np.ndarray, applied_torque_nm: np.ndarray,
              speed_before_rad_s: np.ndarray, speed_after_rad_s: np.ndarray,
              period_s: float) -> np.ndarray:
    acceleration = (speed_after_rad_s - speed_before_rad_s) / period_s
    load = (motor.inertia_kg_m2 * acceleration
            + motor.viscous_friction_nm_s_rad * speed_before_rad_s
            + friction_before_nm - applied_torque_nm)
    return load / motor.drum_radius_m


def sensorless_tension_bounds(motor: Motor, friction: FrictionModel, applied_torque_nm: np.ndarray,
                              speed_before_rad_s: np.ndarray, speed_after_rad_s: np.ndarray,
                              period_s: float) -> tuple[np.ndarray, np.ndarray]:
    """The lowest and highest τ̂ (N) the friction between the two speeds allows."""
    friction_before = friction.torque_nm(speed_before_rad_s)
    at_start = _tensions(motor, friction_before, applied_torque_nm, speed_before_rad_s,
                         speed_after_rad_s, period_s)
    other_end = at_start + (friction.torque_nm(speed_after_rad_s)
                            - friction_before) / motor.drum_radius_m
    return np.minimum(at_start, other_end), np.maximum(at_start, other_end)
