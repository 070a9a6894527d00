"""The launch files start what cdpr-graph starts, name only what exists, and — where the
`launch` package is importable (it is not on PyPI) — run the paper's failure demo."""
from __future__ import annotations

import ast
import importlib.util
import os
import shutil
import subprocess
import sys
from importlib.metadata import distribution
from pathlib import Path

import pytest
import yaml

from cdpr_bringup.bags.bag_io import read_messages
from cdpr_bringup.graph.composed_loop import COMPOSABLE
from cdpr_msgs_py import contract
from cdpr_bringup.graph.launcher import STOP_GRACE_S, parser, requested_graph, speaker
from cdpr_bringup.graph.launch_files import (SIGTERM_TIMEOUT_S, command_line, graph_from_launch, launch_arguments,
                                    launch_parameters)
from cdpr_msgs_py.runtime.spin import SHUTDOWN_LIMIT_S
from cdpr_bringup.runs.settle import GRAPH_FORMS

from conftest import REPO

LAUNCH_FOLDER = REPO / 'src' / 'cdpr_bringup' / 'launch'
LAUNCH_FILES = sorted(LAUNCH_FOLDER.glob('*.launch.py'))
DEFAULTS = {argument.name: argument.default for argument in launch_arguments()}
LAUNCH_MISSING = next((name for name in ('launch', 'launch_ros') if importlib.util.find_spec(name) is None), None)


def demo_arguments() -> dict[str, str]:
    """The arguments cdpr_demo.launch.py gives cdpr.launch.py (read from its source)."""
    tree = ast.parse((LAUNCH_FOLDER / 'cdpr_demo.launch.py').read_text())
    assignment = next(node for node in tree.body if isinstance(node, ast.Assign)
                      and node.targets[0].id == 'DEMO')
    return ast.literal_eval(assignment.value)


def test_every_launch_argument_is_a_cdpr_graph_option_with_its_default():
    options = {action.dest: action for action in parser()._actions if action.option_strings}
    assert {argument.name for argument in launch_arguments()} == set(options) - {'help'}
    assert DEFAULTS['config'] == 'paper_robot.yaml' and DEFAULTS['hardware'] == 'false'
    assert command_line(DEFAULTS) == ['--config', 'paper_robot.yaml', '--motions', 'motions.yaml',
                                      '--motion', 'circle', '--clock', 'lockstep',
                                      '--graph-form', 'separate', '--namespace', '/cdpr']


def test_the_launch_file_starts_the_nodes_cdpr_graph_starts_with_the_same_parameters():
    for values, argv in (({}, []),
                         ({'hardware': 'true', 'bag': '/tmp/b', 'detector': 'cusum'},
                          ['--hardware', '--bag', '/tmp/b', '--detector', 'cusum'])):
        graph = graph_from_launch(dict(DEFAULTS, **values))
        launched, namespace, simulated = graph.specs, graph.namespace, graph.simulated
        started, _ = requested_graph(parser().parse_args(argv))
        assert [(s.package, s.executable, s.parameters) for s in launched] == \
               [(s.package, s.executable, s.parameters) for s in started]
        assert namespace == '/cdpr' and simulated == ('hardware' not in values)
        assert graph.bag == values.get('bag')
    assert 'plant_simulator' not in {spec.name for spec in graph_from_launch(dict(DEFAULTS, hardware='true')).specs}


def test_launch_gives_every_node_the_time_its_shutdown_takes_before_sigterm():
    """ros2 launch sends SIGTERM `sigterm_timeout` after SIGINT (5 s by default); a node
    drains, waits for acknowledgements and tears DDS down in up to SHUTDOWN_LIMIT_S (6 s):
    with the default, Ctrl-C killed nodes mid-shutdown. The nodes' Node actions get
    cdpr-graph's grace, which the graph tests stop every graph with."""
    assert SIGTERM_TIMEOUT_S == STOP_GRACE_S > SHUTDOWN_LIMIT_S
    tree = ast.parse((LAUNCH_FOLDER / 'cdpr.launch.py').read_text())
    calls = [node for node in ast.walk(tree) if isinstance(node, ast.Call)
             and getattr(node.func, 'id', None) == 'Node']
    assert calls
    for call in calls:
        timeout = next((keyword.value for keyword in call.keywords if keyword.arg == 'sigterm_timeout'), None)
        assert timeout is not None and 'SIGTERM_TIMEOUT_S' in ast.unparse(timeout), ast.unparse(call)


def test_every_package_and_executable_the_launch_files_start_exists():
    arguments = demo_arguments()
    assert set(arguments) <= set(DEFAULTS)
    specs = graph_from_launch(dict(DEFAULTS, **arguments)).specs
    for spec in specs:
        scripts = {entry.name for entry in distribution(spec.package).entry_points
                   if entry.group == 'console_scripts'}
        assert spec.executable in scripts, spec
    plant = next(spec for spec in specs if spec.name == 'plant_simulator')
    # the paper's failure: cable 4 (index 3) at 3/8 of the circle
    assert plant.parameters['run.failure_cable_indices'] == [3]


def test_the_launch_files_are_installed_with_the_package():
    setup = (REPO / 'src' / 'cdpr_bringup' / 'setup.py').read_text()
    assert "glob('launch/*.launch.py')" in setup
    assert [path.name for path in LAUNCH_FILES] == ['cdpr.launch.py', 'cdpr_demo.launch.py']


@pytest.mark.workspace
@pytest.mark.skipif(LAUNCH_MISSING is not None,
                    reason=f'the `{LAUNCH_MISSING}` package is not importable (it is not on PyPI): '
                           'this test runs where ros2/launch and ros2/launch_ros are on PYTHONPATH '
                           '(pip-installed from their sources), see docs/testing.md, "The real-launch test"')
