"""The topic table of cdpr_msgs_py.contract and what is derived from it: the graph's
start handshake, the recorder's topics, and the table of docs/design.md §3."""
from __future__ import annotations

import itertools
import re
import time

import numpy as np
import pytest
import rclpy

from cdpr_bringup.bags.recorder_node import BagRecorderNode
from cdpr_bringup.graph.launcher import graph_nodes
from cdpr_control.control.controller_node import ControllerNode
from cdpr_control.control.trajectory_generator_node import TrajectoryGeneratorNode
from cdpr_fdi.nodes.markers_node import MarkersNode
from cdpr_fdi.nodes.supervisor_node import SupervisorNode
from cdpr_msgs_py import contract, qos
from cdpr_msgs_py.conversions import joint_state
from cdpr_twin.nodes.digital_twin_node import DigitalTwinNode
from cdpr_twin.nodes.plant_simulator_node import PlantSimulatorNode

from conftest import MOTIONS, PAPER_ROBOT, REPO, settled_parameters

# The `matches` of each node (package/executable, in start order), as graph_nodes()
# computed them when the handshake was still written out by hand, per
# (supervised, plant, bag, clock_mode). Sorted and space-joined: a node waits for all its
# entries, so their order means nothing.
PINNED = {
    (True, True, False, 'lockstep'): {
        'cdpr_control/trajectory_generator': 'publisher:reference=3',
        'cdpr_control/controller': (
            'publisher:effort_command=2 subscription:fdi/residual=1 subscription:reference=1'),
        'cdpr_twin/digital_twin': 'publisher:twin/joint_states=1',
        'cdpr_fdi/supervisor': (
            'publisher:fdi/residual=1 subscription:effort_command=1 subscription:reference=1 '
            'subscription:twin/joint_states=1'),
        'cdpr_twin/plant_simulator': 'publisher:joint_states=3 subscription:effort_command=1',
    },
    (True, True, False, 'realtime'): {
        'cdpr_control/trajectory_generator': 'publisher:reference=3',
        'cdpr_control/controller': 'publisher:effort_command=2 subscription:reference=1',
        'cdpr_twin/digital_twin': 'publisher:twin/joint_states=1',
        'cdpr_fdi/supervisor': (
            'subscription:effort_command=1 subscription:reference=1 '
            'subscription:twin/joint_states=1'),
        'cdpr_twin/plant_simulator': 'publisher:joint_states=3 subscription:effort_command=1',
    },
    (True, True, True, 'lockstep'): {
        'cdpr_control/trajectory_generator': 'publisher:reference/pose=1 publisher:reference=4',
        'cdpr_control/controller': (
            'publisher:effort_command=3 subscription:fdi/residual=1 subscription:reference=1'),
        'cdpr_twin/digital_twin': 'publisher:twin/joint_states=2 publisher:twin/pose=1',
        'cdpr_fdi/supervisor': (
            'publisher:fdi/residual=2 subscription:effort_command=1 subscription:reference=1 '
            'subscription:twin/joint_states=1'),
        'cdpr_bringup/bag_recorder': (
            'subscription:/clock=1 subscription:effort_command=1 subscription:fdi/residual=1 '
            'subscription:ground_truth/pose=1 subscription:ground_truth/tensions=1 '
            'subscription:reference/pose=1 subscription:reference=1 '
            'subscription:twin/joint_states=1 subscription:twin/pose=1'),
        'cdpr_twin/plant_simulator': (
            'publisher:/clock=1 publisher:ground_truth/pose=1 publisher:ground_truth/tensions=1 '
            'publisher:joint_states=4 subscription:effort_command=1'),
    },
    (True, True, True, 'realtime'): {
        'cdpr_control/trajectory_generator': 'publisher:reference/pose=1 publisher:reference=4',
        'cdpr_control/controller': 'publisher:effort_command=3 subscription:reference=1',
        'cdpr_twin/digital_twin': 'publisher:twin/joint_states=2 publisher:twin/pose=1',
        'cdpr_fdi/supervisor': (
            'publisher:fdi/residual=1 subscription:effort_command=1 subscription:reference=1 '
            'subscription:twin/joint_states=1'),
        'cdpr_bringup/bag_recorder': (
            'subscription:effort_command=1 subscription:fdi/residual=1 '
            'subscription:ground_truth/pose=1 subscription:ground_truth/tensions=1 '
            'subscription:reference/pose=1 subscription:reference=1 '
            'subscription:twin/joint_states=1 subscription:twin/pose=1'),
        'cdpr_twin/plant_simulator': (
            'publisher:ground_truth/pose=1 publisher:ground_truth/tensions=1 '
            'publisher:joint_states=4 subscription:effort_command=1'),
    },
    (True, False, False, 'lockstep'): {
        'cdpr_control/trajectory_generator': 'publisher:reference=3',
        'cdpr_control/controller': (
            'publisher:effort_command=2 subscription:fdi/residual=1 subscription:reference=1'),
        'cdpr_twin/digital_twin': 'publisher:twin/joint_states=1',
        'cdpr_fdi/supervisor': (
            'publisher:fdi/residual=1 subscription:effort_command=1 subscription:reference=1 '
            'subscription:twin/joint_states=1'),
    },
    (True, False, False, 'realtime'): {
        'cdpr_control/trajectory_generator': 'publisher:reference=3',
        'cdpr_control/controller': 'publisher:effort_command=2 subscription:reference=1',
        'cdpr_twin/digital_twin': 'publisher:twin/joint_states=1',
        'cdpr_fdi/supervisor': (
            'subscription:effort_command=1 subscription:reference=1 '
            'subscription:twin/joint_states=1'),
    },
    (True, False, True, 'lockstep'): {
        'cdpr_control/trajectory_generator': 'publisher:reference/pose=1 publisher:reference=4',
        'cdpr_control/controller': (
            'publisher:effort_command=3 subscription:fdi/residual=1 subscription:reference=1'),
        'cdpr_twin/digital_twin': 'publisher:twin/joint_states=2 publisher:twin/pose=1',
        'cdpr_fdi/supervisor': (
            'publisher:fdi/residual=2 subscription:effort_command=1 subscription:reference=1 '
            'subscription:twin/joint_states=1'),
        'cdpr_bringup/bag_recorder': (
            'subscription:/clock=1 subscription:effort_command=1 subscription:fdi/residual=1 '
            'subscription:ground_truth/pose=1 subscription:ground_truth/tensions=1 '
            'subscription:reference/pose=1 subscription:reference=1 '
            'subscription:twin/joint_states=1 subscription:twin/pose=1'),
    },
    (True, False, True, 'realtime'): {
        'cdpr_control/trajectory_generator': 'publisher:reference/pose=1 publisher:reference=4',
        'cdpr_control/controller': 'publisher:effort_command=3 subscription:reference=1',
        'cdpr_twin/digital_twin': 'publisher:twin/joint_states=2 publisher:twin/pose=1',
        'cdpr_fdi/supervisor': (
            'publisher:fdi/residual=1 subscription:effort_command=1 subscription:reference=1 '
            'subscription:twin/joint_states=1'),
        'cdpr_bringup/bag_recorder': (
            'subscription:effort_command=1 subscription:fdi/residual=1 '
            'subscription:ground_truth/pose=1 subscription:ground_truth/tensions=1 '
            'subscription:reference/pose=1 subscription:reference=1 '
            'subscription:twin/joint_states=1 subscription:twin/pose=1'),
    },
    (False, True, False, 'lockstep'): {
        'cdpr_control/trajectory_generator': 'publisher:reference=2',
        'cdpr_control/controller': 'publisher:effort_command=1 subscription:reference=1',
        'cdpr_twin/digital_twin': '',
        'cdpr_twin/plant_simulator': 'publisher:joint_states=2 subscription:effort_command=1',
    },
    (False, True, False, 'realtime'): {
        'cdpr_control/trajectory_generator': 'publisher:reference=2',
        'cdpr_control/controller': 'publisher:effort_command=1 subscription:reference=1',
        'cdpr_twin/digital_twin': '',
        'cdpr_twin/plant_simulator': 'publisher:joint_states=2 subscription:effort_command=1',
    },
    (False, True, True, 'lockstep'): {
        'cdpr_control/trajectory_generator': 'publisher:reference/pose=1 publisher:reference=3',
        'cdpr_control/controller': 'publisher:effort_command=2 subscription:reference=1',
        'cdpr_twin/digital_twin': 'publisher:twin/joint_states=1 publisher:twin/pose=1',
        'cdpr_bringup/bag_recorder': (
            'subscription:/clock=1 subscription:effort_command=1 subscription:fdi/residual=1 '
            'subscription:ground_truth/pose=1 subscription:ground_truth/tensions=1 '
            'subscription:reference/pose=1 subscription:reference=1 '
            'subscription:twin/joint_states=1 subscription:twin/pose=1'),
        'cdpr_twin/plant_simulator': (
            'publisher:/clock=1 publisher:ground_truth/pose=1 publisher:ground_truth/tensions=1 '
            'publisher:joint_states=3 subscription:effort_command=1'),
    },
    (False, True, True, 'realtime'): {
        'cdpr_control/trajectory_generator': 'publisher:reference/pose=1 publisher:reference=3',
        'cdpr_control/controller': 'publisher:effort_command=2 subscription:reference=1',
        'cdpr_twin/digital_twin': 'publisher:twin/joint_states=1 publisher:twin/pose=1',
        'cdpr_bringup/bag_recorder': (
            'subscription:effort_command=1 subscription:fdi/residual=1 '
            'subscription:ground_truth/pose=1 subscription:ground_truth/tensions=1 '
            'subscription:reference/pose=1 subscription:reference=1 '
            'subscription:twin/joint_states=1 subscription:twin/pose=1'),
        'cdpr_twin/plant_simulator': (
            'publisher:ground_truth/pose=1 publisher:ground_truth/tensions=1 '
            'publisher:joint_states=3 subscription:effort_command=1'),
    },
    (False, False, False, 'lockstep'): {
        'cdpr_control/trajectory_generator': 'publisher:reference=2',
        'cdpr_control/controller': 'publisher:effort_command=1 subscription:reference=1',
        'cdpr_twin/digital_twin': '',
    },
    (False, False, False, 'realtime'): {
        'cdpr_control/trajectory_generator': 'publisher:reference=2',
        'cdpr_control/controller': 'publisher:effort_command=1 subscription:reference=1',
        'cdpr_twin/digital_twin': '',
    },
    (False, False, True, 'lockstep'): {
        'cdpr_control/trajectory_generator': 'publisher:reference/pose=1 publisher:reference=3',
        'cdpr_control/controller': 'publisher:effort_command=2 subscription:reference=1',
        'cdpr_twin/digital_twin': 'publisher:twin/joint_states=1 publisher:twin/pose=1',
        'cdpr_bringup/bag_recorder': (
            'subscription:/clock=1 subscription:effort_command=1 subscription:fdi/residual=1 '
            'subscription:ground_truth/pose=1 subscription:ground_truth/tensions=1 '
            'subscription:reference/pose=1 subscription:reference=1 '
            'subscription:twin/joint_states=1 subscription:twin/pose=1'),
    },
    (False, False, True, 'realtime'): {
        'cdpr_control/trajectory_generator': 'publisher:reference/pose=1 publisher:reference=3',
        'cdpr_control/controller': 'publisher:effort_command=2 subscription:reference=1',
        'cdpr_twin/digital_twin': 'publisher:twin/joint_states=1 publisher:twin/pose=1',
        'cdpr_bringup/bag_recorder': (
            'subscription:effort_command=1 subscription:fdi/residual=1 '
            'subscription:ground_truth/pose=1 subscription:ground_truth/tensions=1 '
            'subscription:reference/pose=1 subscription:reference=1 '
            'subscription:twin/joint_states=1 subscription:twin/pose=1'),
    },
}


