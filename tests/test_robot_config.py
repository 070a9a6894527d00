"""Loading robot configs: the paper's parameters (DESIGN §6) and errors naming key and file."""
from __future__ import annotations

import copy
import math

import numpy as np
import pytest
import yaml

from cdpr_bringup.paths import shipped_calibration
from cdpr_control.config import ConfigError, load_config, load_section
from cdpr_control.setup.robot_file import load_robot
from cdpr_fdi.settings.config import load_fdi_config
from cdpr_msgs_py import contract

from conftest import CONFIG_DIR, PAPER_ROBOT

# DESIGN §6: frame a x b x h, exit points at the upper vertices.
A, B, H = 1.688, 1.930, 2.438


def test_paper_robot_has_design_parameters(paper_robot):
    expected_exits = np.array([[0, 0, H], [0, B, H], [A, B, H], [A, 0, H]])
    np.testing.assert_allclose(paper_robot.exit_points_m, expected_exits, atol=1e-12)
    assert paper_robot.cable_count == 4
    assert contract.joint_names(paper_robot.cable_count) == ['motor_1', 'motor_2', 'motor_3', 'motor_4']
    assert paper_robot.mass_kg == pytest.approx(2.941)
    np.testing.assert_allclose(paper_robot.gravity_m_s2, [0.0, 0.0, -9.81])
    np.testing.assert_allclose(paper_robot.weight_wrench_n, [0.0, 0.0, -2.941 * 9.81])
    motor = paper_robot.motor
    assert motor.inertia_kg_m2 == pytest.approx(5.12e-4)
    assert motor.drum_radius_m == pytest.approx(0.036)
    assert motor.viscous_friction_nm_s_rad == pytest.approx(0.0015)
    assert motor.static_friction_nm == pytest.approx(0.2)
    assert motor.nominal_torque_nm == pytest.approx(1.3)
    # 3000 rpm in rad/s
    assert motor.nominal_speed_rad_s == pytest.approx(3000 * 2 * math.pi / 60)
    # the tension bound must be reachable with the motor's torque limit
    assert paper_robot.tension_max_n * motor.drum_radius_m <= motor.torque_limit_nm + 1e-12
    assert 0.0 <= paper_robot.tension_min_n < paper_robot.tension_max_n


def test_paper_control_period_and_threshold():
    assert load_section(PAPER_ROBOT, 'control').number('period_s') == pytest.approx(0.002)
    fdi = load_section(PAPER_ROBOT, 'fdi')
    assert fdi.number('epsilon_nm') == pytest.approx(0.03)
    # the shipped calibration of the elastic plant, made on this robot, loads and raises ε
    # above the noise-free one
    calibration = shipped_calibration(load_robot(PAPER_ROBOT).fingerprint(), 'elastic')
    assert calibration == CONFIG_DIR / 'fdi_calibration_elastic.yaml'
    calibrated = load_fdi_config(PAPER_ROBOT, load_robot(PAPER_ROBOT), calibration)
    assert calibrated.epsilon_nm > 0.03


def test_cable_length_offsets_are_distances_from_home(robot):
    # θ = 0 at home: l_i0 = |A_i − home|
    expected = np.linalg.norm(robot.exit_points_m - robot.home_position_m, axis=1)
    np.testing.assert_allclose(robot.cable_length_offset_m, expected, rtol=1e-15)
    assert np.all(robot.exit_points_m[:, 2] > robot.workspace_max_m[2])


def test_robot_arrays_are_read_only(paper_robot):
    with pytest.raises(ValueError):
        paper_robot.exit_points_m[0, 0] = 1.0


def test_cable_mask(paper_robot):
    np.testing.assert_array_equal(paper_robot.cable_mask([3]), [True, True, True, False])
    with pytest.raises(IndexError):
        paper_robot.cable_mask([4])


# ---- bad configs -------------------------------------------------------------------

def _paper_config():
    return yaml.safe_load(PAPER_ROBOT.read_text())


def _write(tmp_path, data, name='bad_robot.yaml'):
    path = tmp_path / name
    path.write_text(yaml.safe_dump(data))
    return path


def _drop_inertia(cfg):
    del cfg['robot']['motor']['inertia_kg_m2']


def _three_cables(cfg):
    cfg['robot']['exit_points_m'] = cfg['robot']['exit_points_m'][:3]


def _low_exit_point(cfg):
    cfg['robot']['exit_points_m'][2][2] = 2.0     # workspace top is 2.2 m


def _zero_mass(cfg):
    cfg['robot']['end_effector']['mass_kg'] = 0.0


def _negative_mass(cfg):
    cfg['robot']['end_effector']['mass_kg'] = -2.941


def _text_drum_radius(cfg):
    cfg['robot']['motor']['drum_radius_m'] = 'thirty-six mm'


def _text_in_exit_point(cfg):
    cfg['robot']['exit_points_m'][1] = [0.0, 'b', 2.438]


def _short_exit_point(cfg):
    cfg['robot']['exit_points_m'][3] = [1.688, 0.0]


def _inverted_tension_bounds(cfg):
    cfg['robot']['cables']['tension_max_n'] = 0.5


def _home_outside(cfg):
    cfg['robot']['home_position_m'] = [0.844, 0.965, 2.3]


def _gravity_up(cfg):
    cfg['robot']['gravity_m_s2'] = [0.0, 0.0, 9.81]


def _boolean_friction(cfg):
    cfg['robot']['motor']['viscous_friction_nm_s_rad'] = True


def _missing_section(cfg):
    del cfg['robot']['cables']


def _coinciding_exit_points(cfg):
    x, y, z = cfg['robot']['exit_points_m'][0]
    cfg['robot']['exit_points_m'][3] = [x + 0.0005, y, z]


