"""Parameters the ROS way: declared with descriptions, read-only where a change is not
supported, the /diagnostics limits changeable while a node runs, integers taken for
numbers, shipped parameter files, and one FATAL line for a node that cannot start."""
from __future__ import annotations

import math
import os
import subprocess
from contextlib import contextmanager

import pytest
import rclpy
import yaml
from rclpy.parameter import Parameter

from cdpr_bringup.graph.launcher import executable_command, node_environment, parser
from cdpr_bringup.graph.params_files import parameter_files
from cdpr_control.config import load_yaml
from cdpr_control.control.controller_node import ControllerNode
from cdpr_control.control.trajectory_generator_node import TrajectoryGeneratorNode
from cdpr_fdi.nodes.supervisor_node import SupervisorNode
from cdpr_msgs_py import contract
from cdpr_twin.nodes.digital_twin_node import DigitalTwinNode
from cdpr_twin.nodes.plant_simulator_node import PlantSimulatorNode

from conftest import CONFIG_DIR, PAPER_ROBOT, settled_parameters

SHIPPED = CONFIG_DIR / 'params'


@contextmanager
def supervisor(*arguments: str):
    rclpy.init(args=['--ros-args', *arguments])
    node = SupervisorNode()
    try:
        yield node
    finally:
        node.destroy_node()
        rclpy.shutdown()


def test_the_shipped_parameter_files_are_the_default_runs():
    """cdpr-params writes them again unchanged (else run it: they are stale)."""
    written = parameter_files(parser().parse_args([]))
    # the default graph has no recorder (no bag): a file for each of its other nodes
    assert set(written) == {contract.TRAJECTORY_GENERATOR, contract.CONTROLLER, contract.DIGITAL_TWIN,
                            contract.SUPERVISOR, contract.MARKERS_NODE, contract.PLANT_SIMULATOR}
    assert sorted(path.stem for path in SHIPPED.glob('*.yaml')) == sorted(written)
    for name, text in written.items():
        assert (SHIPPED / f'{name}.yaml').read_text() == text, name


@pytest.mark.parametrize('node_class', [TrajectoryGeneratorNode, ControllerNode, DigitalTwinNode,
                                        SupervisorNode, PlantSimulatorNode])
def test_every_parameter_of_a_settled_run_is_one_its_node_has(node_class, tmp_path):
    """Nothing the launcher settles is dropped as unknown: a failure on the elastic plant."""
    name = {TrajectoryGeneratorNode: 'trajectory_generator', ControllerNode: 'controller',
            DigitalTwinNode: 'digital_twin', SupervisorNode: 'supervisor',
            PlantSimulatorNode: 'plant_simulator'}[node_class]
    parameters = settled_parameters('lockstep', motion='along-2', fail_cables=[4])[name]
    path = tmp_path / 'parameters.yaml'
    path.write_text(yaml.safe_dump({'/**': {'ros__parameters': parameters}}))
    rclpy.init(args=['--ros-args', '--params-file', str(path)])
    try:
        node = node_class()
        assert node.ignored_parameters() == []
        node.destroy_node()
    finally:
        rclpy.shutdown()


def test_a_node_started_with_its_shipped_file_has_described_read_only_settings():
    calibrated = load_yaml(CONFIG_DIR / 'fdi_calibration_elastic.yaml')['fdi']['epsilon_nm']
    with supervisor('--params-file', str(SHIPPED / 'supervisor.yaml')) as node:
        assert node.supervisor.fdi.epsilon_nm == calibrated
        descriptor = node.describe_parameter('fdi.epsilon_nm')
        assert descriptor.read_only and 'threshold' in descriptor.description
        # the defaults file's words are of the noise-free default; the value is calibrated
        assert f'this run has {calibrated!r}' in descriptor.description, descriptor.description
        assert 'this run has' not in node.describe_parameter('fdi.detector').description
        assert node.describe_parameter('robot_description').read_only
        refused = node.set_parameters([Parameter('fdi.epsilon_nm', value=1.0)])[0]
        assert not refused.successful and 'read-only' in refused.reason
        assert node.supervisor.fdi.epsilon_nm == calibrated