# Four changes since: a reader waits only for a writer the graph starts (without a
# supervisor the recorder waited for fdi/residual, which nobody wrote, and the plant never
# started); a hardware bridge writes nothing only a simulation has (the recorder waited
# for the ground truth, and never subscribed to the states); the plant simulator reads
# fdi/residual in lockstep (the tick a mode it learns was decided on; in realtime it takes
# its own tick); the markers node starts before
# the plant and waits for nobody, but the writers of the view topics it reads count it
# among the graph's readers (a display's reader, whose lag is not an outside reader's).
NEVER_WRITTEN = {
    'no supervisor': {'subscription:fdi/residual=1'},
    'hardware': {'subscription:ground_truth/pose=1', 'subscription:ground_truth/tensions=1',
                 'subscription:/clock=1'},
}


def one_more_reader(entries: list[str], topic: str) -> None:
    """The writer's entries, `topic` counting one reader more."""
    written = [entry for entry in entries if entry.startswith(f'publisher:{topic}=')]
    readers = int(written[0].split('=')[1]) if written else 0
    entries[:] = [entry for entry in entries if entry not in written] + [f'publisher:{topic}={readers + 1}']


def expected_handshake(supervised, plant, bag, clock_mode) -> dict[str, str]:
    stale = set()
    if not supervised:
        stale |= NEVER_WRITTEN['no supervisor']
    if not plant:
        stale |= NEVER_WRITTEN['hardware']
    recorder = 'cdpr_bringup/bag_recorder'
    expected = {node: [entry for entry in matches.split() if node != recorder or entry not in stale]
                for node, matches in PINNED[supervised, plant, bag, clock_mode].items()}
    if supervised and plant and clock_mode == 'lockstep':
        expected['cdpr_twin/plant_simulator'].append('subscription:fdi/residual=1')
        one_more_reader(expected['cdpr_fdi/supervisor'], 'fdi/residual')
    one_more_reader(expected['cdpr_twin/digital_twin'], 'twin/pose')
    one_more_reader(expected['cdpr_control/trajectory_generator'], 'reference/pose')
    if plant:
        one_more_reader(expected['cdpr_twin/plant_simulator'], 'ground_truth/pose')
        one_more_reader(expected['cdpr_twin/plant_simulator'], 'ground_truth/tensions')
    nodes = list(expected.items())
    nodes.insert(len(nodes) - 1 if plant else len(nodes), ('cdpr_fdi/markers', []))
    return {node: ' '.join(sorted(entries)) for node, entries in nodes}


