"""The node graph: every node its own process, over DDS on localhost, private domain."""
from __future__ import annotations

import json
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from cdpr_bringup.reports import fdi_offline
from cdpr_bringup.bags.bag_io import read_messages, recording_from_bag
from cdpr_bringup.runs.engine import run_inprocess
from cdpr_bringup.graph.launcher import Graph, graph_nodes, node_environment, run_to_completion
from cdpr_bringup.reports.report import run_settings, write_report
from cdpr_bringup.reports.summary import bag_summary
from cdpr_bringup.runs.metrics import (fdi_summary_from_diagnostics, fdi_summary_of, run_figures_of,
                                      statuses_beside, take_statuses, twin_kpis, written_statuses)
from cdpr_bringup.scenario import command as scenario_cli
from cdpr_bringup.runs.settle import GRAPH_FORMS, ScenarioOptions, build_scenario

from cdpr_msgs_py.dds import PROFILE_VARIABLE
from cdpr_msgs_py.stamps import stamp_to_ns

from conftest import (LOOP_ROWS, MOTIONS, PAPER_ROBOT, VIEW_ROWS, GraphLog, assert_close_figures, in_private_shm,
                      private_shm_allowed, settled_parameters, timing_check)
from test_report import assert_figure

pytestmark = pytest.mark.graph
QUIET = lambda line: None  # noqa: E731


def run(tmp_path, name, clock_mode='lockstep', log=QUIET, form='separate', **options):
    """A run of along-2 (or `options`' motion) as cdpr-scenario settles it, in graph
    `form`; its bag."""
    bag = tmp_path / name
    (tmp_path / f'{name}_said').mkdir()
    run_to_completion(graph_nodes(settled_parameters(clock_mode, **dict({'motion': 'along-2'}, **options)),
                                  str(bag), form=form, last_diagnostics=str(tmp_path / f'{name}_said')),
                      f'/cdpr_test_{name}', timeout_s=120.0, log=log)
    return bag


# Cable 4 breaks 1 s into along-2, moving at speed, between two ticks: the run, which
# ends once the recovery is over, is half as long as with the failure at the midpoint.
FAILURE_S = 1.001


def failure_scenario():
    return build_scenario(ScenarioOptions(config=str(PAPER_ROBOT), motions=str(MOTIONS),
                                          motion='along-2', fail_cables=[4], fail_at_s=FAILURE_S))


# The second run, for repeatability, goes through the failure and its detection into the
# recovery (1.2 s after the failure): the first run covers the rest. The first has the
# loop's nodes composed in one process (40 % less CPU for the whole run), the second
# every node in its own.
REPEATED_S = 2.2


@pytest.fixture(scope='module')
def lockstep_bags(tmp_path_factory):
    folder = tmp_path_factory.mktemp('lockstep')
    return [run(folder, 'run0', form='composed', fail_cables=[4], fail_at_s=FAILURE_S),
            run(folder, 'run1', fail_cables=[4], fail_at_s=FAILURE_S, duration_s=REPEATED_S)]


def test_lockstep_graph_equals_the_inprocess_engine(lockstep_bags):
    """Through the failure, its detection and the whole recovery: every loop topic, the
    view topics on the view ticks, and the figures the plant computed from every tick, so
    that metrics.json is the in-process engine's."""
    scenario = failure_scenario()
    engine = run_inprocess(scenario)
    bag = lockstep_bags[0]
    graph = recording_from_bag(bag, '/cdpr_test_run0')
    # the run ends hold_after_s after SAFE_HOLD in both, before its scheduled end
    assert graph.time_s.size == engine.time_s.size < scenario.cycles
    for name in LOOP_ROWS + VIEW_ROWS:
        np.testing.assert_allclose(getattr(graph, name), getattr(engine, name), rtol=0, atol=1e-9, err_msg=name)
    # the view topics on every 10th tick only, from the first
    np.testing.assert_array_equal(np.round(graph.view_time_s / scenario.period_s), np.arange(0, graph.time_s.size, 10))
    diagnostics = read_messages(bag, ['/diagnostics'])['/diagnostics']
    assert fdi_summary_from_diagnostics(diagnostics) == engine.fdi
    assert engine.fdi['broken_cables'] == [4] and engine.fdi['mode'] == 'SAFE_HOLD'
    # what the nodes said as they stopped, whatever the recorder kept (cdpr-scenario's
    # verdicts and figures)
    said = written_statuses(bag.with_name('run0_said'))
    assert fdi_summary_of(said['supervisor']) == engine.fdi
    assert_close_figures(run_figures_of(said['plant_simulator']), engine.figures)
    assert int(said['plant_simulator']['states total']) == engine.time_s.size
    # metrics.json of either engine
    take_statuses(graph, statuses_beside(bag, diagnostics), None)
    metrics = {name: scenario_cli.metrics_of(scenario, recording, wall_time_s=0.0) for name, recording
               in (('graph', graph), ('engine', engine))}
    # what the recorder lacks, of a graph run's bag only: nothing
    assert not any(metrics['graph'].pop('bag_missing_ticks').values())
    assert_close_figures(metrics['graph'], metrics['engine'])
    assert metrics['engine']['recovery']['reached_safe_point'] and metrics['engine']['tracking_error_m'] > 0.0


