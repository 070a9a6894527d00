"""Publishers whose failure is counted and reported, never fatal; composed, delivering to
the process's own readers inside it (local_bus)."""
from __future__ import annotations

from rclpy.impl.implementation_singleton import rclpy_implementation
from rclpy.publisher import Publisher
from rclpy.qos import DurabilityPolicy


class GuardedPublisher(Publisher):
    """Every publisher of a CdprNode: a publish that fails is counted and reported, never
    fatal (an exception in a callback would end the node, and with it the graph)."""

    failed = None   # CdprNode.create_publisher sets it: failed(topic, error)
    bus = None      # deliver_locally sets it
    latched = False

    def deliver_locally(self, bus) -> None:
        """Composed: the process's readers of this topic get each message inside it; DDS
        carries it only to readers outside (a latched one always: a late joiner's)."""
        self.bus = bus
        self.latched = self.qos_profile.durability == DurabilityPolicy.TRANSIENT_LOCAL

    def publish(self, msg) -> None:
        if self.bus is not None:
            self.bus.publish(self.topic_name, msg, self.latched)
            if not self.latched and not self.get_subscription_count():
                return
        try:
            super().publish(msg)
        except rclpy_implementation.RCLError as err:
            self.failed(self.topic_name, err)

    def publish_if_subscribed(self, build) -> None:
        """Publish `build()` only while a reader is matched: for a topic that no node of
        the loop reads, only the recorder or a viewer (contract.Topic.on_demand). A
        volatile topic loses nothing to an empty room, and building and publishing a
        message costs ~15 µs of CPU (several times that on a loaded machine); the start
        handshake has the recorder matched before the first tick, and a reader that
        joins later gets every message from then on."""
        if self.get_subscription_count() or (self.bus is not None and self.bus.has_readers(self.topic_name)):
            self.publish(build())
