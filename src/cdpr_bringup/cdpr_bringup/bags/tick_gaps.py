"""Which ticks a recorded per-tick topic lacks, counted from the stamps as messages arrive.

Every per-tick message of the graph is stamped with its tick (origin + k · period), and
its serialized form starts with that stamp (a std_msgs/Header, or the Clock's Time), so
the recorder counts without decoding: a tick between the first and the newest stamp seen
that never came is missing. A late (repaired) message fills its hole; memory grows with
the holes only, not with the ticks.
"""
from __future__ import annotations


class TickGaps:
    """The ticks of one topic: `seen(stamp_ns)` for each message; `missing` is how many
    ticks from the earliest to the newest stamp seen have had no message."""

    def __init__(self, period_ns: int):
        self.period_ns = period_ns
        self.first_ns: int | None = None
        self.newest = 0
        self.holes: set[int] = set()

    def seen(self, stamp_ns: int) -> None:
        if self.first_ns is None:
            self.first_ns = stamp_ns
            return
        tick = round((stamp_ns - self.first_ns) / self.period_ns)
        if tick < 0:
            # earlier than the first seen: count from it
            self.holes = {hole - tick for hole in self.holes} | set(range(1, -tick))
            self.newest -= tick
            self.first_ns = stamp_ns
        elif tick > self.newest:
            self.holes.update(range(self.newest + 1, tick))
            self.newest = tick
        else:
            self.holes.discard(tick)

    @property
    def missing(self) -> int:
        return len(self.holes)

    @property
    def ticks(self) -> int:
        """Ticks from the earliest to the newest stamp seen."""
        return 0 if self.first_ns is None else self.newest + 1
