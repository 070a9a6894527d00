"""The `field` plant: its physics, and its figures beside the paper's real robot (§5).

The calibration figures (issue 15): on the failure-free circle K_c, K_j, K_t within
±30 % of the paper's; with the paper's detector (threshold, ε = 0.3 N·m) the median
detection delay of the Table 4 motions (failure at the midpoint, counted from the
electromagnet's signal as the paper counts) within ±30 % of Table 5's, and those of
Table 6 and of the circle within ±30 % of Table 7's and of 190 ms. What the field plant
does not reproduce is marked xfail (strict: it fails the suite once it passes), with the
reason, and only a figure off the paper's (an AssertionError) counts as that failure; what
must hold around it (the run detected, the cable named) is judged in tests of its own.
docs/field-plant.md has the whole table.
"""
from __future__ import annotations

import copy
import dataclasses
import math
import statistics
import time

import numpy as np
import pytest
import yaml

from cdpr_bringup.runs.engine import run_inprocess
from cdpr_bringup.paths import DEFAULT_ROBOT, config_file
from cdpr_bringup.runs.metrics import PAPER_KPI
from cdpr_bringup.scenario.command import metrics_of
from cdpr_bringup.runs.settle import ScenarioOptions, build_scenario
from cdpr_twin.models.elastic_model import swivel_pulley_length_m
from cdpr_control.config import ConfigError, Section, load_config
from cdpr_twin.models.plant import PlantConfig, PlantSimulator

# Paper §5.2: Tables 5 (along cable 4) and 7 (orthogonal), forward and backward (ms);
# §5.3: the circle, failure after 135° of arc.
PAPER_ALONG_MS = {1: (50, 80), 2: (60, 30), 3: (60, 40), 4: (50, 60)}
PAPER_ORTHOGONAL_MS = {1: (230, 210), 2: (290, 230), 3: (270, 210), 4: (200, 240)}
PAPER_CIRCLE_MS = 190.0
PAPER_EPSILON_NM = 0.3
TOLERANCE = 0.3
# Detections come within 0.3 s of the signal: the recovery after them is not needed.
RECOVERY_BUDGET_S = 0.5
# Once the cable has really parted, the detector needs a few periods.
DETECTED_AFTER_PARTING_MS = 20.0


def within(value, paper) -> bool:
    return abs(value - paper) <= TOLERANCE * paper


def field_run(motion: str, reverse: bool = False, fail: bool = True) -> dict:
    options = ScenarioOptions(
        motion=motion, reverse=reverse, fail_cables=[4] if fail else [],
        fail_at_fraction=(0.375 if motion == 'circle' else None) if fail else None,
        fidelity='field', detector='threshold', epsilon_nm=PAPER_EPSILON_NM,
        recovery_budget_s=RECOVERY_BUDGET_S)
    scenario = build_scenario(options)
    start = time.perf_counter()
    recording = run_inprocess(scenario)
    return metrics_of(scenario, recording, time.perf_counter() - start)


@pytest.fixture(scope='module')
def circle_without_failure():
    return field_run('circle', fail=False)


@pytest.fixture(scope='module')
def along_runs():
    return [field_run(f'along-{motion}', reverse) for motion in PAPER_ALONG_MS
            for reverse in (False, True)]


@pytest.fixture(scope='module')
def orthogonal_runs():
    return [field_run(f'orthogonal-{motion}') for motion in PAPER_ORTHOGONAL_MS]


@pytest.fixture(scope='module')
def circle_with_failure():
    return field_run('circle')


def assert_detected_soon_after_parting_and_named(runs, count):
    """Each of the `count` runs detected its failure of cable 4, named it and no other,
    and (their median) within a few periods of the real parting."""
    assert len(runs) == count
    assert not any(run['false_alarm'] for run in runs)
    assert None not in [run['detection_delay_from_signal_ms'] for run in runs]
    assert all(run['identified_cables'] == [4] for run in runs)
    assert statistics.median(run['detection_delay_ms'] for run in runs) < DETECTED_AFTER_PARTING_MS


# ---- physics -------------------------------------------------------------------------

@pytest.mark.parametrize('key, value', [('command_delay_s', -0.001), ('torque_lag_s', 0.5),
                                        ('pulley_radius_m', -0.005)])
