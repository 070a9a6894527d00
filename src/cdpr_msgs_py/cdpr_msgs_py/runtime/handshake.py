"""The start handshake: a node subscribes to the tick only once every endpoint the
launcher named (the `matches` parameter) has matched its peers and every required
sole-writer subscription knows its writer."""
from __future__ import annotations


def parse_matches(entries) -> list[tuple[str, str, int]]:
    """'publisher:TOPIC=N' / 'subscription:TOPIC=N' entries as (kind, topic, N)."""
    requirements = []
    for entry in filter(None, entries):
        kind, _, rest = entry.partition(':')
        topic, _, count = rest.rpartition('=')
        if kind not in ('publisher', 'subscription') or not topic or not count.isdigit():
            raise ValueError(f"parameter matches: expected 'publisher:TOPIC=N' or "
                             f"'subscription:TOPIC=N', got {entry!r}")
        requirements.append((kind, topic, int(count)))
    return requirements


class StartHandshake:
    """Mixin of an rclpy Node; the node sets `match_requirements` (parse_matches) and
    `required_writers` (sole-writer subscriptions) and calls `try_start` when idle."""

    pending_start = None

    def start_when_matched(self, start) -> None:
        """Call `start` (which subscribes to the tick, /cdpr/joint_states) once every
        endpoint named in the `matches` parameter has matched its peers.

        DDS matches endpoints pairwise and late under load: a per-cycle message sent
        before its subscriber matched is lost. The graph launcher names what each node
        must be matched with, and the plant starts only when it sees every node's
        subscription to the tick, so nothing is sent before everyone listens.
        """
        self.pending_start = start
        self.try_start()

    def try_start(self) -> None:
        if self.pending_start is None or not self.matched():
            return
        start, self.pending_start = self.pending_start, None
        start()

    def matched(self) -> bool:
        """True when every required endpoint has matched at least its count of peers and
        every sole-writer subscription knows its writer's publisher, so that the first
        messages of the run are neither lost nor rejected."""
        endpoints = {('publisher', p.topic_name): p.get_subscription_count for p in self.publishers}
        endpoints.update({('subscription', s.topic_name): s.get_publisher_count
                          for s in self.subscriptions})
        for kind, topic, count in self.match_requirements:
            matched = endpoints.get((kind, self.resolve_topic_name(topic)))
            if matched is None or matched() < count:
                return False
        return all(subscription.known() for subscription in self.required_writers)
