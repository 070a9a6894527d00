"""The interface every tension-distribution method implements."""
from __future__ import annotations

from abc import ABC, abstractmethod

import numpy as np

from ..linalg3 import solve3


class InfeasibleTensionError(ValueError):
    """No tensions within the bounds produce the wrench; names the pose when known."""

    def __init__(self, reason: str, position_m=None, row: int | None = None):
        self.reason = reason
        self.row = row
        self.position_m = None if position_m is None else np.array(position_m, dtype=float)
        where = '' if position_m is None else ' at p = ({:.4f}, {:.4f}, {:.4f}) m'.format(*position_m)
        super().__init__(f'no feasible cable tensions{where}: {reason}')

    def __reduce__(self):
        # rebuilt from its parts, not its message, when it crosses to another process (a
        # campaign's or a calibration's worker): the message is not prefixed twice
        return type(self), (self.reason, self.position_m, self.row)

    def at(self, position_m) -> 'InfeasibleTensionError':
        """The same error, naming the end-effector position."""
        return InfeasibleTensionError(self.reason, position_m)

    def in_row(self, row: int) -> 'InfeasibleTensionError':
        """The same error, naming the row of a stack it came from."""
        return InfeasibleTensionError(self.reason, self.position_m, row)


class TensionDistribution(ABC):
    """Cable tensions τ (N) with S τ = w for a structure matrix S (3 × k) and wrench w (N)."""

    name = ''

    def __init__(self, tension_min_n: float, tension_max_n: float):
        if not 0.0 <= tension_min_n < tension_max_n:
            raise ValueError(f'need 0 <= tension_min_n < tension_max_n, got '
                             f'{tension_min_n}, {tension_max_n}')
        self.tension_min_n = float(tension_min_n)
        self.tension_max_n = float(tension_max_n)

    @abstractmethod
    def distribute(self, structure: np.ndarray, wrench_n: np.ndarray) -> np.ndarray:
        """Tensions τ within [tension_min_n, tension_max_n]; InfeasibleTensionError if none."""

    def distribute_rows(self, structures: np.ndarray, wrenches_n: np.ndarray) -> np.ndarray:
        """`distribute` of every row of a stack: S (n × 3 × k) and w (n × 3) give τ (n × k).
        The first infeasible row raises its error, with `row` set to its index."""
        tensions = np.empty(structures.shape[:-2] + structures.shape[-1:])
        for row, (structure, wrench) in enumerate(zip(structures, wrenches_n)):
            try:
                tensions[row] = self.distribute(structure, wrench)
            except InfeasibleTensionError as err:
                raise err.in_row(row) from None
        return tensions

    def _check_bounds(self, tensions: np.ndarray) -> np.ndarray:
        low = np.min(tensions)
        high = np.max(tensions)
        if low < self.tension_min_n - 1e-9 or high > self.tension_max_n + 1e-9:
            raise InfeasibleTensionError(
                f'{self.name} gives tensions in [{low:.3f}, {high:.3f}] N, outside '
                f'[{self.tension_min_n}, {self.tension_max_n}] N')
        return tensions


def minimum_norm(structure: np.ndarray, wrench_n: np.ndarray) -> np.ndarray:
    """S⁺ w = Sᵀ (S Sᵀ)⁻¹ w for S of full row rank; of each row for stacks (n × 3 × k, n × 3)."""
    gram = structure @ np.swapaxes(structure, -1, -2)
    try:
        return np.einsum('...ij,...i->...j', structure, solve3(gram, wrench_n))
    except np.linalg.LinAlgError:
        raise InfeasibleTensionError('the cables span less than 3 directions') from None
