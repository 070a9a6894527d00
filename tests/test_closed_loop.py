"""The closed loop in one process: twin, plant fidelities and failure injection; the
plant's holding torque and torque limit."""
from __future__ import annotations

import numpy as np
import pytest

from cdpr_bringup.runs.engine import run_inprocess
from cdpr_bringup.runs.metrics import twin_kpis
from cdpr_bringup.runs.settle import ScenarioOptions
from cdpr_control.point_mass.kinematics import structure_matrix
from cdpr_twin.models.plant import PlantSimulator

from conftest import every_tick_scenario


@pytest.fixture(scope='module')
def rigid_run():
    scenario = every_tick_scenario(ScenarioOptions(motion='along-2', fidelity='rigid'))
    return scenario, run_inprocess(scenario)


def test_rigid_plant_is_the_twin_when_nothing_fails(rigid_run):
    scenario, recording = rigid_run
    kpi = twin_kpis(scenario.robot, recording)
    assert kpi['K_j_rad'] == 0.0 and kpi['K_t_nm'] == 0.0 and kpi['K_c_m'] < 1e-12
    # the plant's figures of a failure-free run: over every tick
    assert recording.figures['detection']['tracking_error_m'] < 1e-3


def test_elastic_plant_tracks_within_5_mm_and_stays_taut():
    scenario = every_tick_scenario(ScenarioOptions(motion='circle', fidelity='elastic'))
    recording = run_inprocess(scenario)
    assert recording.figures['detection']['tracking_error_m'] < 0.005
    assert recording.true_tension_n.min() > 0.0
    kpi = twin_kpis(scenario.robot, recording)
    # the elastic plant differs from the twin, by about the paper's orders of magnitude
    assert 1e-4 < kpi['K_c_m'] < 0.05 and 1e-3 < kpi['K_j_rad'] < 0.2 and 0.01 < kpi['K_t_nm'] < 1.0


def test_injected_failure_frees_the_motor_but_not_the_twin(rigid_run):
    healthy_scenario, healthy = rigid_run
    scenario = every_tick_scenario(ScenarioOptions(motion='along-2', fidelity='rigid', fail_cables=[4]))
    broken = run_inprocess(scenario)
    failure = scenario.failure_time_s
    assert failure == pytest.approx(scenario.motion.time_at_fraction(0.5))
    # the failure run goes on for the recovery; compare the motion both runs share
    n = healthy.time_s.size
    after = broken.time_s[:n] > failure + scenario.period_s
    before = broken.time_s[:n] <= failure
    # the rest of the motion, half of it at least, is judged after the failure
    motion_left_s = scenario.motion.trajectory.duration_s - failure
    assert np.count_nonzero(after) >= 0.5 * motion_left_s / scenario.period_s
    # the twin never sees the plant: identical with and without the failure
    np.testing.assert_array_equal(broken.twin_torque_nm[:n], healthy.twin_torque_nm)
    # the plant: identical up to the failure, then cable 4 carries nothing ...
    np.testing.assert_array_equal(broken.angle_rad[:n][before], healthy.angle_rad[before])
    assert np.all(broken.true_tension_n[:n][after, 3] == 0.0)
    # ... and motor 4 is a free rotor: its speed follows J θ̈ = −b θ̇ + c
    motor = scenario.robot.motor
    k = int(np.flatnonzero(after)[5])
    speed, period = broken.angular_velocity_rad_s[:, 3], scenario.period_s
    predicted = speed[k] + period * (broken.command_nm[k, 3] - motor.viscous_friction_nm_s_rad * speed[k]) / motor.inertia_kg_m2
    assert speed[k + 1] == pytest.approx(predicted, rel=1e-9)
    assert np.max(np.abs(broken.command_nm[:n][after] - healthy.command_nm[after])) > 0.1


@pytest.fixture(scope='module')
def circle_scenario():
    return every_tick_scenario(ScenarioOptions(motion='circle', fidelity='rigid'))


def test_holding_torque_keeps_the_plant_where_it_starts_on_the_cables_left(circle_scenario):
    robot, start = circle_scenario.robot, circle_scenario.reference.position_m[0]
    plant = PlantSimulator(robot, circle_scenario.plant, start)
    holding = plant.holding_torque_nm()
    # the drum turns the rigid plant's static tensions into torque: c = −ρ t
    np.testing.assert_allclose(holding, -robot.motor.drum_radius_m * plant.tension_n, rtol=1e-12)
    for _ in range(250):   # half a second
        plant.step(holding, circle_scenario.period_s)
    np.testing.assert_array_equal(plant.position_m, start)
    # without cable 4 the other three balance the weight alone: S t = −m_e g
    plant.inject_failure(3)
    tensions = -plant.holding_torque_nm() / robot.motor.drum_radius_m
    structure, _ = structure_matrix(robot, plant.position_m)
    assert tensions[3] == 0.0 and np.all(tensions[:3] > 0.0)
    np.testing.assert_allclose(structure @ tensions, -robot.weight_wrench_n, atol=1e-9)


def test_the_motors_apply_a_command_within_their_torque_limit(circle_scenario):
    robot, start = circle_scenario.robot, circle_scenario.reference.position_m[0]
    limit = robot.motor.torque_limit_nm
    plant = PlantSimulator(robot, circle_scenario.plant, start)
    command = np.array([-3.0 * limit, -0.5, 0.25, 2.0 * limit])
    np.testing.assert_array_equal(plant.applied_torque_nm(command), [-limit, -0.5, 0.25, limit])
    # and a step applies just that
    within = PlantSimulator(robot, circle_scenario.plant, start)
    plant.step(command, circle_scenario.period_s)
    within.step(np.array([-limit, -0.5, 0.25, limit]), circle_scenario.period_s)
    np.testing.assert_array_equal(plant.model.angle_rad, within.model.angle_rad)
    np.testing.assert_array_equal(plant.position_m, within.position_m)
    assert np.any(plant.position_m != start)
