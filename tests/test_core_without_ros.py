"""The core runs without ROS: importing the model, controller, twin, plants, FDI,
recovery and the in-process engine loads no rclpy (docs/architecture.md)."""
from __future__ import annotations

import subprocess
import sys

CORE = ['cdpr_msgs_py.contract', 'cdpr_msgs_py.stamps', 'cdpr_msgs_py.health', 'cdpr_msgs_py.sole_writer',
        'cdpr_control.control.controller', 'cdpr_control.point_mass.dynamics', 'cdpr_control.model.reference_table',
        'cdpr_control.control.setpoints', 'cdpr_control.setup.settings', 'cdpr_fdi.supervision.monitor',
        'cdpr_control.control.reference_schedule',
        'cdpr_twin.models.twin', 'cdpr_twin.models.plant', 'cdpr_twin.nodes.run_length', 'cdpr_twin.nodes.joint_mapping',
        'cdpr_fdi.supervision.supervisor', 'cdpr_fdi.recovery_planning.recovery', 'cdpr_fdi.recovery_strategies',
        'cdpr_fdi.detection.calibration', 'cdpr_fdi.view.markers',
        'cdpr_bringup.runs.engine', 'cdpr_bringup.runs.settle']


def test_the_core_imports_no_rclpy():
    script = ('import importlib, sys\n'
              f'for name in {CORE!r}:\n'
              '    importlib.import_module(name)\n'
              'print(sorted(m for m in sys.modules if m.split(".")[0] in ("rclpy", "rosidl_runtime_py")))\n')
    result = subprocess.run([sys.executable, '-c', script], capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip() == '[]', result.stdout