@pytest.mark.parametrize('supervised, plant, bag, clock_mode',
                         list(itertools.product((True, False), (True, False), (False, True),
                                                ('lockstep', 'realtime'))))
def test_the_start_handshake_is_the_one_written_by_hand_but_for_two_mends(supervised, plant, bag,
                                                                          clock_mode):
    nodes = graph_nodes(settled_parameters(clock_mode), 'bag' if bag else None,
                        supervised=supervised, plant=plant)
    matches = {f'{node.package}/{node.executable}': ' '.join(sorted(node.parameters.get('matches', [])))
               for node in nodes}
    expected = expected_handshake(supervised, plant, bag, clock_mode)
    assert matches == expected
    assert list(matches) == list(expected)


# ---- the nodes keep the table ----------------------------------------------------------

NODES = {contract.TRAJECTORY_GENERATOR: TrajectoryGeneratorNode,
         contract.CONTROLLER: ControllerNode, contract.DIGITAL_TWIN: DigitalTwinNode,
         contract.SUPERVISOR: SupervisorNode, contract.PLANT_SIMULATOR: PlantSimulatorNode,
         contract.BAG_RECORDER: BagRecorderNode, contract.MARKERS_NODE: MarkersNode}
# What rclpy gives every node, besides the contract.
RCLPY_TOPICS = {'/rosout', '/parameter_events'}


