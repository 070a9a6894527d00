"""An outside reader that stops reading — a user's `ros2 topic echo` suspended with
Ctrl-Z — neither stops nor crashes a writer of ours, and /diagnostics reports it.

Before the per-cycle writers were keep-last (qos.stream_writer), such a reliable reader
filled a keep-all writer's history (5000 samples, 10 s at 500 Hz); every publish then
blocked 100 ms and failed, and the plant died ('Failed to publish: cannot publish
data'). Here the reader is a separate process of plain rclpy
(cdpr_bringup/graph/outside_reader.py), run as a user's tool would be, suspended (SIGSTOP) for
well over the writers' history and the lag limit, both set to HISTORY_S for the run (the shipped 10 s of each would
make every run last half a minute; that the writers keep the configured history and
never keep all is tests/test_health.py's and test_topics.py's subject).
"""
from __future__ import annotations

import os
import select
import signal
import subprocess
import sys
import time

import pytest

from cdpr_bringup.bags.bag_io import missing_ticks, read_messages
from cdpr_bringup.graph.launcher import Graph, graph_nodes, node_environment
from cdpr_msgs_py.conversions import stamp_to_ns
from cdpr_msgs_py.health import WARN

from conftest import (GraphLog, assert_stopped_cleanly, in_private_shm, keep_running,
                      private_shm_allowed, settled_parameters, timing_check)
from test_faults import START_TIMEOUT_S
from test_graph import user_environment

pytestmark = pytest.mark.graph
# The per-cycle topics the outside reader reads, by the node that writes them.
READ = {'plant_simulator': ['joint_states', 'ground_truth/pose'],
        'controller': ['effort_command'], 'trajectory_generator': ['reference'],
        'digital_twin': ['twin/joint_states'], 'supervisor': ['fdi/residual']}
# Written too, but read by the graph (the recorder) only: never reported as lagging.
UNREAD = ['reference/pose', 'twin/pose', 'ground_truth/tensions']
# The writers' history and the lag limit of the run (s): streams.history_s,
# health.reader_lag_limit_s.
HISTORY_S = 2.0
# The reader stays stopped longer than both.
STALL_S = 2.5 * HISTORY_S
PERIOD_NS = 2_000_000
HISTORY_TICKS = round(HISTORY_S * 1e9 / PERIOD_NS)
# Simulated s of the run, which is stopped well before: the reader's start (up to
# 2 START_TIMEOUT_S of wall time) and the stall included, in lockstep too, which runs
# ~2-3x faster than real time here: a run that ended before the reader had matched
# every writer left it waiting for topics no one wrote any more.
RUN_LIMIT_S = 3 * (2 * START_TIMEOUT_S + 2 * STALL_S)


def start_outside_reader(namespace: str, topics: list[str]) -> subprocess.Popen:
    """The reader, in its own process group (so SIGSTOP reaches it through any wrapper)."""
    command = [sys.executable, '-m', 'cdpr_bringup.graph.outside_reader', namespace, '600', *topics]
    if private_shm_allowed():
        command, environment = in_private_shm(command, stale=()), user_environment()
    else:
        environment = node_environment()
    return subprocess.Popen(command, stdout=subprocess.PIPE, text=True, env=environment,
                            start_new_session=True)


def wait_until_receiving(reader: subprocess.Popen, timeout_s: float, log: GraphLog) -> None:
    """Until the reader has had a message on every topic: each writer has matched it.
    Failing, it ends with the launcher's last lines (the reader's stderr, captured, names
    the topics it heard)."""
    deadline = time.monotonic() + timeout_s
    while True:
        remaining = deadline - time.monotonic()
        assert remaining > 0 and reader.poll() is None, (
            f'the outside reader did not receive every topic in {timeout_s:g} s; the log\'s end:\n'
            + '\n'.join(list(log)[-40:]))
        if select.select([reader.stdout], [], [], remaining)[0] and reader.stdout.readline().strip() == 'receiving':
            return


def end(reader: subprocess.Popen) -> None:
    os.killpg(reader.pid, signal.SIGCONT)
    os.killpg(reader.pid, signal.SIGKILL)
    reader.wait(timeout=10)


