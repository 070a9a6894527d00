"""cdpr-bench far: false alarms per hour with their Poisson bound, each alarm episode
once and pushes the supervisor names left out; the delays at the same thresholds from the
failure matrix's instants; and cdpr-calibrate --from-far choosing thresholds from it."""
from __future__ import annotations

import numpy as np
import pytest
import yaml
from scipy.stats import chi2

from cdpr_bringup.bench.far import bench_far, table
from cdpr_bringup.campaigns.operating_point import choose, far_points, rate_upper_per_hour, read_rows
from cdpr_bringup.bench.roc import Judgement, episode_counts, write_rows
from cdpr_bringup.campaigns import calibrate
from cdpr_bringup.campaigns.campaign import random_fraction
from cdpr_bringup.paths import config_file
from cdpr_bringup.runs.settle import ScenarioOptions, build_scenario

from conftest import MOTIONS, PAPER_ROBOT

TINY, CALIBRATED, LARGE = 0.2, 1.0, 10.0


def test_the_poisson_upper_bound_is_the_exact_one():
    # no false alarm in 30 h: fewer than 0.1 per hour; 3 in 10 h: fewer than 0.7754
    assert rate_upper_per_hour(0, 30.0) == pytest.approx(0.0999, abs=1e-4)
    assert rate_upper_per_hour(3, 10.0) == pytest.approx(0.7754, abs=1e-4)
    for count in (1, 7, 40, 500):
        assert rate_upper_per_hour(count, 2.0) == pytest.approx(chi2.ppf(0.95, 2 * count + 2) / 4.0, rel=1e-9)


def judgement(alarm_ticks, namings=(), disturbance_starts=(), ticks=2000):
    alarmed = np.zeros(ticks, dtype=bool)
    alarmed[list(alarm_ticks)] = True
    return Judgement([(tick, [1]) for tick in namings], alarmed, list(disturbance_starts))


def test_an_alarm_episode_is_counted_once():
    gap = 500
    # a residual flickering about ε, named twice (the fresh supervisor names again)
    flicker = judgement([100, 101, 103, 180, 400, 402], namings=[103, 181])
    assert episode_counts(flicker, gap) == dict(false_alarm_episodes=1, naming_episodes=1,
                                                pushes_named=0)
    # two episodes more than the gap apart: two false alarms, neither named
    assert episode_counts(judgement([100, 1200]), gap)['false_alarm_episodes'] == 2


def test_a_push_the_supervisor_names_is_left_out_and_nothing_else():
    gap = 500
    # the balance weighs the push a few ticks after the residual jumps; a CUSUM alarms on long after
    push = judgement(range(300, 1400), disturbance_starts=[304])
    assert episode_counts(push, gap) == dict(false_alarm_episodes=0, naming_episodes=0, pushes_named=1)
    # a push that got a cable named is a false alarm (it would stop the robot)
    named = judgement(range(300, 400), namings=[350], disturbance_starts=[304])
    assert episode_counts(named, gap)['false_alarm_episodes'] == 1
    # an episode alarming long before the push came is no push's
    before = judgement(range(0, 1400), disturbance_starts=[900])
    assert episode_counts(before, gap)['false_alarm_episodes'] == 1


@pytest.fixture(scope='module')
def far(tmp_path_factory):
    """Half a simulated minute on the elastic plant: pushed failure-free runs and cables 1
    and 4 failing at random instants, judged at a tiny, the calibrated and a large ε."""
    out = tmp_path_factory.mktemp('far')
    points = bench_far(str(PAPER_ROBOT), out, ['elastic'], hours=0.01, jobs=2,
                       factors=(TINY, CALIBRATED, LARGE), motions_file=str(MOTIONS),
                       motions=['along-1'], cables=[1, 4])
    return out, points, read_rows(out / 'far.csv')


def test_a_large_threshold_gives_no_false_alarm_and_a_tiny_one_many(far):
    out, points, rows = far
    assert (out / 'far.png').stat().st_size > 0
    for detector in ('threshold', 'cusum'):
        curve = {p['factor']: p for p in points[('elastic', detector)]}
        assert curve[TINY]['false_alarms'] >= 3
        assert curve[LARGE]['false_alarms'] == 0 and curve[CALIBRATED]['false_alarms'] == 0
        assert curve[LARGE]['upper_per_hour'] == pytest.approx(rate_upper_per_hour(0, curve[LARGE]['failure_free_hours']))
        # every failure-free run was pushed, and the supervisor named the pushes
        assert curve[LARGE]['pushes_applied'] == sum(1 for r in rows if r['cable'] is None
                                                      and r['detector'] == detector and r['factor'] == LARGE)
        assert curve[CALIBRATED]['pushes_named'] > 0
    assert any('elastic plant, cusum' in line for line in table(points))


