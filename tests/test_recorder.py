"""bag_recorder and bag_io: embedded definitions, no loss at 500 Hz, complete bag on
SIGINT, readable prefix after SIGKILL; read back by rosbags and by mcap + mcap_ros2, an
incomplete bag counted by the mcap package's own stream reader."""
from __future__ import annotations

import json
import os
import shutil
import signal
import struct
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import rclpy
from geometry_msgs.msg import PoseStamped
from mcap.exceptions import EndOfFile
from mcap.reader import NonSeekingReader, make_reader
from mcap_ros2.decoder import DecoderFactory
from rclpy.serialization import serialize_message
from rosbags.rosbag2 import Reader
from rosgraph_msgs.msg import Clock
from std_msgs.msg import Int32, String

from cdpr_bringup.bags.bag_io import BagWriter, is_complete, missing_ticks, read_messages
from cdpr_bringup.bags.tick_gaps import TickGaps
from cdpr_bringup.bags.recorder_node import RECORDED
from cdpr_bringup.graph.launcher import executable_command, node_environment
from cdpr_control.config import load_section
from cdpr_msgs_py.cdr import cdr_stamp_ns
from cdpr_msgs_py import contract, qos
from cdpr_msgs_py.conversions import joint_state, ns_to_stamp
from cdpr_msgs_py.stamps import NANOSECONDS

from conftest import PAPER_ROBOT

RATE_HZ = 500.0
# The stamp of tick k is k periods: the recorder counts ticks on the robot's period.
PERIOD_NS = round(1e9 / RATE_HZ)
PUBLISH_S = 2.0
WAIT_S = 20.0
NAMES = contract.joint_names(4)
# The test's publisher: the recorder records its effort_command as the controller's.
PUBLISHER = 'recorder_test_publisher'
# The per-cycle topics a test publishes at RATE_HZ, with a message for tick k.
STREAMS = {
    contract.JOINT_STATES: lambda k: joint_state(NAMES, k, [k, 1, 2, 3], [0.5] * 4, [-0.3] * 4),
    contract.EFFORT_COMMAND: lambda k: joint_state(NAMES, k, effort=[-0.4, -0.3, 0.1, k]),
    contract.TWIN_JOINT_STATES: lambda k: joint_state(NAMES, k, [k] * 4, [0.0] * 4, [0.2] * 4),
    contract.REFERENCE_POSE: lambda k: pose(k),
    contract.GROUND_TRUTH_POSE: lambda k: pose(k),
    contract.CLOCK: lambda k: Clock(clock=ns_to_stamp(k)),
}


def full_name(namespace: str, topic: str) -> str:
    return topic if topic.startswith('/') else f'{namespace}/{topic}'


def pose(k: int) -> PoseStamped:
    message = PoseStamped()
    message.header.stamp = ns_to_stamp(k)
    message.pose.position.x, message.pose.position.y, message.pose.position.z = 0.1 * k, 1.0, 1.25
    message.pose.orientation.w = 1.0
    return message


def stamp_of(message) -> int:
    stamp = message.header.stamp if hasattr(message, 'header') else message.clock
    return stamp.sec * 1_000_000_000 + stamp.nanosec


def installed_hash(msgtype: str) -> str:
    """The RIHS01 hash the installed ROS 2 message package declares for `msgtype`."""
    package, _, name = msgtype.split('/')
    described = json.loads((Path(sys.prefix) / 'share' / package / 'msg' / f'{name}.json').read_text())
    return next(h['hash_string'] for h in described['type_hashes'] if h['type_name'] == msgtype)


def mcap_file(bag: Path) -> Path:
    return next(bag.glob('*.mcap'))


def decoded_by_mcap(bag: Path) -> dict[str, list]:
    """Every message of a complete MCAP bag, decoded by mcap_ros2 from the embedded schemas."""
    found: dict[str, list] = {}
    with open(mcap_file(bag), 'rb') as file:
        reader = make_reader(file, decoder_factories=[DecoderFactory()])
        for _, channel, _, message in reader.iter_decoded_messages():
            found.setdefault(channel.topic, []).append(message)
    return found


def counted_by_mcap(path: Path) -> dict[str, int]:
    """Messages per topic of an MCAP file, complete or cut by a kill, as the mcap package's
    own stream reader yields them: it checks each chunk's CRC, and a record shorter than
    its length prefix (or a cut fixed-size field) ends the stream."""
    counts: dict[str, int] = {}
    with open(path, 'rb') as file:
        try:
            # in file order: sorting by log time would read everything before the cut first
            for _, channel, _ in NonSeekingReader(file, validate_crcs=True).iter_messages(
                    log_time_order=False):
                counts[channel.topic] = counts.get(channel.topic, 0) + 1
        except (EndOfFile, struct.error):
            assert file.tell() == path.stat().st_size, 'stopped before the end of the file'
    return counts