def test_a_health_limit_changes_while_the_node_runs_and_a_bad_one_is_refused_saying_why():
    with supervisor('-p', f'config_file:={PAPER_ROBOT}') as node:
        assert not node.describe_parameter('health.warning_hold_s').read_only
        # an integer, as `ros2 param set … health.warning_hold_s 5` sends it
        changed = node.set_parameters([Parameter('health.warning_hold_s', value=5)])[0]
        assert changed.successful and node.diagnostics.health.limits.warning_hold_s == 5.0
        # beyond the declared range (a fraction), refused by rclpy; an integer is not
        # range-checked by rclpy on a number parameter, but by the node
        beyond = node.set_parameters([Parameter('health.unjudged_limit', value=2.0)])[0]
        assert not beyond.successful and 'out of range' in beyond.reason
        refused = node.set_parameters([Parameter('health.unjudged_limit', value=2)])[0]
        assert not refused.successful and 'must be a fraction' in refused.reason
        assert node.diagnostics.health.limits.unjudged_limit == 0.01


def test_a_settled_value_is_declared_with_the_bounds_its_loader_checks():
    with supervisor('-p', f'config_file:={PAPER_ROBOT}') as node:
        epsilon = node.describe_parameter('fdi.epsilon_nm')
        fraction = node.describe_parameter('health.unjudged_limit')
        detector = node.describe_parameter('fdi.detector')
        priority = node.describe_parameter('realtime_priority')
    # positive: from 0 (excluded, said in words) to unbounded
    (epsilon_range,) = epsilon.floating_point_range
    assert (epsilon_range.from_value, epsilon_range.to_value) == (0.0, math.inf)
    assert epsilon.additional_constraints == '> 0'
    (fraction_range,) = fraction.floating_point_range
    assert (fraction_range.from_value, fraction_range.to_value) == (0.0, 1.0)
    assert fraction.additional_constraints == '>= 0 and <= 1'
    assert not detector.floating_point_range and not detector.integer_range
    assert detector.additional_constraints == 'one of threshold, cusum'
    (priority_range,) = priority.integer_range
    assert (priority_range.from_value, priority_range.to_value) == (0, 99)


def test_an_integer_is_taken_for_a_number():
    with supervisor('-p', f'config_file:={PAPER_ROBOT}', '-p', 'fdi.epsilon_nm:=1',
                    '-p', 'recovery.hold_after_s:=3') as node:
        assert node.supervisor.fdi.epsilon_nm == 1.0
        assert node.supervisor.recovery_config.hold_after_s == 3.0
        assert node.get_parameter('fdi.epsilon_nm').type_ == Parameter.Type.DOUBLE


def test_a_misspelt_parameter_is_reported_as_ignored():
    with supervisor('-p', f'config_file:={PAPER_ROBOT}', '-p', 'fdi.epsilonn:=0.5') as node:
        assert node.ignored_parameters() == ['fdi.epsilonn']


def start(executable: str, *parameters: str) -> subprocess.CompletedProcess:
    command = executable_command('cdpr_control', executable) + ['--ros-args']
    for parameter in parameters:
        command += ['-p', parameter]
    return subprocess.run(command, capture_output=True, text=True, timeout=60,
                          env=dict(node_environment(), CDPR_LAUNCHER_PID=str(os.getpid())))


@pytest.mark.parametrize('parameters, named', [
    ((f'config_file:={CONFIG_DIR / "absent.yaml"}',), 'absent.yaml'),
    (('clock_mode:=banana',), 'clock_mode'),
    ((f'config_file:={PAPER_ROBOT}', 'control.period_s:=-0.002'), 'control.period_s'),
    (('realtime_priority:=120',), 'realtime_priority'),
])
def test_a_node_that_cannot_start_says_why_in_one_fatal_line_and_exits_1(parameters, named):
    result = start('controller', *parameters)
    output = result.stdout + result.stderr
    fatal = [line for line in output.splitlines() if '[FATAL]' in line]
    assert result.returncode == 1, output
    assert len(fatal) == 1 and named in fatal[0], output
    assert 'Traceback' not in output


def test_a_parameters_file_that_cannot_be_read_is_one_fatal_line():
    command = executable_command('cdpr_fdi', 'supervisor') + [
        '--ros-args', '--params-file', str(CONFIG_DIR / 'params' / 'absent.yaml')]
    result = subprocess.run(command, capture_output=True, text=True, timeout=60,
                            env=dict(node_environment(), CDPR_LAUNCHER_PID=str(os.getpid())))
    output = result.stdout + result.stderr
    fatal = [line for line in output.splitlines() if '[FATAL]' in line]
    assert result.returncode == 1 and len(fatal) == 1 and 'absent.yaml' in fatal[0], output
    assert 'Traceback' not in output
