"""The level of a node's /diagnostics status, and why (no ROS here).

A diagnostic aggregator acts on the level alone, so each level says one thing:

- ERROR: the node cannot do its job — its inputs are stale (the supervisor's "FDI
  unavailable", the controller's SAFE_HOLD), the drums are braked, the plant's loop does
  not keep its period, or the supervisor is in FAULT;
- WARN: it does its job, with something an operator should look at — rejected messages,
  a failed publish, a reader that does not acknowledge, ticks left unjudged, an alarm
  that ended without a free motor, a broken cable being handled;
- OK: none of these; for the supervisor, the safety function is on.

Conditions (stale inputs, the last window's counts) count while they last. Events (a
rejected message, an alarm without a free motor, a lagging reader) keep their WARN for
`warning_hold_s` after they were last seen, so a monitor that looks now and then still
sees them; the counts in the status's values keep the whole history.
"""
from __future__ import annotations

from dataclasses import dataclass, fields, replace

from .contract import FAULT

# diagnostic_msgs/DiagnosticStatus levels
OK, WARN, ERROR = 0, 1, 2

# The limits that are fractions of a window's ticks or periods.
FRACTIONS = ('unjudged_limit', 'tick_rate_min', 'deadline_miss_limit')


@dataclass(frozen=True)
class HealthLimits:
    """The config's `health` section; each field's default stands for a missing key."""

    # An event's WARN lasts this long after it was last seen (s): several polls of a
    # monitor that looks every few seconds, short enough not to colour a whole run.
    warning_hold_s: float = 30.0
    # A writer read from outside the graph and not once fully acknowledged by its
    # readers for this long has one that lags (s): longer than the graph's readers alone
    # leave it so in lockstep here (3-6 s), shorter than the 20 s after which DDS drops a
    # reader that stopped (AcknowledgementWatch).
    reader_lag_limit_s: float = 10.0
    # WARN when more than this fraction of the window's ticks went unjudged.
    unjudged_limit: float = 0.01
    # Realtime ERROR when the window's tick rate falls below this fraction of 1/period ...
    tick_rate_min: float = 0.95
    # ... or more than this fraction of its periods missed their deadline.
    deadline_miss_limit: float = 0.02

    @classmethod
    def from_section(cls, health) -> 'HealthLimits':
        """From a config section (cdpr_control.config.Section: this package reads no file)."""
        limits = cls()
        for field in fields(cls):
            value = health.number(field.name, field.default, non_negative=True,
                                  maximum=1.0 if field.name in FRACTIONS else None)
            try:
                limits = limits.with_value(field.name, value)
            except ValueError as err:
                raise health.error(field.name, str(err)) from err
        return limits

    def with_value(self, name: str, value) -> 'HealthLimits':
        """These limits with `name` set to `value` (a ROS parameter changed while the node
        runs); ValueError saying why for a value it cannot be."""
        if name not in {field.name for field in fields(self)}:
            raise ValueError(f'is not a health limit (one of {", ".join(f.name for f in fields(self))})')
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not value >= 0.0:
            raise ValueError(f'must be a number, not negative, got {value!r}')
        if name in FRACTIONS and value > 1.0:
            raise ValueError(f'must be a fraction (0 to 1), got {value!r}')
        return replace(self, **{name: float(value)})


class Health:
    """Turns a node's conditions and recent events into (level, message)."""

    def __init__(self, limits: HealthLimits):
        self.limits = limits
        self.events: dict[str, tuple[float, str]] = {}   # key → (last seen s, text)

    def warn(self, key: str, text: str, now_s: float) -> None:
        """An event worth a warning (the latest text of `key` is the one reported)."""
        self.events[key] = (now_s, text)

    def assess(self, now_s: float, errors: list[str], warnings: list[str]) -> tuple[int, str]:
        """The level and message from the current conditions ('' counts as none) and the
        events seen within `warning_hold_s`."""
        hold = self.limits.warning_hold_s
        self.events = {key: event for key, event in self.events.items() if now_s - event[0] <= hold}
        errors = [text for text in errors if text]
        warnings = [text for text in warnings if text] + [text for _, text in self.events.values()]
        level = ERROR if errors else WARN if warnings else OK
        return level, '; '.join(errors + warnings) or 'ok'


