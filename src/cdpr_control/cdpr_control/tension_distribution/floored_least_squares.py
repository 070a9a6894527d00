"""Another method's tensions where they exist; elsewhere the floored least-squares ones."""
from __future__ import annotations

import numpy as np

from cdpr_control.tension_distribution.base import InfeasibleTensionError, TensionDistribution, floored_fit


class FlooredLeastSquares(TensionDistribution):
    """`within`'s tensions wherever they lie within its bounds; where none do, the
    tensions no lower than its tension_min_n whose wrench comes nearest the one asked
    (base.floored_fit), none above its tension_max_n. It never raises
    InfeasibleTensionError: a wrench out of the cables' reach is missed by a little, and
    no cable is planned slack (a platform's recovery move through poses where the cables
    cannot pull its wrench within the bounds, cdpr_fdi.recovery_strategies.braked)."""

    name = 'floored_least_squares'

    def __init__(self, within: TensionDistribution):
        super().__init__(within.tension_min_n, within.tension_max_n)
        self.within = within

    def distribute(self, structure: np.ndarray, wrench_n: np.ndarray) -> np.ndarray:
        try:
            return self.within.distribute(structure, wrench_n)
        except InfeasibleTensionError:
            return np.minimum(floored_fit(structure, wrench_n, self.tension_min_n), self.tension_max_n)

    def distribute_each(self, structures: np.ndarray, wrenches_n: np.ndarray) -> np.ndarray:
        """`distribute` of every row: `within`'s for the whole stack at once, the floored
        fit of the rows where it has none."""
        tensions = self.within.distribute_each(structures, wrenches_n)
        for row in np.flatnonzero(np.isnan(tensions).any(axis=-1)):
            tensions[row] = np.minimum(floored_fit(structures[row], wrenches_n[row], self.tension_min_n),
                                       self.tension_max_n)
        return tensions