@pytest.fixture(scope='module', params=['lockstep', 'realtime'])
def clock_mode(request, tmp_path_factory):
    """rclpy in this process, every node made in it in `clock_mode`, as graph_nodes() sets
    them up with a supervisor and a bag, and waiting for an endpoint that never matches:
    the test starts it, to tell its tick from its other subscriptions."""
    bag = tmp_path_factory.mktemp('bag') / 'bag'
    rclpy.init(args=['--ros-args', '-p', f'clock_mode:={request.param}',
                     '-p', f'config_file:={PAPER_ROBOT}', '-p', f'motions_file:={MOTIONS}',
                     '-p', 'wait_for_supervisor:=true', '-p', 'wait_for_recorder:=true',
                     '-p', f'bag_path:={bag}',
                     '-p', 'matches:=["subscription:/never=1"]'])
    yield request.param
    rclpy.shutdown()


def endpoints(entities) -> dict[str, tuple[str, object]]:
    """Topic → (message type as the contract spells it, QoS profile)."""
    def type_name(message_class) -> str:
        return f'{message_class.__module__.split(".")[0]}/msg/{message_class.__name__}'
    return {entity.topic_name: (type_name(entity.msg_type), entity.qos_profile)
            for entity in entities if entity.topic_name not in RCLPY_TOPICS}


@pytest.mark.parametrize('name', NODES)
def test_each_node_writes_and_reads_what_the_table_says(clock_mode, name):
    node = NODES[name]()
    try:
        before = set(endpoints(node.subscriptions))
        if node.pending_start is not None:  # the plant has no tick: it makes it
            node.pending_start()
        written, read = endpoints(node.publishers), endpoints(node.subscriptions)
        # /diagnostics: every node
        writes = [topic for topic in contract.TOPICS.values()
                  if topic.writer == name or topic.name == contract.DIAGNOSTICS]
        reads = {topic: reader for topic in contract.TOPICS.values() for reader in topic.readers
                 if reader.node == name and (clock_mode == 'lockstep' or not (reader.pacing or reader.lockstep))}
        resolve = node.resolve_topic_name
        # a stream's writer keeps the config's history (qos.stream_writer)
        assert written == {resolve(topic.name): (
            topic.type, node.stream_qos if topic.delivery is contract.Delivery.STREAM
            else qos.of_readers(topic.name)) for topic in writes}
        assert read == {resolve(topic.name): (topic.type, qos.of_readers(topic.name))
                        for topic in reads}
        assert set(read) - before == {resolve(topic.name) for topic, reader in reads.items()
                                      if reader.tick}
    finally:
        node.destroy_node()


