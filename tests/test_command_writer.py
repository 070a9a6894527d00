"""One writer to the motors (issue 11, item 3): the plant and the supervisor obey the
effort commands of the graph's controller only.

The rule (cdpr_msgs_py.sole_writer.SoleWriter) is tested directly; then in this process,
through both executors, on the GIDs the middleware reports; then on a graph (lockstep and
realtime) that another process writes zero torques to: tests/test_outside_nodes.py.
"""
from __future__ import annotations

import time
from types import SimpleNamespace

import pytest
import rclpy
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.serialization import deserialize_message
from sensor_msgs.msg import JointState

from cdpr_msgs_py import contract, qos
from cdpr_msgs_py.runtime.node import CdprNode
from cdpr_msgs_py.runtime.spin import make_executor
from cdpr_msgs_py.runtime.subscriptions import PROBE_IDLE_S, UNKNOWN_NODE_NAME, message_info_callback
from cdpr_msgs_py.sole_writer import Endpoint, SoleWriter


CONTROLLER = '/cdpr/controller'
REAL, OTHER, SPOOF = b'\x01' * 16, b'\x02' * 16, b'\x03' * 16


# ---- the rule ---------------------------------------------------------------------------

def pinned_writer() -> SoleWriter:
    writer = SoleWriter(CONTROLLER)
    writer.learn([Endpoint(CONTROLLER, REAL), Endpoint('/cdpr/intruder', OTHER)])
    return writer


def test_the_controller_is_admitted_once_the_graph_shows_it():
    writer = SoleWriter(CONTROLLER)
    assert not writer.admits(REAL), 'nothing is obeyed before the graph names the writer'
    writer.learn([Endpoint('/cdpr/intruder', OTHER)])
    assert writer.pinned is None and not writer.admits(OTHER)
    writer.learn([Endpoint(CONTROLLER, REAL), Endpoint('/cdpr/intruder', OTHER)])
    assert writer.admits(REAL) and not writer.admits(OTHER)


def test_another_writer_is_rejected_counted_and_named():
    writer = pinned_writer()
    assert writer.reject(OTHER) == (f'node /cdpr/intruder (GID {OTHER.hex()})', True)
    assert writer.reject(OTHER) == (f'node /cdpr/intruder (GID {OTHER.hex()})', False)
    assert writer.rejected_writers() == f'node /cdpr/intruder (GID {OTHER.hex()}): 2'


def test_a_writer_the_graph_cannot_name_yet_is_named_by_gid_and_again_once_it_can():
    writer = pinned_writer()
    who, news = writer.reject(SPOOF)
    assert news and SPOOF.hex() in who and 'does not name' in who
    writer.learn([Endpoint(CONTROLLER, REAL), Endpoint('/cdpr/late', SPOOF)])
    assert writer.reject(SPOOF) == (f'node /cdpr/late (GID {SPOOF.hex()})', True)


def test_a_publisher_whose_node_the_graph_has_not_announced_is_looked_up_again():
    """The graph knows an endpoint before its node's name; the pinned writer then stays."""
    writer = pinned_writer()
    writer.learn([Endpoint(None, REAL), Endpoint(None, SPOOF)])
    assert writer.admits(REAL), 'a writer whose name is not known for a moment is still there'
    assert 'does not name' in writer.reject(SPOOF)[0]
    assert writer.lookup_due(SPOOF, 0.0)
    writer.learn([Endpoint(CONTROLLER, REAL), Endpoint('/cdpr/late', SPOOF)])
    assert writer.reject(SPOOF)[0].startswith('node /cdpr/late')


def test_a_second_node_named_controller_after_the_first_is_rejected():
    writer = pinned_writer()
    writer.learn([Endpoint(CONTROLLER, REAL), Endpoint(CONTROLLER, SPOOF)])
    assert writer.admits(REAL) and not writer.admits(SPOOF)
    assert writer.reject(SPOOF)[0] == f'another node named {CONTROLLER} (GID {SPOOF.hex()})'