def test_lockstep_runs_are_bit_for_bit_repeatable_and_the_same_in_either_graph_form(lockstep_bags):
    first = recording_from_bag(lockstep_bags[0], '/cdpr_test_run0')
    second = recording_from_bag(lockstep_bags[1], '/cdpr_test_run1')
    ticks = second.time_s.size
    failure_s = failure_scenario().failure_time_s
    assert second.time_s[-1] == pytest.approx(REPEATED_S) and first.time_s.size > ticks
    # the failure shows: cable 4 slack, its motor freed
    assert np.all(second.true_tension_n[second.view_time_s > failure_s + 0.1, 3] == 0.0)
    views = second.view_time_s.size
    for name in LOOP_ROWS:
        np.testing.assert_array_equal(getattr(first, name)[:ticks], getattr(second, name), err_msg=name)
    for name in VIEW_ROWS:
        np.testing.assert_array_equal(getattr(first, name)[:views], getattr(second, name), err_msg=name)


def test_failure_in_the_graph_frees_the_plant_motor_not_the_twin(lockstep_bags):
    graph = recording_from_bag(lockstep_bags[0], '/cdpr_test_run0')
    healthy = run_inprocess(build_scenario(ScenarioOptions(
        config=str(PAPER_ROBOT), motions=str(MOTIONS), motion='along-2')), supervised=False)
    n = healthy.time_s.size
    np.testing.assert_allclose(graph.twin_torque_nm[:n], healthy.twin_torque_nm, rtol=0, atol=1e-9)
    views = healthy.view_time_s.size
    late = graph.view_time_s[:views] > graph.time_s[n - 1] - 1.0
    assert np.any(late)
    assert np.all(graph.true_tension_n[:views][late, 3] == 0.0)
    assert np.all(healthy.true_tension_n[late, 3] > 1.0)


def test_the_report_of_the_graphs_own_bag(lockstep_bags, tmp_path):
    """Without a metrics.json the failure instant is the plant's own report in the bag
    (its /diagnostics), not the first tick without the cable; the launch files' closing
    summary says the same."""
    bag, namespace, scenario = lockstep_bags[0], '/cdpr_test_run0', failure_scenario()
    metrics = write_report(bag, tmp_path / 'plots', run_settings(bag, PAPER_ROBOT), namespace)
    recording = recording_from_bag(bag, namespace)
    assert metrics['true_broken_cables'] == [4]
    assert metrics['failure_time_s'] == pytest.approx(FAILURE_S, abs=1e-9)
    summary = bag_summary(bag, scenario.settings, namespace)
    assert summary[0].startswith(f'along-2 on the {scenario.plant.fidelity} plant, node graph, threshold detector')
    assert f'  cable(s) [4] broke at {FAILURE_S:.4f} s' in summary
    assert f'detected at {metrics["detection_time_s"]:.3f} s' in '\n'.join(summary)
    assert summary[-1].startswith(f'bag: {bag} ')
    assert bag_summary(tmp_path / 'no-bag', scenario.settings)[0].startswith('no summary of the run:')
    before = slice(0, int(np.ceil(FAILURE_S / scenario.period_s)))
    assert metrics['kpi'] == pytest.approx(twin_kpis(scenario.robot, recording, before))
    for name in ('torques', 'residuals', 'position', 'path_3d', 'path_top', 'tensions'):
        assert_figure(tmp_path / 'plots' / f'{name}.png')