def test_a_field_value_out_of_its_range_is_refused_naming_its_key(key, value):
    # a copy: the loaded document shares the cached defaults
    plant = copy.deepcopy(load_config(config_file(DEFAULT_ROBOT)).data['plant'])
    plant['field'][key] = value
    with pytest.raises(ConfigError, match=f"plant.field.{key}"):
        PlantConfig.from_section(Section({'plant': plant}, 'set-up.yaml').section('plant'), 4, 'field')


def test_the_electromagnet_must_be_on_a_cable_of_the_robot():
    scenario = build_scenario(ScenarioOptions(motion='along-2', fidelity='field'))
    config = dataclasses.replace(scenario.plant, electromagnet_cable=scenario.robot.cable_count)
    with pytest.raises(ValueError, match='electromagnet.cable 5'):
        PlantSimulator(scenario.robot, config, scenario.reference.position_m[0])


def test_a_cable_over_a_swivel_pulley_pulls_along_its_free_length():
    """The gradient of the length over the pulley with respect to the end-effector is the
    unit vector from the tangent point to it (a string's length changes only along its
    free end), and a pulley of no radius is the point exit of the rigid model."""
    exits = np.array([[0.0, 0.0, 2.438], [1.688, 1.93, 2.438]])
    p = np.array([0.9, 0.7, 1.25])
    radius = 0.005
    step = 1e-7
    gradient = np.array([(swivel_pulley_length_m(exits, p + step * e, radius)
                          - swivel_pulley_length_m(exits, p - step * e, radius)) / (2 * step)
                         for e in np.eye(3)]).T
    assert np.allclose(np.linalg.norm(gradient, axis=1), 1.0, atol=1e-6)
    # The free length leaves the pulley below and beside the exit point: its direction
    # is off the straight line to A by about r / d.
    straight = (p - exits) / np.linalg.norm(p - exits, axis=1)[:, None]
    angle = np.arccos(np.sum(gradient * straight, axis=1))
    assert np.all(angle < 2 * radius / np.linalg.norm(p - exits, axis=1))
    assert np.allclose(swivel_pulley_length_m(exits, p, 1e-12), np.linalg.norm(p - exits, axis=1))
    # The wrap makes the cable longer than the straight line, by less than r π.
    excess = swivel_pulley_length_m(exits, p, radius) - np.linalg.norm(p - exits, axis=1)
    assert np.all((excess > 0) & (excess < radius * math.pi))


def test_the_electromagnet_lets_go_when_its_holding_force_falls_to_the_tension():
    """Switched off, the magnet holds F_0 e^{-t/T_r}: the cable parts when that no longer
    exceeds its tension plus the spring's force, and not before."""
    scenario = build_scenario(ScenarioOptions(motion='along-2', fidelity='field'))
    config = scenario.plant
    start = scenario.reference.position_m[0]
    plant = PlantSimulator(scenario.robot, config, start)
    cable = config.electromagnet_cable
    tension = plant.tension_n[cable]
    plant.inject_failure(cable)
    assert cable not in plant.broken
    holding = plant.holding_torque_nm()
    while cable not in plant.broken:
        plant.step(holding, scenario.period_s)
    expected_s = config.electromagnet_release_time_constant_s * math.log(
        config.electromagnet_holding_force_n / (tension + config.electromagnet_spring_force_n))
    substep_s = scenario.period_s / config.substeps
    assert abs(plant.broken_at_s[cable] - expected_s) <= 2 * substep_s
    assert plant.tension_n[cable] == 0.0


def test_a_cable_without_the_electromagnet_parts_at_once():
    scenario = build_scenario(ScenarioOptions(motion='along-2', fidelity='field'))
    plant = PlantSimulator(scenario.robot, scenario.plant, scenario.reference.position_m[0],
                           failures=[(0.003, 0)])
    for _ in range(3):
        plant.step(plant.holding_torque_nm(), scenario.period_s)
    assert plant.broken == [0] and plant.broken_at_s[0] == pytest.approx(0.003)


