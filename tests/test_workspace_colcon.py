"""The packages build with colcon as a ROS 2 workspace would, `ros2 run` would find them, and
`colcon test` runs and passes the tests each package names (its setup.cfg)."""
from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
from importlib.metadata import distribution
from pathlib import Path

import pytest

from cdpr_bringup.graph.launcher import graph_nodes
from conftest import REPO, settled_parameters

PACKAGES = ['cdpr_msgs_py', 'cdpr_control', 'cdpr_twin', 'cdpr_fdi', 'cdpr_bringup']


def console_scripts(package: str) -> list[str]:
    return [entry.name for entry in distribution(package).entry_points
            if entry.group == 'console_scripts']


COLCON = Path(sys.executable).parent / 'colcon'
# The checkout as docs/environment.md's workspace section clones it: the packages' tests are in tests/.
CHECKOUT = ['src', 'tests']


@pytest.fixture(scope='module')
def colcon_workspace(tmp_path_factory) -> Path:
    workspace = tmp_path_factory.mktemp('ws')
    for folder in CHECKOUT:
        shutil.copytree(REPO / folder, workspace / 'src' / 'cdpr' / folder,
                        ignore=shutil.ignore_patterns('*.egg-info', '__pycache__'))
    result = subprocess.run(
        [str(COLCON), '--log-base', 'log', 'build', '--base-paths', 'src/cdpr/src'],
        cwd=workspace, capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stdout + result.stderr
    return workspace


@pytest.fixture(scope='module')
def colcon_install(colcon_workspace) -> Path:
    return colcon_workspace / 'install'


@pytest.mark.workspace
@pytest.mark.parametrize('package', PACKAGES)
def test_package_is_in_the_ament_index(colcon_install, package):
    marker = colcon_install / package / 'share' / 'ament_index' / 'resource_index' / 'packages' / package
    assert marker.is_file()
    assert (colcon_install / package / 'share' / package / 'package.xml').is_file()


@pytest.mark.workspace
@pytest.mark.parametrize('package', PACKAGES)
def test_every_executable_lands_where_ros2_run_looks(colcon_install, package):
    scripts = console_scripts(package)
    # among them the package's nodes of the graph, a recorder's too (cdpr_msgs_py has none)
    assert {spec.executable for spec in graph_nodes(settled_parameters(), 'bag')
            if spec.package == package} <= set(scripts)
    for name in scripts:
        executable = colcon_install / package / 'lib' / package / name
        assert executable.is_file() and os.access(executable, os.X_OK), executable


@pytest.mark.workspace
def test_installed_executable_runs_from_the_workspace(colcon_install):
    site = [str(p) for p in colcon_install.glob('*/lib/python3*/site-packages')]
    environment = dict(os.environ, PYTHONPATH=os.pathsep.join(site),
                       AMENT_PREFIX_PATH=os.pathsep.join(str(colcon_install / p) for p in PACKAGES))
    script = colcon_install / 'cdpr_bringup' / 'lib' / 'cdpr_bringup' / 'cdpr-robot'
    result = subprocess.run([sys.executable, str(script), '--config', 'paper_robot.yaml'],
                            env=environment, capture_output=True, text=True, timeout=120,
                            cwd=colcon_install)
    assert result.returncode == 0, result.stderr
    assert 'cable 4 broken: SP = (0.5627, 1.2867' in result.stdout
    assert str(colcon_install) in result.stdout, 'config must come from the installed share dir'


# A few fast tests of each package's list: enough to show that colcon finds each list,
# runs it against the workspace's install and reports it; make test runs every one of
# them in its own session, where a failure is reported test by test.
PACKAGE_TESTS_SAMPLE = ' or '.join((
    'core_imports_no_rclpy', 'cable_mask', 'flatten_gives_ros_names',                  # cdpr_bringup
    'inverse_kinematics_zero_at_home', 'torque_limit_is_enforced', 'bad_names_and_bounds',  # cdpr_control
    'motor_reading_a_push_is_free',                                                   # cdpr_fdi
    'only_the_required_fields_are_checked',                                           # cdpr_msgs_py
    'each_window_counts_its_own_intervals'))                                          # cdpr_twin


@pytest.mark.workspace
def test_colcon_test_runs_each_packages_tests(colcon_workspace):
    # colcon takes an argument for pytest that looks like an option of its own with a space before it
    result = subprocess.run(
        [str(COLCON), '--log-base', 'log', 'test', '--base-paths', 'src/cdpr/src',
         '--event-handlers', 'console_direct-', '--pytest-args', ' -k', PACKAGE_TESTS_SAMPLE],
        cwd=colcon_workspace, capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stdout + result.stderr
    summary = subprocess.run([str(COLCON), 'test-result', '--test-result-base', 'build', '--all', '--verbose'],
                             cwd=colcon_workspace, capture_output=True, text=True, timeout=60)
    assert summary.returncode == 0, summary.stdout + summary.stderr
    # one result file per package (--all lists those without failures too), each with tests
    for package in PACKAGES:
        assert re.search(rf'build/{package}/pytest.xml: [1-9]\d* tests?, 0 errors, 0 failures',
                         summary.stdout), summary.stdout
    assert re.search(r'Summary: [1-9]\d* tests, 0 errors, 0 failures', summary.stdout), summary.stdout
