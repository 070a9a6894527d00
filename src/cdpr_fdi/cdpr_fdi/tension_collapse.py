"""A break the residual cannot see: a lightly loaded cable parting.

The torque residual is the tension a cable lost felt through its drum (ρ Δτ), and its
threshold ε is set by the largest mismatch of failure-free motion. On a light robot with
small drums ε is more than a cable carries: the tall frame's ε = 0.125 N·m over a 30 mm
drum is 4.2 N, and its cables carry 1.5–3 N on their motions. Such a cable parts with a
residual of ~0.05 N·m, and the robot goes on on the others until one of them slackens.

What the parted cable still shows is a motor that feels no tension while the reference
asks for one: its sensorless tension τ̂, averaged over `window` periods, within `band_n`
of zero while the reference tension of those periods is at least `reference_min_n`. An
attached cable can read about zero too: on a robot with more cables than degrees of
freedom, the joints' position control, not the tension distribution, settles how the
cables share the load, and a cable planned at τ_min may carry nothing for a while (the
tall frame on the elastic plant: 0.04 N on a cable planned at 1.0 N for 0.5 s; τ̂ within
0.5 N of zero only where the plan asked at most 1.34 N). So the reference must ask
clearly more than τ_min, and over enough periods that a cable unloaded by the swing of a
motion is not taken for a parted one.
"""
from __future__ import annotations

from collections import deque

import numpy as np


class TensionCollapse:
    """The cables whose motors have felt no tension over the last `window` periods while
    the reference asked for at least `reference_min_n` (N)."""

    def __init__(self, window: int, band_n: float, reference_min_n: float):
        self.window = window
        self.band_n = band_n
        self.reference_min_n = reference_min_n
        # per period, a row each: τ̂'s lower and upper bounds (N), the reference tension (N)
        self.recent: deque[np.ndarray] = deque()
        # their sum over `recent`: kept as periods come and go, as the supervisor asks every
        # period (averaging the window afresh each time cost half of a tick)
        self.total: np.ndarray | None = None

    def update(self, tension_low_n: np.ndarray, tension_high_n: np.ndarray,
               reference_tension_n: np.ndarray) -> list[int]:
        """A period's τ̂ bounds and reference tension in; the collapsed cables (0-based) out."""
        period = np.array((tension_low_n, tension_high_n, reference_tension_n), dtype=float)
        self.recent.append(period)
        self.total = period.copy() if self.total is None else self.total + period
        if len(self.recent) > self.window:
            self.total -= self.recent.popleft()
        if len(self.recent) < self.window:
            return []
        low, high, reference = self.total / self.window
        distance_n = np.maximum(np.maximum(low, -high), 0.0)
        return [int(cable) for cable in
                np.flatnonzero((distance_n < self.band_n) & (reference >= self.reference_min_n))]