def test_the_drive_applies_a_command_after_its_transport_delay():
    """A torque step sent at t = 0 moves the drum only once `command_delay_s` has passed."""
    scenario = build_scenario(ScenarioOptions(motion='along-2', fidelity='field'))
    config = dataclasses.replace(scenario.plant, torque_noise_nm=0.0, command_delay_s=0.0015)
    plant = PlantSimulator(scenario.robot, config, scenario.reference.position_m[0])
    hold = plant.holding_torque_nm()
    kick = hold + np.array([0.5, 0.0, 0.0, 0.0])     # 0.5 N·m: ~1000 rad/s² on the drum
    plant.step(kick, 0.001)                          # due at 1.5 ms: not yet applied
    assert abs(plant.model.angular_velocity_rad_s[0]) < 0.01
    plant.step(hold, 0.001)                          # the kick acts from 1.5 to 2 ms
    assert plant.model.angular_velocity_rad_s[0] > 0.1


# ---- the paper's figures ---------------------------------------------------------------

def test_failure_free_circle_torque_gap_is_the_papers(circle_without_failure):
    assert not circle_without_failure['false_alarm'] and circle_without_failure['detection_time_s'] is None
    assert within(circle_without_failure['kpi']['K_t_nm'], PAPER_KPI['K_t_nm'])


def test_failure_free_circle_position_gaps_are_measured_and_below_the_papers(circle_without_failure):
    """The shortfall the xfail below names: gaps there are, but the stiff joint PD keeps
    them under the paper's."""
    kpi = circle_without_failure['kpi']
    assert 0.0 < kpi['K_c_m'] < PAPER_KPI['K_c_m']
    assert 0.0 < kpi['K_j_rad'] < PAPER_KPI['K_j_rad']


@pytest.mark.xfail(strict=True, raises=AssertionError, reason=(
    "K_c and K_j stay far below the paper's (0.4 mm, 0.007 rad): with the controller's 12 Hz joint PD "
    "(~24 N·m/rad) a joint gap of 0.058 rad would take ~1.4 N·m, nine times the paper's "
    "K_t; see docs/field-plant.md"))
def test_failure_free_circle_position_gaps_are_the_papers(circle_without_failure):
    kpi = circle_without_failure['kpi']
    assert within(kpi['K_c_m'], PAPER_KPI['K_c_m']) and within(kpi['K_j_rad'], PAPER_KPI['K_j_rad'])


def test_along_cable_4_the_median_delay_is_table_5s(along_runs):
    delays = [run['detection_delay_from_signal_ms'] for run in along_runs]
    assert None not in delays and not any(run['false_alarm'] for run in along_runs)
    paper = statistics.median(d for pair in PAPER_ALONG_MS.values() for d in pair)
    assert within(statistics.median(delays), paper)
    # Most of it is the electromagnet letting go.
    assert statistics.median(run['detection_delay_ms'] for run in along_runs) < DETECTED_AFTER_PARTING_MS


def test_every_orthogonal_failure_is_detected_soon_after_the_parting_and_named(orthogonal_runs):
    """What the xfail below leaves out: the figure is off, the detection is not."""
    assert_detected_soon_after_parting_and_named(orthogonal_runs, len(PAPER_ORTHOGONAL_MS))


@pytest.mark.xfail(strict=True, raises=AssertionError, reason=(
    'the detector sees the freed motor within a few ms of the real parting, which the '
    'electromagnet delays by its release (~80 ms at the ~10 N of cable 4 here); the '
    "paper's slow rise after it (Fig. 18) is not produced: docs/field-plant.md"))
def test_orthogonal_to_cable_4_the_median_delay_is_table_7s(orthogonal_runs):
    paper = statistics.median(pair[0] for pair in PAPER_ORTHOGONAL_MS.values())
    assert within(statistics.median(run['detection_delay_from_signal_ms']
                                    for run in orthogonal_runs), paper)


def test_orthogonal_failures_are_detected_later_than_along_ones(along_runs, orthogonal_runs):
    """The ordering of Tables 5 and 7: cable 4 carries less on the orthogonal motions, so
    the magnet lets it go later (and its motor loses less load)."""
    assert (statistics.median(run['detection_delay_from_signal_ms'] for run in orthogonal_runs)
            > 1.2 * statistics.median(run['detection_delay_from_signal_ms'] for run in along_runs))


def test_every_cable_4_failure_along_it_is_named(along_runs):
    """The supervisor knows its drives' delay (fdi.drive_delay_s, in the field calibration):
    the freed motor's tension estimate then uses the torque it felt, and only cable 4 is
    named (without it, the diagonal cable 2, slack too, was named on three of 8 runs)."""
    assert all(run['identified_cables'] == [4] for run in along_runs)


