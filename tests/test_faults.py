"""Node faults: a node killed (SIGKILL) mid-run in realtime mode.

Three of the graph's nodes, each with its own consequence: the controller (the plant
brakes its drums), the supervisor (the safety function is gone; nothing else changes)
and the recorder (the bag keeps what it had). The launcher watches every node's process
alike (tests/test_dds_and_launcher.py); a stale twin or reference is tests/test_watchdogs.py's.

The launcher names the node that died and stops the graph; no failure alarm is raised,
before or after the kill; the bag stays readable; the end-effector does not fall (the
plant brakes its drums when the commands stop: their true angular velocity, which the
plant's truth carries, goes to zero and stays there). The control loop runs under
SCHED_FIFO (config `scheduling`), as realtime FDI needs on a shared 2-core machine (README).
"""
from __future__ import annotations

import os
import signal
import time

import numpy as np
import pytest

from cdpr_bringup.bags.bag_io import read_messages, stamp_ns
from cdpr_bringup.graph.launcher import Graph, GraphError, graph_nodes
from cdpr_bringup.runs.metrics import run_figures_of, written_statuses
from cdpr_bringup.runs.settle import ScenarioOptions, build_scenario

from conftest import (MOTIONS, PAPER_ROBOT, GraphLog, assert_stopped_cleanly,
                      start_until_the_plant_runs, timing_check)

pytestmark = [pytest.mark.graph, pytest.mark.realtime]
RUN_BEFORE_KILL_S = 1.0
# The circle starts after 1 s at rest: the controller is killed while it turns the drums
# (0.3 rad/s and more), so that their brake is told from their rest.
CONTROLLER_RUN_BEFORE_KILL_S = 1.5
# From every node up to the plant's first tick: the start handshake (DDS matching).
START_TIMEOUT_S = 30.0
NODES = ['controller', 'supervisor', 'bag_recorder']


def realtime_scenario():
    return build_scenario(ScenarioOptions(config=str(PAPER_ROBOT), motions=str(MOTIONS),
                                          motion='circle', duration_s=60.0))


# How long the graph runs on without the node once the launcher has named it (s), so
# that the bag witnesses what follows the kill, and the share of those ticks it must hold.
RUN_AFTER_KILL_S = 0.5
AFTER_THE_KILL_SHARE = 0.5
# The bag keeps the run before the kill: at least this share of its ticks.
BEFORE_THE_KILL_SHARE = 0.5
# Nothing falls: the end-effector never more than this below where it was (m).
FALL_M = 0.02
# When the controller is killed the fastest drum turns at least this fast (rad/s): a
# drum at rest after the kill is told from one that turns.
DRUMS_TURN_RAD_S = 0.1


def poses(bag, namespace: str) -> list[tuple[int, float]]:
    """(plant stamp ns, z m) of the bag's ground-truth poses, also while it is written."""
    topic = f'{namespace}/ground_truth/pose'
    return [(stamp_ns(message), message.pose.position.z)
            for _, message in read_messages(bag, [topic])[topic]]


