"""The plant's motors each off the model by their own factors (plant.elastic.mismatch:
a number, or a list of one factor per motor): a freed motor under a torque step follows
J_i θ̈ = c_i − b_i θ̇ − f_c,i sign θ̇ with its own J_i, b_i and f_c,i, on both elastic
plants; a factor given as a number is that factor repeated, to the bit; a list of
another length, or of a bad factor, is refused in one line naming its key and file."""
from __future__ import annotations

import copy

import numpy as np
import pytest

from cdpr_bringup.runs.engine import run_inprocess
from cdpr_bringup.runs.settle import ScenarioOptions, build_scenario
from cdpr_control.config import ConfigError, Section, load_config
from cdpr_control.setup.robot_file import load_robot
from cdpr_twin.models.plant import ELASTIC_MODELS, PlantConfig

from conftest import CONFIG_DIR, MOTIONS, PAPER_ROBOT

PLATFORM_ROBOT = CONFIG_DIR / 'robots' / 'crossed_platform_robot.yaml'
PLATFORM_MOTIONS = CONFIG_DIR / 'crossed_platform_motions.yaml'
MOTOR_KEYS = ('inertia', 'viscous_friction', 'static_friction')
PERIOD_S = 0.002
RECORDED = ('angle_rad', 'angular_velocity_rad_s', 'command_nm', 'true_position_m',
            'true_tension_n', 'residual_nm', 'twin_torque_nm')


def plant_with(robot_path, mismatch: dict) -> PlantConfig:
    """The robot file's elastic plant with `mismatch`'s factors."""
    robot = load_robot(robot_path)
    # a copy: the loaded document shares the cached defaults
    plant = copy.deepcopy(load_config(robot_path).data['plant'])
    plant['elastic']['mismatch'].update(mismatch)
    return PlantConfig.from_section(Section({'plant': plant}, 'set-up.yaml').section('plant'),
                                    robot.cable_count, 'elastic')


def spread_factors(rng, count: int) -> list[float]:
    """`count` factors from 0.6 to 1.8 in a random order, at least ~10 % apart: each
    motor's response then tells its factor from any other's."""
    return (rng.permutation(np.linspace(0.6, 1.8, count)) * rng.uniform(0.98, 1.02, count)).tolist()


@pytest.mark.parametrize('robot_path', [PAPER_ROBOT, PLATFORM_ROBOT], ids=['point_mass', 'platform'])
def test_each_freed_motor_answers_a_torque_step_with_its_own_inertia_and_friction(robot_path):
    rng = np.random.default_rng(51)
    robot = load_robot(robot_path)
    m, motor = robot.cable_count, robot.motor
    factors = {key: spread_factors(rng, m) for key in MOTOR_KEYS}
    config = plant_with(robot_path, factors)
    model = ELASTIC_MODELS[robot.body.kind](robot, config, robot.home_position_m, None)
    # every cable broken: the drums turn free, under their torque and friction alone
    model.break_cables(range(m))
    inertia = motor.inertia_kg_m2 * np.array(factors['inertia'])
    viscous = motor.viscous_friction_nm_s_rad * np.array(factors['viscous_friction'])
    coulomb = motor.static_friction_nm * np.array(factors['static_friction'])
    # well beyond the Coulomb friction (≤ 1.8 × the datasheet's), either way
    torque = rng.choice([-1.0, 1.0], m) * rng.uniform(1.0, 1.5, m)

    def closed_form(t, j, b, f):
        # J θ̈ = c − b θ̇ − f sign θ̇ from rest: θ̇ = (c − f sign c) / b · (1 − exp(−b t / J))
        return (torque - f * np.sign(torque)) / b * (1.0 - np.exp(-b * t / j))

    times = PERIOD_S * np.arange(1, 201)
    speeds = []
    for _ in times:
        model.step(torque, PERIOD_S)
        speeds.append(np.array(model.angular_velocity_rad_s))
    speeds = np.array(speeds)
    assert np.all(np.array(model.tension_n) == 0.0)
    # past the first 50 ms, where the tanh smoothing of the Coulomb friction has faded
    late = times >= 0.05
    expected = closed_form(times[late, None], inertia, viscous, coulomb)
    error = np.abs(speeds[late] - expected) / np.abs(expected)
    assert error.max() < 5e-3, error.max()
    # each motor's own factors, not another's: the nearest other motor's prediction is off
    # by many times that
    for i in range(m):
        for k in range(m):
            if k != i:
                theirs = closed_form(times[late, None], inertia[k], viscous[k], coulomb[k])[:, i]
                assert np.max(np.abs(speeds[late, i] - theirs) / np.abs(theirs)) > 0.02, (i, k)


