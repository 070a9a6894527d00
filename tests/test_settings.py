"""A run settled once: the values a node gets as ROS parameters give it the very settings
the launcher checked and the in-process engine runs with; no node needs a file."""
from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest
import yaml

from cdpr_bringup.scenario_setup import ScenarioOptions, build_scenario
from cdpr_control.settings import flatten, node_settings, unflatten
from cdpr_fdi.config import settled_fdi

from conftest import MOTIONS, PAPER_ROBOT


def test_flatten_gives_ros_names_and_unflatten_undoes_it():
    document = {'fdi': {'epsilon_nm': 0.3, 'cusum': {'sigma_nm': [0.1, 0.2]}},
                'recovery': {'safe_points_m': {4: [0.5, 1.3, 1.2]}, 'hold_after_s': 1.0},
                'run': {'failure_times_s': [], 'failure_cable_indices': []}}
    values = flatten(document)
    assert values == {'fdi.epsilon_nm': 0.3, 'fdi.cusum.sigma_nm': [0.1, 0.2],
                      'recovery.safe_points_m.4': [0.5, 1.3, 1.2], 'recovery.hold_after_s': 1.0}
    assert unflatten(values) == {'fdi': document['fdi'], 'recovery': {
        'safe_points_m': {'4': [0.5, 1.3, 1.2]}, 'hold_after_s': 1.0}}


def node_given(parameters: dict, name: str, tmp_path):
    """An rclpy node started as the launcher starts ours: its parameters from a file."""
    import rclpy
    from rclpy.node import Node
    path = tmp_path / f'{name}.yaml'
    path.write_text(yaml.safe_dump({'/**': {'ros__parameters': parameters}}))
    context = rclpy.Context()
    rclpy.init(args=['--ros-args', '--params-file', str(path)], context=context)
    node = Node(name, context=context, automatically_declare_parameters_from_overrides=True)
    return node, context


@pytest.fixture
def scenario(tmp_path):
    """The elastic plant (calibrated thresholds merged), detector and ε from the command
    line, a safe point set per cable in the robot file, two cables failing."""
    robot_file = yaml.safe_load(PAPER_ROBOT.read_text())
    robot_file['recovery'] = {'safe_points_m': {4: [0.6, 1.2, 1.25]}}
    path = tmp_path / 'robot.yaml'
    path.write_text(yaml.safe_dump(robot_file))
    return build_scenario(ScenarioOptions(config=str(path), motions=str(MOTIONS), motion='along-3',
                                          fail_cables=[4, 2], fail_at_fraction=0.3,
                                          detector='cusum', epsilon_nm=0.4, fidelity='elastic'))


def test_the_supervisor_node_gets_the_launchers_fdi_and_recovery_settings(scenario, tmp_path):
    parameters = scenario.node_parameters('lockstep')['supervisor']
    node, context = node_given(dict(parameters, config_file=str(tmp_path / 'absent.yaml')),
                               'supervisor', tmp_path)
    try:
        settings = node_settings(node)
        fdi, recovery = settled_fdi(settings, settings.robot)
    finally:
        node.destroy_node()
        context.try_shutdown()
    assert settings.robot.fingerprint() == scenario.robot.fingerprint()
    assert fdi == scenario.fdi
    assert (fdi.detector, fdi.epsilon_nm) == ('cusum', 0.4)
    assert fdi.friction.coulomb_nm == scenario.fdi.friction.coulomb_nm > 0.0   # as calibrated
    assert recovery.safe_points_m.keys() == {4}
    np.testing.assert_array_equal(recovery.safe_points_m[4], [0.6, 1.2, 1.25])
    def without_safe_points(config):
        return {key: value for key, value in vars(config).items() if key != 'safe_points_m'}
    assert without_safe_points(recovery) == without_safe_points(scenario.recovery)


def test_the_plant_gets_the_failures_as_times_and_0_based_cables(scenario, tmp_path):
    parameters = scenario.node_parameters('lockstep')['plant_simulator']
    assert not any(key.startswith(('motion', 'fdi')) for key in parameters)
    node, context = node_given(parameters, 'plant_simulator', tmp_path)
    try:
        run = node_settings(node).section('run')
    finally:
        node.destroy_node()
        context.try_shutdown()
    failure_time = scenario.motion.time_at_fraction(0.3)
    assert list(zip(run.raw('failure_times_s'), run.raw('failure_cable_indices'))) == [
        (failure_time, 3), (failure_time, 1)] == scenario.failures
    np.testing.assert_array_equal(run.vector('start_position_m', 3), scenario.reference.position_m[0])
    assert run.integer('last_tick') == scenario.cycles - 1
    assert run.integer('hold_after_ticks') == scenario.hold_after_cycles


def test_the_plant_node_does_not_know_the_motion_catalogue():
    script = ('import sys, cdpr_twin.plant_simulator_node\n'
              'print("cdpr_control.motions" in sys.modules)\n')
    result = subprocess.run([sys.executable, '-c', script], capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip() == 'False'
