"""The detector interface: one residual vector per control tick in, alarm out."""
from __future__ import annotations

from abc import ABC, abstractmethod

import numpy as np


class Detector(ABC):
    """Decides from the torque residuals r = c − c_DT (N·m) whether a cable has failed."""

    name = ''

    def __init__(self):
        self.statistic = np.zeros(0)

    @abstractmethod
    def update(self, residual_nm: np.ndarray, twin_speed_rad_s: np.ndarray) -> bool:
        """Feed one tick; True while the detection condition holds.

        `twin_speed_rad_s` is the twin's θ̇, the noise-free speed of the nominal motion.
        """

    @property
    @abstractmethod
    def threshold(self) -> float:
        """The level `statistic` is compared with (for plots and diagnostics)."""

    @property
    @abstractmethod
    def least_alarming_nm(self):
        """The least steady residual (N·m; one number, or one per motor) this detector
        ever alarms on: a cable that parts carrying less than that over its drum radius
        leaves no residual it sees (cdpr_fdi.detection.visibility)."""