# ---- bag_io without DDS ------------------------------------------------------------

def sample_messages():
    """One message of every recorded type, serialized by rclpy (which may pad the CDR)."""
    mode = String(data='RECOVERY_TENSION')
    return {contract.JOINT_STATES: joint_state(NAMES, 7, [1.5, -2, 3, 4], [0.1] * 4, [-0.2] * 4),
            contract.REFERENCE_POSE: pose(7), contract.FDI_BROKEN_CABLE: Int32(data=4),
            contract.MODE: mode, contract.CLOCK: Clock(clock=ns_to_stamp(7)),
            contract.DIAGNOSTICS: RECORDED[contract.DIAGNOSTICS]()}


@pytest.mark.parametrize('storage', ['mcap', 'sqlite3'])
def test_bag_embeds_the_kilted_definitions_and_reads_back_in_both_readers(tmp_path, storage):
    bag = tmp_path / 'bag'
    writer = BagWriter(bag, storage)
    writer.open()
    samples = sample_messages()
    for topic, message in samples.items():
        connection = writer.add_topic(topic, contract.TOPICS[topic].type)
        writer.write(connection, 1_000, serialize_message(message))
    writer.close()

    with Reader(bag) as reader:
        for connection in reader.connections:
            assert connection.msgdef.data, f'{connection.topic} has no embedded definition'
            assert connection.digest == installed_hash(connection.msgtype)
    read = read_messages(bag, list(samples))
    assert read[contract.JOINT_STATES][0][1].position.tolist() == [1.5, -2, 3, 4]
    assert read[contract.FDI_BROKEN_CABLE][0][1].data == 4
    assert read[contract.MODE][0][1].data == 'RECOVERY_TENSION'
    if storage == 'mcap':
        decoded = decoded_by_mcap(bag)
        assert list(decoded[contract.JOINT_STATES][0].position) == [1.5, -2, 3, 4]
        assert decoded[contract.FDI_BROKEN_CABLE][0].data == 4
        assert decoded[contract.CLOCK][0].clock.nanosec == 7


