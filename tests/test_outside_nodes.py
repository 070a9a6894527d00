"""Nodes from outside the graph, as a user's tools are, in one run per clock mode: an
outside reader that stops reading, and outside writers on the motors.

The reader — a user's `ros2 topic echo` suspended with Ctrl-Z — neither stops nor crashes a
writer of ours, and /diagnostics reports it. Before the per-cycle writers were keep-last
(qos.stream_writer), such a reliable reader filled a keep-all writer's history (5000
samples, 10 s at 500 Hz); every publish then blocked 100 ms and failed, and the plant died
('Failed to publish: cannot publish data'). Here the reader is a separate process of plain
rclpy (cdpr_bringup/graph/outside_reader.py), run as a user's tool would be, suspended
(SIGSTOP) for well over the writers' history and the lag limit, both set to HISTORY_S for
the run (the shipped 10 s of each would make every run last half a minute; that the writers
keep the configured history and never keep all is tests/test_health.py's and
test_topics.py's subject).

The writers (issue 11, item 3): while the reader is stopped, another process writes zero
torques to the motors — as an extra node and as a second node named controller — whose
commands must be rejected, counted, named and never applied by the plant and the
supervisor, which obey the graph's controller only (the rule itself:
tests/test_command_writer.py); the extra node also asks for a cable to break, which the
plant refuses. The two answer different questions of one run: the reader's stall and the
writers' commands reach different nodes' different checks.
"""
from __future__ import annotations

import functools
import json
import math
import os
import select
import signal
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
from diagnostic_msgs.msg import DiagnosticStatus

from cdpr_bringup.bags.bag_io import missing_ticks, read_messages
from cdpr_bringup.bags.recorder_node import OTHER_WRITERS
from cdpr_bringup.graph.launcher import Graph, graph_nodes, node_environment
from cdpr_bringup.runs.metrics import written_statuses
from cdpr_bringup.runs.settle import ScenarioOptions, build_scenario
from cdpr_msgs_py import contract
from cdpr_msgs_py.conversions import stamp_to_ns
from cdpr_msgs_py.health import WARN

from conftest import (LOOP_REPORT_PERIOD_S, MOTIONS, PAPER_ROBOT, GraphLog, assert_stopped_cleanly,
                      in_private_shm, keep_running, private_shm_allowed, timing_check,
                      wait_until_the_plant_runs)
from test_faults import START_TIMEOUT_S
from test_graph import offline_verdict, user_environment

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
# How long the outside writers answer states (s), and how long the run goes on after them.
WRITE_S = 6.0
AFTER_WRITE_S = 1.0
OUTSIDE_WRITERS = ('outside_writer', 'controller')
# The share of the run's ticks the bag must hold (a realtime recorder is niced below the loop).
RECORDED_SHARE = 0.5
# Simulated s of the run, which is stopped well before: the reader's start (up to
# 2 START_TIMEOUT_S of wall time), the writers' (up to START_TIMEOUT_S) and their
# answering, and the stall, in lockstep too, which runs ~2-3x faster than real time
# here: a run that ended before the reader had matched every writer left it waiting for
# topics no one wrote any more.
RUN_LIMIT_S = 3 * (3 * START_TIMEOUT_S + WRITE_S + 2 * STALL_S)


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


def lost_ticks(recorded_ns: set[int], ticks: int, period_ns: int, window_ns: tuple[float, float]) -> int:
    """Of the plant's `ticks` states, how many stamped within `window_ns` (ns from its
    first tick) the bag lacks (`recorded_ns`, the stamps it has)."""
    first = max(0, math.ceil(window_ns[0] / period_ns))
    last = min(ticks - 1, math.floor(window_ns[1] / period_ns))
    return sum(1 for tick in range(first, last + 1) if tick * period_ns not in recorded_ns)


def write(namespace: str) -> dict:
    """Run the outside writers (plain rclpy, nothing of ours) and return what they sent."""
    script = Path(__file__).parent / 'tools' / 'outside_writer.py'
    process = subprocess.Popen([sys.executable, str(script), namespace, str(WRITE_S),
                                str(START_TIMEOUT_S), *OUTSIDE_WRITERS],
                               stdout=subprocess.PIPE, text=True, env=node_environment())
    try:
        output, _ = process.communicate(timeout=WRITE_S + START_TIMEOUT_S + 20.0)
    finally:
        if process.poll() is None:
            process.kill()
            process.wait(timeout=10)
    return json.loads(output.strip().splitlines()[-1])


