"""Where a break hides from the residual: a cable carrying less than the detector sees.

A cable that parts takes its tension τ off its motor: the controller, holding the freed
drum on its reference, then commands about ρ τ more than the twin. A detector alarms on
no steady residual below its least (Detector.least_alarming_nm: the threshold
detector's ε; the CUSUM's drift ν times each motor's σ), so a cable parting with less
than that over ρ is found by the tension collapse (its motor feels nothing while the
reference asks for a tension, tension_collapse.py) or once the end-effector, hanging on
the others, slackens another cable: later, and then the wrench balance must tell the two
apart. Said ahead of a run (cdpr-robot, per motion and cable) and of a run that met one
(metrics.json).
"""
from __future__ import annotations

import numpy as np

# A cable this close to the level (N) counts as at it, not under it: rounding (a cable
# planned at τ_min where ε / ρ = τ_min).
AT_THRESHOLD_N = 1e-6


def hidden_below_n(least_alarming_nm, drum_radius_m: float) -> np.ndarray:
    """The tension (N, per cable where the level is per motor) under which a cable's break
    leaves the residual below what the detector alarms on."""
    return np.asarray(least_alarming_nm, dtype=float) / drum_radius_m


def hidden_spans(tension_n: np.ndarray, least_alarming_nm, drum_radius_m: float) -> list[list[tuple[int, int]]]:
    """Per cable, the spans of rows (first, last, both inclusive) of a motion's tensions
    (N, rows × cables) where it carries less than the detector's level over ρ."""
    hidden = np.asarray(tension_n, dtype=float) < hidden_below_n(least_alarming_nm, drum_radius_m) - AT_THRESHOLD_N
    spans = []
    for column in hidden.T:
        edges = np.diff(np.concatenate([[0], column.astype(int), [0]]))
        starts, ends = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1) - 1
        spans.append(list(zip(starts.tolist(), ends.tolist())))
    return spans
