"""The node graph: every node its own process, over DDS on localhost, private domain."""
from __future__ import annotations

import numpy as np
import pytest

from cdpr_bringup.bag_io import read_topics, recording_from_bag
from cdpr_bringup.engine import run_inprocess
from cdpr_bringup.graph import graph_nodes, run_to_completion
from cdpr_bringup.scenario_setup import ScenarioOptions, build_scenario

from conftest import MOTIONS, PAPER_ROBOT

pytestmark = pytest.mark.graph
QUIET = lambda line: None  # noqa: E731


def parameters(**extra):
    return dict({'config_file': str(PAPER_ROBOT), 'motions_file': str(MOTIONS),
                 'motion': 'along-2', 'clock_mode': 'lockstep'}, **extra)


def run(tmp_path, name, **extra):
    bag = tmp_path / name
    run_to_completion(graph_nodes(parameters(**extra), str(bag)), f'/cdpr_test_{name}',
                      timeout_s=120.0, log=QUIET)
    return bag


@pytest.fixture(scope='module')
def lockstep_bags(tmp_path_factory):
    folder = tmp_path_factory.mktemp('lockstep')
    return [run(folder, f'run{i}', fail_cables=[4]) for i in range(2)]


def test_lockstep_graph_equals_the_inprocess_engine(lockstep_bags):
    scenario = build_scenario(ScenarioOptions(config=str(PAPER_ROBOT), motions=str(MOTIONS),
                                              motion='along-2', fail_cables=[4]))
    engine = run_inprocess(scenario)
    graph = recording_from_bag(lockstep_bags[0], '/cdpr_test_run0')
    assert graph.time_s.size == engine.time_s.size == scenario.cycles
    np.testing.assert_allclose(graph.true_position_m, engine.true_position_m, rtol=0, atol=1e-9)
    np.testing.assert_allclose(graph.command_nm, engine.command_nm, rtol=0, atol=1e-9)
    np.testing.assert_allclose(graph.twin_torque_nm, engine.twin_torque_nm, rtol=0, atol=1e-9)


def test_lockstep_runs_are_bit_for_bit_repeatable(lockstep_bags):
    first = recording_from_bag(lockstep_bags[0], '/cdpr_test_run0')
    second = recording_from_bag(lockstep_bags[1], '/cdpr_test_run1')
    np.testing.assert_array_equal(first.true_position_m, second.true_position_m)
    np.testing.assert_array_equal(first.command_nm, second.command_nm)


def test_failure_in_the_graph_frees_the_plant_motor_not_the_twin(lockstep_bags):
    graph = recording_from_bag(lockstep_bags[0], '/cdpr_test_run0')
    healthy = run_inprocess(build_scenario(ScenarioOptions(
        config=str(PAPER_ROBOT), motions=str(MOTIONS), motion='along-2')))
    np.testing.assert_allclose(graph.twin_torque_nm, healthy.twin_torque_nm, rtol=0, atol=1e-9)
    late = graph.time_s > graph.time_s[-1] - 1.0
    assert np.all(graph.true_tension_n[late, 3] == 0.0)
    assert np.all(healthy.true_tension_n[late, 3] > 1.0)


def test_realtime_smoke_run_answers_every_state(tmp_path):
    bag = run(tmp_path, 'realtime', clock_mode='realtime', duration_s=2.0)
    topics = read_topics(bag, ['/cdpr_test_realtime/joint_states', '/cdpr_test_realtime/effort_command'])
    states = set(topics['/cdpr_test_realtime/joint_states'])
    commands = set(topics['/cdpr_test_realtime/effort_command'])
    assert len(states) >= 990, 'about 2 s at 500 Hz'
    # every state but possibly the very last one got its command
    assert len(states - commands) <= 1