@dataclass
class OutsideRun:
    """One run with both outside nodes: where it ran and what was measured."""
    clock_mode: str
    namespace: str
    bag: Path
    said: Path              # each node's last status, written as it stopped
    folder: Path
    log: GraphLog
    scenario: object
    stopped_ns: int         # wall clock ns of the reader's stop (the recorder stamps wall time)
    stalled_s: float        # s from the reader's stop to the graph's stop
    sent: dict              # what the outside writers sent, by node
    writes_s: tuple         # monotonic s of the writers' start and end
    ended_s: float          # monotonic s of the graph's stop

    @property
    def topics(self) -> list[str]:
        """The bag's topics both tests judge: the failure verdicts, the joint states, the statuses."""
        return [f'{self.namespace}/fdi/broken_cable', f'{self.namespace}/joint_states', '/diagnostics']

    @functools.cached_property
    def found(self) -> dict:
        """The messages of `topics` in the bag, read once for both tests."""
        return read_messages(self.bag, self.topics)


@pytest.fixture(scope='module', params=['lockstep', pytest.param('realtime', marks=pytest.mark.realtime)])
def outside_run(request, tmp_path_factory) -> OutsideRun:
    """The graph with a bag, and an outside reader on READ, started with the graph (its
    discovery takes seconds) and stopped as soon as it receives; then, while it is
    stopped, the outside writers; the run goes on STALL_S + 1 s after the reader's stop
    and AFTER_WRITE_S after the writers, and is stopped as with Ctrl-C."""
    clock_mode = request.param
    folder = tmp_path_factory.mktemp(f'outside_{clock_mode}')
    namespace, bag, said = f'/cdpr_outside_{clock_mode}', folder / 'bag', folder / 'said'
    said.mkdir()
    scenario = build_scenario(ScenarioOptions(config=str(PAPER_ROBOT), motions=str(MOTIONS),
                                              motion='circle', duration_s=RUN_LIMIT_S))
    parameters = scenario.node_parameters(clock_mode)
    for node in parameters.values():
        node.update({'streams.history_s': HISTORY_S, 'health.reader_lag_limit_s': HISTORY_S})
    log = GraphLog()
    graph = Graph(graph_nodes(parameters, str(bag), last_diagnostics=str(said)), namespace,
                  completion='plant_simulator', log=log)
    reader = None
    try:
        graph.start()
        reader = start_outside_reader(namespace, [topic for topics in READ.values() for topic in topics]
                                      + (['/clock'] if clock_mode == 'lockstep' else []))
        graph.wait_until_up()
        wait_until_the_plant_runs(log, START_TIMEOUT_S)
        # the reader is no part of the start handshake: its discovery of every writer, on
        # this loaded 2-core machine, has taken over START_TIMEOUT_S once (CI, 2026-11-27)
        wait_until_receiving(reader, 2 * START_TIMEOUT_S, log)
        os.killpg(reader.pid, signal.SIGSTOP)
        stopped_ns, stopped_s = time.time_ns(), time.monotonic()
        # the run goes on, longer than the writers' history lasts: no node dies of the
        # stopped reader (GraphError names one that did); only then the writers come,
        # whose answering at 500 Hz loads the machine: a realtime recorder, niced below
        # the loop, can lose ticks to that (1262 in one fresh-clone CI run), not to the
        # stopped reader
        keep_running(graph, stopped_s, STALL_S + 1.0, 'the reader stopped')
        writing_s = time.monotonic()
        sent = write(namespace)
        written_s = time.monotonic()
        keep_running(graph, written_s, AFTER_WRITE_S, 'the outside writers were done')
        stalled_s = time.monotonic() - stopped_s
        print(f'\n{clock_mode}: the outside reader stayed stopped {stalled_s:.1f} s')
    finally:
        if reader is not None:
            end(reader)
        codes = graph.stop()
    assert_stopped_cleanly(codes, log)
    return OutsideRun(clock_mode, namespace, bag, said, folder, log, scenario, stopped_ns, stalled_s, sent,
                      (writing_s, written_s), time.monotonic())