def setup_file(tmp_path, robot_path, mismatch: dict):
    lines = [f'robot_file: {robot_path}', 'plant:', '  elastic:', '    mismatch:']
    lines += [f'      {key}: {value!r}' for key, value in mismatch.items()]
    path = tmp_path / 'setup.yaml'
    path.write_text('\n'.join(lines) + '\n')
    return path


@pytest.mark.parametrize('robot_path, motions, motion, cable', [
    (PAPER_ROBOT, MOTIONS, 'along-2', 4), (PLATFORM_ROBOT, PLATFORM_MOTIONS, 'climb-tilt', 5)],
    ids=['point_mass', 'platform'])
def test_a_factor_given_as_a_number_is_that_factor_for_every_motor_to_the_bit(tmp_path, robot_path, motions,
                                                                               motion, cable):
    robot = load_robot(robot_path)
    shipped = load_config(robot_path).section('plant').section('elastic').section('mismatch')
    repeated = {key: [shipped.number(key)] * robot.cable_count for key in MOTOR_KEYS}
    runs = {}
    for name, config in (('number', robot_path), ('list', setup_file(tmp_path, robot_path, repeated))):
        scenario = build_scenario(ScenarioOptions(
            config=str(config), motions=str(motions), motion=motion, fidelity='elastic',
            fail_cables=[cable], fail_at_s=1.0, duration_s=2.0))
        runs[name] = (scenario.plant, run_inprocess(scenario))
    (number_plant, number), (list_plant, listed) = runs['number'], runs['list']
    assert number_plant == list_plant
    assert list(number.broken_at_s) == [cable - 1]
    for field in RECORDED:
        assert np.array_equal(getattr(number, field), getattr(listed, field), equal_nan=True), field


@pytest.mark.parametrize('mismatch, key, problem', [
    ({'inertia': [1.05, 1.05, 1.05]}, 'plant.elastic.mismatch.inertia',
     'must be a number or a list of 4 numbers, one per cable'),
    ({'viscous_friction': [1.3] * 5}, 'plant.elastic.mismatch.viscous_friction',
     'must be a number or a list of 4 numbers, one per cable'),
    ({'static_friction': [0.5, -0.5, 0.5, 0.5]}, 'plant.elastic.mismatch.static_friction[1]',
     'must not be negative'),
    ({'inertia': [1.0, 1.0, 0.0, 1.0]}, 'plant.elastic.mismatch.inertia[2]', 'must be positive'),
    # one end-effector, one mass
    ({'mass': [1.02] * 4}, 'plant.elastic.mismatch.mass', 'must be a number'),
])
def test_a_list_of_another_length_or_a_bad_factor_is_refused_in_one_line_naming_key_and_file(
        tmp_path, mismatch, key, problem):
    path = setup_file(tmp_path, PAPER_ROBOT, mismatch)
    with pytest.raises(ConfigError) as refused:
        build_scenario(ScenarioOptions(config=str(path), motion='along-2', fidelity='elastic'))
    message = str(refused.value)
    assert '\n' not in message
    assert message.startswith(f"{path}: '{key}' {problem}"), message
