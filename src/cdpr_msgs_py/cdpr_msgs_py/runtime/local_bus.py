"""The composed loop's own messages, delivered inside its process (ROS 2's intra-process
communication, which rclpy lacks): a topic that a composed node writes (contract.TOPICS)
reaches the composed nodes that read it as the very message object, in the order
published, without DDS; DDS carries it only to readers outside the process (the recorder,
the markers, your tools), and only while there are some.

A message published inside a callback is delivered after that callback, from the
process's spin loop (`dispatch`), never from within the publish: the loop of a lockstep
tick (plant → controller → plant) would otherwise recurse. A latched topic's last message
reaches a reader that subscribes later, as transient-local DDS does.
"""
from __future__ import annotations

from collections import deque

from .. import contract

# The bus the nodes constructed in this process now join (spin.run_composed sets it).
current: 'LocalBus | None' = None
# How many messages one `dispatch` delivers at most before the spin loop looks at DDS and
# the nodes' idle work again: a lockstep loop feeds itself and would never return.
DISPATCH_BATCH = 64


class LocalBus:
    """The topics the composed nodes `members` (node names) write, by resolved name."""

    def __init__(self, members):
        self.members = frozenset(members)
        self.readers: dict[str, list] = {}
        self.latched: dict[str, object] = {}
        self.queue: deque = deque()

    def writes(self, topic: str, writer: str | None = None) -> bool:
        """Whether `topic` (as the contract names it) is written by a composed node
        (`writer`, where given, the one a reader obeys, must be it)."""
        known = contract.TOPICS.get(topic)
        return (known is not None and known.writer in self.members
                and (writer is None or writer.rsplit('/', 1)[-1] == known.writer))

    def subscribe(self, resolved: str, callback) -> None:
        self.readers.setdefault(resolved, []).append(callback)
        if resolved in self.latched:
            self.queue.append(((callback,), self.latched[resolved]))

    def has_readers(self, resolved: str) -> bool:
        return bool(self.readers.get(resolved))

    def publish(self, resolved: str, message, latched: bool) -> None:
        if latched:
            self.latched[resolved] = message
        readers = self.readers.get(resolved)
        if readers:
            self.queue.append((tuple(readers), message))

    @property
    def pending(self) -> bool:
        return bool(self.queue)

    def dispatch(self) -> int:
        """Deliver what is queued, oldest first, at most DISPATCH_BATCH messages (what
        their callbacks publish joins the queue's end); how many were delivered."""
        delivered = 0
        while self.queue and delivered < DISPATCH_BATCH:
            callbacks, message = self.queue.popleft()
            for callback in callbacks:
                callback(message)
            delivered += 1
        return delivered