def loop_problem(limits: HealthLimits, period_s: float, intervals: int, duration_s: float,
                 misses: int) -> str:
    """Realtime: why the loop did not keep its period over a window of `intervals` tick
    intervals lasting `duration_s` in all, `misses` of them longer than two periods; ''
    when it did, or when there was no interval to judge."""
    if intervals == 0:
        return ''
    problems = []
    rate_hz, nominal_hz = intervals / duration_s, 1.0 / period_s
    if rate_hz < limits.tick_rate_min * nominal_hz:
        problems.append(f'tick rate {rate_hz:.0f} Hz of {nominal_hz:.0f} Hz')
    if misses > limits.deadline_miss_limit * intervals:
        problems.append(f'{misses} of {intervals} deadlines missed')
    return f'the loop does not keep its period: {", ".join(problems)}' if problems else ''


def unjudged_problem(limits: HealthLimits, ticks: int, unjudged: int) -> str:
    """Why the FDI was partly blind over a window of `ticks` ticks, `unjudged` of which it
    did not judge; '' when within the limit."""
    if ticks == 0 or unjudged <= limits.unjudged_limit * ticks:
        return ''
    return f'{unjudged} of {ticks} ticks unjudged ({100.0 * unjudged / ticks:.1f} %)'


def verdict_problems(mode: str, broken_cables: list[int], fault: str) -> tuple[str, str]:
    """(error, warning) from the supervisor's verdict: FAULT is an error (the robot can
    only be held); a broken cable being recovered from, or held after, is a warning."""
    if mode == FAULT:
        return f'FAULT: {fault}', ''
    if broken_cables:
        return '', f'cable(s) {", ".join(map(str, broken_cables))} broken: {mode}'
    return '', ''


class AcknowledgementWatch:
    """Per topic, when its writer was last acknowledged by all its readers, and which
    topics have a reader from outside the graph that lags.

    A reliable reader acknowledges what it has received on the writer's heartbeats. A
    writer is fully acknowledged only at an instant when every reader has acknowledged
    every sample, which at 500 Hz needs all of them to answer within one period: the
    graph's own readers do, mostly (lockstep, here: at least every 3-6 s, the default
    heartbeat period being 3 s), but a reader starved of CPU (the niced recorder under
    load) can keep a writer from it for tens of seconds while it reads every tick. So a
    writer long without full acknowledgement means a lagging reader only when a reader
    from outside the graph is there to blame: one that has stopped reading never
    acknowledges, until DDS drops it (its participant's lease, 20 s).
    """

    def __init__(self, limit_s: float):
        self.limit_s = limit_s
        self.last_acknowledged_s: dict[str, float] = {}

    def acknowledged(self, topic: str, now_s: float) -> None:
        """Every reader of `topic` has acknowledged everything its writer sent (also how a
        watch starts: a writer that has sent nothing is acknowledged)."""
        self.last_acknowledged_s[topic] = now_s

    def lagging(self, now_s: float, readers: dict[str, tuple[int, int | None]]) -> dict[str, float]:
        """Topic → seconds without full acknowledgement, for the topics beyond the limit
        that have readers from outside the graph. `readers`: topic → (readers matched,
        readers of the graph; None when unknown, as for a node started alone, which then
        counts every reader as outside)."""
        lagging = {}
        # a snapshot: the shell's watching threads update the values meanwhile
        for topic, last in list(self.last_acknowledged_s.items()):
            matched, graph = readers.get(topic, (0, 0))
            outside = matched > 0 if graph is None else matched > graph
            if outside and now_s - last > self.limit_s:
                lagging[topic] = now_s - last
        return lagging