@pytest.mark.realtime
@pytest.mark.parametrize('form', GRAPH_FORMS)
def test_realtime_smoke_run_answers_every_state(tmp_path, form):
    log = GraphLog()
    bag = run(tmp_path, f'realtime_{form}', clock_mode='realtime', log=log, form=form, duration_s=2.0)
    window = (log.plant_started_s(), time.monotonic())
    namespace = f'/cdpr_test_realtime_{form}'
    topics = read_messages(bag, [f'{namespace}/joint_states', f'{namespace}/effort_command',
                                 f'{namespace}/fdi/broken_cable'])
    states = [stamp_to_ns(message.header.stamp) for _, message in topics[f'{namespace}/joint_states']]
    commands = [stamp_to_ns(message.header.stamp) for _, message in topics[f'{namespace}/effort_command']]
    # whatever the machine's speed: the ticks in order, a command only for a state that
    # was sent, no failure alarm
    assert states and commands, 'the bag holds the run'
    assert all(later > earlier for earlier, later in zip(states, states[1:]))
    assert set(commands) <= set(states)
    verdicts = topics[f'{namespace}/fdi/broken_cable']
    assert verdicts, 'no failure verdict in the bag'
    assert all(message.data == 0 for _, message in verdicts)
    with timing_check(log, window, 'realtime smoke run: every tick in the bag'):
        assert len(states) >= 990, f'{len(states)} states of about 1000 (2 s at 500 Hz)'
    with timing_check(log, window, 'realtime smoke run: every state answered'):
        # every state but possibly the very last one got its command
        assert len(set(states) - set(commands)) <= 1, f'{len(set(states) - set(commands))} states unanswered'


def user_environment() -> dict:
    """A ROS 2 user's shell: Fast DDS's own transports (shared memory too) and discovery
    on localhost, not the set-up the graph ships."""
    environment = {key: value for key, value in node_environment().items()
                   if key != PROFILE_VARIABLE}
    return dict(environment, ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST')


def listen(namespace: str, timeout_s: float) -> dict:
    """Run the outside listener (plain rclpy, nothing of ours) and return what it saw.

    It runs as a user's tool would, in its own /dev/shm where the machine allows that
    (so it meets no stale segment of this machine), else with the graph's set-up."""
    script = Path(__file__).parent / 'tools' / 'outside_listener.py'
    command = [sys.executable, str(script), namespace, str(timeout_s)]
    if private_shm_allowed():
        command, environment = in_private_shm(command, stale=()), user_environment()
    else:
        environment = node_environment()
    process = subprocess.Popen(command, stdout=subprocess.PIPE, text=True, env=environment)
    try:
        output, _ = process.communicate(timeout=timeout_s + 20.0)
    finally:
        if process.poll() is None:
            process.kill()
            process.wait(timeout=10)
    return json.loads([line for line in output.splitlines() if line.startswith('{')][-1])


def test_outside_tools_and_late_joiners_see_the_broken_cable():
    """A separate process importing only rclpy and messages gets the joint states, the
    diagnostics and the broken cable; one that joins after the failure still gets it."""
    namespace = '/cdpr_test_listen'
    scenario = failure_scenario()
    # the loop composed in one process (40 % less CPU): what is judged is outside it
    graph = Graph(graph_nodes(settled_parameters(motion='along-2', fail_cables=[4], fail_at_s=FAILURE_S,
                                                 fidelity='rigid', duration_s=scenario.duration_s + 30.0),
                              form='composed'),
                  namespace, completion='plant_simulator', log=QUIET)
    try:
        graph.start()
        graph.wait_until_up()
        early = listen(namespace, 60.0)
        assert early['joint_states'] > 0 and early['diagnostics'] > 0
        assert early['broken_cable'][-1] == 4
        late = listen(namespace, 20.0)
        assert late['broken_cable'] == [4], 'transient local: the late joiner gets the last value'
        assert not graph.check(), 'the graph is still running'
    finally:
        graph.stop()


def offline_verdict(bag, namespace, tmp_path, scenario) -> dict:
    out = tmp_path / f'{bag.name}-offline.json'
    fdi_offline.main([str(bag), '--config', str(PAPER_ROBOT), '--namespace', namespace,
                      '--calibration', str(scenario.calibration_path), '--out', str(out)])
    return json.loads(out.read_text())


def test_offline_fdi_on_a_recorded_failure_names_the_cable_as_live(lockstep_bags, tmp_path):
    scenario = failure_scenario()
    live = run_inprocess(scenario).fdi
    verdict = offline_verdict(lockstep_bags[0], '/cdpr_test_run0', tmp_path, scenario)
    assert verdict['identified_cables'] == live['broken_cables'] == [4]
    assert abs(verdict['detection_time_s'] - live['identified_tick'] * scenario.period_s) \
        <= scenario.period_s + 1e-9
