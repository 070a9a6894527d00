"""bag_recorder: every /cdpr topic (or the `topics` parameter) into a rosbag2 bag.

Parameters: `bag_path` (folder to create), `storage` (`mcap`, the default, or `sqlite3`),
`topics` (names relative to the namespace, or absolute; default every topic of the
contract plus /clock and /diagnostics), `flush_period_s` (0.5).

Messages are taken serialized (no decode/encode on the way) and stamped with their
receive time. `effort_command` holds the commands of the graph's controller only
(parameter `command_writer`, as the plant obeys): those of any other writer go to
`effort_command/other_writers`, so that offline FDI and reports see what the motors
obeyed. Per-cycle topics are subscribed reliable + keep-all, so none is lost. The
newest tick written goes out on `bag_recorder/progress` (at most every
PROGRESS_PERIOD_S), which a lockstep plant waits for (cdpr_twin.nodes.recorder_pacing).
On SIGINT/SIGTERM the node drains its queue, also while it is quiet as long as a writer
of a per-tick topic is still there (at most runtime.spin.DRAIN_LIMIT_S), and closes the
bag; if it is killed, the bag keeps every chunk flushed so far (at most
`flush_period_s` old, see bag_io).

A bag is the evidence of what the robot did, so a hole in it is said: per loop topic (and
per view topic, on its view ticks) the recorder counts the ticks it lacks from the stamps
(tick_gaps), keeps the counts in
the bag's metadata (bag_io.MISSING_TICKS_KEY), in /diagnostics, and says them in its last
log line (WARN when a tick is missing).
"""
from __future__ import annotations

import json
import time

from rosbags.interfaces import (Qos, QosDurability, QosHistory, QosLiveliness, QosReliability,
                                QosTime)
from std_msgs.msg import Header

from cdpr_control.setup.settings import node_settings
from cdpr_msgs_py import contract, qos
from cdpr_msgs_py.cdr import cdr_stamp_ns
from cdpr_msgs_py.conversions import ns_to_stamp
from cdpr_msgs_py.runtime.node import CdprNode
from cdpr_msgs_py.runtime.spin import run
from cdpr_msgs_py.stamps import ns_parts

from .bag_io import MISSING_TICKS_KEY, BagWriter
from .tick_gaps import TickGaps

# topic (relative to the namespace unless absolute) → message class: every topic of the
# contract (contract.TOPICS)
RECORDED = {topic.name: contract.message_class(topic.type)
            for topic in contract.topics_read_by(contract.BAG_RECORDER)}
FLUSH_PERIOD_S = 0.5
# How often the recorder says its newest tick written, at most (s): a lockstep plant
# waiting for it runs no further ahead than its lead (cdpr_twin.nodes.recorder_pacing).
PROGRESS_PERIOD_S = 0.02
# The bag topic, beside effort_command, of the commands of writers other than the controller.
OTHER_WRITERS = 'other_writers'


def bag_qos(profile) -> Qos:
    """An rclpy QoS profile as rosbag2 metadata, so `ros2 bag play` offers it again."""
    def duration(value) -> QosTime:
        seconds, nanoseconds = ns_parts(value.nanoseconds)
        return QosTime(seconds, nanoseconds)
    return Qos(QosHistory[profile.history.name], profile.depth,
               QosReliability[profile.reliability.name], QosDurability[profile.durability.name],
               duration(profile.deadline), duration(profile.lifespan),
               QosLiveliness[profile.liveliness.name], duration(profile.liveliness_lease_duration),
               profile.avoid_ros_namespace_conventions)