def test_a_bag_cut_anywhere_reads_as_its_whole_chunks(tmp_path):
    bag = tmp_path / 'bag'
    writer = BagWriter(bag)
    writer.open()
    connection = writer.add_topic('/cdpr/joint_states', contract.TOPICS[contract.JOINT_STATES].type)
    for k in range(3000):
        writer.write(connection, k, serialize_message(STREAMS[contract.JOINT_STATES](k)))
    writer.close()
    data = mcap_file(bag).read_bytes()
    counts = []
    for cut in np.linspace(0, len(data), 40, dtype=int):
        cut_bag = tmp_path / f'cut{cut}'
        cut_bag.mkdir()
        (cut_bag / 'cut.mcap').write_bytes(data[:cut])
        assert not is_complete(cut_bag)
        read = read_messages(cut_bag, ['/cdpr/joint_states'])['/cdpr/joint_states']
        stamps = [stamp_of(message) for _, message in read]
        assert stamps == list(range(len(stamps))), 'a prefix, in order, without gaps'
        assert len(stamps) == counted_by_mcap(cut_bag / 'cut.mcap').get('/cdpr/joint_states', 0)
        counts.append(len(stamps))
    assert counts == sorted(counts) and counts[-1] == 3000 and 0 < counts[len(counts) // 2] < 3000


def test_flush_makes_everything_written_so_far_survive_a_kill(tmp_path):
    bag = tmp_path / 'bag'
    writer = BagWriter(bag)
    writer.open()
    connection = writer.add_topic('/cdpr/fdi/broken_cable', contract.TOPICS[contract.FDI_BROKEN_CABLE].type)
    writer.write(connection, 5, serialize_message(Int32(data=2)))
    writer.flush()
    # what a kill leaves: the file as it is on disk now, no metadata.yaml
    snapshot = tmp_path / 'killed'
    shutil.copytree(bag, snapshot)
    writer.close()
    assert [(t, m.data) for t, m in read_messages(snapshot, ['/cdpr/fdi/broken_cable'])[
        '/cdpr/fdi/broken_cable']] == [(5, 2)]


# ---- the recorder node, as its own process ------------------------------------------

class Publisher:
    """An rclpy node in the test process publishing STREAMS at RATE_HZ with the contract QoS."""

    def __init__(self, namespace: str):
        self.namespace = namespace
        self.context = rclpy.Context()
        rclpy.init(context=self.context)
        self.node = rclpy.create_node(PUBLISHER, namespace=namespace,
                                      context=self.context)
        # what the graph's writers offer: keep-last, the config's streams.history_s deep
        writer = qos.stream_writer(load_section(PAPER_ROBOT, 'streams'), 1.0 / RATE_HZ)
        self.streams = {topic: self.node.create_publisher(
            type(make(0)), topic, writer) for topic, make in STREAMS.items()}
        self.latched = {topic: self.node.create_publisher(kind, topic, qos.LATCHED)
                        for topic, kind in ((contract.FDI_BROKEN_CABLE, Int32), (contract.MODE, String))}
        self.published = {full_name(namespace, topic): 0 for topic in [*STREAMS, *self.latched]}
        self.elapsed_s = 0.0
        # ticks whose joint state is not published: holes the recorder must count
        self.skipped: frozenset[int] = frozenset()

    def wait_for_recorder(self, recorder: subprocess.Popen) -> None:
        deadline = time.monotonic() + WAIT_S
        publishers = [*self.streams.values(), *self.latched.values()]
        while any(p.get_subscription_count() < 1 for p in publishers):
            assert recorder.poll() is None, 'the recorder died while starting'
            assert time.monotonic() < deadline, f'the recorder did not subscribe within {WAIT_S} s'
            time.sleep(0.05)

    def publish(self, duration_s: float) -> None:
        """Every stream once per tick at RATE_HZ (stamp = tick number), and the latched
        verdict and mode once."""
        self.latched[contract.FDI_BROKEN_CABLE].publish(Int32(data=4))
        self.latched[contract.MODE].publish(String(data='NOMINAL'))
        for topic in self.latched:
            self.published[full_name(self.namespace, topic)] += 1
        start = time.monotonic()
        for k in range(int(duration_s * RATE_HZ)):
            delay = start + k / RATE_HZ - time.monotonic()
            if delay > 0:
                time.sleep(delay)
            for topic, make in STREAMS.items():
                if topic == contract.JOINT_STATES and k in self.skipped:
                    continue
                self.streams[topic].publish(make(k * PERIOD_NS))
                self.published[full_name(self.namespace, topic)] += 1
        self.elapsed_s = time.monotonic() - start

    def close(self) -> None:
        self.node.destroy_node()
        rclpy.shutdown(context=self.context)


def start_recorder(bag: Path, namespace: str, storage: str = 'mcap') -> subprocess.Popen:
    command = executable_command('cdpr_bringup', 'bag_recorder') + [
        '--ros-args', '-r', f'__ns:={namespace}', '-p', f'bag_path:={bag}',
        '-p', f'storage:={storage}', '-p', f'command_writer:={PUBLISHER}']
    return subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                            stdin=subprocess.DEVNULL, text=True, start_new_session=True,
                            env=node_environment())


def record(tmp_path: Path, name: str, stop_signal: int, storage: str = 'mcap',
           skipped: frozenset[int] = frozenset()):
    """Start a recorder, publish PUBLISH_S at RATE_HZ (but the joint states of the
    `skipped` ticks), stop it with `stop_signal`; (bag, published counts per topic, exit
    code, recorder output)."""
    bag, namespace = tmp_path / name, f'/cdpr_rec_{name}'
    recorder = start_recorder(bag, namespace, storage)
    publisher = Publisher(namespace)
    publisher.skipped = skipped
    try:
        publisher.wait_for_recorder(recorder)
        publisher.publish(PUBLISH_S)
        os.kill(recorder.pid, stop_signal)
        output, _ = recorder.communicate(timeout=WAIT_S)
    finally:
        if recorder.poll() is None:
            os.killpg(recorder.pid, signal.SIGKILL)
            recorder.wait(timeout=10)
        publisher.close()
    print(f'\n{name}: {sum(publisher.published.values())} messages published in '
          f'{publisher.elapsed_s:.2f} s ({len(STREAMS)} streams at {RATE_HZ:.0f} Hz)')
    return bag, publisher.published, recorder.returncode, output


