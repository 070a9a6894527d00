"""Another method's tensions where they exist; elsewhere the most margin the pose allows."""
from __future__ import annotations

from functools import lru_cache

import numpy as np

from cdpr_control.tension_distribution.base import BOUND_TOLERANCE_N, FreeDirection, InfeasibleTensionError, TensionDistribution, minimum_norm

# Bisection steps of the largest floor where the cables leave a null space of two or more
# dimensions: the floor to within (τ_floor − τ_lowest) / 2¹² of the best.
FLOOR_BISECTIONS = 12


def largest_floors(structures: np.ndarray, wrenches_n: np.ndarray, tension_max_n: float,
                   free: FreeDirection | None = None):
    """Per row of a stack (S n × d × k, w n × d), the largest floor f (N) for which
    tensions within [f, τ_max] pull w, and those tensions (n × k); −inf and NaN where no
    tensions below τ_max pull it. Closed form where the cables leave a null space of at
    most one dimension (a platform on seven cables, d = 6, k = 7; its FreeDirection
    `free`, found here where not given); LinAlgError above.

    Every τ with S τ = w is τ₀ + λ n (τ₀ = S⁺ w, n spanning the null space): the least
    tension, min_i (τ₀_i + λ n_i), is concave in λ and peaks where two of the lines
    cross, or at an end of the λ the upper bound allows; with one point left at the
    largest floor, that point is the tensions.
    """
    nullity = structures.shape[-1] - structures.shape[-2]
    if nullity <= 0:
        particular = minimum_norm(structures, wrenches_n)
        held = particular.max(axis=-1) <= tension_max_n + BOUND_TOLERANCE_N
        return (np.where(held, particular.min(axis=-1), -np.inf),
                np.where(held[:, None], particular, np.nan))
    if nullity > 1:
        raise np.linalg.LinAlgError(f'a null space of {nullity} dimensions has no closed form here')
    free = FreeDirection.of(structures, wrenches_n) if free is None else free
    particular, null = free.particular, free.null
    low, high = free.interval(-np.inf, tension_max_n)
    with np.errstate(divide='ignore', invalid='ignore'):
        crossings = ((particular[:, None, :] - particular[:, :, None])
                     / (null[:, :, None] - null[:, None, :])).reshape(len(particular), -1)
    candidates = np.concatenate([low[:, None], high[:, None], crossings], axis=1)
    # an unbounded end or parallel lines give no candidate: an end that is there stands in
    inside = np.where(np.isfinite(high), high, np.where(np.isfinite(low), low, 0.0))[:, None]
    candidates = np.where(np.isfinite(candidates), np.clip(candidates, low[:, None], high[:, None]), inside)
    least = (particular[:, None, :] + candidates[:, :, None] * null[:, None, :]).min(axis=-1)
    best = np.argmax(least, axis=1)
    rows = np.arange(len(particular))
    scale = candidates[rows, best]
    held = low <= high
    tensions = particular + scale[:, None] * null
    return np.where(held, least[rows, best], -np.inf), np.where(held[:, None], tensions, np.nan)


