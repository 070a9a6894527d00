"""How far a lockstep plant may run ahead of its graph's recorder.

The recorder writes each tick into the bag after the loop has moved on; the per-tick
writers keep only their history (`streams.history_s`) for a reader that lags, so a
recorder left further behind than that loses ticks (docs/recording.md). Lockstep has no
wall-clock period to keep: its plant holds the next state while the recorder is more
than a lead behind, and the bag gets every tick whatever the machine's load. Realtime
cannot wait (hardware does not), so there the recorder's lag is only measured.
"""
from __future__ import annotations


class RecorderPacing:
    """The newest tick the recorder has written, and whether a tick may go out now."""

    def __init__(self, lead_ticks: int):
        if lead_ticks < 1:
            raise ValueError(f'the recorder lead must be at least one tick, got {lead_ticks}')
        self.lead_ticks = lead_ticks
        self.recorded_tick = -1   # none yet

    def recorded(self, tick: int) -> None:
        """The recorder has written every tick up to `tick` (it reports its newest; an
        older report, overtaken, changes nothing)."""
        self.recorded_tick = max(self.recorded_tick, tick)

    def may_publish(self, tick: int) -> bool:
        """Whether the state of `tick` may go out: the recorder is at most the lead behind."""
        return tick - self.recorded_tick <= self.lead_ticks

    def has_recorded(self, tick: int) -> bool:
        return self.recorded_tick >= tick