# ---- view topics go out on the view ticks, and only to a reader ----------------------------

MATCH_TIMEOUT_S = 10.0


def a_tick(name: str, node, tick: int) -> None:
    """What makes `node` write its topics of a tick: the state of `tick` for the generator
    (its time base: it writes the reference reference_lead_cycles ahead), the reference at
    home (angles 0) for the twin, the plant's state."""
    names = contract.joint_names(node.robot.cable_count)
    at_home = joint_state(names, tick * node.period_ns, np.zeros(len(names)), np.zeros(len(names)),
                          np.zeros(len(names)))

    def plant_state():
        node.tick = tick
        node.publish_state()
    {contract.TRAJECTORY_GENERATOR: lambda: node.on_state(at_home),
     contract.DIGITAL_TWIN: lambda: node.on_reference(at_home),
     contract.PLANT_SIMULATOR: plant_state}[name]()


def written_in_a_tick(name: str, node, tick: int) -> set[str]:
    """The topics (as the contract names them) `node` publishes on in `tick`."""
    written = set()
    for publisher in node.publishers:
        publisher.publish = lambda message, topic=publisher.topic_name: written.add(topic)
    a_tick(name, node, tick)
    return {topic.name for topic in contract.TOPICS.values()
            if node.resolve_topic_name(topic.name) in written}


@pytest.mark.parametrize('name', sorted({topic.writer for topic in contract.TOPICS.values()
                                         if topic.on_demand and topic.from_first_tick}))
def test_a_view_topic_is_written_on_the_view_ticks_and_only_while_read(clock_mode, name):
    writes = [topic for topic in contract.TOPICS.values() if topic.writer == name and topic.from_first_tick
              and (clock_mode == 'lockstep' or not topic.lockstep)]
    loop = {topic.name for topic in writes if topic.rate is contract.Rate.TICK}
    node = NODES[name]()
    every = node.view_ticks.every
    # the generator's tick writes the reference of the tick reference_lead_cycles ahead
    ahead = node.lead if name == contract.TRAJECTORY_GENERATOR else 0
    assert every == 10 and ahead % every == 0, 'the default view rate: every 10th tick of 500 Hz'
    listener = rclpy.create_node('on_demand_listener')
    try:
        assert written_in_a_tick(name, node, 0) == loop
        on_demand = [topic for topic in writes if topic.on_demand]
        for topic in on_demand:
            listener.create_subscription(contract.message_class(topic.type),
                                         node.resolve_topic_name(topic.name), lambda message: None,
                                         qos.of_readers(topic.name))
        publishers = [publisher for publisher in node.publishers
                      if publisher.topic_name in {node.resolve_topic_name(topic.name) for topic in on_demand}]
        # a writer of view topics in this clock mode, each with its publisher to wait for
        assert len(publishers) == len(on_demand) > 0, [topic.name for topic in on_demand]
        deadline = time.monotonic() + MATCH_TIMEOUT_S
        while not all(publisher.get_subscription_count() for publisher in publishers):
            assert time.monotonic() < deadline, 'the listener did not match'
            time.sleep(0.01)
        assert written_in_a_tick(name, node, every) == {topic.name for topic in writes}
        assert written_in_a_tick(name, node, every + 1) == loop, 'a view topic on a tick that is not a view tick'
    finally:
        listener.destroy_node()
        node.destroy_node()


def test_the_markers_node_reads_no_loop_topic():
    """design.md §3: the markers are drawn from the view topics (and the verdict)."""
    read = contract.topics_read_by(contract.MARKERS_NODE)
    assert {topic.rate for topic in read} == {contract.Rate.VIEW, contract.Rate.CHANGE}
    assert {topic.name for topic in read if topic.rate is contract.Rate.VIEW} == {
        contract.TWIN_POSE, contract.REFERENCE_POSE, contract.GROUND_TRUTH_POSE, contract.GROUND_TRUTH_TENSIONS}


# ---- the doc keeps the table -------------------------------------------------------------

def test_design_doc_lists_the_topics_of_the_table_with_their_types():
    """docs/design.md §3: one row per topic, `name` | package/Type."""
    text = (REPO / 'docs' / 'design.md').read_text()
    section = text[text.index('## 3. Topic contract'):text.index('## 4.')]
    rows = re.findall(r'^\| `([^`|]+)` \| (\w+)/(\w+) \|', section, flags=re.MULTILINE)
    assert len(rows) == len(set(name for name, _, _ in rows)), 'a topic listed twice'
    assert {name: f'{package}/msg/{kind}' for name, package, kind in rows} == {
        topic.name: topic.type for topic in contract.TOPICS.values()}