def check_graph_unharmed_and_reader_reported(run: OutsideRun, reported_by_all: bool) -> list:
    """No false alarm, every tick in the bag and in order, no writer of a topic the reader
    did not read reported lagging, nothing failed to publish; if `reported_by_all`, every
    writer the reader read reported it (WARN). The joint states."""
    namespace, bag, log = run.namespace, run.bag, run.log
    topics, found = run.topics, run.found
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
    # every tick up to the writers' start, in realtime; of the whole run in lockstep (its
    # plant waits for the recorder)
    started_s = log.plant_started_s()
    judged_s = (started_s, run.writes_s[0] if run.clock_mode == 'realtime' else run.ended_s)
    lost = lost_ticks(set(stamps), stamps[-1] // PERIOD_NS + 1, PERIOD_NS,
                      tuple((at - started_s) * 1e9 for at in judged_s))
    with timing_check(log, judged_s, 'stopped reader: every tick recorded'):
        assert lost == 0, f'the recorder lost {lost} ticks ({lacking} in the whole run)'
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


def test_a_stopped_outside_reader_neither_stops_nor_crashes_the_graph(outside_run):
    run = outside_run
    assert run.stalled_s > STALL_S, f'the reader was stopped for {run.stalled_s:.1f} s only'
    if run.clock_mode == 'realtime':
        # Every tick in realtime too since the writers piggyback no heartbeat on their
        # samples (docs/recording.md). The plant's report of the stopped reader can fail
        # to come in realtime (it once did in a fresh-clone CI run): the lockstep run
        # checks the reports.
        check_graph_unharmed_and_reader_reported(run, reported_by_all=False)
        return
    states = check_graph_unharmed_and_reader_reported(run, reported_by_all=True)
    after = sum(1 for at, _ in states if at > run.stopped_ns)
    assert after > HISTORY_TICKS, f'only {after} ticks after the reader stopped'


