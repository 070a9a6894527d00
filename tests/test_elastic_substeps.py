"""The elastic plant's sub-steps compiled by numba give the pure-Python ones' numbers, to
the last bit: one source (cdpr_twin.models.elastic_substeps), the same operations in the same
order, on every path (drive lags, speed filter, breakaway friction, pulleys, the
electromagnet's release and hanging mass, a push, slack cables, locked drums)."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from cdpr_bringup.runs.engine import run_inprocess
from cdpr_bringup.runs.settle import ScenarioOptions, build_scenario
from cdpr_control.setup.robot_file import load_robot
from cdpr_twin.models.elastic_model import ElasticCableRobot
from cdpr_control.kernels import KERNELS

from conftest import MOTIONS, PAPER_ROBOT

pytest.importorskip('numba')

RECORDED = ('angle_rad', 'angular_velocity_rad_s', 'command_nm', 'true_position_m',
            'true_tension_n', 'residual_nm', 'twin_torque_nm')


def test_a_field_run_with_a_failure_and_a_push_is_the_same_with_both_kernels():
    scenario = build_scenario(ScenarioOptions(
        config=str(PAPER_ROBOT), motions=str(MOTIONS), motion='along-2', fidelity='field',
        fail_cables=[4], fail_at_s=1.0, duration_s=2.0, pushes=[(0.4, 0.3, 0.0, 25.0, 0.0)]))
    # the pulleys are off by default: on, so that their path runs too
    drive = dataclasses.replace(scenario.plant.drive, pulley_radius_m=0.005)
    recordings = {name: run_inprocess(dataclasses.replace(
        scenario, plant=dataclasses.replace(scenario.plant, drive=drive, kernel=name)))
        for name in KERNELS}
    python, compiled = recordings['python'], recordings['compiled']
    # the electromagnet let go of cable 4 (0-based 3) within the run
    assert list(python.broken_at_s) == [3] and python.broken_at_s == compiled.broken_at_s
    # a cable went slack after the failure: the unilateral branch ran
    assert np.any(python.true_tension_n[:, 3] == 0.0)
    for field in RECORDED:
        assert np.array_equal(getattr(python, field), getattr(compiled, field)), field


def test_locked_drums_hold_the_same_with_both_kernels():
    robot = load_robot(PAPER_ROBOT)
    motors = np.array([np.full(robot.cable_count, robot.motor.inertia_kg_m2),
                       np.full(robot.cable_count, robot.motor.viscous_friction_nm_s_rad),
                       np.full(robot.cable_count, 0.1)])
    models = [ElasticCableRobot(robot, motors, robot.home_position_m + np.array([0.05, -0.02, 0.03]),
                                8, 3e5, 400.0, 0.1, kernel=name) for name in KERNELS]
    for model in models:
        model.break_cables([1])
        model.drums_locked = True
        for _ in range(50):
            model.step(np.full(robot.cable_count, -0.5), 0.002)
    python, compiled = models
    assert np.all(python.angular_velocity_rad_s == 0.0)
    for field in ('position_m', 'velocity_m_s', 'angle_rad', 'tension_n', 'motors'):
        assert np.array_equal(getattr(python, field), getattr(compiled, field)), field
