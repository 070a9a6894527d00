"""A sequential detector: CUSUM with a Shewhart limit, per motor, on normalised residuals.

The nominal residual of a real drive is mostly the Coulomb friction the twin does not
model; it follows the sign of the motion's speed, which the twin knows. Removing it and
dividing by the nominal spread σ leaves z_i = |r_i − f_c tanh(θ̇_DT,i / v)| / σ_i, which a
healthy robot keeps near 1. Three tests run, each calibrated for a third of the
false-alarm budget: the CUSUM g_i ← max(0, g_i + z_i − ν) alarms at g_i > h and finds a
shift a few σ above normal that persists (a lightly loaded cable), long before a fixed
ε set above the nominal peaks would; the limit z_i > z_max finds a jump on the tick it
happens; and the paper's |r_i| > ε keeps the jumps whose friction adds to the residual,
which removing the friction would hide. It is never much slower than the threshold
detector and much faster where that one is slow.
"""
from __future__ import annotations

import numpy as np

from cdpr_control.model.friction import FrictionModel

from .base import Detector


class CusumDetector(Detector):

    name = 'cusum'

    def __init__(self, sigma_nm, drift: float, threshold: float, limit: float,
                 epsilon_nm: float, friction: FrictionModel):
        super().__init__()
        self.sigma_nm = np.asarray(sigma_nm, dtype=float)
        if np.any(self.sigma_nm <= 0.0):
            raise ValueError(f'sigma must be positive, got {sigma_nm}')
        if drift < 0.0 or threshold <= 0.0 or limit <= drift:
            raise ValueError(f'need drift >= 0, threshold > 0 and limit > drift, got '
                             f'{drift}, {threshold}, {limit}')
        self.drift = float(drift)
        self.level = float(threshold)
        self.limit = float(limit)
        self.epsilon_nm = float(epsilon_nm)
        self.friction = friction
        self.statistic = np.zeros(0)

    def normalised_residual(self, residual_nm: np.ndarray, twin_speed_rad_s: np.ndarray) -> np.ndarray:
        """z_i: the residual without the expected friction, in units of the nominal spread."""
        return np.abs(residual_nm - self.friction.torque_nm(twin_speed_rad_s)) / self.sigma_nm

    def update(self, residual_nm: np.ndarray, twin_speed_rad_s: np.ndarray) -> bool:
        if self.statistic.shape != residual_nm.shape:
            self.statistic = np.zeros_like(residual_nm, dtype=float)
        z = self.normalised_residual(residual_nm, twin_speed_rad_s)
        self.statistic = np.maximum(0.0, self.statistic + z - self.drift)
        return bool(np.max(self.statistic) > self.level or np.max(z) > self.limit
                    or np.max(np.abs(residual_nm)) > self.epsilon_nm)

    @property
    def threshold(self) -> float:
        return self.level

    @property
    def least_alarming_nm(self) -> np.ndarray:
        # a steady residual of z = ν never grows the sum (friction aside)
        return self.drift * self.sigma_nm