def run_with_a_stopped_reader(tmp_path, clock_mode: str):
    """The graph with a bag, and an outside reader on READ, started with the graph (its
    discovery takes seconds) and stopped as soon as it receives; (namespace, bag, wall
    clock ns of the stop, s from the stop to the graph's stop, the launcher's log)."""
    namespace = f'/cdpr_outside_{clock_mode}'
    bag = tmp_path / 'bag'
    parameters = settled_parameters(clock_mode, motion='circle', duration_s=RUN_LIMIT_S)
    for node in parameters.values():
        node.update({'streams.history_s': HISTORY_S, 'health.reader_lag_limit_s': HISTORY_S})
    log = GraphLog()
    graph = Graph(graph_nodes(parameters, str(bag)), namespace, completion='plant_simulator',
                  log=log)
    reader = None
    try:
        graph.start()
        reader = start_outside_reader(namespace, [topic for topics in READ.values() for topic in topics]
                                      + (['/clock'] if clock_mode == 'lockstep' else []))
        graph.wait_until_up()
        # the reader is no part of the start handshake: its discovery of every writer, on
        # this loaded 2-core machine, has taken over START_TIMEOUT_S once (CI, 2026-11-27)
        wait_until_receiving(reader, 2 * START_TIMEOUT_S, log)
        os.killpg(reader.pid, signal.SIGSTOP)
        stopped_ns, stopped_s = time.time_ns(), time.monotonic()   # the recorder stamps wall time
        # the run goes on, longer than the writers' history lasts: no node dies of the
        # stopped reader (GraphError names one that did), then the graph is stopped as
        # with Ctrl-C
        keep_running(graph, stopped_s, STALL_S + 1.0, 'the reader stopped')
        stalled_s = time.monotonic() - stopped_s
        print(f'\n{clock_mode}: the outside reader stayed stopped {stalled_s:.1f} s')
    finally:
        if reader is not None:
            end(reader)
        codes = graph.stop()
    assert_stopped_cleanly(codes, log)
    return namespace, bag, stopped_ns, stalled_s, log


def check_graph_unharmed_and_reader_reported(namespace: str, bag, log: GraphLog, reported_by_all: bool) -> list:
    """No false alarm, every tick in the bag and in order, no writer of a topic the reader
    did not read reported lagging, nothing failed to publish; if `reported_by_all`, every
    writer the reader read reported it (WARN). The joint states."""
    topics = [f'{namespace}/fdi/broken_cable', f'{namespace}/joint_states', '/diagnostics']
    found = read_messages(bag, topics)
    assert found[topics[0]], 'no failure verdict in the bag'
    assert all(message.data == 0 for _, message in found[topics[0]]), 'a false failure alarm'
    states = found[topics[1]]
    stamps = [stamp_to_ns(message.header.stamp) for _, message in states]
    assert stamps, 'no joint state in the bag'
    assert all(later > earlier for earlier, later in zip(stamps, stamps[1:])), \
        'the recorder (a reader of the graph) got the ticks in order'
    # what the bag lacks, the recorder said: in the bag's metadata and its last line
    lacking = (stamps[-1] - stamps[0]) // PERIOD_NS + 1 - len(stamps)
    counted = missing_ticks(bag)
    assert counted['joint_states'] == lacking
    # the last line says HOLES when any per-tick topic lacks a tick (not only joint_states)
    said = [line for line in log if line.startswith('[bag_recorder]') and 'bag closed' in line]
    assert said and ('HOLES' in said[-1]) == any(counted.values()), (said, counted)
    with timing_check(log, (log.plant_started_s(), time.monotonic()), 'stopped reader: every tick recorded'):
        assert lacking == 0, f'the recorder lost {lacking} ticks'
    statuses = [status for _, message in found['/diagnostics'] for status in message.status]
    assert statuses, 'no /diagnostics in the bag'
    assert not [value.key for status in statuses for value in status.values
                if value.key.startswith('publish failed')]
    reported = 0
    for node, read in READ.items():
        reports = [status.message for status in statuses if status.name == f'{namespace}/{node}'
                   and status.level >= WARN]
        for topic in read if reported_by_all else ():
            assert any(f'a reader of {namespace}/{topic} lags' in report for report in reports), \
                f'{node} did not report the stopped reader of {topic}'
            reported += 1
    assert reported == (sum(map(len, READ.values())) if reported_by_all else 0)
    for topic in UNREAD:
        assert not any(f'a reader of {namespace}/{topic} lags' in status.message for status in statuses)
    return states


@pytest.mark.realtime
def test_a_stopped_outside_reader_neither_stops_nor_crashes_the_realtime_graph(tmp_path):
    namespace, bag, _, stalled_s, log = run_with_a_stopped_reader(tmp_path, 'realtime')
    assert stalled_s > STALL_S, f'the reader was stopped for {stalled_s:.1f} s only'
    # Every tick in realtime too since the writers piggyback no heartbeat on their
    # samples (docs/recording.md). The plant's report of the stopped reader can fail to
    # come in realtime (it once did in a fresh-clone CI run): the lockstep test checks
    # the reports.
    check_graph_unharmed_and_reader_reported(namespace, bag, log, reported_by_all=False)


def test_a_stopped_outside_reader_neither_stops_nor_crashes_the_lockstep_graph(tmp_path):
    namespace, bag, stopped_ns, stalled_s, log = run_with_a_stopped_reader(tmp_path, 'lockstep')
    assert stalled_s > STALL_S, f'the reader was stopped for {stalled_s:.1f} s only'
    states = check_graph_unharmed_and_reader_reported(namespace, bag, log, reported_by_all=True)
    after = sum(1 for at, _ in states if at > stopped_ns)
    assert after > HISTORY_TICKS, f'only {after} ticks after the reader stopped'
