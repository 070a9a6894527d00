"""The packages build with colcon as a ROS 2 workspace would, and `ros2 run` would find them."""
from __future__ import annotations

import os
import shutil
import subprocess
import sys
from importlib.metadata import distribution
from pathlib import Path

import pytest

from conftest import REPO

PACKAGES = ['cdpr_msgs_py', 'cdpr_control', 'cdpr_twin', 'cdpr_fdi', 'cdpr_bringup']


def console_scripts(package: str) -> list[str]:
    return [entry.name for entry in distribution(package).entry_points
            if entry.group == 'console_scripts']


@pytest.fixture(scope='module')
def colcon_install(tmp_path_factory) -> Path:
    workspace = tmp_path_factory.mktemp('ws')
    shutil.copytree(REPO / 'src', workspace / 'src',
                    ignore=shutil.ignore_patterns('*.egg-info', '__pycache__'))
    colcon = Path(sys.executable).parent / 'colcon'
    result = subprocess.run(
        [str(colcon), '--log-base', 'log', 'build', '--base-paths', 'src'],
        cwd=workspace, capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stdout + result.stderr
    return workspace / 'install'


@pytest.mark.workspace
@pytest.mark.parametrize('package', PACKAGES)
def test_package_is_in_the_ament_index(colcon_install, package):
    marker = colcon_install / package / 'share' / 'ament_index' / 'resource_index' / 'packages' / package
    assert marker.is_file()
    assert (colcon_install / package / 'share' / package / 'package.xml').is_file()


@pytest.mark.workspace
@pytest.mark.parametrize('package', PACKAGES)
def test_every_executable_lands_where_ros2_run_looks(colcon_install, package):
    for name in console_scripts(package):
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
