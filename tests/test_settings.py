"""A run settled once: the values a node gets as ROS parameters give it the very settings
the launcher checked and the in-process engine runs with; no node needs a file."""
from __future__ import annotations

from contextlib import contextmanager

import numpy as np
import pytest
import yaml
from rclpy.parameter import Parameter

from cdpr_bringup.runs.settle import ScenarioOptions, build_scenario
from cdpr_control.setup.settings import flatten, unflatten
from cdpr_fdi.nodes.supervisor_node import SupervisorNode
from cdpr_twin.nodes.plant_simulator_node import PlantSimulatorNode

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


@contextmanager
def node_given(parameters: dict, node_class, tmp_path):
    """Our node, built in this process as the launcher starts it: its parameters from a file."""
    import rclpy
    path = tmp_path / 'parameters.yaml'
    path.write_text(yaml.safe_dump({'/**': {'ros__parameters': parameters}}))
    rclpy.init(args=['--ros-args', '--params-file', str(path)])
    node = node_class()
    try:
        yield node
    finally:
        node.destroy_node()
        rclpy.shutdown()


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
    with node_given(dict(parameters, config_file=str(tmp_path / 'absent.yaml')), SupervisorNode,
                    tmp_path) as node:
        robot, fdi, recovery = node.robot, node.supervisor.fdi, node.supervisor.recovery_config
        # a settled value is read-only: the run it belongs to is under way
        refused = node.set_parameters([Parameter('fdi.epsilon_nm', value=1.0)])[0]
    assert not refused.successful and 'read-only' in refused.reason
    assert robot.fingerprint() == scenario.robot.fingerprint()
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
    assert not any(key.startswith('fdi') for key in parameters)
    with node_given(parameters, PlantSimulatorNode, tmp_path) as node:
        failures, position = node.plant.failures, node.plant.position_m
        run_length = node.run_length
    failure_time = scenario.motion.time_at_fraction(0.3)
    assert failures == sorted([(failure_time, 3), (failure_time, 1)]) == sorted(scenario.failures)
    np.testing.assert_allclose(position, scenario.reference.position_m[0], rtol=0, atol=1e-9)
    assert run_length.last_tick == scenario.cycles - 1
    assert run_length.hold_cycles == scenario.hold_after_cycles


def test_the_plant_tracks_its_truth_against_the_generators_reference_poses_to_the_bit(scenario, tmp_path):
    """The plant computes the tracking error of every tick (cdpr_twin.models.run_figures) against
    the settled motion's poses, which it tabulates as the generator does: the same rows."""
    parameters = scenario.node_parameters('lockstep')['plant_simulator']
    with node_given(parameters, PlantSimulatorNode, tmp_path) as node:
        positions, orientations = node.reference_poses
    np.testing.assert_array_equal(positions, scenario.reference.position_m)
    assert orientations is None
