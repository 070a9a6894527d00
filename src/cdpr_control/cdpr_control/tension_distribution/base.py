"""The interface every tension-distribution method implements."""
from __future__ import annotations

from abc import ABC, abstractmethod

import numpy as np

from ..linalg3 import solve3


class InfeasibleTensionError(ValueError):
    """No tensions within the bounds produce the wrench; names the pose when known."""

    def __init__(self, reason: str, position_m=None):
        self.reason = reason
        self.position_m = None if position_m is None else np.array(position_m, dtype=float)
        where = '' if position_m is None else ' at p = ({:.4f}, {:.4f}, {:.4f}) m'.format(*position_m)
        super().__init__(f'no feasible cable tensions{where}: {reason}')

    def at(self, position_m) -> 'InfeasibleTensionError':
        """The same error, naming the end-effector position."""
        return InfeasibleTensionError(self.reason, position_m)


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

    def _check_bounds(self, tensions: np.ndarray) -> np.ndarray:
        low = np.min(tensions)
        high = np.max(tensions)
        if low < self.tension_min_n - 1e-9 or high > self.tension_max_n + 1e-9:
            raise InfeasibleTensionError(
                f'{self.name} gives tensions in [{low:.3f}, {high:.3f}] N, outside '
                f'[{self.tension_min_n}, {self.tension_max_n}] N')
        return tensions


def minimum_norm(structure: np.ndarray, wrench_n: np.ndarray) -> np.ndarray:
    """S⁺ w = Sᵀ (S Sᵀ)⁻¹ w for S of full row rank."""
    gram = structure @ structure.T
    try:
        return structure.T @ solve3(gram, wrench_n)
    except np.linalg.LinAlgError:
        raise InfeasibleTensionError('the cables span less than 3 directions') from None