def drum_speeds(bag, namespace: str, cables: int) -> list[tuple[int, float]]:
    """(plant stamp ns, the fastest drum's true |θ̇| rad/s) of the bag's truth of the
    drums (ground_truth/tensions' velocity, the plant's model: never measured)."""
    topic = f'{namespace}/ground_truth/tensions'
    messages = read_messages(bag, [topic])[topic]
    assert all(len(message.velocity) == cables for _, message in messages), \
        'the truth of the drums lacks their angular velocity'
    return [(stamp_ns(message), float(np.max(np.abs(message.velocity)))) for _, message in messages]


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
    bag, said = tmp_path / 'bag', tmp_path / 'said'
    said.mkdir()
    log = GraphLog()
    scenario = realtime_scenario()
    parameters = scenario.node_parameters('realtime')
    plant_parameters = parameters['plant_simulator']
    period_ns = round(plant_parameters['control.period_s'] * 1e9)
    # the ground-truth pose is a view topic: on the view ticks only
    view_period_s = 1.0 / plant_parameters['streams.view_rate_hz']
    # each node's last status, written as it stops (a killed one writes none): no
    # recorder can lose it
    graph = Graph(graph_nodes(parameters, str(bag), last_diagnostics=str(said)), namespace,
                  completion='plant_simulator', log=log)
    try:
        start_until_the_plant_runs(graph, log, START_TIMEOUT_S)
        time.sleep(CONTROLLER_RUN_BEFORE_KILL_S if victim == 'controller' else RUN_BEFORE_KILL_S)
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
    # what the plant said as it stopped: whatever the bag kept, nothing fell over the run
    plant = written_statuses(said).get('plant_simulator')
    assert plant is not None, f'the plant wrote no last status ({sorted(p.name for p in said.iterdir())})'
    figures = run_figures_of(plant)
    assert figures is not None and figures['ticks'] > 0, plant
    lowest_reference_m = float(scenario.reference.position_m[:, 2].min())
    assert figures['lowest_point_m'] > lowest_reference_m - FALL_M, (figures['lowest_point_m'], lowest_reference_m)
    topics = [f'{namespace}/fdi/broken_cable', '/diagnostics']
    found = read_messages(bag, topics)   # a killed recorder leaves a readable prefix
    verdicts = found[topics[0]]
    scheduling = {value.value for _, message in found['/diagnostics'] for status in message.status
                  for value in status.values if value.key == 'scheduling'}
    # the supervisor's first verdict (latched) goes out before the plant's first tick
    assert verdicts, 'no failure verdict in the bag'
    assert all(message.data == 0 for _, message in verdicts), \
        f'a false failure alarm (node scheduling: {scheduling})'
    # A pose is before the kill by its plant stamp (ticks from the plant's first), not by
    # when the niced recorder received it: it may run a second behind a loaded machine.
    recorded = poses(bag, namespace)
    killed_ns = (killed_s - started_s) * 1e9
    before = [z for stamp, z in recorded if stamp < killed_ns]
    after = [z for stamp, z in recorded if stamp >= killed_ns]
    if victim == 'bag_recorder':
        # what the recorder had not received is gone with it; what it had written stays,
        # a prefix of the run without a hole
        assert held and recorded[:len(held)] == held, 'the bag lost what it held before the recorder was killed'
        stamps = [stamp for stamp, _ in recorded]
        view_period_ns = round(view_period_s * 1e9)
        assert stamps == [tick * view_period_ns for tick in range(len(stamps))], \
            'the bag of the killed recorder is not the run from its first tick without a hole'
        assert_stopped_cleanly(exit_codes, log, but=victim)
        return
    # the poses judged exist, whatever the machine's speed; only how many may be excused
    assert before and after, f'{len(before)} poses before the kill and {len(after)} after it: nothing to judge'
    with timing_check(log, (started_s, killed_s), f'{victim} killed: the run before it recorded'):
        expected = BEFORE_THE_KILL_SHARE * (killed_s - started_s) / view_period_s
        assert len(before) >= expected, f'{len(before)} poses before the kill, expected {expected:.0f}'
    with timing_check(log, (killed_s, stopping_s), f'{victim} killed: the run after it recorded'):
        expected = AFTER_THE_KILL_SHARE * (stopping_s - named_s) / view_period_s
        assert len(after) >= expected, f'{len(after)} poses after the kill, expected {expected:.0f}'
    # nothing sags or falls once the node is gone, whichever it was
    assert min(after) > before[-1] - FALL_M, (min(after), before[-1])
    if victim == 'controller':
        # the plant says so as it stops (its last status, which no recorder can lose) ...
        assert 'drums braked' in plant.get('command watchdog', ''), plant.get('command watchdog')
        # ... and the drums do it: their true speed, that of the circle before the kill,
        # is zero from some tick after it to the end of the record (a locked drum does
        # not turn at all)
        speeds = drum_speeds(bag, namespace, scenario.robot.cable_count)
        turning = [speed for stamp, speed in speeds if stamp < killed_ns]
        later = [(stamp, speed) for stamp, speed in speeds if stamp >= killed_ns]
        assert turning and later, f'{len(turning)} true drum speeds before the kill, {len(later)} after it'
        assert max(turning) > DRUMS_TURN_RAD_S, f'the drums hardly turned before the kill: {max(turning)} rad/s'
        at_rest = [index for index, (_, speed) in enumerate(later) if speed == 0.0]
        assert at_rest, (f'no drum braked after the kill: the fastest turned at {min(s for _, s in later):.3g} '
                         f'rad/s or more in each of the {len(later)} true states after it')
        braked_ns = later[at_rest[0]][0]
        turned_again = [(stamp, speed) for stamp, speed in later[at_rest[0]:] if speed != 0.0]
        assert not turned_again, f'braked at {braked_ns / 1e9:.3f} s, the drums turned again: {turned_again[:3]}'
        # the watchdog holds the last command command_timeout_cycles periods, then brakes;
        # twice that covers a view period and the start line's way to the test. A loaded
        # machine may deliver a last command late: the bound depends on its speed.
        hold_ns = plant_parameters['plant.command_timeout_cycles'] * period_ns
        with timing_check(log, (killed_s, killed_s + 2 * hold_ns / 1e9), 'controller killed: braked within the hold'):
            assert braked_ns - killed_ns <= 2 * hold_ns, \
                f'braked {(braked_ns - killed_ns) / 1e6:.0f} ms after the kill, the hold is {hold_ns / 1e6:.0f} ms'
