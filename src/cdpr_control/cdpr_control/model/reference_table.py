"""A joint-space reference tabulated at the control period, of either body."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from cdpr_control.geometry.rotation import IDENTITY


@dataclass
class ReferenceTable:
    """Reference at t_k = k · period: pose (m), θ_d (rad), θ̇_d (rad/s), c_ID (N·m)."""

    period_s: float
    position_m: np.ndarray
    velocity_m_s: np.ndarray
    angle_rad: np.ndarray
    angular_velocity_rad_s: np.ndarray
    feedforward_nm: np.ndarray

    def __len__(self) -> int:
        return self.position_m.shape[0]

    def orientation_at(self, row: int) -> np.ndarray:
        """The end-effector's orientation at `row`, as a pose message carries it: a point
        mass has none, the identity (PoseReferenceTable: a platform's)."""
        return IDENTITY

    def index_at(self, time_s: float) -> int:
        """The sample at or before `time_s`, held at the ends."""
        return min(max(int(np.floor(time_s / self.period_s + 1e-9)), 0), len(self) - 1)


def tick_times(period_s: float, duration_s: float, start_s: float = 0.0) -> np.ndarray:
    """The times (s) of the ticks of `duration_s` from `start_s`, both ends included: where
    a trajectory is tabulated."""
    count = int(round(duration_s / period_s)) + 1
    return start_s + np.arange(count) * period_s