# Breaks of cable 4 at random instants (cdpr-campaign --random-instants, seeds 0-2) that
# named cable 2 or 3, or nothing, when the supervisor judged each period's tension
# estimate and residual alone, or weighed the end-effector with the stiffer line's 5 N:
# (motion, reverse, failure instant s, seed, detector).
SCRAMBLED_BREAKS = [('along-1', False, 3.2093918881801704, 0, 'threshold'),
                    ('along-2', False, 3.810394557891776, 1, 'threshold'),
                    ('along-3', False, 3.896318899874333, 2, 'cusum'),
                    ('along-4', False, 4.871050637747751, 0, 'cusum'),
                    ('along-1', True, 2.721952733371368, 2, 'threshold')]


@pytest.mark.parametrize('motion, reverse, failure_s, seed, detector', SCRAMBLED_BREAKS)
def test_a_freed_motor_swinging_under_a_lagging_drive_is_named_and_recovered(
        motion, reverse, failure_s, seed, detector):
    """The freed motor's one-period tension estimate swings by ±10 N and its residual
    changes sign while the diagonal cable 2 unloads: judged on the alarm's periods
    averaged (the field calibration's fdi.identification_window_cycles), cable 4 and no
    other is named before cable 2 goes slack, and the end-effector reaches its safe point."""
    scenario = build_scenario(ScenarioOptions(
        motion=motion, reverse=reverse, fail_cables=[4], fail_at_s=failure_s,
        fidelity='field', seed=seed, detector=detector))
    run = metrics_of(scenario, run_inprocess(scenario), 0.0)
    assert run['identified_cables'] == [4]
    assert run['mode'] == 'SAFE_HOLD' and run['recovery']['reached_safe_point']


# Drives at the ends of their plausible range (docs/identification.md): the same breaks
# named cable 2 or 3 when an alarm that lapsed for a tick while the freed motor swung
# started its average afresh; with the drive two periods late the freed motor swings at
# its torque limit and reads tens of newtons of either sign: nothing was named, and at
# the corner of the range (4 ms, 2 ms lag, noise x3) cable 4 when it slackened 0.8 s
# after cable 2 had parted; with no current-loop lag (seed 2) the diagonal cable 2 went
# slack 12 ms after cable 4 parted while the alarm lapsed, and both were named after a
# push's 3 s hold. (plant.field and resolver changes, motion, reverse, cable, s, seed,
# detector)
DRIVES_AT_THEIR_ENDS = [
    ({'torque_lag_s': 0.0}, 'along-1', True, 4, 2.8364844970960377, 0, 'threshold'),
    ({'torque_lag_s': 0.0}, 'along-2', True, 4, 2.5817670155279826, 0, 'threshold'),
    ({'noise': 0.5}, 'along-2', True, 4, 2.5817670155279826, 0, 'threshold'),
    ({'noise': 3.0}, 'along-1', True, 4, 2.8364844970960377, 0, 'threshold'),
    ({'command_delay_s': 0.002}, 'along-2', True, 4, 2.5817670155279826, 0, 'threshold'),
    ({'command_delay_s': 0.004}, 'along-3', False, 1, 4.412554441744373, 0, 'threshold'),
    ({'command_delay_s': 0.004}, 'orthogonal-1', True, 3, 2.6768229776644965, 0, 'cusum'),
    ({'command_delay_s': 0.004, 'torque_lag_s': 0.002, 'noise': 3.0}, 'along-4', True, 2,
     2.3904893181247853, 0, 'threshold'),
    ({'torque_lag_s': 0.0}, 'along-1', True, 4, 2.721952733371368, 2, 'threshold')]


@pytest.mark.parametrize('drive, motion, reverse, cable, failure_s, seed, detector', DRIVES_AT_THEIR_ENDS)
def test_a_freed_motor_is_named_across_the_drives_plausible_range(drive, motion, reverse, cable,
                                                                  failure_s, seed, detector, tmp_path):
    setup = drive_setup(tmp_path, drive)
    scenario = build_scenario(ScenarioOptions(
        config=str(setup), motion=motion, reverse=reverse, fail_cables=[cable], fail_at_s=failure_s,
        fidelity='field', seed=seed, detector=detector))
    run = metrics_of(scenario, run_inprocess(scenario), 0.0)
    assert run['identified_cables'] == [cable] and run['mode'] == 'SAFE_HOLD'


