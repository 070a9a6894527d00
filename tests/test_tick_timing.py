"""The plant's tick timing on a fake clock: rate, deadline misses, latency percentiles."""
from __future__ import annotations

import pytest

from cdpr_twin.nodes import tick_timing
from cdpr_twin.nodes.tick_timing import TickTiming

PERIOD_S = 0.002


class FakeClock:
    def __init__(self):
        self.now_s = 100.0

    def monotonic(self) -> float:
        return self.now_s


@pytest.fixture
def clock(monkeypatch):
    fake = FakeClock()
    monkeypatch.setattr(tick_timing.time, 'monotonic', fake.monotonic)
    return fake


def run_ticks(timing, clock, intervals_s, latency_s):
    for k, interval in enumerate(intervals_s):
        clock.now_s += interval
        timing.state_published(k)
        clock.now_s += latency_s(k)
        timing.command_received(k)
        clock.now_s -= latency_s(k)


def test_rate_and_deadline_misses(clock):
    timing = TickTiming(PERIOD_S, deadlines=True)
    # 1000 ticks on time, but ticks 100 and 700 come 2.5 periods after the one before
    intervals = [2.5 * PERIOD_S if k in (100, 700) else PERIOD_S for k in range(1000)]
    run_ticks(timing, clock, intervals, lambda k: 3e-4)
    facts = timing.facts()
    assert facts['deadline misses total'] == '2'
    assert float(facts['deadline misses pct']) == pytest.approx(100 * 2 / 999, abs=1e-3)
    assert float(facts['tick rate wall hz']) == pytest.approx(999 / (sum(intervals[1:])), rel=1e-3)


def test_latency_percentiles_within_the_bin_width(clock):
    timing = TickTiming(PERIOD_S, deadlines=False)
    # 98 % of the answers take 0.4 ms, 2 % take 3 ms
    run_ticks(timing, clock, [PERIOD_S] * 1000, lambda k: 3e-3 if k % 50 == 0 else 4e-4)
    facts = timing.facts()
    assert 'deadline misses total' not in facts
    assert facts['states answered'] == '1000'
    assert 0.4 <= float(facts['state to command p50 ms']) <= 0.4 * 1.021
    assert 3.0 <= float(facts['state to command p99 ms']) <= 3.0 * 1.021


def test_commands_for_unknown_or_repeated_stamps_are_not_counted(clock):
    timing = TickTiming(PERIOD_S, deadlines=False)
    timing.state_published(0)
    timing.command_received(0)
    timing.command_received(0)
    timing.command_received(12345)
    assert timing.facts()['states answered'] == '1'


def test_each_window_counts_its_own_intervals_and_misses(clock):
    timing = TickTiming(PERIOD_S, deadlines=True)
    run_ticks(timing, clock, [PERIOD_S] * 100 + [3 * PERIOD_S], lambda k: 3e-4)
    intervals, duration_s, misses = timing.take_window()
    # the first tick opens the run: 100 intervals, the last one late
    assert (intervals, misses) == (100, 1)
    assert duration_s == pytest.approx(99 * PERIOD_S + 3 * PERIOD_S)
    # a stall across the window's start counts in the window it ends in
    clock.now_s += 0.5
    timing.state_published(101)
    assert timing.take_window() == (1, pytest.approx(0.5), 1)
    assert timing.take_window() == (0, 0.0, 0)