def _collinear_exit_points(cfg):
    cfg['robot']['exit_points_m'] = [[0.4 * i, 0.4 * i, 2.5] for i in range(4)]


def _exit_points_in_a_plane_through_the_workspace(cfg):
    # a vertical plane at x = 0.8 m: at those poses no cable pulls along x
    cfg['robot']['exit_points_m'] = [[0.8, 0.0, 2.4], [0.8, 1.9, 2.4], [0.8, 0.0, 3.0], [0.8, 1.9, 3.0]]


BAD_CONFIGS = [
    (_drop_inertia, 'robot.motor.inertia_kg_m2'),
    (_three_cables, 'robot.exit_points_m'),
    (_low_exit_point, 'robot.exit_points_m[2]'),
    (_zero_mass, 'robot.end_effector.mass_kg'),
    (_negative_mass, 'robot.end_effector.mass_kg'),
    (_text_drum_radius, 'robot.motor.drum_radius_m'),
    (_text_in_exit_point, 'robot.exit_points_m[1]'),
    (_short_exit_point, 'robot.exit_points_m[3]'),
    (_inverted_tension_bounds, 'robot.cables.tension_max_n'),
    (_home_outside, 'robot.home_position_m'),
    (_gravity_up, 'robot.gravity_m_s2'),
    (_boolean_friction, 'robot.motor.viscous_friction_nm_s_rad'),
    (_missing_section, 'robot.cables'),
    (_coinciding_exit_points, 'robot.exit_points_m[3]'),
    (_collinear_exit_points, 'robot.exit_points_m'),
    (_exit_points_in_a_plane_through_the_workspace, 'robot.exit_points_m'),
]


@pytest.mark.parametrize('mutate, key', BAD_CONFIGS, ids=[m.__name__.lstrip('_') for m, _ in BAD_CONFIGS])
def test_bad_config_names_key_and_file(tmp_path, mutate, key):
    cfg = _paper_config()
    mutate(cfg)
    path = _write(tmp_path, cfg)
    with pytest.raises(ConfigError) as info:
        load_robot(path)
    message = str(info.value)
    assert str(path) in message
    assert f"'{key}'" in message
    assert info.value.key == key
    assert info.value.path == str(path)


def test_unmodified_copy_loads(tmp_path):
    # the mutation harness itself must not break a good config
    path = _write(tmp_path, copy.deepcopy(_paper_config()), 'good.yaml')
    robot = load_robot(path)
    np.testing.assert_array_equal(robot.exit_points_m, load_robot(PAPER_ROBOT).exit_points_m)


def test_missing_file_names_the_file(tmp_path):
    path = tmp_path / 'no_such_robot.yaml'
    with pytest.raises(ConfigError) as info:
        load_robot(path)
    assert str(path) in str(info.value)


def test_invalid_yaml_names_the_file(tmp_path):
    path = tmp_path / 'broken.yaml'
    path.write_text('robot: [unclosed\n')
    with pytest.raises(ConfigError) as info:
        load_robot(path)
    assert str(path) in str(info.value)


def test_config_error_is_a_value_error(tmp_path):
    cfg = _paper_config()
    _zero_mass(cfg)
    with pytest.raises(ValueError):
        load_robot(_write(tmp_path, cfg))


def test_eight_cable_robot_loads(eight_cable_robot):
    assert eight_cable_robot.cable_count == 8
    assert eight_cable_robot.mass_kg == pytest.approx(5.0)
    assert len(set(eight_cable_robot.exit_points_m[:, 2])) > 1   # irregular heights


# ---- robot files and set-ups ------------------------------------------------------------

def test_shipped_robot_files_hold_the_robot_alone():
    files = sorted((CONFIG_DIR / 'robots').glob('*.yaml'))
    assert len(files) == 5
    for path in files:
        assert list(yaml.safe_load(path.read_text())) == ['robot'], path


def test_a_set_up_takes_its_robot_from_the_robot_file_and_its_options_from_itself():
    setup = load_config(CONFIG_DIR / 'tall_frame_robot.yaml')
    robot = load_config(CONFIG_DIR / 'robots' / 'tall_frame_robot.yaml')
    assert setup.data['robot'] == robot.data['robot']
    assert not setup.section('fdi').is_default('identification_delta_n')
    assert robot.section('fdi').is_default('identification_delta_n')
    assert (setup.section('fdi').number('identification_delta_n')
            != robot.section('fdi').number('identification_delta_n'))
    assert setup.section('fdi').is_default('epsilon_nm')


def test_a_bad_robot_in_a_set_up_names_the_robot_file(tmp_path):
    robot = _paper_config()
    robot['robot']['end_effector']['mass_kg'] = -1.0
    (tmp_path / 'robots').mkdir()
    robot_path = _write(tmp_path / 'robots', robot, 'mine.yaml')
    setup = _write(tmp_path, {'robot_file': 'robots/mine.yaml', 'control': {'stale_cycles': 40}}, 'setup.yaml')
    with pytest.raises(ConfigError) as error:
        load_robot(setup)
    assert str(robot_path) in str(error.value) and 'robot.' in str(error.value)
    assert load_config(setup).section('control').integer('stale_cycles') == 40


@pytest.mark.parametrize('setup, problem', [
    ({'robot_file': 'robots/absent.yaml'}, 'which is not a file'),
    ({'robot_file': 'robot.yaml', 'robot': {}}, 'not both'),
])
def test_a_set_up_that_names_no_robot_file_is_one_error_naming_the_key(tmp_path, setup, problem):
    _write(tmp_path, _paper_config(), 'robot.yaml')
    path = _write(tmp_path, setup, 'setup.yaml')
    with pytest.raises(ConfigError, match=problem) as error:
        load_config(path)
    assert f"{path}: 'robot_file'" in str(error.value)
