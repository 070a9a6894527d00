"""Which cables broke (paper eq. 21, docs/design.md §5).

A broken cable's motor turns freely: its sensorless tension is about zero and the
controller, pulling on nothing, commands more torque than the twin (positive residual).
"""
from __future__ import annotations

import numpy as np


def identify_broken_cables(tension_low_n: np.ndarray, residual_nm: np.ndarray,
                           drum_radius_m: float, delta_nm: float) -> list[int]:
    """0-based cables whose motor torque is within `delta_nm` of a free motor's, or reads a
    push, residual > 0.

    A motor looks free when the lower bound of its sensorless tension (N) is under δ/ρ:
    the estimate comes within δ of zero (the paper's |τ̂| ≤ δ), or lies below zero. A cable
    pulls and never pushes: a motor whose estimate says it is pushed is not held by its
    cable either (a freed motor swinging under a lagging drive reads tens of newtons of
    either sign, period by period). Sorted most certain first; empty when none looks free.
    """
    load_nm = np.maximum(tension_low_n, 0.0) * drum_radius_m
    candidates = np.flatnonzero((load_nm < delta_nm) & (residual_nm > 0.0))
    return [int(i) for i in candidates[np.argsort(load_nm[candidates], kind='stable')]]