@pytest.mark.graph
@pytest.mark.realtime
@pytest.mark.parametrize('storage', ['mcap', 'sqlite3'])
def test_recorder_keeps_every_message_at_500_hz_and_closes_the_bag_on_sigint(tmp_path, storage):
    bag, published, code, output = record(tmp_path, f'sigint_{storage}', signal.SIGINT, storage)
    assert code == 0, output
    assert is_complete(bag)
    recorded = read_messages(bag, list(published))
    assert {t: len(m) for t, m in recorded.items()} == published, output
    for topic in STREAMS:
        name = full_name(f'/cdpr_rec_sigint_{storage}', topic)
        stamps = [stamp_of(m) for _, m in recorded[name]]
        assert stamps == [k * PERIOD_NS for k in range(len(stamps))], f'{name}: every tick once, in order'
    assert missing_ticks(bag) == {topic: 0 for topic in STREAMS}, output
    assert 'no tick missing' in output and 'HOLES' not in output, output
    if storage == 'mcap':
        decoded = decoded_by_mcap(bag)
        assert {t: len(m) for t, m in decoded.items() if t in published} == published
        assert decoded[f'/cdpr_rec_sigint_mcap/{contract.FDI_BROKEN_CABLE}'][0].data == 4
    print(f'{storage}: recorded {sum(len(m) for m in recorded.values())} of them')


@pytest.mark.graph
@pytest.mark.realtime
def test_killed_recorder_leaves_a_readable_prefix(tmp_path):
    bag, published, code, output = record(tmp_path, 'sigkill', signal.SIGKILL)
    assert code == -signal.SIGKILL
    assert not is_complete(bag)
    streams = {full_name('/cdpr_rec_sigkill', topic) for topic in STREAMS}
    recorded = read_messages(bag, list(published))
    counted = {t: n for t, n in counted_by_mcap(mcap_file(bag)).items() if t in published}
    assert counted == {t: len(m) for t, m in recorded.items() if m}, 'as the mcap package reads it'
    assert all(counted[t] <= published[t] for t in counted), f'more than published: {counted}'
    ticks = int(PUBLISH_S * RATE_HZ)
    # flushed at least every 0.5 s: at most that much of the end (plus one tick) is lost
    floor = ticks - int(0.5 * RATE_HZ) - 1
    for topic in streams:
        stamps = [stamp_of(m) for _, m in recorded[topic]]
        assert stamps == [k * PERIOD_NS for k in range(len(stamps))], f'{topic}: a prefix without gaps'
        assert len(stamps) >= floor, f'{topic}: only {len(stamps)} of {ticks} ticks readable'
    size = mcap_file(bag).stat().st_size
    kept = sum(len(recorded[t]) for t in streams)
    print(f'SIGKILL after {ticks} ticks: {kept} of {ticks * len(streams)} stream messages '
          f'readable ({size} bytes)')


@pytest.mark.graph
@pytest.mark.realtime
def test_the_recorder_counts_and_says_the_ticks_a_topic_lacks(tmp_path):
    """Joint states of three ticks never sent, one of them the tick before the last: the
    bag's metadata and the recorder's last line say so, the other topics lack nothing."""
    ticks = int(PUBLISH_S * RATE_HZ)
    skipped = frozenset({100, 101, ticks - 2})
    bag, _, code, output = record(tmp_path, 'holes', signal.SIGINT, skipped=skipped)
    assert code == 0, output
    assert missing_ticks(bag) == {topic: len(skipped) if topic == contract.JOINT_STATES else 0
                                  for topic in STREAMS}
    assert f'HOLES: ticks missing on {contract.JOINT_STATES} {len(skipped)} of {ticks}' in output, output



def test_a_serialized_messages_stamp_is_read_without_decoding_it():
    """Each per-tick type starts with its stamp, as rclpy serializes it."""
    stamp = 1_234 * NANOSECONDS + 567_000
    for message in (joint_state(NAMES, stamp, [1.0] * 4, [0.0] * 4, [0.0] * 4), pose(stamp),
                    Clock(clock=ns_to_stamp(stamp))):
        assert cdr_stamp_ns(serialize_message(message)) == stamp
    with pytest.raises(ValueError, match='not a plain CDR message'):
        cdr_stamp_ns(b'\x00\x02\x00\x00' + bytes(8))


def test_tick_gaps_count_the_ticks_never_seen_whatever_the_order():
    gaps = TickGaps(PERIOD_NS)
    for k in (5, 6, 9, 7, 12):          # 8, 10, 11 missing; 7 came late
        gaps.seen(k * PERIOD_NS)
    assert (gaps.missing, gaps.ticks) == (3, 8)
    gaps.seen(3 * PERIOD_NS)            # before the first: 4 missing too
    assert (gaps.missing, gaps.ticks) == (4, 10)
    for k in (4, 8, 10, 11):
        gaps.seen(k * PERIOD_NS)
    assert gaps.missing == 0 and not gaps.holes