@pytest.mark.parametrize('form', GRAPH_FORMS)
def test_the_demo_launch_file_runs_the_papers_failure_with_real_launch(tmp_path, form):
    """Built with colcon, started as `ros2 launch cdpr_bringup cdpr_demo.launch.py
    graph_form:=FORM` would: the run completes, names cable 4 and ends at the safe point."""
    workspace = tmp_path / 'ws'
    shutil.copytree(REPO / 'src', workspace / 'src', ignore=shutil.ignore_patterns('*.egg-info', '__pycache__'))
    built = subprocess.run([str(Path(sys.executable).parent / 'colcon'), '--log-base', 'log', 'build',
                            '--base-paths', 'src'], cwd=workspace, capture_output=True, text=True,
                           timeout=300)
    assert built.returncode == 0, built.stdout + built.stderr
    install = workspace / 'install'
    site = [str(path) for path in install.glob('*/lib/python3*/site-packages')]
    environment = dict(os.environ, PYTHONPATH=os.pathsep.join(site + [os.environ.get('PYTHONPATH', '')]),
                       AMENT_PREFIX_PATH=os.pathsep.join(
                           [str(path) for path in install.glob('cdpr_*')] + [sys.prefix]))
    bag = tmp_path / 'bag'
    launch_file = install / 'cdpr_bringup' / 'share' / 'cdpr_bringup' / 'launch' / 'cdpr_demo.launch.py'
    process = subprocess.Popen([sys.executable, str(REPO / 'tests' / 'tools' / 'run_launch_file.py'),
                                str(launch_file), f'bag:={bag}', f'graph_form:={form}'],
                               env=environment, text=True,
                               stdout=subprocess.PIPE, stderr=subprocess.STDOUT, start_new_session=True)
    try:
        output, _ = process.communicate(timeout=240)
    finally:
        if process.poll() is None:
            os.killpg(process.pid, 9)
            process.wait(timeout=10)
    assert process.returncode == 0, output[-3000:]
    assert 'SAFE_HOLD from tick' in output and 'process has finished cleanly' in output
    assert 'escalating to SIGTERM' not in output, output[-3000:]
    # it ends as make demo does: how the run went, and where the bag is
    summary = output[output.index('circle on the elastic plant, node graph'):]
    assert 'cable(s) [4] broke at' in summary and 'cable(s) [4] named' in summary, output[-3000:]
    assert 'recovery to SP' in summary and output.rstrip().splitlines()[-1].startswith(f'bag: {bag} ')
    verdicts = read_messages(bag, ['/cdpr/fdi/broken_cable'])['/cdpr/fdi/broken_cable']
    assert [message.data for _, message in verdicts][-1] == 4


def test_a_composed_graph_runs_the_loop_in_one_process_each_node_with_its_own_parameters():
    values = dict(DEFAULTS, clock='realtime', bag='/tmp/b')
    separate = graph_from_launch(dict(values, graph_form='separate')).specs
    launched = graph_from_launch(dict(values, graph_form='composed')).specs
    assert [(s.executable, s.node_names) for s in launched] == \
           [(s.executable, s.node_names) for s in requested_graph(parser().parse_args(
               ['--clock', 'realtime', '--bag', '/tmp/b', '--graph-form', 'composed']))[0]]
    loop = launched[0]
    assert (loop.package, loop.executable) == ('cdpr_bringup', 'composed_loop')
    assert loop.node_names == list(COMPOSABLE) == loop.arguments()
    # the recorder and the markers stay in their own processes, as in the separate form
    assert [s.name for s in launched[1:]] == [s.name for s in separate if s.name not in COMPOSABLE] \
        == ['bag_recorder', 'markers']
    by_name = {spec.name: spec for spec in separate}
    # SCHED_FIFO is a process's: the loop's process runs at its highest node's priority
    priority = max(by_name[name].parameters['realtime_priority'] for name in COMPOSABLE)
    assert priority > min(by_name[name].parameters['realtime_priority'] for name in COMPOSABLE)
    # the members' start handshake leaves out what they take from one another inside the
    # process (local_bus): only the readers outside it count (the recorder's, the markers')
    for member in loop.members:
        assert member.parameters == dict(by_name[member.name].parameters, realtime_priority=priority,
                                         matches=member.parameters.get('matches'))
        for entry in member.parameters.get('matches') or []:
            kind, _, rest = entry.partition(':')
            topic = contract.TOPICS[rest.rsplit('=', 1)[0]]
            readers = {reader.node for reader in topic.readers} - set(COMPOSABLE)
            assert kind == 'publisher' and int(rest.rsplit('=', 1)[1]) == len(readers & set(by_name)), entry
    document = yaml.safe_load(Path(launch_parameters(loop)).read_text())
    assert document == {f'/**/{member.name}': {'ros__parameters': member.parameters}
                        for member in loop.members}
    assert launch_parameters(by_name['markers']) == by_name['markers'].parameters


def test_a_composed_processs_log_lines_are_told_apart_by_the_node_that_wrote_them():
    loop = next(spec for spec in graph_from_launch(dict(DEFAULTS, graph_form='composed')).specs
                if spec.members)
    assert speaker('[ERROR] [1764.123] [cdpr_ns.plant_simulator]: the loop does not keep its period',
                   loop) == 'plant_simulator'
    assert speaker('[INFO] [1764.1] [a.b.supervisor]: safety function on', loop) == 'supervisor'
    # what no composed node's logger wrote (a traceback) is the process's
    assert speaker('Traceback (most recent call last):', loop) == 'composed_loop'
    markers = next(spec for spec in graph_from_launch(DEFAULTS).specs if spec.name == 'markers')
    assert speaker('[INFO] [1764.1] [cdpr.markers]: up', markers) == 'markers'
