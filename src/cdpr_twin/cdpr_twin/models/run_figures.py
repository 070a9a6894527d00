"""A run's figures of the end-effector, from every tick: the node that holds the truth
computes them as the run goes (the plant simulator; the in-process engine the same way),
and says them in its last status, from where metrics.json takes them. The view topics,
which carry the truth only on the view ticks, serve plots.

Per tick: the end-effector's pose and the cables' tensions (true, or as estimated where
there is no truth), and the reference pose of the tick where it is known. The figures:
the lowest point over the run; the last pose; and relative to an event — the first
cable's parting (`failure_at`) or, in a run where none parts, the first naming of a
broken cable (`detection_at`) — the largest tracking error (position, and a platform's
orientation) on the ticks before it, and the least and greatest tension of the cables
left (all but those that parted) on the ticks from it on, and the ticks on which one of
them carried less than τ_min: before the detection (`undetected`: nothing acts on the
break yet), within JOLT_S of the later of the event and the detection (the break's jolt and
the recovery's first step, which docs/recovery-tensions.md allows) and after. A tick is
before an event when its time (tick × period) is before the event's instant, as
metrics.ticks_before counts.

A naming is learnt a few ticks after the tick it judged: rows are kept HOLD_S before they
are counted, so that a tick is judged against the events of its own time.
"""
from __future__ import annotations

import math

import numpy as np

from cdpr_control.geometry.rotation import difference

# How long (s) a tick's row waits before it is counted: longer than a verdict takes to
# reach the plant (VERDICT_DELAY_TICKS in lockstep; a realtime supervisor trails by a
# few ms).
HOLD_S = 1.0
# The break's jolt (s): a cable left may go slack this soon after the parting, before a
# detection can act (docs/recovery-tensions.md, the allowance)
JOLT_S = 0.075
# a tension this far (N) under τ_min is not under it: the plant's rounding
UNDER_TOLERANCE_N = 1e-6
EVENTS = ('failure', 'detection')


def first_tick_at_or_after(time_s: float, period_s: float) -> int:
    """The first tick whose time (tick × period_s) is not before `time_s`."""
    tick = max(int(math.floor(time_s / period_s)), 0)
    while tick * period_s < time_s:
        tick += 1
    while tick > 0 and (tick - 1) * period_s >= time_s:
        tick -= 1
    return tick


class _Window:
    """The figures relative to one event: tracking before it, tensions from it on."""

    def __init__(self, cable_count: int):
        self.tracking_m = -math.inf
        self.turn_rad = -math.inf
        self.low_n = np.full(cable_count, math.inf)
        self.high_n = np.full(cable_count, -math.inf)
        self.after = 0
        self.under = {'undetected': 0, 'jolt': 0, 'after_jolt': 0}

    def fold(self, ticks, event, detected, error_m, turn_rad, tension_n, remaining, tension_min_n,
             jolt_ticks) -> None:
        """`detected`: the tick of the first naming, None where none was learnt yet."""
        before = ticks < event if event is not None else np.ones(ticks.size, dtype=bool)
        tracked = before & np.isfinite(error_m)
        if tracked.any():
            self.tracking_m = max(self.tracking_m, float(np.max(error_m[tracked])))
            if turn_rad is not None:
                self.turn_rad = max(self.turn_rad, float(np.max(turn_rad[tracked])))
        after = ~before
        if after.any():
            self.low_n = np.minimum(self.low_n, tension_n[after].min(axis=0))
            self.high_n = np.maximum(self.high_n, tension_n[after].max(axis=0))
            self.after += int(np.count_nonzero(after))
            if tension_min_n is not None and remaining.any():
                under = (tension_n[after][:, remaining] < tension_min_n - UNDER_TOLERANCE_N).any(axis=1)
                undetected = (ticks[after] < detected if detected is not None
                              else np.ones(under.size, dtype=bool))
                in_jolt = ~undetected & (ticks[after] < max(event, detected or 0) + jolt_ticks)
                self.under['undetected'] += int(np.count_nonzero(under & undetected))
                self.under['jolt'] += int(np.count_nonzero(under & in_jolt))
                self.under['after_jolt'] += int(np.count_nonzero(under & ~undetected & ~in_jolt))

    def copy(self) -> '_Window':
        other = _Window(self.low_n.size)
        other.tracking_m, other.turn_rad, other.after = self.tracking_m, self.turn_rad, self.after
        other.low_n, other.high_n = self.low_n.copy(), self.high_n.copy()
        other.under = dict(self.under)
        return other

    def figures(self, remaining: np.ndarray, has_orientation: bool, counts_under: bool) -> dict:
        held = self.after and remaining.any()
        return {
            'tracking_error_m': None if self.tracking_m == -math.inf else self.tracking_m,
            **({'orientation_tracking_error_rad': None if self.turn_rad == -math.inf else self.turn_rad}
               if has_orientation else {}),
            'min_tension_n': float(np.min(self.low_n[remaining])) if held else None,
            'max_tension_n': float(np.max(self.high_n[remaining])) if held else None,
            'ticks_under_tension_min': dict(self.under) if held and counts_under else None,
        }