def test_the_delays_come_from_the_failure_matrix_instants(far):
    _, points, rows = far
    failures = [r for r in rows if r['cable'] is not None and r['factor'] == CALIBRATED]
    assert len(failures) == 2 * 1 * 2 * 2    # cables × motions × directions × detectors
    fractions = set()
    for row in failures:
        fraction = random_fraction(10, row['motion'], row['direction'], row['cable'], 'elastic', 'threshold')
        fractions.add(fraction)
        scenario = build_scenario(ScenarioOptions(
            config=str(PAPER_ROBOT), motions=str(MOTIONS), motion=row['motion'],
            reverse=row['direction'] == 'reverse', fail_cables=[row['cable']],
            fail_at_fraction=fraction, fidelity='elastic', seed=10))
        assert row['failure_time_s'] == pytest.approx(scenario.failure_time_s)
        assert row['delay_ms'] == pytest.approx(1000.0 * (row['detection_time_s'] - row['failure_time_s']))
        assert row['identified']
    assert len(fractions) == len(failures) / 2     # random instants, not the midpoint
    delays = sorted(r['delay_ms'] for r in failures if r['detector'] == 'threshold')
    point = next(p for p in points[('elastic', 'threshold')] if p['factor'] == CALIBRATED)
    assert point['delay_max_ms'] == delays[-1]
    assert point['delay_median_ms'] == pytest.approx(np.median(delays))


def hand_made_far(path, alarms: dict) -> None:
    """far.csv with 40 failure-free hours a sensitivity: `alarms` {(detector, factor): k}."""
    shipped = str(config_file('fdi_calibration_elastic.yaml'))
    rows = []
    for (detector, factor), count in alarms.items():
        thresholds = dict(epsilon_nm=0.24 * factor, cusum_threshold=0.77 * factor,
                          cusum_limit=5.0 + 3.0 * factor, cusum_epsilon_nm=0.25 * factor)
        common = dict(fidelity='elastic', detector=detector, factor=factor, calibration=shipped, **thresholds)
        rows.append(dict(common, cable=None, hours=40.0, false_alarm_episodes=count, naming_episodes=0,
                         pushes_applied=100, pushes_named=100, false_alarms=0))
        rows.append(dict(common, cable=4, hours=0.001, delay_ms=3.0 * factor, false_alarms=0, identified=True))
    write_rows(rows, path)


def test_calibrate_from_far_takes_the_most_sensitive_thresholds_under_the_target(tmp_path, capsys):
    far_csv = tmp_path / 'far.csv'
    # 0 in 40 h: < 0.075 /h; 1: < 0.119 /h; 5: < 0.262 /h
    hand_made_far(far_csv, {('threshold', 0.5): 5, ('threshold', 0.7): 0, ('threshold', 1.0): 0,
                            ('cusum', 0.5): 0, ('cusum', 0.7): 1, ('cusum', 1.0): 0})
    curves = far_points(read_rows(far_csv))
    assert choose(curves[('elastic', 'threshold')], 0.1)['factor'] == 0.7
    # ×0.5 meets the target between two that do not: luck, not an operating point
    assert choose(curves[('elastic', 'cusum')], 0.1)['factor'] == 1.0
    assert choose(curves[('elastic', 'cusum')], 0.01) is None
    out = tmp_path / 'calibration.yaml'
    assert calibrate.main(['--from-far', str(far_csv), '--false-alarms-per-hour', '0.1',
                           '--fidelity', 'elastic', '--out', str(out)]) == 0
    written = yaml.safe_load(out.read_text())
    shipped = yaml.safe_load(config_file('fdi_calibration_elastic.yaml').read_text())
    assert written['fdi']['epsilon_nm'] == pytest.approx(0.24 * 0.7)
    assert written['fdi']['cusum'] | {'threshold': 0, 'limit': 0, 'epsilon_nm': 0} == \
        shipped['fdi']['cusum'] | {'threshold': 0, 'limit': 0, 'epsilon_nm': 0}
    assert (written['fdi']['cusum']['threshold'], written['fdi']['cusum']['limit']) == (0.77, 8.0)
    assert written['fdi']['coulomb_friction_nm'] == shipped['fdi']['coulomb_friction_nm']
    assert written['calibration']['threshold_factor'] == 0.7 and written['calibration']['cusum_factor'] == 1.0
    # the file loads as a calibration
    build_scenario(ScenarioOptions(config=str(PAPER_ROBOT), motions=str(MOTIONS), fidelity='elastic',
                                   calibration=str(out)))
    capsys.readouterr()
    assert calibrate.main(['--from-far', str(far_csv), '--false-alarms-per-hour', '0.05',
                           '--fidelity', 'elastic', '--out', str(tmp_path / 'none.yaml')]) == 1
    said = capsys.readouterr().err.strip().splitlines()
    assert len(said) == 1 and 'no swept threshold of the' in said[0]
    assert not (tmp_path / 'none.yaml').exists()
