"""Node faults: a node killed (SIGKILL) mid-run in realtime mode.

Three of the graph's nodes, each with its own consequence: the controller (the plant
brakes its drums), the supervisor (the safety function is gone; nothing else changes)
and the recorder (the bag keeps what it had). The launcher watches every node's process
alike (tests/test_dds_and_launcher.py); a stale twin or reference is tests/test_watchdogs.py's.

The launcher names the node that died and stops the graph; no failure alarm is raised,
before or after the kill; the bag stays readable; the end-effector does not fall (the
plant brakes its drums when the commands stop). The control loop runs under SCHED_FIFO
(config `scheduling`), as realtime FDI needs on a shared 2-core machine (README).
"""
from __future__ import annotations

import os
import signal
import time

import pytest

from cdpr_bringup.bags.bag_io import read_messages, stamp_ns
from cdpr_bringup.graph.launcher import Graph, GraphError, graph_nodes

from conftest import (GraphLog, assert_stopped_cleanly, settled_parameters,
                      start_until_the_plant_runs, timing_check)

pytestmark = [pytest.mark.graph, pytest.mark.realtime]
RUN_BEFORE_KILL_S = 1.0
# From every node up to the plant's first tick: the start handshake (DDS matching).
START_TIMEOUT_S = 30.0
NODES = ['controller', 'supervisor', 'bag_recorder']


def realtime_parameters() -> dict[str, dict]:
    return settled_parameters('realtime', motion='circle', duration_s=60.0)


# How long the graph runs on without the node once the launcher has named it (s), so
# that the bag witnesses what follows the kill, and the share of those ticks it must hold.
RUN_AFTER_KILL_S = 0.5
AFTER_THE_KILL_SHARE = 0.5
# The bag keeps the run before the kill: at least this share of its ticks.
BEFORE_THE_KILL_SHARE = 0.5


def poses(bag, namespace: str) -> list[tuple[int, float]]:
    """(plant stamp ns, z m) of the bag's ground-truth poses, also while it is written."""
    topic = f'{namespace}/ground_truth/pose'
    return [(stamp_ns(message), message.pose.position.z)
            for _, message in read_messages(bag, [topic])[topic]]


def bag_holding_poses(bag, namespace: str, timeout_s: float) -> list[tuple[int, float]]:
    """The poses the bag being recorded holds, once it holds some (a flushed chunk)."""
    deadline = time.monotonic() + timeout_s
    while not (held := poses(bag, namespace) if bag.exists() else []):
        assert time.monotonic() < deadline, f'the bag held no pose {timeout_s} s into the run'
        time.sleep(0.05)
    return held


@pytest.mark.parametrize('victim', NODES)
def test_a_killed_node_is_named_and_nothing_falls_or_false_alarms(victim, tmp_path):
    """For the controller and the supervisor the bag witnesses the graph after the kill;
    a killed recorder leaves no witness of what follows, so there its consequence is
    checked instead: the bag ends at the kill and the nodes left stop cleanly."""
    namespace = f'/cdpr_kill_{victim}'
    bag = tmp_path / 'bag'
    log = GraphLog()
    parameters = realtime_parameters()
    # the ground-truth pose is a view topic: on the view ticks only
    view_period_s = 1.0 / parameters['plant_simulator']['streams.view_rate_hz']
    graph = Graph(graph_nodes(parameters, str(bag)), namespace,
                  completion='plant_simulator', log=log)
    try:
        start_until_the_plant_runs(graph, log, START_TIMEOUT_S)
        time.sleep(RUN_BEFORE_KILL_S)
        assert not graph.check(), 'the graph runs before the kill'
        held = bag_holding_poses(bag, namespace, START_TIMEOUT_S) if victim == 'bag_recorder' else []
        killed_s = time.monotonic()
        os.killpg(graph.processes[victim].pid, signal.SIGKILL)
        with pytest.raises(GraphError, match=f'node {victim} died'):
            graph.wait(timeout_s=10.0)
        named_s = time.monotonic()
        time.sleep(RUN_AFTER_KILL_S)
        stopping_s = time.monotonic()
    finally:
        exit_codes = graph.stop()
    started_s = log.plant_started_s()
    assert not log.repeated_lines(), log.repeated_lines()
    topics = [f'{namespace}/fdi/broken_cable', '/diagnostics']
    found = read_messages(bag, topics)   # a killed recorder leaves a readable prefix
    verdicts = found[topics[0]]
    scheduling = {value.value for _, message in found['/diagnostics'] for status in message.status
                  for value in status.values if value.key == 'scheduling'}
    assert all(message.data == 0 for _, message in verdicts), \
        f'a false failure alarm (node scheduling: {scheduling})'
    # A pose is before the kill by its plant stamp (ticks from the plant's first), not by
    # when the niced recorder received it: it may run a second behind a loaded machine.
    recorded = poses(bag, namespace)
    killed_ns = (killed_s - started_s) * 1e9
    before = [z for stamp, z in recorded if stamp < killed_ns]
    after = [z for stamp, z in recorded if stamp >= killed_ns]
    with timing_check(log, (started_s, killed_s), f'{victim} killed: the verdict recorded'):
        assert verdicts, 'no failure verdict in the bag'
    if victim == 'bag_recorder':
        # what the recorder had not received is gone with it; what it had written stays,
        # a prefix of the run without a hole
        stamps = [stamp for stamp, _ in recorded]
        assert recorded[:len(held)] == held, 'the bag lost what it held before the recorder was killed'
        period_ns = round(view_period_s * 1e9)
        assert stamps == [tick * period_ns for tick in range(len(stamps))], \
            'the bag of the killed recorder is not the run from its first tick without a hole'
        assert_stopped_cleanly(exit_codes, log, but=victim)
        return
    with timing_check(log, (started_s, killed_s), f'{victim} killed: the run before it recorded'):
        expected = BEFORE_THE_KILL_SHARE * (killed_s - started_s) / view_period_s
        assert len(before) >= expected, f'{len(before)} poses before the kill, expected {expected:.0f}'
    with timing_check(log, (killed_s, stopping_s), f'{victim} killed: the run after it recorded'):
        expected = AFTER_THE_KILL_SHARE * (stopping_s - named_s) / view_period_s
        assert len(after) >= expected, f'{len(after)} poses after the kill, expected {expected:.0f}'
    # nothing sags or falls once the node is gone, whichever it was: judged on poses that
    # exist (the counts above may be excused on a slow machine, this never is)
    assert before and after, f'{len(before)} poses before the kill and {len(after)} after it: nothing to judge'
    assert min(after) > before[-1] - 0.02
    if victim == 'controller':
        facts = [value.value for _, message in found['/diagnostics'] for status in message.status
                 if status.name.endswith('/plant_simulator') for value in status.values
                 if value.key == 'command watchdog']
        with timing_check(log, (killed_s, stopping_s), 'controller killed: the plant status recorded'):
            assert facts, 'no command watchdog status of the plant in the bag'
        assert facts and any('drums braked' in fact for fact in facts), facts
