"""Publishers whose failure is counted and reported, never fatal."""
from __future__ import annotations

from rclpy.impl.implementation_singleton import rclpy_implementation
from rclpy.publisher import Publisher


class GuardedPublisher(Publisher):
    """Every publisher of a CdprNode: a publish that fails is counted and reported, never
    fatal (an exception in a callback would end the node, and with it the graph)."""

    failed = None   # CdprNode.create_publisher sets it: failed(topic, error)

    def publish(self, msg) -> None:
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
        if self.get_subscription_count():
            self.publish(build())
