"""Searches over a robot's workspace made once (a safe pose or point: tenths of a second,
more than a tick), kept by what the robot is — the digest of its pickled form, so that a
robot loaded anew from the same file finds them — and the search's own settings."""
from __future__ import annotations

import hashlib
import pickle
from typing import Callable

import numpy as np

# Results kept per store; the oldest goes first.
KEPT_SEARCHES = 64


def found_once(store: dict, robot, settings: tuple, search: Callable[[], object]):
    """`search()`'s result for `robot` and `settings` (hashable), made on the first call
    and kept in `store`; a search that found nothing returns why (a str), raised here as
    ValueError each time it is asked."""
    key = (hashlib.sha256(pickle.dumps(robot)).digest(), settings)
    if key not in store:
        if len(store) >= KEPT_SEARCHES:
            del store[next(iter(store))]
        store[key] = search()
    found = store[key]
    if isinstance(found, str):
        raise ValueError(found)
    return found


def section_grid(robot, height_m: float, spacing_m: float | None = None, points_per_side: int | None = None):
    """Positions (n × 3, m) at `height_m` on a grid over the workspace box's x-y extent:
    `spacing_m` apart, or `points_per_side` points a side."""
    axes = [np.linspace(low, high, points_per_side or max(2, int(round((high - low) / spacing_m)) + 1))
            for low, high in zip(robot.workspace_min_m[:2], robot.workspace_max_m[:2])]
    grid = np.stack(np.meshgrid(*axes, indexing='ij'), axis=-1).reshape(-1, 2)
    return np.column_stack([grid, np.full(len(grid), height_m)])
