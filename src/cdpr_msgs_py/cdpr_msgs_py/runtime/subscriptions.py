"""Subscriptions that obey one writer: the contract's sole-writer rule (sole_writer.py)
applied to the publisher GID of every message, and the second look at the ROS graph
that pins a writer the node's own graph has lost the name of (GraphProbe)."""
from __future__ import annotations

import inspect
import time

import rclpy
from rclpy.node import Node
from rclpy.signals import SignalHandlerOptions

from ..contract import raw_stream
from ..sole_writer import Endpoint, SoleWriter, qualified_name


# What the ROS graph (rmw_dds_common) calls the node of a publisher it has discovered
# before that node's own announcement.
UNKNOWN_NODE_NAME = '_NODE_NAME_UNKNOWN_'
# A second look's participant is closed once nothing has asked it for this long (s: the
# writers are pinned), and replaced after this long (s) at most: one participant at a
# time, opened only while a required writer's topic shows publishers without their node.
PROBE_IDLE_S = 1.0
PROBE_LIFETIME_S = 60.0
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
        self.learn(self.node.get_publishers_info_by_topic(self.resolved_topic))

    def learn(self, publishers) -> None:
        """Tell the core what a graph (the node's, or a second look's) says publishes the topic."""
        pinned = self.core.pinned
        self.core.learn(Endpoint(None if info.node_name == UNKNOWN_NODE_NAME
                                 else qualified_name(info.node_namespace, info.node_name),
                                 bytes(info.endpoint_gid))
                        for info in publishers)
        if self.core.pinned is not None and self.core.pinned != pinned:
            self.node.get_logger().info(f'{self.resolved_topic}: obeying {self.writer_fact()}')
        if self.core.problem != self.problem:
            self.problem = self.core.problem
            if self.problem:
                self.node.get_logger().warning(f'{self.resolved_topic}: {self.problem}')

    def known(self) -> bool:
        """Whether the writer is pinned; asks the graph while it is not (before the run),
        and a second look's (GraphProbe) once the node's has long shown publishers of the
        topic without their node."""
        if self.local:
            return True
        if self.core.pinned is None:
            self.look_up()
            if self.core.second_look_due(time.monotonic()):
                self.learn(self.node.graph_probe.publishers(self.resolved_topic))
        return self.core.pinned is not None

    def writer_fact(self) -> str:
        if self.local:
            return f'{self.core.writer}, in this process'
        if self.core.pinned is None:
            unnamed = (f'{len(self.core.unnamed)} publisher(s) of the topic the ROS graph does not '
                       f'name' if self.core.unnamed else '')
            why = '; '.join(filter(None, (self.problem, unnamed)))
            return f'{self.core.writer}, not seen yet' + (f': {why}' if why else '')
        return f'{self.core.writer} (GID {self.core.pinned.hex()})'

    def facts(self) -> dict[str, str]:
        facts = {f'{self.topic} writer': self.writer_fact()}
        if self.core.rejected:
            facts[f'rejected {self.topic} from'] = self.core.rejected_writers()
        return facts


class GraphProbe:
    """A second look at the ROS graph: a participant of the node's own, opened on demand,
    whose graph names the publishers of a topic afresh.

    rmw_fastrtps learns which node an endpoint belongs to from that participant's
    ParticipantEntitiesInfo (topic ros_discovery_info: reliable, transient local, the
    last sample kept), sent when the participant creates or destroys an entity. A
    participant that has not heard a peer for the lease (20 s: a stalled process, or
    datagrams lost on a loaded machine) drops it and forgets its nodes; found again, the
    peer's endpoints come back but not their nodes, since Fast DDS remembers, across a
    drop by lease, the peer's samples its reader had and does not deliver the last one
    again. Until that peer creates or destroys an entity (a started controller never
    does), the graph shows its publishers as _NODE_NAME_UNKNOWN_: the plant never pinned
    the controller and never started, while the supervisor, pinned before the drop, ran
    on. A new participant is sent every peer's last sample."""

    def __init__(self, node: Node):
        self.node = node
        self.context: rclpy.Context | None = None
        self.probe: Node | None = None
        self.opened_s = self.asked_s = 0.0

    def publishers(self, topic: str) -> list:
        """What the probe's graph says publishes `topic` (fully qualified); it may still be
        discovering the domain (nothing, or publishers without their node, for a while)."""
        self.asked_s = time.monotonic()
        if self.probe is not None and self.asked_s - self.opened_s > PROBE_LIFETIME_S:
            self.close()
        if self.probe is None:
            self.open(topic)
        return self.probe.get_publishers_info_by_topic(topic)

    def open(self, topic: str) -> None:
        self.context = rclpy.Context()
        # no arguments: the node's remappings and parameters files are not the probe's
        rclpy.init(args=[], context=self.context, domain_id=self.node.context.get_domain_id(),
                   signal_handler_options=SignalHandlerOptions.NO)
        self.probe = rclpy.create_node(f'{self.node.get_name()}_graph_probe', context=self.context,
                                       namespace=self.node.get_namespace(), use_global_arguments=False,
                                       enable_rosout=False, start_parameter_services=False)
        self.opened_s = time.monotonic()
        self.node.get_logger().warning(
            f'{topic}: the ROS graph shows publishers without their node; asking a participant '
            f'of this node\'s own')

    def idle(self) -> None:
        """Close the probe once nothing has asked it for PROBE_IDLE_S."""
        if self.probe is not None and time.monotonic() - self.asked_s > PROBE_IDLE_S:
            self.close()

    def close(self) -> None:
        if self.probe is None:
            return
        self.probe.destroy_node()
        self.context.try_shutdown()
        self.probe = self.context = None
