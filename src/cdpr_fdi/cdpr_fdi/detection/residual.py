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

from cdpr_control.model.friction import FrictionModel
from cdpr_control.model.robot import Motor

from . import tick_arithmetic


def sensorless_tensions(motor: Motor, friction: FrictionModel, applied_torque_nm: np.ndarray,
                        speed_before_rad_s: np.ndarray, speed_after_rad_s: np.ndarray,
                        period_s) -> np.ndarray:
    """τ̂ (N) over one period in which `applied_torque_nm` took the motors between two speeds.

    Friction is evaluated at the speed the period started with, as the drive integrates it.
    One period (a value per motor, `period_s` s), or a run's: a row per period, `period_s`
    one for all or one per row.
    """
    return _sensorless(motor, friction, applied_torque_nm, speed_before_rad_s, speed_after_rad_s, period_s)[0]


def sensorless_tension_bounds(motor: Motor, friction: FrictionModel, applied_torque_nm: np.ndarray,
                              speed_before_rad_s: np.ndarray, speed_after_rad_s: np.ndarray,
                              period_s) -> tuple[np.ndarray, np.ndarray]:
    """The lowest and highest τ̂ (N) the friction between the two speeds allows."""
    _, low, high = _sensorless(motor, friction, applied_torque_nm, speed_before_rad_s, speed_after_rad_s,
                               period_s)
    return low, high


def _sensorless(motor, friction, applied_torque_nm, speed_before_rad_s, speed_after_rad_s,
                period_s) -> np.ndarray:
    """τ̂, its lowest and highest (3, *shape) (tick_arithmetic.sensorless_tensions)."""
    constants, kernel = tick_arithmetic.motor_constants(motor, friction), tick_arithmetic.kernel()
    rows = [np.ascontiguousarray(values, dtype=float)
            for values in (applied_torque_nm, speed_before_rad_s, speed_after_rad_s)]
    if rows[0].ndim == 1:
        result = np.empty((3, rows[0].size))
        kernel.sensorless_tensions(constants, *rows, float(period_s), *result)
        return result
    periods = np.broadcast_to(np.asarray(period_s, dtype=float).reshape(-1), len(rows[0]))
    result = np.empty((3, *rows[0].shape))
    for k, period in enumerate(periods.tolist()):
        kernel.sensorless_tensions(constants, rows[0][k], rows[1][k], rows[2][k], period, result[0, k],
                                   result[1, k], result[2, k])
    return result
