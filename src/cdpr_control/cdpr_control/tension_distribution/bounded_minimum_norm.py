"""Bounded tension distribution: the tensions closest to a reference within the bounds.

Solves  min ½‖τ − τ_ref‖²  s.t.  S τ = w,  τ_min ≤ τ ≤ τ_max  by an active-set method:
free cables take the closed-form (minimum-norm) correction, a cable that leaves its
bounds is pinned to the bound, and a pinned cable whose multiplier has the wrong sign
is released. Pinning the worst violator first can pin a cable the optimum keeps free
and strand the search (about 1 case in 1000 on an 8-cable robot); then Dykstra's
alternating projections between {S τ = w} and the box, which converge to the optimum
whenever one exists, find the active set and the active-set step makes it exact
(that fallback can take up to DYKSTRA_ITERATIONS sweeps, ~0.3 s, before it declares a
wrench infeasible). With τ_ref = 0 the result equals the paper's S⁺ w whenever that is within
the bounds; with τ_ref = (τ_min + τ_max)/2 it is the improved closed-form method.
"""
from __future__ import annotations

import numpy as np

from ..linalg3 import solve3
from .base import InfeasibleTensionError, TensionDistribution, minimum_norm

BOUND_TOLERANCE_N = 1e-9
DYKSTRA_ITERATIONS = 50000
DYKSTRA_TOLERANCE_N = 1e-8
FEASIBILITY_TOLERANCE_N = 1e-6
PIN_TOLERANCE_N = 1e-6


class BoundedMinimumNorm(TensionDistribution):

    name = 'bounded_minimum_norm'

    def __init__(self, tension_min_n: float, tension_max_n: float, reference_tension_n: float = 0.0):
        super().__init__(tension_min_n, tension_max_n)
        self.reference_tension_n = float(reference_tension_n)

    def distribute(self, structure: np.ndarray, wrench_n: np.ndarray) -> np.ndarray:
        count = structure.shape[1]
        reference = np.full(count, self.reference_tension_n)
        tensions = reference + minimum_norm(structure, wrench_n - structure @ reference)
        if (np.min(tensions) >= self.tension_min_n - BOUND_TOLERANCE_N
                and np.max(tensions) <= self.tension_max_n + BOUND_TOLERANCE_N):
            return tensions
        try:
            return self._active_set(structure, wrench_n, reference, np.zeros(count, dtype=int))
        except InfeasibleTensionError as first_attempt:
            if count - structure.shape[0] < 2:
                # With one redundant cable or none, the active set was never seen to strand
                # (21,000 random cases on the paper robot); the fallback is slow (~0.3 s).
                raise
            estimate = self._dykstra(structure, wrench_n, reference)
            low, high = self.tension_min_n, self.tension_max_n
            pinned = np.where(estimate <= low + PIN_TOLERANCE_N, -1,
                              np.where(estimate >= high - PIN_TOLERANCE_N, 1, 0))
            try:
                return self._active_set(structure, wrench_n, reference, pinned)
            except InfeasibleTensionError:
                if np.linalg.norm(structure @ estimate - wrench_n) > FEASIBILITY_TOLERANCE_N:
                    raise first_attempt from None
                return estimate

    def _dykstra(self, structure, wrench_n, reference):
        """Projection of the reference onto {S τ = w} ∩ box by Dykstra's algorithm.

        The affine set needs no correction term (its projection is affine), the box does.
        """
        pseudo_inverse = np.linalg.pinv(structure)
        x = reference.copy()
        correction = np.zeros_like(x)
        for _ in range(DYKSTRA_ITERATIONS):
            y = x - pseudo_inverse @ (structure @ x - wrench_n)
            x = np.clip(y + correction, self.tension_min_n, self.tension_max_n)
            correction = y + correction - x
            if np.max(np.abs(x - y)) < DYKSTRA_TOLERANCE_N:
                break
        return x

    def _active_set(self, structure, wrench_n, reference, pinned):
        count = structure.shape[1]
        low, high = self.tension_min_n, self.tension_max_n
        # pinned: 0 free, −1 at the lower bound, +1 at the upper bound
        pinned = pinned.copy()
        tensions = reference.copy()
        for _ in range(4 * count + 4):
            free = pinned == 0
            tensions[pinned < 0] = low
            tensions[pinned > 0] = high
            free_structure = structure[:, free]
            remainder = wrench_n - structure[:, ~free] @ tensions[~free]
            try:
                multiplier = solve3(free_structure @ free_structure.T,
                                    remainder - free_structure @ reference[free])
            except np.linalg.LinAlgError:
                raise InfeasibleTensionError(
                    f'with cables {_names(~free)} at their bounds the rest span less than '
                    '3 directions') from None
            tensions[free] = reference[free] + free_structure.T @ multiplier
            violation = np.maximum(low - tensions, tensions - high)
            violation[~free] = -np.inf
            worst = int(np.argmax(violation))
            if violation[worst] > BOUND_TOLERANCE_N:
                pinned[worst] = -1 if tensions[worst] < low else 1
                continue
            # KKT: τ − τ_ref − Sᵀλ = μ_low − μ_high with μ ≥ 0
            slack = tensions - reference - structure.T @ multiplier
            wrong_sign = np.where(pinned < 0, -slack, np.where(pinned > 0, slack, -np.inf))
            release = int(np.argmax(wrong_sign))
            if wrong_sign[release] > BOUND_TOLERANCE_N:
                pinned[release] = 0
                continue
            return tensions
        raise InfeasibleTensionError('the active-set search did not settle')


def _names(mask: np.ndarray) -> str:
    return ', '.join(str(i + 1) for i in np.flatnonzero(mask)) or 'none'