def drive_setup(folder, drive: dict):
    """A set-up of the paper robot whose field plant has the `drive` values (plant.field
    keys, and 'noise': a factor on the torque and resolver noise), written in `folder`."""
    drive = dict(drive)
    noise = drive.pop('noise', 1.0)
    defaults = load_config(config_file(DEFAULT_ROBOT)).section('plant')
    resolver = defaults.section('elastic').section('resolver')
    field = {'torque_noise_nm': defaults.section('field').number('torque_noise_nm') * noise, **drive}
    setup = folder / 'drive.yaml'
    setup.write_text(yaml.safe_dump({
        'robot_file': str(config_file(DEFAULT_ROBOT)),
        'plant': {'field': field, 'elastic': {'resolver': {
            name: resolver.number(name) * noise for name in ('angle_noise_rad', 'velocity_noise_rad_s')}}}}))
    return setup


def test_a_drum_reversing_in_tension_control_under_a_lagging_drive_keeps_its_cable_taut(tmp_path):
    """Current-loop lag 2 ms, cable 3 parting 0.117 of the way back along-1 (seed 2): in
    recovery phase 1 a remaining motor's drum reverses ~30 ms after the parting. Its Coulomb
    compensation taken for the direction it had, its cable went slack for 3 periods (0 N);
    taken for when the command acts (command_lead_periods), every remaining cable stays at
    τ_min or above."""
    scenario = build_scenario(ScenarioOptions(
        config=str(drive_setup(tmp_path, {'torque_lag_s': 0.002})), motion='along-1', reverse=True,
        fail_cables=[3], fail_at_s=2.1231421445978063, fidelity='field', seed=2, detector='cusum'))
    run = metrics_of(scenario, run_inprocess(scenario), 0.0)
    assert run['identified_cables'] == [3] and run['recovery']['reached_safe_point']
    assert run['recovery']['phase_times_s'].get('RECOVERY_MOVE', 0.0) > run['detection_time_s']
    assert run['recovery']['min_tension_n'] >= scenario.robot.tension_min_n


def test_the_circle_failure_after_135_degrees_is_detected_soon_after_the_parting_and_named(
        circle_with_failure):
    assert_detected_soon_after_parting_and_named([circle_with_failure], 1)


@pytest.mark.xfail(strict=True, raises=AssertionError, reason=(
    'cable 4 carries ~14 N where the circle passes nearest A4, so the magnet lets it go '
    "after ~50 ms and it is detected soon after: the paper's 190 ms is not reproduced"))
def test_the_circle_failure_after_135_degrees_is_detected_as_late_as_the_papers(circle_with_failure):
    assert within(circle_with_failure['detection_delay_from_signal_ms'], PAPER_CIRCLE_MS)


def test_the_papers_rig_runs_by_name_on_its_own_calibration():
    """`--config paper_rig`: the field plant with the rig's pulleys and the 4 Hz PD, on the
    calibration made on that set-up; the paper robot's own field runs keep theirs."""
    rig = build_scenario(ScenarioOptions(config='paper_rig', motion='along-2', fail_cables=[4]))
    assert rig.plant.fidelity == 'field' and rig.plant.drive.pulley_radius_m == 0.005
    assert rig.settings.section('control').number('pd_natural_frequency_hz') == 4.0
    assert rig.calibration_path.name == 'paper_rig_calibration_field.yaml'
    paper = build_scenario(ScenarioOptions(motion='along-2', fidelity='field'))
    assert paper.calibration_path.name == 'fdi_calibration_field.yaml'
    assert rig.fdi.epsilon_nm != paper.fdi.epsilon_nm
    run = metrics_of(rig, run_inprocess(rig), 0.0)
    assert run['identified_cables'] == [4] and run['mode'] == 'SAFE_HOLD'
    assert run['recovery']['reached_safe_point']


def test_a_robot_without_a_field_calibration_is_told_the_key_that_names_one(tmp_path):
    unseen = tmp_path / 'unseen.yaml'
    unseen.write_text(config_file(DEFAULT_ROBOT).read_text().replace('mass_kg: 2.941', 'mass_kg: 3.2'))
    with pytest.raises(ConfigError) as error:
        build_scenario(ScenarioOptions(config=str(unseen), motion='along-2', fidelity='field'))
    assert error.value.key == 'fdi.field_calibration_file'
    assert 'for the field plant' in str(error.value) and '--calibration FILE' in str(error.value)