class RunFigures:
    """The figures of a run, fed a row per tick (`add`), or a stack of rows (`add_rows`)."""

    def __init__(self, cable_count: int, period_s: float, has_orientation: bool, hold_s: float = HOLD_S,
                 tension_min_n: float | None = None):
        """`tension_min_n` (N): the robot's τ_min, the ticks under it counted; None: not."""
        self.cable_count = cable_count
        self.tension_min_n = tension_min_n
        self.jolt_ticks = int(math.ceil(JOLT_S / period_s))
        self.period_s = period_s
        self.has_orientation = has_orientation
        self.hold_ticks = max(1, int(math.ceil(hold_s / period_s)))
        self.rows: list[tuple] = []
        self.windows = {event: _Window(cable_count) for event in EVENTS}
        self.events: dict[str, int | None] = dict.fromkeys(EVENTS)
        self.broken: set[int] = set()
        self.lowest_m = math.inf
        self.ticks = 0
        self.last: tuple | None = None
        # the tracking error counts the settled motion only: a goal moves the reference away
        self.tracked_until: int | None = None

    def cable_broken(self, cable: int) -> None:
        """Cable `cable` (0-based) is broken, when is not known: its tension leaves the figures."""
        self.broken.add(cable)

    def failure_at(self, time_s: float, cable: int) -> None:
        """Cable `cable` (0-based) really parted at `time_s`: its tension leaves the
        figures, and the first parting is the run's event."""
        self.cable_broken(cable)
        if self.events['failure'] is None:
            self.events['failure'] = first_tick_at_or_after(time_s, self.period_s)

    def take_breaks(self, broken_at_s: dict[int, float]) -> None:
        """The plant's record of the cables it parted (0-based cable → instant s): those
        not known yet, by `failure_at`."""
        for cable, at in broken_at_s.items():
            if cable not in self.broken:
                self.failure_at(at, cable)

    def detection_at(self, tick: int) -> None:
        """The verdict on `tick` first named a broken cable."""
        if self.events['detection'] is None:
            self.events['detection'] = tick

    def goal_at(self, tick: int) -> None:
        """A goal reached the generator by `tick`: from then on the reference is not the
        settled motion's, whose poses the tracking error is counted against."""
        if self.tracked_until is None:
            self.tracked_until = tick

    def add(self, tick: int, position_m, orientation, tension_n, reference_position_m=None,
            reference_orientation=None) -> None:
        """One tick: the end-effector's pose (orientation None for a point mass), the
        tensions (N), and the reference pose where known."""
        # as lists, copies: a model may write its next state into the same arrays (a list
        # of floats is the cheapest copy of a few, ~0.2 µs)
        position_m = np.asarray(position_m).tolist()
        orientation = None if orientation is None else np.asarray(orientation).tolist()
        self.rows.append((tick, position_m, orientation, np.asarray(tension_n).tolist(), reference_position_m,
                          reference_orientation))
        self.last = (tick, position_m, orientation)
        if len(self.rows) >= 2 * self.hold_ticks:
            self._fold(self.rows[:-self.hold_ticks], self)
            del self.rows[:-self.hold_ticks]

    def add_rows(self, ticks, position_m, orientation, tension_n, reference_position_m=None,
                 reference_orientation=None) -> None:
        """A stack of rows at once, after those added so far, counted at once: the events
        must be said beforehand (a recorded run, or the in-process engine's at its end)."""
        if self.rows:
            self._fold(self.rows, self)
            self.rows = []
        count = len(ticks)
        if not count:
            return
        reference = (np.full((count, 3), np.nan) if reference_position_m is None
                     else np.asarray(reference_position_m, dtype=float))
        wanted = (None if not self.has_orientation else np.full((count, 4), np.nan) if reference_orientation is None
                  else np.asarray(reference_orientation, dtype=float))
        self._fold_arrays(np.asarray(ticks), np.asarray(position_m, dtype=float),
                          None if orientation is None else np.asarray(orientation, dtype=float),
                          np.asarray(tension_n, dtype=float), reference, wanted, self)
        self.last = (int(ticks[-1]), np.asarray(position_m[-1], dtype=float).tolist(),
                     None if orientation is None else np.asarray(orientation[-1], dtype=float).tolist())

    def _fold(self, rows: list[tuple], into: 'RunFigures') -> None:
        nan_position, nan_orientation = [np.nan] * 3, [np.nan] * 4
        self._fold_arrays(np.array([row[0] for row in rows]), np.array([row[1] for row in rows], dtype=float),
                          np.array([row[2] for row in rows], dtype=float) if self.has_orientation else None,
                          np.array([row[3] for row in rows], dtype=float),
                          np.array([nan_position if row[4] is None else row[4] for row in rows], dtype=float),
                          np.array([nan_orientation if row[5] is None else row[5] for row in rows], dtype=float)
                          if self.has_orientation else None, into)

    def _fold_arrays(self, ticks, position, orientation, tension, reference, wanted, into: 'RunFigures') -> None:
        """Rows as arrays (the references NaN where not known) into `into`'s figures."""
        into.ticks += len(ticks)
        into.lowest_m = min(into.lowest_m, float(np.min(position[:, 2])))
        error = np.linalg.norm(position - reference, axis=1)
        turn = None
        if self.has_orientation:
            turn = np.full(len(ticks), np.nan)
            known = np.isfinite(wanted).all(axis=1)
            if known.any():
                turn[known] = np.linalg.norm(difference(orientation[known], wanted[known]), axis=-1)
        if self.tracked_until is not None:
            error[ticks >= self.tracked_until] = np.nan
        remaining = np.ones(self.cable_count, dtype=bool)
        remaining[list(self.broken)] = False
        for event, window in into.windows.items():
            window.fold(ticks, self.events[event], self.events['detection'], error, turn, tension, remaining,
                        self.tension_min_n, self.jolt_ticks)

    def summary(self) -> dict:
        """The figures so far, in plain types (cables 1-based); the rows still held are
        counted without being let go."""
        whole = RunFigures(self.cable_count, self.period_s, self.has_orientation,
                           tension_min_n=self.tension_min_n)
        whole.windows = {event: window.copy() for event, window in self.windows.items()}
        whole.lowest_m, whole.ticks = self.lowest_m, self.ticks
        if self.rows:
            self._fold(self.rows, whole)
        remaining = np.ones(self.cable_count, dtype=bool)
        remaining[list(self.broken)] = False
        tick, position, orientation = self.last if self.last is not None else (None, None, None)
        return {
            'ticks': whole.ticks,
            'lowest_point_m': None if whole.lowest_m == math.inf else whole.lowest_m,
            'final_tick': tick,
            'final_position_m': None if position is None else [float(v) for v in position],
            **({'final_orientation': None if orientation is None else [float(v) for v in orientation]}
               if self.has_orientation else {}),
            'broken_cables': sorted(cable + 1 for cable in self.broken),
            'failure_tick': self.events['failure'],
            'detection_tick': self.events['detection'],
            'tracked_until_tick': self.tracked_until,
            **{event: whole.windows[event].figures(remaining, self.has_orientation, self.tension_min_n is not None)
               for event in EVENTS},
        }
