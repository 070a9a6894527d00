"""Which cables broke (paper eq. 21, docs/design.md §5).

A broken cable's motor turns freely: its sensorless tension is about zero and the
controller, pulling on nothing, commands more torque than the twin (positive residual).
"""
from __future__ import annotations

import numpy as np


def identify_broken_cables(tension_low_n: np.ndarray, tension_high_n: np.ndarray,
                           residual_nm: np.ndarray, drum_radius_m: float,
                           delta_nm: float) -> list[int]:
    """0-based cables whose motor torque is within `delta_nm` of a free motor's, residual > 0.

    The sensorless tension is the interval [low, high] (N); a motor looks free when that
    interval comes within δ/ρ of zero. Sorted most certain first; empty when none looks free.
    """
    distance_n = np.maximum(np.maximum(tension_low_n, -tension_high_n), 0.0)
    load_nm = distance_n * drum_radius_m
    candidates = np.flatnonzero((load_nm < delta_nm) & (residual_nm > 0.0))
    return [int(i) for i in candidates[np.argsort(load_nm[candidates], kind='stable')]]
