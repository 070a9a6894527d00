"""Tensions within their bounds whose wrench comes nearest the one asked, in a weighted norm."""
from __future__ import annotations

import numpy as np

# Tie-break between tensions that pull the same wrench (the free directions of more cables
# than degrees of freedom): this share of the problem's scale times |τ|² is added, so the
# lowest such tensions are taken, as the bounded minimum norm does.
TIE_BREAK_SHARE = 1e-12
# A held cable is let go of only where the objective's slope away from its bound exceeds
# this share of the problem's scale: a slope of rounding size would be let go of and held
# again for ever.
SLOPE_TOLERANCE_SHARE = 1e-10
# An active-set search over m cables ends within a few times m steps; this many is a bug.
ACTIVE_SET_STEPS_PER_CABLE = 8


def nearest_wrench(structure: np.ndarray, wrench_n: np.ndarray, weights, tension_min_n: float,
                   tension_max_n: float) -> np.ndarray:
    """τ (N, m) in [tension_min_n, tension_max_n] minimising |D (S τ − w)|², D = diag(`weights`)
    (one per row of the structure matrix S, k × m): the exact wrench where tensions within
    the bounds pull it, else the nearest in that norm (a platform's weights say how much a
    moment's N·m counts against a force's N). The convex quadratic program is solved by a
    primal active-set search, exactly (against scipy's bounded least squares in
    tests/test_tension_distribution.py)."""
    weighted = np.asarray(weights, dtype=float)[:, None] * structure
    hessian = weighted.T @ weighted
    hessian += TIE_BREAK_SHARE * np.trace(hessian) * np.eye(len(hessian))
    gradient_at_zero = weighted.T @ (np.asarray(weights, dtype=float) * wrench_n)
    cables = structure.shape[1]
    low, high = np.full(cables, float(tension_min_n)), np.full(cables, float(tension_max_n))
    tension = 0.5 * (low + high)
    slope_tolerance = SLOPE_TOLERANCE_SHARE * (np.abs(hessian).max() * tension_max_n + np.abs(gradient_at_zero).max())
    held = np.zeros(cables, dtype=bool)
    for _ in range(ACTIVE_SET_STEPS_PER_CABLE * cables):
        free = ~held
        target = tension.copy()
        if np.any(free):
            right = gradient_at_zero[free] - hessian[np.ix_(free, held)] @ tension[held]
            target[free] = np.linalg.solve(hessian[np.ix_(free, free)], right)
        step = target - tension
        # the longest share of the step that stays within the bounds
        with np.errstate(divide='ignore', invalid='ignore'):
            reach = np.where(step < 0.0, (low - tension) / step, np.where(step > 0.0, (high - tension) / step, np.inf))
        share = min(1.0, float(reach[free].min(initial=np.inf)))
        tension = tension + share * step
        if share < 1.0:
            blocking = free & (reach <= share)
            tension[blocking] = np.where(step[blocking] < 0.0, low[blocking], high[blocking])
            held |= blocking
            continue
        slope = hessian @ tension - gradient_at_zero
        # a held cable whose bound the objective would rather leave is let go of
        leaving = held & (((tension <= low) & (slope < -slope_tolerance))
                          | ((tension >= high) & (slope > slope_tolerance)))
        if not np.any(leaving):
            return tension
        held[np.flatnonzero(leaving)[np.argmax(np.abs(slope[leaving]))]] = False
    raise RuntimeError('nearest_wrench: the active-set search did not end')