def test_two_controllers_before_either_is_pinned_are_both_refused():
    writer = SoleWriter(CONTROLLER)
    writer.learn([Endpoint(CONTROLLER, REAL), Endpoint(CONTROLLER, SPOOF)])
    assert not writer.admits(REAL) and not writer.admits(SPOOF)
    assert '2 publishers belong to nodes named /cdpr/controller' in writer.problem
    writer.learn([Endpoint(CONTROLLER, REAL)])
    assert writer.admits(REAL) and writer.problem == ''


def test_a_restarted_controller_is_obeyed_once_the_old_one_has_left():
    writer = pinned_writer()
    writer.learn([Endpoint(CONTROLLER, REAL), Endpoint(CONTROLLER, SPOOF)])
    assert not writer.admits(SPOOF)
    writer.learn([Endpoint(CONTROLLER, SPOOF)])
    assert writer.admits(SPOOF) and not writer.admits(REAL)


def test_the_graph_is_asked_about_an_unknown_writer_at_most_once_per_interval():
    writer = SoleWriter(CONTROLLER, lookup_interval_s=1.0)
    assert writer.lookup_due(REAL, 0.0) and not writer.lookup_due(REAL, 0.5)
    assert writer.lookup_due(REAL, 1.0)
    writer.learn([Endpoint(CONTROLLER, REAL), Endpoint('/cdpr/intruder', OTHER)])
    assert not writer.lookup_due(OTHER, 5.0), 'a named writer needs no second look'


def test_a_graph_that_long_shows_publishers_without_their_node_is_looked_at_again():
    """A graph that dropped the writer's participant (lease) and found it again shows its
    publisher without a node for good: after the grace, a second look is due, until pinned."""
    writer = SoleWriter(CONTROLLER, unnamed_grace_s=2.0)
    writer.learn([Endpoint(None, REAL)])
    assert not writer.second_look_due(10.0) and not writer.second_look_due(11.9)
    assert writer.second_look_due(12.0)
    writer.learn([Endpoint('/cdpr/intruder', OTHER)])
    assert not writer.second_look_due(13.0), 'every publisher named: nothing to look at again'
    writer.learn([Endpoint(None, REAL)])
    assert not writer.second_look_due(14.0), 'the grace starts again'
    writer.learn([Endpoint(CONTROLLER, REAL)])
    assert writer.pinned == REAL and not writer.second_look_due(20.0)
    writer.learn([Endpoint(None, REAL), Endpoint(None, SPOOF)])
    assert writer.admits(REAL) and not writer.second_look_due(30.0), 'a pinned writer needs none'


def test_the_writer_must_be_fully_qualified():
    with pytest.raises(ValueError, match='fully qualified'):
        SoleWriter('controller')


def test_the_callback_takes_the_message_info_from_either_executor():
    """rclpy 9.1.2's EventsExecutor calls a message-info callback with one (message, info)
    tuple, the other executors with two arguments."""
    got = []
    callback = message_info_callback(lambda message, info: got.append((message, info)))
    callback(('m', 'i'))
    callback('m', 'i')
    assert got == [('m', 'i'), ('m', 'i')]


# ---- on the middleware's GIDs, in this process --------------------------------------------

NAMESPACE = '/cdpr_writer_unit'
MATCH_TIMEOUT_S = 10.0


@pytest.fixture(scope='module')
def ros():
    rclpy.init(args=['--ros-args', '-r', f'__ns:={NAMESPACE}'])
    yield
    rclpy.shutdown()


class Motors(CdprNode):
    """What the plant does with effort commands, and nothing else."""

    def __init__(self):
        super().__init__('motors')
        self.obeyed = []
        self.create_sole_writer_subscription(JointState, contract.EFFORT_COMMAND, self.obeyed.append,
                                             qos.STREAM, 'controller')


