"""The point mass's rigid sub-steps compiled by numba give the pure-Python ones' numbers,
to the last bit: one source (cdpr_control.point_mass.substeps), the same operations in
the same order, on every path (taut cables, a cable going slack and taut again, a broken
cable's free motor, a push, several sub-steps, locked drums)."""
from __future__ import annotations

import numpy as np
import pytest

from cdpr_control.point_mass.dynamics import direct_dynamics
from cdpr_control.kernels import KERNELS
from cdpr_control.setup.robot_file import load_robot
from cdpr_twin.models.rigid_model import RigidModel

from conftest import PAPER_ROBOT

pytest.importorskip('numba')

STATE = ('position_m', 'velocity_m_s', 'angle_rad', 'angular_velocity_rad_s', 'tension_n', 'taut')


def test_a_run_through_slack_a_break_and_a_push_is_the_same_with_both_kernels():
    robot = load_robot(PAPER_ROBOT)
    start = robot.home_position_m + np.array([0.1, -0.05, 0.0])
    models = {name: RigidModel(robot, start, substeps=3, kernel=name) for name in KERNELS}
    holding = -robot.motor.drum_radius_m * models['python'].tension_n
    slack_seen = np.zeros(robot.cable_count, dtype=bool)
    for k in range(600):
        # cable 2's drum pays out for 0.1 s (slack), then winds back in (taut again)
        torque = holding.copy()
        torque[1] += 2.0 if 50 <= k < 70 else (-2.0 if 70 <= k < 90 else 0.0)
        push = (15.0, 0.0, -10.0) if 300 <= k < 320 else (0.0, 0.0, 0.0)
        if k == 200:
            for model in models.values():
                model.break_cables([3])
        for model in models.values():
            model.step(torque, 0.002, external_force_n=push)
        python, compiled = models['python'], models['compiled']
        slack_seen |= python.attached & ~python.taut
        for field in STATE:
            assert np.array_equal(getattr(python, field), getattr(compiled, field)), (k, field)
    assert slack_seen[1], 'cable 2 never went slack: the slack branch did not run'
    assert python.tension_n[3] == 0.0 and np.all(python.tension_n[[0, 1, 2]] > 0.0)


def test_locked_drums_hold_the_same_with_both_kernels():
    robot = load_robot(PAPER_ROBOT)
    models = [RigidModel(robot, robot.home_position_m, kernel=name) for name in KERNELS]
    for model in models:
        model.step(np.full(robot.cable_count, -0.5), 0.002)
        model.drums_locked = True
        model.step(np.full(robot.cable_count, -0.5), 0.002)
    python, compiled = models
    assert np.all(python.angular_velocity_rad_s == 0.0) and np.all(python.velocity_m_s == 0.0)
    for field in STATE:
        assert np.array_equal(getattr(python, field), getattr(compiled, field)), field


def test_direct_dynamics_is_the_same_with_both_kernels():
    """tests/test_dynamics.py checks the compiled one against the inverse dynamics."""
    robot = load_robot(PAPER_ROBOT)
    rng = np.random.default_rng(5)
    for _ in range(20):
        position = robot.home_position_m + rng.uniform(-0.2, 0.2, 3)
        velocity, torque = rng.normal(0.0, 0.5, 3), rng.normal(-0.3, 0.3, robot.cable_count)
        speed, attached = rng.normal(0.0, 5.0, robot.cable_count), rng.random(robot.cable_count) < 0.8
        python, compiled = (direct_dynamics(robot, position, velocity, torque, speed, attached, kernel=name)
                            for name in ('python', 'compiled'))
        for field in ('acceleration_m_s2', 'joint_acceleration_rad_s2', 'tension_n', 'taut'):
            assert np.array_equal(getattr(python, field), getattr(compiled, field)), field
