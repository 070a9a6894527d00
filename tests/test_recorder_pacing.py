"""A plant waits for its graph's recorder (cdpr_twin.nodes.recorder_pacing): in lockstep no
further ahead of it than a lead, and at the end of a run in either mode until it has the
last state."""
from __future__ import annotations

import os
import signal
import time

import pytest

from cdpr_bringup.bags.bag_io import LOOP_TOPICS, missing_ticks, read_topics
from cdpr_bringup.graph.launcher import Graph, graph_nodes
from cdpr_bringup.runs.metrics import written_statuses
from cdpr_twin.nodes.recorder_pacing import RecorderPacing

from conftest import (GraphLog, assert_stopped_cleanly, keep_running, settled_parameters,
                      start_until_the_plant_runs)
from test_faults import START_TIMEOUT_S

# The run's limit (s of wall time): its 4 s of ticks, the stop and a loaded machine.
RUN_TIMEOUT_S = 120.0


def test_a_state_waits_while_the_recorder_is_more_than_the_lead_behind():
    pacing = RecorderPacing(lead_ticks=3)
    # nothing recorded yet: the first ticks of the lead go out
    assert [pacing.may_publish(tick) for tick in range(4)] == [True, True, True, False]
    pacing.recorded(5)
    assert pacing.may_publish(8) and not pacing.may_publish(9)
    # a report overtaken by a newer one changes nothing
    pacing.recorded(2)
    assert pacing.may_publish(8) and pacing.has_recorded(5) and not pacing.has_recorded(6)


def test_a_lead_under_one_tick_is_refused():
    with pytest.raises(ValueError, match='at least one tick'):
        RecorderPacing(lead_ticks=0)


def run_suspending_the_recorder(tmp_path, parameters: dict, namespace: str, after_s: float,
                                while_suspended) -> tuple[dict, dict, object]:
    """A graph run whose recorder is suspended (SIGSTOP) `after_s` after the plant's
    first tick while `while_suspended(graph)` runs, then resumed, and the run completed;
    (the plant's last status, the bag's joint states by stamp, the bag)."""
    bag, said = tmp_path / 'bag', tmp_path / 'said'
    said.mkdir()
    log = GraphLog()
    # the loop composed in one process (40 % less CPU than a process a node): the
    # recorder, the subject here, is its own process either way
    graph = Graph(graph_nodes(parameters, str(bag), last_diagnostics=str(said), form='composed'), namespace,
                  completion='plant_simulator', log=log)
    try:
        start_until_the_plant_runs(graph, log, START_TIMEOUT_S)
        time.sleep(after_s)
        recorder = graph.processes['bag_recorder'].pid
        os.kill(recorder, signal.SIGSTOP)
        try:
            while_suspended(graph)
        finally:
            os.kill(recorder, signal.SIGCONT)
        graph.wait(RUN_TIMEOUT_S)
    finally:
        codes = graph.stop()
    assert_stopped_cleanly(codes, log)
    states = read_topics(bag, [f'{namespace}/joint_states'])[f'{namespace}/joint_states']
    return written_statuses(said)['plant_simulator'], states, bag


# The writers keep HISTORY_S of ticks; the recorder is stopped for longer than that,
# and the plant may be LEAD_S ahead of it.
HISTORY_S, LEAD_S = 1.0, 0.2
STOPPED_S = 2.5


@pytest.mark.graph
def test_a_lockstep_run_waits_for_a_stopped_recorder_and_its_bag_has_every_tick(tmp_path):
    """The recorder suspended (SIGSTOP) for longer than the writers keep: a plant that
    ran on would leave it a hole of ~STOPPED_S of ticks; held at the lead, the bag has
    every state the plant published, and the run completes."""
    parameters = settled_parameters('lockstep', motion='along-2', duration_s=4.0)
    for node in parameters.values():
        node['streams.history_s'] = HISTORY_S
    parameters['plant_simulator']['recorder_lead_s'] = LEAD_S
    plant, states, bag = run_suspending_the_recorder(
        tmp_path, parameters, '/cdpr_test_pacing', 0.0,
        lambda graph: keep_running(graph, time.monotonic(), STOPPED_S, 'the recorder was suspended'))
    # the recorder counted the holes of every loop topic, and found none
    counted = missing_ticks(bag)
    assert counted is not None and set(LOOP_TOPICS) <= counted.keys(), counted
    assert not any(counted.values()), counted
    assert len(states) == int(plant['states total'])
    assert int(plant['states held for the recorder total']) >= 1


# A realtime run of END_RUN_S, its recorder suspended from END_STOPPED_BEFORE_S before its
# last tick to END_RESUMED_AFTER_S after it: longer than the writers wait for
# acknowledgements on their way out (2 s), within that and the plant's drain (3 s more).
END_RUN_S, END_STOPPED_BEFORE_S, END_RESUMED_AFTER_S = 6.0, 2.0, 3.0


@pytest.mark.graph
def test_the_end_of_a_realtime_run_waits_until_its_recorder_has_the_last_state(tmp_path):
    """The plant drains until the recorder has its last state: without that wait the
    recorder, behind at the end, lost 975 of 3 001 states here — after its last, so
    its own count said none (docs/recording.md). Realtime, but nothing here is judged
    against the wall clock: a slow machine only makes the end come later."""
    parameters = settled_parameters('realtime', motion='circle', duration_s=END_RUN_S)
    plant, states, _ = run_suspending_the_recorder(
        tmp_path, parameters, '/cdpr_test_run_end', END_RUN_S - END_STOPPED_BEFORE_S,
        lambda graph: time.sleep(END_STOPPED_BEFORE_S + END_RESUMED_AFTER_S))
    period_s = parameters['plant_simulator']['control.period_s']
    assert len(states) == int(plant['states total']) > END_RUN_S / period_s
