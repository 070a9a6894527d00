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

import numpy as np

from . import tick_arithmetic


class TensionCollapse:
    """The cables whose motors have felt no tension over the last `window` periods while
    the reference asked for at least `reference_min_n` (N)."""

    def __init__(self, window: int, band_n: float, reference_min_n: float):
        self.window = window
        self.band_n = band_n
        self.reference_min_n = reference_min_n
        self.arithmetic = tick_arithmetic.kernel().load_all()
        # per period of the window, rows: τ̂'s lower and upper bounds (N), the reference
        # tension (N); and their sum over it, kept as periods come and go (averaging the
        # window afresh each period cost half of a tick). Sized by the first period.
        self.recent: np.ndarray | None = None
        self.total: np.ndarray | None = None
        self.periods = 0
        # the largest window-average reference tension (N) at which a motor's τ̂ read
        # within the band (-inf: none did): what cdpr-calibrate sets reference_min_n above.
        # Kept by the kernel; the periods that fill the window write into `filling`.
        self.largest = np.full(1, -np.inf)
        self.filling = np.full(1, -np.inf)

    def update(self, tension_low_n: np.ndarray, tension_high_n: np.ndarray,
               reference_tension_n: np.ndarray) -> list[int]:
        """A period's τ̂ bounds and reference tension in; the collapsed cables (0-based) out."""
        low, high = np.ascontiguousarray(tension_low_n, dtype=float), np.ascontiguousarray(tension_high_n, dtype=float)
        reference = np.ascontiguousarray(reference_tension_n, dtype=float)
        if self.recent is None:
            self.recent, self.total = np.zeros((self.window, 3, low.size)), np.zeros((3, low.size))
        collapsed = np.empty(low.size)
        self.periods += 1
        filled = self.periods >= self.window
        count = self.arithmetic.collapse_window(self.recent, self.total, (self.periods - 1) % self.window, low, high,
                                                reference, self.band_n, self.reference_min_n,
                                                self.largest if filled else self.filling, collapsed)
        if not filled or not count:
            return []
        return [int(cable) for cable in np.flatnonzero(collapsed)]

    @property
    def largest_free_reference_n(self) -> float:
        """The largest window-average reference tension (N) at which a motor's τ̂ read
        within the band; -inf where none did."""
        return float(self.largest[0])