class LoweredFloor(TensionDistribution):
    """`within`'s tensions wherever they lie within its bounds; where none do, the
    tensions that keep the least cable as high above `lowest_n` as the wrench allows,
    the wrench pulled exactly (its floor lowered as far as that row needs, no further:
    a platform braking where its cables cannot keep the full margin). Rows no tensions
    above `lowest_n` pull are infeasible, as for any method: its tension_min_n is
    `lowest_n`."""

    name = 'lowered_floor'

    def __init__(self, within: TensionDistribution, lowest_n: float):
        super().__init__(lowest_n, within.tension_max_n)
        self.within = within

    def distribute(self, structure: np.ndarray, wrench_n: np.ndarray) -> np.ndarray:
        tensions = self.distribute_each(structure[None], np.asarray(wrench_n, dtype=float)[None])[0]
        if np.isnan(tensions).any():
            raise InfeasibleTensionError(f'no cable tensions above {self.tension_min_n:g} N pull the wrench')
        return tensions

    def distribute_each(self, structures: np.ndarray, wrenches_n: np.ndarray) -> np.ndarray:
        """`within`'s tensions, the rows it has none for lowered; where the cables leave one
        free direction, found once for both (FreeDirection)."""
        free = None
        if structures.shape[-1] - structures.shape[-2] == 1:
            try:
                free = FreeDirection.of(structures, wrenches_n)
            except InfeasibleTensionError:
                pass   # a row whose cables span too little: each row on its own, as within does
        tensions = (self.within.distribute_each(structures, wrenches_n) if free is None
                    else self.within.distribute_along(free, structures, wrenches_n))
        lowered = np.flatnonzero(np.isnan(tensions).any(axis=-1))
        if not lowered.size:
            return tensions
        try:
            floors, at_floor = largest_floors(structures[lowered], wrenches_n[lowered], self.tension_max_n,
                                              None if free is None else free.rows(lowered))
        except (np.linalg.LinAlgError, InfeasibleTensionError):
            # no closed form for this null space, or a row whose cables span too few
            # directions fails the stacked solve as a whole: row by row, that row NaN
            floors, at_floor = self._bisected(structures[lowered], wrenches_n[lowered])
        tensions[lowered] = np.where((floors >= self.tension_min_n - BOUND_TOLERANCE_N)[:, None], at_floor, np.nan)
        return tensions

    def _bisected(self, structures, wrenches_n):
        """largest_floors by bisection with `within`'s method, for any null space.

        The floors tried are those of a bisection of [tension_min_n, within's floor] in
        FLOOR_BISECTIONS steps, each row's the largest of them its tensions exist at. The
        rows of a stack are the poses of a move, whose floors change little from one to the
        next: each row's search starts at the floor found for the row before and widens
        from there, a few tries a row instead of a bisection's FLOOR_BISECTIONS + 1, to
        the same floor.
        """
        floors = np.full(len(structures), -np.inf)
        tensions = np.full(structures.shape[:1] + structures.shape[-1:], np.nan)
        grid = _bisection_floors(self.tension_min_n, self.within.tension_min_n)
        start = 0
        for row, (structure, wrench) in enumerate(zip(structures, wrenches_n)):
            found = _largest_index(lambda index: self._tensions_at(grid[index], structure, wrench),
                                   len(grid) - 1, start)
            if found is not None:
                start, tensions[row] = found
                floors[row] = grid[start]
        return floors, tensions

    def _tensions_at(self, floor, structure, wrench):
        """`within`'s tensions with its floor at `floor` (N), None where there are none."""
        try:
            return self.within.with_floor(floor).distribute(structure, wrench)
        except InfeasibleTensionError:
            return None


@lru_cache(maxsize=16)
def _bisection_floors(low: float, high: float) -> np.ndarray:
    """The floors (N) a bisection of [low, high] in FLOOR_BISECTIONS steps can end at, in
    increasing order: the value of index j as the bisection's own arithmetic reaches it
    (the midpoints taken, kept where j lies at or above them). Made once per bounds (a
    few tens of ms) and only read."""
    floors = np.empty(2 ** FLOOR_BISECTIONS)
    for index in range(len(floors)):
        value, top, lower_index, upper_index = low, high, 0, len(floors)
        for _ in range(FLOOR_BISECTIONS):
            middle, middle_index = 0.5 * (value + top), (lower_index + upper_index) // 2
            if middle_index <= index:
                value, lower_index = middle, middle_index
            else:
                top, upper_index = middle, middle_index
        floors[index] = value
    return floors


def _largest_index(tensions_at, last: int, start: int):
    """The largest index in [0, last] where `tensions_at` (index → tensions or None,
    None from some index on) has tensions, and those tensions; None where index 0 has
    none. Searched outwards from `start` in doubling steps, then halved."""
    start = min(max(start, 0), last)
    found = tensions_at(start)
    if found is None:
        # down to the first index that has tensions
        high, step = start, 1
        while True:
            low = max(high - step, 0)
            found = tensions_at(low)
            if found is not None:
                break
            if low == 0:
                return None
            high, step = low, 2 * step
    else:
        low, step = start, 1
        while True:
            if low == last:
                return low, found
            high = min(low + step, last)
            above = tensions_at(high)
            if above is None:
                break
            low, found, step = high, above, 2 * step
    while high - low > 1:
        middle = (low + high) // 2
        at_middle = tensions_at(middle)
        if at_middle is None:
            high = middle
        else:
            low, found = middle, at_middle
    return low, found
