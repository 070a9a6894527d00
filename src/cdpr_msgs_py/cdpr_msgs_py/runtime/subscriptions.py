"""Subscriptions that obey one writer: the contract's sole-writer rule (sole_writer.py)
applied to the publisher GID of every message."""
from __future__ import annotations

import inspect
import time

from rclpy.node import Node

from ..contract import raw_stream
from ..sole_writer import Endpoint, SoleWriter, qualified_name


# What the ROS graph (rmw_dds_common) calls the node of a publisher it has discovered
# before that node's own announcement.
UNKNOWN_NODE_NAME = '_NODE_NAME_UNKNOWN_'
# A callback of this signature gets the message info too (rclpy looks at the parameters).
MESSAGE_AND_INFO = inspect.Signature([inspect.Parameter(name, inspect.Parameter.POSITIONAL_ONLY)
                                      for name in ('message', 'info')])


def message_info_callback(handler):
    """`handler(message, info)` as a subscription callback that rclpy hands the message
    info (the publisher's GID) to. rclpy picks that form from the callback's signature;
    its EventsExecutor (rclpy 9.1.2) then calls the callback with one (message, info)
    tuple, its other executors with two arguments: this takes both."""
    def callback(*arguments):
        handler(*(arguments[0] if len(arguments) == 1 else arguments))

    callback.__signature__ = MESSAGE_AND_INFO
    return callback


class SoleWriterSubscription:
    """A subscription whose handler gets only the messages of one node's publisher
    (the SoleWriter rule); any other is rejected, counted as `rejected <topic>` in
    /diagnostics, and its writer named there and in the log (WARN). With `other`, a
    message of any other writer goes there instead, counted as `<topic> from other
    writers` (a recorder keeps it apart)."""

    def __init__(self, node: Node, msg_type, topic: str, handler, qos_profile, writer: str,
                 other=None, raw: bool = False):
        self.node = node
        self.topic = topic
        self.handler = handler
        self.other = other
        self.resolved_topic = node.resolve_topic_name(topic)
        self.core = SoleWriter(writer if writer.startswith('/')
                               else qualified_name(node.get_namespace(), writer))
        self.problem = ''
        # composed with its writer: only that node writes the topic inside the process, and
        # nothing from outside it is heard (local_bus)
        self.local = getattr(node, 'bus', None) is not None and node.bus.writes(topic, writer)
        if self.local:
            node.bus.subscribe(self.resolved_topic, handler)
            return
        Node.create_subscription(node, msg_type, topic, message_info_callback(self.on_message), qos_profile,
                                 raw=raw or raw_stream(topic))

    def on_message(self, message, info) -> None:
        gid = info['publisher_gid']['data']
        if not self.core.admits(gid) and self.core.lookup_due(gid, time.monotonic()):
            self.look_up()
        if self.core.admits(gid):
            self.handler(message)
            return
        who, news = self.core.reject(gid)
        if self.other is not None:
            if news:
                self.node.get_logger().warning(
                    f'a second writer on {self.resolved_topic}: {who}; its messages are kept apart '
                    f'from those of {self.core.writer}')
            self.node.diagnostics.count(f'{self.topic} from other writers')
            self.other(message)
            return
        if news:
            self.node.get_logger().warning(
                f'a second writer on {self.resolved_topic}: {who}; only {self.core.writer} is '
                f'obeyed, the messages of any other are rejected')
        self.node.diagnostics.reject(self.topic, f'not from {self.core.writer} but from {who}')

    def look_up(self) -> None:
        """Tell the core what the ROS graph says publishes the topic."""
        pinned = self.core.pinned
        self.core.learn(Endpoint(None if info.node_name == UNKNOWN_NODE_NAME
                                 else qualified_name(info.node_namespace, info.node_name),
                                 bytes(info.endpoint_gid))
                        for info in self.node.get_publishers_info_by_topic(self.resolved_topic))
        if self.core.pinned is not None and self.core.pinned != pinned:
            self.node.get_logger().info(f'{self.resolved_topic}: obeying {self.writer_fact()}')
        if self.core.problem != self.problem:
            self.problem = self.core.problem
            if self.problem:
                self.node.get_logger().warning(f'{self.resolved_topic}: {self.problem}')

    def known(self) -> bool:
        """Whether the writer is pinned; asks the graph while it is not (before the run)."""
        if self.local:
            return True
        if self.core.pinned is None:
            self.look_up()
        return self.core.pinned is not None

    def writer_fact(self) -> str:
        if self.local:
            return f'{self.core.writer}, in this process'
        if self.core.pinned is None:
            return f'{self.core.writer}, not seen yet' + (f': {self.problem}' if self.problem else '')
        return f'{self.core.writer} (GID {self.core.pinned.hex()})'

    def facts(self) -> dict[str, str]:
        facts = {f'{self.topic} writer': self.writer_fact()}
        if self.core.rejected:
            facts[f'rejected {self.topic} from'] = self.core.rejected_writers()
        return facts