def test_a_second_writer_on_effort_command_is_rejected_named_and_obeyed_by_nothing(outside_run):
    """Both modes: the writers are rejected, counted and named by the plant and the
    supervisor, which stay pinned to the graph's controller, and the motors never get
    their zero torques. Lockstep also: no alarm. A realtime run's alarms also depend on
    the machine's load (a false alarm under load is test_faults' and the soak's subject),
    so there the FDI's inputs are checked instead: the commands it judged are the
    controller's (its pin never moved)."""
    run = outside_run
    clock_mode, namespace, bag, log, scenario, sent = (run.clock_mode, run.namespace, run.bag, run.log,
                                                       run.scenario, run.sent)
    assert not log.repeated_lines(), log.repeated_lines()
    # A lockstep run has no period to slip: nothing of it is ever excused.
    started_s = log.plant_started_s()
    run_s, writes_s = (started_s, run.ended_s), run.writes_s
    # what the plant and the supervisor said as they stopped, and what the tool sent
    last = written_statuses(run.said)
    assert {'plant_simulator', 'supervisor'} <= last.keys(), sorted(last)
    assert sorted(sent) == sorted(OUTSIDE_WRITERS), sent
    # commands from each, half of them stamped as a state. The writers answer best-effort
    # states, so a loaded machine drops most of them (124 of each in one fresh-clone CI
    # run, 7 in another): what matters is that each kind was sent, and all were refused.
    with timing_check(log, writes_s, f'{clock_mode}: the outside writers answered states'):
        assert all(counts['copied_stamps'] > 0 and counts['commands'] > counts['copied_stamps']
                   for counts in sent.values()), sent
    topics, found = run.topics, run.found
    applied = [message.effort for _, message in found[topics[1]]]
    assert applied, 'no joint state in the bag'
    assert not any(np.allclose(effort, 0.0) for effort in applied), \
        "the motors applied an outside writer's zero torques"
    # the states the plant published, as it counted them stopping
    ticks = int(last['plant_simulator']['states total'])
    assert ticks > 0, last['plant_simulator']
    with timing_check(log, run_s, f'{clock_mode}: the applied torques recorded'):
        assert len(applied) >= RECORDED_SHARE * ticks, f'{len(applied)} joint states in the bag of {ticks}'
    # what the niced recorder lost of a realtime run over a window (monotonic s): the
    # bag's statuses of that time with it; a loss elsewhere excuses nothing there
    recorded_ns = {stamp_to_ns(message.header.stamp) for _, message in found[topics[1]]}
    period_ns = round(scenario.period_s * 1e9)

    def recorder_lost(window_s: tuple[float, float]) -> str:
        lost = lost_ticks(recorded_ns, ticks, period_ns,
                          tuple((at - started_s) * 1e9 for at in window_s))
        return (f'the recorder lost {lost} of the run\'s ticks from {window_s[0] - started_s:.1f} s to '
                f'{window_s[1] - started_s:.1f} s' if lost > 0 and clock_mode == 'realtime' else '')

    if clock_mode == 'lockstep':
        verdicts = found[topics[0]]
        assert verdicts and all(message.data == 0 for _, message in verdicts), 'a false failure alarm'
        # the bag keeps the outside commands apart, and FDI on the bag judges the
        # controller's alone: no alarm either (offline FDI on a failure-free graph bag)
        commands = read_messages(bag, [f'{namespace}/{contract.EFFORT_COMMAND}',
                                       f'{namespace}/{contract.EFFORT_COMMAND}/{OTHER_WRITERS}'])
        own, others = commands.values()
        assert own and not any(np.allclose(message.effort, 0.0) for _, message in own), \
            "an outside writer's zero torques among the controller's commands in the bag"
        # (not all: the tool sends before every reader has matched it, and exits at once)
        assert 0 < len(others) <= sum(counts['commands'] for counts in sent.values())
        verdict = offline_verdict(bag, namespace, run.folder, scenario)
        assert verdict['alarm_time_s'] is None and verdict['detection_time_s'] is None, verdict
        assert verdict['ticks_replayed'] >= 0.9 * ticks, verdict
    pins = set()
    for node in ('plant_simulator', 'supervisor'):
        # a node's second-writer warning on its console, whatever the recorder kept
        warned = [(at, line) for at, line in log.entries if line.startswith(f'[{node}] [WARN]')
                  and f'a second writer on {namespace}/{contract.EFFORT_COMMAND}' in line]
        assert any(f'{namespace}/outside_writer' in line for _, line in warned), warned
        # the rejections counted and their writers named, in the node's last status
        stopped = last[node]
        assert int(stopped.get(f'rejected {contract.EFFORT_COMMAND}', 0)) > 0, stopped
        writers = stopped.get(f'rejected {contract.EFFORT_COMMAND} from', '')
        assert f'node {namespace}/outside_writer (GID ' in writers, writers
        assert f'another node named {namespace}/controller (GID ' in writers, writers
        statuses = [status for _, message in found['/diagnostics'] for status in message.status
                    if status.name == f'{namespace}/{node}']
        assert statuses, f'no status of {node} in the bag'
        facts = [{value.key: value.value for value in status.values} for status in statuses] + [stopped]
        # before the run the writer may not be known yet ('not seen yet')
        pins |= {fact[f'{contract.EFFORT_COMMAND} writer'] for fact in facts
                 if '(GID ' in fact[f'{contract.EFFORT_COMMAND} writer']}
        # WARN from the first status that counts a rejection (held warning_hold_s of wall
        # time after the last one, which a slow lockstep run may outlast); the bag reader
        # gives the level as a number, the message class as a byte. That status goes out
        # within a report period of the first rejection, which the warning logs: only what
        # the recorder lost of that time excuses its absence.
        first = next((status for status, fact in zip(statuses, facts)
                      if int(fact.get(f'rejected {contract.EFFORT_COMMAND}', 0)) > 0), None)
        warned_s = warned[0][0]
        around = (warned_s - LOOP_REPORT_PERIOD_S, warned_s + LOOP_REPORT_PERIOD_S)
        with timing_check(log, around, f'{clock_mode}: the status of {node} counting a rejection recorded',
                          recorder_lost(around)):
            assert first is not None, f'{node}: no status counts a rejection ({len(statuses)} statuses of it)'
        if first is not None:   # the one check about that status; the rest are judged above
            assert first.level >= ord(DiagnosticStatus.WARN), first
    # the outside node's injections: refused by a plant started as a run starts it, no
    # cable broken, each counted
    plant = last['plant_simulator']
    assert json.loads(plant[contract.BROKEN_AT_KEY]) == {}, 'an outside node broke a cable'
    refused = int(plant.get(f'rejected {contract.INJECT_FAILURE}', 0))
    injections = sent[OUTSIDE_WRITERS[0]]['injections']
    assert refused <= injections, (refused, sent)
    # the tool injects as it answers states, and exits at once: how many it sent, and
    # whether the last reached the plant, depends on the machine's speed
    with timing_check(log, writes_s, f'{clock_mode}: the outside writer asked for a failure, refused'):
        assert injections > 0, sent
        assert refused > 0, plant
    # one controller publisher obeyed by both, all run long
    assert len(pins) == 1, pins
    assert all(f'{namespace}/controller (GID ' in pin for pin in pins), pins