class BagRecorderNode(CdprNode):

    def __init__(self):
        super().__init__(contract.BAG_RECORDER)
        settings = node_settings(self, contract.BAG_RECORDER)
        path = self.parameter('bag_path', 'bag', 'the bag folder to write')
        storage = self.parameter('storage', 'mcap', 'mcap or sqlite3')
        self.flush_period_s = self.parameter('flush_period_s', FLUSH_PERIOD_S,
                                             'the bag is written out this often (s)',
                                             value_range=(0.0, None))
        namespace = self.get_namespace().rstrip('/')
        topics = [self.contract_name(name, namespace)
                  for name in self.parameter('topics', list(RECORDED), 'the topics to record')]
        unknown = [name for name in topics if name not in RECORDED]
        if unknown:
            raise ValueError(f'parameter topics: cannot record {unknown}; known: {list(RECORDED)}')
        self.writer = BagWriter(path, storage)
        self.writer.open()
        # A message's log time is this node's clock at its receipt: the system clock
        # unless use_sim_time is on, read directly then (rclpy's Clock.now() was a third
        # of a message's writing, ~2.5 % of a core in realtime)
        clock = self.get_clock()
        self.receipt_ns = (time.time_ns if not clock.ros_time_is_active
                           else lambda: clock.now().nanoseconds)
        self.recorded = 0
        # connection id → (topic, its gaps) of the per-tick topics
        self.gaps: dict[int, tuple[str, TickGaps]] = {}
        # the per-tick topics' full names: stopping, the bag waits for their writers
        self.per_tick_names: list[str] = []
        # the newest joint state written (its stamp, ns), and the last one said on
        # RECORDER_PROGRESS, when (monotonic s)
        self.newest_state_ns = self.said_state_ns = -1
        self.said_at = 0.0
        self.progress = self.create_publisher(Header, contract.RECORDER_PROGRESS,
                                              qos.of_readers(contract.RECORDER_PROGRESS))
        command_writer = self.parameter('command_writer', 'controller',
                                        'the node whose effort_command is recorded as such; any '
                                        f'other writer\'s goes to effort_command/{OTHER_WRITERS}')
        subscriptions = []
        for topic in topics:
            name = topic if topic.startswith('/') else f'{namespace}/{topic}'
            profile = qos.of_readers(topic)
            kind = contract.TOPICS[topic].type
            connection = self.writer.add_topic(name, kind, [bag_qos(profile)])
            written = contract.TOPICS[topic]
            if written.from_first_tick:
                # a view topic's ticks are the view ticks
                every = self.view_ticks.every if written.rate is contract.Rate.VIEW else 1
                self.gaps[connection.id] = (topic, TickGaps(settings.period_ns * every))
                self.per_tick_names.append(name)
            if topic == contract.EFFORT_COMMAND:
                others = self.writer.add_topic(f'{name}/{OTHER_WRITERS}', kind, [bag_qos(profile)])
                subscriptions.append((topic, lambda t=topic, c=connection, o=others, p=profile:
                                      self.create_sole_writer_subscription(
                                          RECORDED[t], t, self.writer_for(c), p, command_writer,
                                          other=self.writer_for(o), raw=True)))
                continue
            subscriptions.append((topic, lambda t=topic, n=name, c=connection, p=profile:
                                  self.create_subscription(RECORDED[t], n, self.writer_for(c), p,
                                                           raw=True)))
        # The tick last: the plant starts once it sees this subscription.
        for topic, subscribe in subscriptions:
            if topic != contract.JOINT_STATES:
                subscribe()
        self.start_when_matched(lambda: [subscribe() for topic, subscribe in subscriptions
                                         if topic == contract.JOINT_STATES])
        self.last_flush = time.monotonic()
        self.get_logger().info(f'recording {len(topics)} topics into {path} ({storage})')
        settings.declare(self)

    @staticmethod
    def contract_name(name: str, namespace: str) -> str:
        """`name` as RECORDED spells it: relative, unless outside the namespace."""
        prefix = f'{namespace}/'
        if name in RECORDED or not name.startswith(prefix):
            return name
        return name[len(prefix):]

    def writer_for(self, connection):
        topic, gaps = self.gaps.get(connection.id, (None, None))

        def write(data: bytes) -> None:
            self.writer.write(connection, self.receipt_ns(), data)
            self.recorded += 1
            self.diagnostics.count('messages')
            if gaps is not None:
                stamp_ns = cdr_stamp_ns(data)
                gaps.seen(stamp_ns)
                if topic == contract.JOINT_STATES:
                    self.newest_state_ns = max(self.newest_state_ns, stamp_ns)
        return write

    def say_progress(self) -> None:
        """The newest joint state written, on RECORDER_PROGRESS, at most every
        PROGRESS_PERIOD_S: called after every spin (idle, drain_step), not per message."""
        now = time.monotonic()
        if self.newest_state_ns > self.said_state_ns and now - self.said_at >= PROGRESS_PERIOD_S:
            self.progress.publish(Header(stamp=ns_to_stamp(self.newest_state_ns)))
            self.said_state_ns, self.said_at = self.newest_state_ns, now

    def missing_ticks(self) -> dict[str, int]:
        """Per per-tick topic that has messages, the ticks it lacks so far."""
        return {topic: gaps.missing for topic, gaps in self.gaps.values() if gaps.ticks}

    def current_facts(self) -> dict[str, str]:
        missing = {topic: count for topic, count in self.missing_ticks().items() if count}
        return {**super().current_facts(),
                'missing ticks': ', '.join(f'{topic} {count}' for topic, count in missing.items()) or 'none'}

    def keeps_draining(self) -> bool:
        """A writer of a per-tick topic still there may hold ticks this node has not had
        (it waits for their acknowledgement before it exits): a recorder behind a loaded
        machine, quiet a moment, must not close the bag before them."""
        return any(self.count_publishers(name) for name in self.per_tick_names)

    def drain_step(self) -> None:
        self.say_progress()

    def idle(self) -> None:
        super().idle()
        self.say_progress()
        now = time.monotonic()
        if now - self.last_flush >= self.flush_period_s:
            self.writer.flush()
            self.last_flush = now

    def close(self) -> None:
        super().close()
        missing = self.missing_ticks()
        self.writer.set_custom_data(MISSING_TICKS_KEY, json.dumps(missing))
        self.writer.close()
        holes = [f'{topic} {gaps.missing} of {gaps.ticks}' for topic, gaps in self.gaps.values()
                 if gaps.missing]
        if holes:
            self.get_logger().warning(f'bag closed with {self.recorded} messages and HOLES: ticks '
                                      f'missing on {", ".join(holes)}')
        else:
            self.get_logger().info(f'bag closed with {self.recorded} messages, no tick missing')


def main(args=None):
    return run(BagRecorderNode, args)


if __name__ == '__main__':
    main()
