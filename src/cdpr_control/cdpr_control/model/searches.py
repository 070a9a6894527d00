"""Searches over a robot's workspace made once (a safe pose or point: tenths of a second,
more than a tick), kept by what the robot is — the digest of its pickled form, so that a
robot loaded anew from the same file finds them — and the search's own settings."""
from __future__ import annotations

import hashlib
import pickle
from typing import Callable

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
