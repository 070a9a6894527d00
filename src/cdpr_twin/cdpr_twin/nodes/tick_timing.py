"""Wall-clock timing of the plant's ticks, reported on /diagnostics.

- tick rate: ticks per wall-clock second between the first tick and the latest one;
- deadline misses (realtime): ticks that came more than one period late, i.e. more than
  two periods after the tick before them — a cycle a real drive would have missed;
- state → command latency: from publishing the state of a tick to receiving the command
  stamped with it, kept in a fixed histogram so that a tick costs the same at any hour;
- per window (between two /diagnostics): how many tick intervals, how long in all, and how
  many of them missed their deadline, which health.loop_problem judges.
"""
from __future__ import annotations

import math
import time

import numpy as np

# Latency histogram: bin i holds [1 µs · 1.02^i, 1 µs · 1.02^(i+1)), 2 % wide from 1 µs to
# beyond a minute; shorter latencies count in bin 0.
LATENCY_FLOOR_S = 1e-6
LATENCY_BIN_RATIO = 1.02
LATENCY_BINS = 900
# Published states whose command may still arrive (realtime answers can lag a few ticks).
PENDING_STATES = 64


class TickTiming:

    def __init__(self, period_s: float, deadlines: bool):
        self.period_s = period_s
        self.deadlines = deadlines
        self.ticks = 0
        self.first_s: float | None = None
        self.last_s: float | None = None
        self.deadline_misses = 0
        self.window_intervals = 0
        self.window_duration_s = 0.0
        self.window_misses = 0
        self.sent_s: dict[int, float] = {}
        self.latency_counts = np.zeros(LATENCY_BINS, dtype=np.int64)

    def state_published(self, stamp_ns: int) -> None:
        """The state of tick `stamp_ns` goes out now."""
        now = time.monotonic()
        if self.last_s is None:
            self.first_s = now
        else:
            self.window_intervals += 1
            self.window_duration_s += now - self.last_s
            if self.deadlines and now - self.last_s > 2.0 * self.period_s:
                self.deadline_misses += 1
                self.window_misses += 1
        self.last_s = now
        self.ticks += 1
        self.sent_s[stamp_ns] = now
        if len(self.sent_s) > PENDING_STATES:
            del self.sent_s[next(iter(self.sent_s))]

    def take_window(self) -> tuple[int, float, int]:
        """(tick intervals, their total duration in s, deadline misses) since the last call.

        Intervals, not ticks per wall-clock window: a window that holds the start, the end
        or a stall of the loop then still gives its true rate."""
        window = (self.window_intervals, self.window_duration_s, self.window_misses)
        self.window_intervals, self.window_duration_s, self.window_misses = 0, 0.0, 0
        return window

    def command_received(self, stamp_ns: int) -> None:
        """The command answering the state `stamp_ns` has just arrived."""
        sent = self.sent_s.pop(stamp_ns, None)
        if sent is not None:
            ratio = max(time.monotonic() - sent, LATENCY_FLOOR_S) / LATENCY_FLOOR_S
            self.latency_counts[min(int(math.log(ratio, LATENCY_BIN_RATIO)), LATENCY_BINS - 1)] += 1

    def latency_percentile_s(self, percent: float) -> float:
        """Upper edge (s) of the histogram bin holding that percentile of the latencies."""
        cumulative = np.cumsum(self.latency_counts)
        rank = percent / 100.0 * cumulative[-1]
        return LATENCY_FLOOR_S * LATENCY_BIN_RATIO ** (int(np.searchsorted(cumulative, rank)) + 1)

    def facts(self) -> dict[str, str]:
        """Diagnostics key-values; the monotonic clock is the same in every process here."""
        facts = {'ticks timed': str(self.ticks)}
        if self.ticks >= 2 and self.last_s > self.first_s:
            facts.update({
                'tick rate wall hz': f'{(self.ticks - 1) / (self.last_s - self.first_s):.1f}',
                'first tick monotonic s': f'{self.first_s:.6f}',
                'last tick monotonic s': f'{self.last_s:.6f}'})
        if self.deadlines and self.ticks >= 2:
            facts['deadline misses total'] = str(self.deadline_misses)
            facts['deadline misses pct'] = f'{100.0 * self.deadline_misses / (self.ticks - 1):.3f}'
        if self.latency_counts.any():
            facts['states answered'] = str(int(self.latency_counts.sum()))
            facts['state to command p50 ms'] = f'{self.latency_percentile_s(50) * 1e3:.3f}'
            facts['state to command p99 ms'] = f'{self.latency_percentile_s(99) * 1e3:.3f}'
        return facts
