"""The paper's detector (eq. 20): some |r_i| > ε."""
from __future__ import annotations

import numpy as np

from .base import Detector


class ThresholdDetector(Detector):

    name = 'threshold'

    def __init__(self, epsilon_nm: float):
        super().__init__()
        if epsilon_nm <= 0.0:
            raise ValueError(f'epsilon must be positive, got {epsilon_nm}')
        self.epsilon_nm = float(epsilon_nm)

    def update(self, residual_nm: np.ndarray, twin_speed_rad_s: np.ndarray) -> bool:
        self.statistic = np.abs(residual_nm)
        return bool(self.statistic.max() > self.epsilon_nm)

    @property
    def threshold(self) -> float:
        return self.epsilon_nm

    @property
    def least_alarming_nm(self) -> float:
        return self.epsilon_nm
