"""The interface every tension-distribution method implements."""
from __future__ import annotations

import copy
from abc import ABC, abstractmethod
from dataclasses import dataclass

import numpy as np

from cdpr_control.geometry.linalg3 import solve3


# A platform's S Sᵀ whose smallest Cholesky pivot is this small against its largest
# diagonal entry: the cables do not span the six directions of force and moment
# (solve3's determinant test does it for 3 × 3).
SINGULAR_PIVOT_RATIO = 1e-12
# Tensions this far (N) beyond a bound still count as within it: rounding.
BOUND_TOLERANCE_N = 1e-9


class InfeasibleTensionError(ValueError):
    """No tensions within the bounds produce the wrench; names the pose when known, and
    the cable that cannot be held (`cable`, 0-based: a column of the structure matrix
    given, the robot's cable once `of_cables` has told which cables those columns are)."""

    def __init__(self, reason: str, position_m=None, row: int | None = None, orientation=None,
                 cable: int | None = None):
        self.reason = reason
        self.row = row
        self.cable = cable
        self.position_m = None if position_m is None else np.array(position_m, dtype=float)
        self.orientation = None if orientation is None else np.array(orientation, dtype=float)
        where = '' if position_m is None else ' at p = ({:.4f}, {:.4f}, {:.4f}) m'.format(*position_m)
        if orientation is not None:
            where += ', q = ({:.4f}, {:.4f}, {:.4f}, {:.4f})'.format(*orientation)
        named = reason if cable is None else f'cable {cable + 1} {reason}'
        super().__init__(f'no feasible cable tensions{where}: {named}')

    def __reduce__(self):
        # rebuilt from its parts, not its message, when it crosses to another process (a
        # campaign's or a calibration's worker): the message is not prefixed twice
        return type(self), (self.reason, self.position_m, self.row, self.orientation, self.cable)

    def at(self, position_m, orientation=None) -> 'InfeasibleTensionError':
        """The same error, naming the end-effector's position (and a platform's orientation)."""
        return InfeasibleTensionError(self.reason, position_m, self.row, orientation, self.cable)

    def in_row(self, row: int) -> 'InfeasibleTensionError':
        """The same error, naming the row of a stack it came from."""
        return InfeasibleTensionError(self.reason, self.position_m, row, self.orientation, self.cable)

    def of_cables(self, cables: np.ndarray) -> 'InfeasibleTensionError':
        """The same error where the structure's columns were the robot's `cables` (0-based
        indices, e.g. the attached ones): its cable named as the robot numbers it."""
        cable = None if self.cable is None else int(cables[self.cable])
        return InfeasibleTensionError(self.reason, self.position_m, self.row, self.orientation, cable)


class TensionDistribution(ABC):
    """Cable tensions τ (N) with S τ = w for a structure matrix S (3 × k) and wrench w (N)."""

    name = ''

    def __init__(self, tension_min_n: float, tension_max_n: float):
        if not 0.0 <= tension_min_n < tension_max_n:
            raise ValueError(f'need 0 <= tension_min_n < tension_max_n, got '
                             f'{tension_min_n}, {tension_max_n}')
        self.tension_min_n = float(tension_min_n)
        self.tension_max_n = float(tension_max_n)

    def with_floor(self, tension_min_n: float) -> 'TensionDistribution':
        """The same method with its lower bound at `tension_min_n` (N)."""
        lowered = copy.copy(self)
        lowered.tension_min_n = float(tension_min_n)
        return lowered

    @abstractmethod
    def distribute(self, structure: np.ndarray, wrench_n: np.ndarray) -> np.ndarray:
        """Tensions τ within [tension_min_n, tension_max_n]; InfeasibleTensionError if none."""

    def distribute_rows(self, structures: np.ndarray, wrenches_n: np.ndarray) -> np.ndarray:
        """`distribute` of every row of a stack: S (n × 3 × k, or n × 6 × k) and w (n × 3, or
        n × 6) give τ (n × k). The first infeasible row raises its error, with `row` set to
        its index."""
        tensions = self.distribute_each(structures, wrenches_n)
        missing = np.flatnonzero(np.isnan(tensions).any(axis=-1))
        if missing.size:
            row = int(missing[0])
            try:
                self.distribute(structures[row], wrenches_n[row])
            except InfeasibleTensionError as err:
                raise err.in_row(row) from None
        return tensions

    def distribute_each(self, structures: np.ndarray, wrenches_n: np.ndarray) -> np.ndarray:
        """`distribute` of every row of a stack, NaN for each row no tensions within the
        bounds pull (a workspace sampled at once)."""
        tensions = np.full(structures.shape[:-2] + structures.shape[-1:], np.nan)
        for row, (structure, wrench) in enumerate(zip(structures, wrenches_n)):
            try:
                tensions[row] = self.distribute(structure, wrench)
            except InfeasibleTensionError:
                pass
        return tensions

    def distribute_along(self, free: 'FreeDirection', structures: np.ndarray, wrenches_n: np.ndarray) -> np.ndarray:
        """`distribute_each` of a stack whose cables leave one free direction, `free` (its
        τ₀ and n): a method that takes its tensions along n takes them from there, not
        found again."""
        return self.distribute_each(structures, wrenches_n)

    def _outside_bounds(self, tensions: np.ndarray) -> np.ndarray:
        """Per row of a stack of tensions (n × k), whether one leaves [τ_min, τ_max]."""
        return ((tensions.min(axis=-1) < self.tension_min_n - BOUND_TOLERANCE_N)
                | (tensions.max(axis=-1) > self.tension_max_n + BOUND_TOLERANCE_N))

    def _check_bounds(self, tensions: np.ndarray) -> np.ndarray:
        """`tensions` (k) if within the bounds, else InfeasibleTensionError saying where."""
        if self._outside_bounds(tensions):
            raise InfeasibleTensionError(
                f'{self.name} gives tensions in [{np.min(tensions):.3f}, {np.max(tensions):.3f}] N, outside '
                f'[{self.tension_min_n}, {self.tension_max_n}] N')
        return tensions