def spin_until(executor, condition, what: str) -> None:
    deadline = time.monotonic() + MATCH_TIMEOUT_S
    while not condition():
        assert time.monotonic() < deadline, what
        executor.spin_once(timeout_sec=0.05)


@pytest.mark.parametrize('make', [make_executor, SingleThreadedExecutor], ids=['events', 'single'])
def test_only_the_controllers_publisher_reaches_the_motors(ros, make):
    motors = Motors()
    controller = rclpy.create_node('controller')
    intruder = rclpy.create_node('intruder')
    nodes = [motors, controller, intruder]
    executor = make()
    try:
        publishers = {'controller': controller.create_publisher(JointState, contract.EFFORT_COMMAND,
                                                                qos.STREAM),
                      'intruder': intruder.create_publisher(JointState, contract.EFFORT_COMMAND,
                                                            qos.STREAM)}
        for node in nodes:
            executor.add_node(node)
        spin_until(executor, motors.matched, 'the motors never learnt the controller')
        # a second node named controller, after the first was pinned (`ros2 run` by mistake)
        spoof = rclpy.create_node('controller')
        nodes.append(spoof)
        executor.add_node(spoof)
        publishers['spoof'] = spoof.create_publisher(JointState, contract.EFFORT_COMMAND, qos.STREAM)
        spin_until(executor, lambda: all(p.get_subscription_count() for p in publishers.values()),
                   'the publishers never matched the motors')
        for sender, publisher in publishers.items():
            publisher.publish(JointState(name=[sender]))
        spin_until(executor, lambda: len(motors.obeyed) + sum(motors.diagnostics.rejected.values()) == 3,
                   'not every command arrived')
        # a JointState stream arrives as its CDR bytes (contract.raw_stream)
        assert [list(deserialize_message(message, JointState).name) for message in motors.obeyed] == [['controller']]
        assert motors.diagnostics.rejected == {contract.EFFORT_COMMAND: 2}
        rejected = motors.current_facts()[f'rejected {contract.EFFORT_COMMAND} from']
        assert f'node {NAMESPACE}/intruder (GID ' in rejected
        assert f'another node named {NAMESPACE}/controller (GID ' in rejected
    finally:
        executor.shutdown()
        for node in nodes:
            node.destroy_node()


def without_nodes(node):
    """`node`'s graph as one that dropped its peers' participants and found them again
    shows their publishers: without a node (subscriptions.GraphProbe)."""
    def publishers(topic_name, no_mangle=False):
        return [SimpleNamespace(node_name=UNKNOWN_NODE_NAME, node_namespace='_NODE_NAMESPACE_UNKNOWN_',
                                endpoint_gid=info.endpoint_gid)
                for info in Node.get_publishers_info_by_topic(node, topic_name, no_mangle)]
    return publishers


def test_a_writer_the_nodes_graph_has_lost_the_name_of_is_pinned_by_a_second_look(ros):
    """The plant never started when its graph had lost the controller's name (the
    supervisor's had not): a participant of its own names it, then closes."""
    motors = Motors()
    motors.get_publishers_info_by_topic = without_nodes(motors)
    controller = rclpy.create_node('controller')
    executor = make_executor()
    try:
        publisher = controller.create_publisher(JointState, contract.EFFORT_COMMAND, qos.STREAM)
        for node in (motors, controller):
            executor.add_node(node)
        spin_until(executor, motors.matched, 'the motors never learnt the controller')
        [named] = controller.get_publishers_info_by_topic(publisher.topic_name)
        assert motors.required_writers[0].core.pinned == bytes(named.endpoint_gid)
        assert motors.graph_probe.probe is not None
        deadline = time.monotonic() + PROBE_IDLE_S + 1.0
        while time.monotonic() < deadline:
            executor.spin_once(timeout_sec=0.05)
            motors.idle()
        assert motors.graph_probe.probe is None, 'the second look stays open once the writer is pinned'
    finally:
        motors.graph_probe.close()
        executor.shutdown()
        for node in (motors, controller):
            node.destroy_node()
