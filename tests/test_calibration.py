"""Detector calibration from failure-free residuals: friction fit, Gumbel levels, CUSUM."""
from __future__ import annotations

import numpy as np
import pytest

from cdpr_bringup.campaigns import calibrate as cdpr_calibrate
from cdpr_control.config import ConfigError, load_section
from cdpr_control.model.friction import FrictionModel
from cdpr_control.setup.robot_file import load_robot
from cdpr_fdi.detection.calibration import (FailureFreeRun, calibrate, collapse_reference_level, cusum_trace,
                                           fit_coulomb_friction, gumbel_threshold)
from cdpr_fdi.settings.config import load_fdi_config

import copy

from conftest import CONFIG_DIR, LIGHT_TALL_MOTIONS, LIGHT_TALL_ROBOT, PAPER_ROBOT, written_robot

PERIOD_S = 0.002


def synthetic_runs(rng, coulomb_nm=0.1, noise_nm=0.02, count=40, ticks=2000):
    """Residuals of a drive with Coulomb friction the twin lacks, plus white noise."""
    runs = []
    for _ in range(count):
        speed = 3.0 * np.sin(np.linspace(0, 2 * np.pi, ticks))[:, None] * rng.uniform(0.5, 1.5, 4)
        residual = (FrictionModel(coulomb_nm, 0.1).torque_nm(speed)
                    + noise_nm * rng.standard_normal(speed.shape))
        runs.append(FailureFreeRun(residual, speed))
    return runs


def test_friction_fit_recovers_the_coulomb_level(rng):
    assert fit_coulomb_friction(synthetic_runs(rng), 0.1) == pytest.approx(0.1, rel=0.01)


def test_gumbel_level_grows_as_the_false_alarm_rate_falls(rng):
    maxima = rng.gumbel(1.0, 0.1, size=5000)
    rare = gumbel_threshold(maxima, 4.0, 0.01)
    often = gumbel_threshold(maxima, 4.0, 10.0)
    assert often < rare
    # P(block max > level) = rate · W: check against the Gumbel law the maxima came from
    probability = 1.0 - np.exp(-np.exp(-(rare - 1.0) / 0.1))
    assert probability == pytest.approx(0.01 * 4.0 / 3600.0, rel=0.5)
    assert gumbel_threshold(np.array([0.1, 0.5]), 4.0, 1e6) >= 0.5   # never below what was seen


def test_cusum_trace_accumulates_only_above_the_drift():
    z = np.array([[1.0, 2.0], [5.0, 0.0], [5.0, 0.0], [0.0, 0.0], [0.0, 0.0]])
    np.testing.assert_allclose(cusum_trace(z, drift=3.0), [0.0, 2.0, 4.0, 1.0, 0.0])


def test_a_calibration_that_never_sees_the_sum_grow_still_gives_the_sum_a_level(rng):
    """Quiet runs (|z| never above ν): no sum to fit, but h must be positive, and at least
    what one sample the limit lets pass adds to the sum."""
    runs = [FailureFreeRun(rng.normal(0.0, 0.01, (2000, 3)), rng.uniform(-2.0, 2.0, (2000, 3)))
            for _ in range(20)]
    result = calibrate(runs, PERIOD_S, 0.1, cusum_drift=5.0, false_alarms_per_hour=0.1)
    assert result.largest_cusum == 0.0
    assert result.cusum_threshold >= result.cusum_limit - result.cusum_drift > 0.0


def test_a_limit_below_the_drift_still_gives_the_sum_a_positive_level(rng):
    """Short runs of bounded noise (quantised angles): the limit on z falls below ν,
    limit − ν is negative, and the level the detector refuses (0) must not come out."""
    runs = [FailureFreeRun(rng.uniform(-0.01, 0.01, (300, 8)), rng.uniform(-2.0, 2.0, (300, 8)))
            for _ in range(6)]
    result = calibrate(runs, PERIOD_S, 0.1, cusum_drift=5.0, false_alarms_per_hour=0.1)
    assert result.cusum_limit < result.cusum_drift
    assert result.cusum_threshold == pytest.approx(result.cusum_limit)


