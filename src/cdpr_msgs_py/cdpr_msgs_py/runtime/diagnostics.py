"""What a node did and rejected, and its health (health.py), on /diagnostics once a second."""
from __future__ import annotations

import time
from collections import Counter

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rclpy.node import Node

from .. import contract, qos
from ..health import ERROR, OK, WARN, Health, HealthLimits

# A condition that repeats (rejected messages, failed publishes, alarms that name no
# cable) is logged at most once per this long (s); /diagnostics counts every one.
LOG_THROTTLE_S = 1.0
LEVELS = {OK: DiagnosticStatus.OK, WARN: DiagnosticStatus.WARN, ERROR: DiagnosticStatus.ERROR}
LEVEL_NAMES = {OK: 'OK', WARN: 'WARN', ERROR: 'ERROR'}


class Diagnostics:
    """Counts of what a node did and rejected, and its health (health.py), published on
    /diagnostics once a second."""

    def __init__(self, node: Node, period_s: float = 1.0):
        self.node = node
        self.totals: Counter = Counter()
        self.window: Counter = Counter()
        self.rejected: Counter = Counter()
        self.publish_failures: Counter = Counter()
        # What the node wants reported besides counts (key → text), e.g. its verdicts.
        self.facts: dict[str, str] = {}
        # A condition the node cannot do its job in (stale inputs, braked drums), reported
        # as ERROR while it lasts; '' when none.
        self.error = ''
        self.health = Health(HealthLimits())
        self.level = OK   # of the last status published
        # The last status published, as last_status() gives it.
        self.last_values: dict[str, str] = {}
        self.last_message = ''
        self.activity = 0
        self.period_s = period_s
        self.last_publish = time.monotonic()
        self.publisher = node.create_publisher(DiagnosticArray, contract.DIAGNOSTICS, qos.DIAGNOSTICS)

    def count(self, key: str) -> None:
        """One more handled `key` (a message, a tick)."""
        self.totals[key] += 1
        self.window[key] += 1
        self.activity += 1

    def warn(self, key: str, text: str) -> None:
        """An event worth a warning (held for the config's `health.warning_hold_s`)."""
        self.health.warn(key, text, time.monotonic())

    def reject(self, topic: str, reason: str) -> None:
        self.rejected[topic] += 1
        self.activity += 1
        self.warn(f'rejected {topic}', f'rejected messages on {topic}')
        self.node.get_logger().warning(f'rejected a message on {topic}: {reason}',
                                       throttle_duration_sec=LOG_THROTTLE_S)

    def publish_failed(self, topic: str, error: Exception) -> None:
        """A publish raised: the sample is lost (lockstep sends its state again), the node
        goes on."""
        self.publish_failures[topic] += 1
        self.warn(f'publish failed {topic}', f'publishing on {topic} failed')
        self.node.get_logger().warning(f'publishing on {topic} failed: {error}',
                                       throttle_duration_sec=LOG_THROTTLE_S)

    def maybe_publish(self) -> None:
        now = time.monotonic()
        if now - self.last_publish >= self.period_s:
            self.publish(now - self.last_publish)
            self.last_publish = now

    def publish(self, elapsed_s: float = 0.0) -> None:
        now = time.monotonic()
        readers = self.node.stream_readers()
        for topic, seconds in self.node.acknowledgements.lagging(now, readers).items():
            matched, graph = readers[topic]
            key = f'lagging {topic}'
            text = (f'a reader of {topic} lags: not everything acknowledged for {seconds:.1f} s '
                    f'({matched} readers, {"?" if graph is None else graph} of the graph)')
            if key not in self.health.events:
                self.node.get_logger().warning(text)
            self.warn(key, text)
        errors, warnings = self.node.current_problems()
        level, text = self.health.assess(now, [self.error, *errors], warnings)
        if level == ERROR and self.level != ERROR:
            # the console too: whoever watches the node's output, not /diagnostics, learns
            # that it cannot do its job (once per episode, not once a second)
            self.node.get_logger().error(text)
        elif self.level == ERROR and level != ERROR:
            # and that the episode is over, so a log alone tells how long it lasted
            self.node.get_logger().info(f'no longer in error: {text}')
        self.level = level
        status = DiagnosticStatus(level=LEVELS[level], message=text, hardware_id='cdpr',
                                  name=self.node.get_fully_qualified_name())
        pairs = [(f'{key} total', str(value)) for key, value in self.totals.items()]
        if elapsed_s > 0:
            pairs += [(f'{key} rate hz', f'{value / elapsed_s:.1f}') for key, value in self.window.items()]
        pairs += [(f'rejected {key}', str(value)) for key, value in self.rejected.items()]
        pairs += [(f'publish failed {key}', str(value)) for key, value in self.publish_failures.items()]
        pairs += list({**self.facts, **self.node.current_facts()}.items())
        status.values = [KeyValue(key=k, value=v) for k, v in pairs]
        self.last_values, self.last_message = dict(pairs), text
        message = DiagnosticArray()
        message.header.stamp = self.node.get_clock().now().to_msg()
        message.status = [status]
        self.publisher.publish(message)
        self.window.clear()

    def last_status(self) -> dict:
        """The status last published, as JSON-able values: the node's `name`, `level`
        (OK, WARN, ERROR), `message` and its key-`values` (texts)."""
        return {'name': self.node.get_fully_qualified_name(), 'level': LEVEL_NAMES[self.level],
                'message': self.last_message, 'values': self.last_values}
