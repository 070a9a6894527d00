"""The paper's tension distribution: τ = S⁺ w (minimum 2-norm), checked against bounds."""
from __future__ import annotations

import numpy as np

from cdpr_control.tension_distribution.base import InfeasibleTensionError, TensionDistribution, minimum_norm


class PseudoInverse(TensionDistribution):
    """τ = S⁺ w. Never returns a tension outside the bounds: that is an error instead."""

    name = 'pseudo_inverse'

    def distribute(self, structure: np.ndarray, wrench_n: np.ndarray) -> np.ndarray:
        return self._check_bounds(minimum_norm(structure, wrench_n))

    def distribute_each(self, structures: np.ndarray, wrenches_n: np.ndarray) -> np.ndarray:
        try:
            tensions = minimum_norm(structures, wrenches_n)
        except InfeasibleTensionError:
            # a row whose cables span too little: the others are still answered
            return super().distribute_each(structures, wrenches_n)
        outside = self._outside_bounds(tensions)
        tensions[outside] = np.nan
        return tensions