def test_calibration_of_white_noise_gives_thresholds_above_every_failure_free_run(rng):
    runs = synthetic_runs(rng)
    result = calibrate(runs, PERIOD_S, 0.1, cusum_drift=5.0, false_alarms_per_hour=0.1)
    assert result.coulomb_friction_nm == pytest.approx(0.1, rel=0.02)
    np.testing.assert_allclose(result.cusum_sigma_nm, 0.02, rtol=0.05)
    largest = max(np.max(np.abs(run.residual_nm)) for run in runs)
    assert result.epsilon_nm > largest and result.cusum_epsilon_nm >= result.epsilon_nm
    # white noise at 5 σ and beyond is rare: the limit on z lies above it
    assert result.cusum_limit > 5.0 and result.cusum_threshold >= result.largest_cusum
    assert result.hours == pytest.approx(40 * 2000 * PERIOD_S / 3600.0)


def test_the_collapse_floor_lies_above_what_failure_free_runs_read_free_and_higher_the_more_runs_do():
    """Runs that never read a loaded motor free (None) lower the odds that a run does: of
    nine runs, three reading free at 1.9–2.1 N give a lower floor than nine that do alike;
    both above every value seen; one run: its value; none: no floor."""
    seen = [1.9, 2.0, 2.1]
    rare, often = (collapse_reference_level(values, 6.0, 0.1) for values in ([None] * 6 + seen, seen * 3))
    assert 2.1 <= rare < often
    assert collapse_reference_level([None, 1.7], 6.0, 0.1) == 1.7
    assert collapse_reference_level([None, None], 6.0, 0.1) is None


def test_a_calibrated_collapse_floor_is_a_share_of_tension_min_just_above_the_level(paper_robot):
    """A thousandth of τ_min above the level (the test alarms from the floor on), never
    below the robot file's share; nothing where no run read a motor free."""
    fdi = load_section(PAPER_ROBOT, 'fdi')
    configured = fdi.number('collapse_reference_share')
    level = 7.0 * paper_robot.tension_min_n
    share = cdpr_calibrate.collapse_reference_share(level, paper_robot, fdi)
    assert share * paper_robot.tension_min_n > level and share == pytest.approx(7.001)
    assert cdpr_calibrate.collapse_reference_share(0.1, paper_robot, fdi) == configured
    assert cdpr_calibrate.collapse_reference_share(None, paper_robot, fdi) is None


def test_a_new_robot_calibrates_from_nothing_and_its_calibration_is_bound_to_it(tmp_path,
                                                                              paper_robot):
    """cdpr-calibrate needs no thresholds to start from (its runs' supervisor acts on nothing),
    writes the robot's fingerprint, and the file then loads for that robot only."""
    tall = CONFIG_DIR / 'tall_frame_robot.yaml'
    out = tmp_path / 'calibration.yaml'
    assert cdpr_calibrate.main(['--config', str(tall), '--motions', str(CONFIG_DIR / 'tall_frame_motions.yaml'),
                           '--seeds', '0', '--jobs', '2', '--out', str(out)]) == 0
    config = load_fdi_config(tall, load_robot(tall), out)
    assert 0.0 < config.epsilon_nm < 1.0
    with pytest.raises(ConfigError, match='robot_fingerprint'):
        load_fdi_config(PAPER_ROBOT, paper_robot, out)


def test_a_robot_whose_failure_free_runs_reach_the_torque_limit_is_not_calibrated(tmp_path, capsys):
    """The light tall robot with motors that barely hold it (0.087 N·m, its cables' peak
    is 0.084 N·m): on the elastic plant the failure-free motion drives them to the limit,
    where the residual shows the saturation and not the robot: one line naming the key
    and the file, and no calibration written (a drawn robot at its PD's edge gave ε/ρ
    above τ_max that way, and the detector never saw a break)."""
    weak = copy.deepcopy(LIGHT_TALL_ROBOT)
    weak['robot']['motor'].update(torque_limit_nm=0.087, nominal_torque_nm=0.087)
    weak['robot']['cables']['tension_max_n'] = 0.087 / weak['robot']['motor']['drum_radius_m']
    robot, motions, _ = written_robot(tmp_path, weak, LIGHT_TALL_MOTIONS)
    out = tmp_path / 'calibration.yaml'
    assert cdpr_calibrate.main(['--config', str(robot), '--motions', str(motions), '--seeds', '0',
                                '--jobs', '2', '--out', str(out)]) == 2
    error = capsys.readouterr().err.strip().splitlines()
    assert len(error) == 1 and f"{robot}: 'robot.motor.torque_limit_nm'" in error[0] and 'reached' in error[0]
    assert not out.exists()