def minimum_norm(structure: np.ndarray, wrench_n: np.ndarray) -> np.ndarray:
    """S⁺ w = Sᵀ (S Sᵀ)⁻¹ w for S of full row rank (3 × k for a point mass, 6 × k for a
    platform); of each row for stacks (n × 3 × k, n × 3)."""
    gram = structure @ np.swapaxes(structure, -1, -2)
    rows = gram.shape[-1]
    try:
        if rows == 3:
            solved = solve3(gram, wrench_n)
        else:
            # S Sᵀ is positive semi-definite: a Cholesky pivot this small against its
            # diagonal means the cables do not span the six directions
            pivots = np.diagonal(np.linalg.cholesky(gram), axis1=-2, axis2=-1) ** 2
            if np.any(pivots < SINGULAR_PIVOT_RATIO * np.diagonal(gram, axis1=-2, axis2=-1).max(axis=-1,
                                                                                                keepdims=True)):
                raise np.linalg.LinAlgError('singular Gram matrix')
            solved = np.linalg.solve(gram, wrench_n[..., None])[..., 0]
    except np.linalg.LinAlgError:
        raise InfeasibleTensionError(f'the cables span less than {rows} directions') from None
    return np.einsum('...ij,...i->...j', structure, solved)


def null_vectors(structures: np.ndarray) -> np.ndarray:
    """For each S of a stack whose cables leave one free direction (n × d × (d + 1), of
    full row rank), the unit vector spanning its null space (either sign): the column of
    the projector I − S⁺S onto that space with the largest diagonal entry, n_j² ≥ 1/(d + 1)
    of it, normalised (a quarter of an SVD's time on a platform's stacks)."""
    transposed = np.swapaxes(structures, -1, -2)
    projector = np.eye(structures.shape[-1]) - transposed @ np.linalg.solve(structures @ transposed, structures)
    column = projector[np.arange(len(structures)), :, np.argmax(np.diagonal(projector, axis1=-2, axis2=-1), axis=-1)]
    return column / np.linalg.norm(column, axis=-1, keepdims=True)


@dataclass(frozen=True)
class FreeDirection:
    """Every τ with S τ = w, for each row of a stack whose cables leave one free direction
    (S n × d × (d + 1) of full row rank, w n × d): τ₀ + λ n, with τ₀ = S⁺ w (n × k, N) and
    n the unit vector spanning the null space of S (n × k, either sign). Found once for a
    stack, it serves every method that takes its tensions along n (the bounded minimum
    norm's interval, the lowered floor's largest floors)."""
    particular: np.ndarray
    null: np.ndarray

    @classmethod
    def of(cls, structures: np.ndarray, wrenches_n: np.ndarray) -> 'FreeDirection':
        """InfeasibleTensionError where a row's cables span fewer than d directions."""
        return cls(minimum_norm(structures, wrenches_n), null_vectors(structures))

    def rows(self, index) -> 'FreeDirection':
        """Those of the rows `index` picks."""
        return FreeDirection(self.particular[index], self.null[index])

    def interval(self, tension_min_n: float, tension_max_n: float) -> tuple[np.ndarray, np.ndarray]:
        """Per row, the least and greatest λ (N) for which τ₀ + λ n keeps every cable within
        [tension_min_n, tension_max_n] (either bound may be infinite; low > high where no
        λ does)."""
        particular, null = self.particular, self.null
        with np.errstate(divide='ignore', invalid='ignore'):
            to_min = (tension_min_n - particular) / null
            to_max = (tension_max_n - particular) / null
        rising, falling = null > 0.0, null < 0.0
        low = np.where(rising, to_min, np.where(falling, to_max, -np.inf)).max(axis=-1)
        high = np.where(rising, to_max, np.where(falling, to_min, np.inf)).min(axis=-1)
        # a cable the free direction does not move must itself lie within the bounds
        fixed = ~rising & ~falling & ((particular < tension_min_n) | (particular > tension_max_n))
        return np.where(fixed.any(axis=-1), np.inf, low), high


def floored_fit(structure: np.ndarray, wrench_n: np.ndarray, floor_n: float) -> np.ndarray:
    """Tensions (N) no lower than `floor_n` whose wrench S τ comes near `wrench_n` where
    no tensions above the floor pull it: the least-squares fit of every cable; while one
    falls below the floor, the lowest is held at it and the others are fitted again to
    what is left (greedy: near the bounded least-squares optimum, not always at it). A
    wrench the cables can pull with tension to spare gets the minimum-norm fit."""
    tensions = np.full(structure.shape[1], floor_n)
    free = np.ones(tensions.size, dtype=bool)
    while np.any(free):
        held = tensions[~free] @ structure[:, ~free].T
        fit, *_ = np.linalg.lstsq(structure[:, free], wrench_n - held, rcond=None)
        if np.min(fit) >= floor_n:
            tensions[free] = fit
            break
        free[np.flatnonzero(free)[np.argmin(fit)]] = False
    return tensions
