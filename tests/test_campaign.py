"""cdpr-campaign: the run matrix, the summary figures, the written tables, and a tiny
real campaign that resumes without re-running."""
from __future__ import annotations

import csv
import json
import re

import pytest

from cdpr_bringup.campaigns.campaign import (CSV_COLUMNS, PAPER_DETECTION_MS, RANDOM_FRACTION_RANGE, Run,
                                   build_matrix, completed, expand_motion_set, main, outcome, outcome_lines,
                                   progress_bar, run_campaign, summarize, summary_markdown,
                                   write_summary_csv)
from cdpr_control.geometry.motions import motion_names
from cdpr_control.setup.robot_file import load_robot

from conftest import CONFIG_DIR, MOTIONS


def test_motion_set_expands_the_paper_tables():
    available = motion_names(MOTIONS)
    assert expand_motion_set(['along'], available) == ['along-1', 'along-2', 'along-3', 'along-4']
    assert expand_motion_set(['orthogonal', 'circle', 'along-2', 'circle'], available) == [
        'orthogonal-1', 'orthogonal-2', 'orthogonal-3', 'orthogonal-4', 'circle', 'along-2']
    with pytest.raises(ValueError):
        expand_motion_set(['diagonal'], available)


def test_matrix_counts_and_ids():
    motions = ['along-1', 'circle']
    runs = build_matrix(motions, cables=[3, 4], seeds=[0, 1])
    # (2 cables + failure-free) × 2 motions × 2 directions × 3 fidelities × 2 detectors × 2 seeds
    assert len(runs) == 3 * 2 * 2 * 3 * 2 * 2
    assert len({run.id for run in runs}) == len(runs)
    assert sum(run.cable is None for run in runs) == 2 * 2 * 3 * 2 * 2
    assert runs[0].id == 'along-1_forward_cable3_at0.500_rigid_threshold_seed0'
    assert runs[-1].id == 'circle_reverse_no-failure_field_cusum_seed1'
    # The paper's failure points: the midpoint of a line, 135° of the circle.
    assert {run.fail_at_fraction for run in runs if run.motion == 'along-1'} == {0.5}
    assert {run.fail_at_fraction for run in runs if run.motion == 'circle'} == {0.375}
    assert len(build_matrix(motions, [4], failure_free=False, fidelities=['rigid'])) == 2 * 2 * 2
    assert {run.fail_at_fraction for run in build_matrix(motions, [4], fail_at_fraction=0.3)} == {0.3}


def test_random_instants_are_drawn_per_run_inside_the_move_and_again_the_same():
    runs = build_matrix(['along-1', 'circle'], cables=[1, 2, 3, 4], seeds=[0, 1],
                        random_instants=True, failure_free=False)
    # 2 motions × 4 cables × 2 directions × 3 fidelities × 2 detectors × 2 seeds
    assert len(runs) == 2 * 4 * 2 * 3 * 2 * 2
    fractions = [run.fail_at_fraction for run in runs]
    low, high = RANDOM_FRACTION_RANGE
    assert all(low <= fraction <= high for fraction in fractions)
    assert len(set(fractions)) == len(runs), 'every run its own instant'
    assert spread(fractions) > 0.5 * (high - low)
    again = build_matrix(['along-1', 'circle'], cables=[1, 2, 3, 4], seeds=[0, 1],
                         random_instants=True, failure_free=False)
    assert [run.id for run in again] == [run.id for run in runs], 'a resumed campaign finds its runs'


def spread(values):
    return max(values) - min(values)


def test_all_expands_to_every_motion_of_the_file():
    available = ['along-4', 'lift', 'circle']
    assert expand_motion_set(['all'], available) == available
    assert expand_motion_set(['circle', 'all'], available) == ['circle', 'along-4', 'lift']


def test_scenario_arguments():
    run = Run('along-2', 'reverse', 4, 'elastic', 'cusum', 7, 0.5, epsilon_nm=0.05)
    argv = run.scenario_argv('out/x')
    for flag, value in [('--motion', 'along-2'), ('--fail-cable', '4'), ('--fail-at-fraction', '0.5'),
                        ('--fidelity', 'elastic'), ('--detector', 'cusum'), ('--seed', '7'),
                        ('--engine', 'inprocess'), ('--epsilon', '0.05'), ('--out', 'out/x')]:
        assert argv[argv.index(flag) + 1] == value
    assert '--reverse' in argv and '--quiet' in argv
    failure_free = Run('circle', 'forward', None, 'rigid', 'threshold', 0, 0.375, engine='graph')
    argv = failure_free.scenario_argv('out/y')
    assert '--fail-cable' not in argv and '--reverse' not in argv
    assert argv[argv.index('--namespace') + 1] == '/cdpr_circle_forward_no_failure_rigid_threshold_seed0'


def row(motion='along-1', direction='forward', cable=4, detector='threshold', fidelity='rigid',
        delay_ms=None, identified=(), correct=None, false_alarm=False, reached=None,
        final_error_m=None, final_orientation_error_deg=None, min_tension_n=5.0, max_tension_n=30.0, cycles=5000,
        error=None, mode='SAFE_HOLD'):
    values = {column: None for column in CSV_COLUMNS}
    values.update(run_id=f'{motion}_{direction}_{cable}', motion=motion, direction=direction,
                  cable=cable, fidelity=fidelity, detector=detector, seed=0,
                  detection_delay_ms=delay_ms, identified_cables=list(identified),
                  correct_identification=correct, false_alarm=false_alarm,
                  reached_safe_point=reached, final_error_m=final_error_m,
                  final_orientation_error_deg=final_orientation_error_deg,
                  min_tension_n=min_tension_n, max_tension_n=max_tension_n, cycles=cycles,
                  control_period_s=0.002, error=error,
                  mode=mode)
    return values


def synthetic_rows():
    return [
        row('along-1', delay_ms=40.0, identified=[4], correct=True, reached=True, final_error_m=0.01),
        row('along-2', delay_ms=60.0, identified=[4], correct=True, reached=True, final_error_m=0.03,
            final_orientation_error_deg=0.5),
        row('along-3', 'reverse', delay_ms=100.0, identified=[3], correct=False, reached=False,
            final_error_m=0.2, min_tension_n=1.5),
        row('orthogonal-1', delay_ms=250.0, identified=[4], correct=True, reached=True),
        row('orthogonal-2', delay_ms=None, correct=False),          # missed
        row('along-1', cable=3, delay_ms=2.0, identified=[3], correct=True, reached=True),  # not cable 4
        # Failure-free: 3 runs of 0.5 h each, one with a detection.
        row('along-1', cable=None, cycles=900_000),
        row('circle', cable=None, cycles=900_000, false_alarm=True),
        row('orthogonal-1', cable=None, cycles=900_000),
        row('along-4', error='cdpr-scenario exited with 1'),
        row('along-1', detector='cusum', delay_ms=20.0, identified=[4], correct=True, reached=True),
        row('circle', cable=2, detector='cusum', delay_ms=8.0, identified=[2], correct=True,
            reached=False, min_tension_n=0.4, max_tension_n=130.0, mode='FAULT'),
    ]


def test_outcome_counts_every_failure_run_of_any_cable():
    rows = synthetic_rows()
    figures = outcome(rows)
    # 8 completed failure runs (one did not complete), 7 detected, 6 named exactly
    assert (figures['failure_runs'], figures['detected'], figures['named']) == (8, 7, 6)
    assert figures['reached_safe_point'] == 5 and figures['faults'] == 1
    assert figures['min_tension_n'] == 0.4 and figures['max_tension_n'] == 130.0
    assert figures['final_error_max_m'] == 0.2 and figures['final_orientation_error_max_deg'] == 0.5
    assert figures['delay_median_ms'] == 40.0 and figures['delay_max_ms'] == 250.0
    assert (figures['failure_free_runs'], figures['false_alarms'], figures['not_completed']) == (3, 1, 1)
    lines = outcome_lines(rows)
    assert '| 2 | 1 | 1 | 1 | 0 | 1 | – / – | 0.40 / 130.0 | 8.0 / 8.0 | 0 | 0 | 0 |' in lines
    assert '| **all** | 8 | 7 | 6 | 5 | 1 | 200.0 / 0.500 | 0.40 / 130.0 | 40.0 / 250.0 | 3 | 1 | 1 |' in lines


def test_summarize_figures():
    summary = summarize(synthetic_rows())
    assert set(summary) == {'threshold/rigid', 'cusum/rigid'}
    figures = summary['threshold/rigid']
    assert figures['runs'] == 10 and figures['errors'] == 1
    # Delays only over detected failures of cable 4, split by motion family.
    assert figures['along_delay_median_ms'] == 60.0
    assert figures['along_delay_max_ms'] == 100.0
    assert figures['orthogonal_delay_median_ms'] == 250.0
    assert figures['orthogonal_delay_max_ms'] == 250.0
    # 6 completed failure runs: 4 right, one wrong cable, one missed.
    assert figures['identification_pct'] == pytest.approx(400 / 6)
    assert figures['detection_pct'] == pytest.approx(500 / 6)
    assert figures['recovery_success_pct'] == pytest.approx(400 / 6)
    # 3 × 900 000 cycles × 2 ms = 1.5 h, one false alarm.
    assert figures['failure_free_hours'] == pytest.approx(1.5)
    assert figures['false_alarms_per_hour'] == pytest.approx(1 / 1.5)
    assert figures['min_tension_n'] == 1.5
    assert figures['final_error_max_m'] == 0.2
    cusum = summary['cusum/rigid']
    assert cusum['along_delay_median_ms'] == cusum['along_delay_max_ms'] == 20.0
    assert cusum['orthogonal_delay_median_ms'] is None
    assert cusum['false_alarms_per_hour'] is None and cusum['failure_free_hours'] == 0.0


def test_csv_and_markdown_hold_the_paper_columns(tmp_path):
    rows = synthetic_rows()
    write_summary_csv(rows, tmp_path / 'summary.csv')
    with open(tmp_path / 'summary.csv') as stream:
        written = list(csv.DictReader(stream))
    assert len(written) == len(rows)
    assert tuple(written[0]) == CSV_COLUMNS
    assert written[0]['identified_cables'] == '4' and written[0]['detection_delay_ms'] == '40.0'
    assert written[4]['detection_delay_ms'] == ''
    assert written[9]['error'] == 'cdpr-scenario exited with 1'

    markdown = summary_markdown(rows)
    for heading in ('along delay median / max (ms)', 'orthogonal delay median / max (ms)',
                    'identification %', 'false alarms / h', 'recovery success %',
                    'min tension (N)', 'final error max (m)', 'paper t (ms)'):
        assert heading in markdown
    lines = markdown.splitlines()
    # Columns cusum/rigid, threshold/rigid. Table 5, motion 2 forward: 60 ms; ours not run
    # (cusum) and 60 ms (threshold).
    assert '| along-2 | forward | 60 | – | 60.0 |' in lines
    # Table 7, motion 2 forward: 290 ms; ours missed.
    assert '| orthogonal-2 | forward | 290 | – | missed |' in lines
    assert '| orthogonal-4 | reverse | 240 | – | – |' in lines
    assert '| circle | forward | 190 | – | – |' in lines
    assert '`along-4_forward_4`: cdpr-scenario exited with 1' in markdown
    assert PAPER_DETECTION_MS['along-1'] == {'forward': 50, 'reverse': 80}
    assert PAPER_DETECTION_MS['orthogonal-3'] == {'forward': 270, 'reverse': 210}


def test_progress_bar():
    assert progress_bar(12, 40, 30.4, width=10) == '[###.......] 12/40 runs, eta 30 s'
    assert progress_bar(0, 4, None, width=4) == '[....] 0/4 runs, eta ?'


def test_a_failed_run_is_a_row_and_the_campaign_goes_on(tmp_path):
    bad = Run('along-4', 'forward', 9, 'rigid', 'threshold', 0, 0.5)  # the robot has 4 cables
    rows = run_campaign([bad], tmp_path, jobs=1, show_progress=False)
    assert len(rows) == 1 and '--fail-cable 9: the robot has cables 1..4' in rows[0]['error']
    assert (tmp_path / 'runs' / bad.id / 'scenario.log').exists()


def test_a_run_cut_short_by_ctrl_c_is_not_done(tmp_path):
    assert not completed(tmp_path)
    (tmp_path / 'metrics.json').write_text(json.dumps({'cycles': 10, 'interrupted': True}))
    assert not completed(tmp_path)
    (tmp_path / 'metrics.json').write_text(json.dumps({'cycles': 5000}))
    assert completed(tmp_path)


def test_tiny_campaign_runs_in_parallel_and_resumes(tmp_path):
    out = tmp_path / 'campaign'
    argv = ['--motion-set', 'along-4', '--cables', '4', '--directions', 'forward',
            '--fidelities', 'rigid', '--detectors', 'threshold', '--seeds', '0',
            '--config', str(CONFIG_DIR / 'paper_robot.yaml'), '--motions', str(MOTIONS),
            '--jobs', '2', '--out', str(out)]
    assert main(argv) == 0
    with open(out / 'summary.csv') as stream:
        rows = list(csv.DictReader(stream))
    assert [(row['motion'], row['cable'], row['error']) for row in rows] == [
        ('along-4', '4', ''), ('along-4', '', '')]
    assert all(int(row['cycles']) > 0 for row in rows)
    assert all(re.fullmatch(r'local:\d+', row['worker']) for row in rows)
    assert float(rows[0]['failure_time_s']) > 0 and rows[1]['failure_time_s'] == ''
    assert '| along-4 | forward | 50 |' in (out / 'summary.md').read_text()

    metrics = sorted((out / 'runs').glob('*/metrics.json'))
    assert len(metrics) == 2
    written = [path.stat().st_mtime_ns for path in metrics]
    assert main(argv) == 0
    assert [path.stat().st_mtime_ns for path in metrics] == written
    with open(out / 'summary.csv') as stream:
        assert len(list(csv.DictReader(stream))) == 2


# The new robots' hard cases on the elastic plant, every cable at a random instant
# (cdpr-campaign --random-instants; the whole matrix, both detectors, is a campaign,
# README), one detector each: the tall frame's along-4 with the threshold detector,
# where its light load once had two cables named (FAULT), and the 6-cable robot's motion
# across it with CUSUM. One run at a time: this session's workers already share the cores.
NEW_ROBOT_CASES = [('tall_frame', 'along-4', 'threshold'), ('six_cable', 'across', 'cusum')]


@pytest.mark.parametrize('robot, motion, detector', NEW_ROBOT_CASES, ids=[robot for robot, _, _ in NEW_ROBOT_CASES])
def test_every_cable_of_a_new_robot_at_a_random_instant_is_named_and_recovered(robot, motion, detector, tmp_path):
    out = tmp_path / robot
    argv = ['--config', str(CONFIG_DIR / f'{robot}_robot.yaml'),
            '--motions', str(CONFIG_DIR / f'{robot}_motions.yaml'), '--motion-set', motion,
            '--cables', 'all', '--directions', 'forward', '--fidelities', 'elastic',
            '--detectors', detector, '--random-instants', '--jobs', '1', '--out', str(out)]
    assert main(argv) == 0
    with open(out / 'summary.csv') as stream:
        rows = list(csv.DictReader(stream))
    failures = [row for row in rows if row['cable']]
    cables = {int(row['cable']) for row in failures}
    cable_count = load_robot(CONFIG_DIR / f'{robot}_robot.yaml').cable_count
    # every cable of the robot, once
    assert cables == set(range(1, cable_count + 1)) and len(failures) == cable_count
    assert {row['detector'] for row in rows} == {detector}
    for row in failures:
        assert row['identified_cables'] == row['cable'], row['run_id']
        assert row['mode'] == 'SAFE_HOLD' and row['reached_safe_point'] == 'True', row['run_id']
        assert float(row['min_tension_n']) > 0.0, row['run_id']
    assert all(row['false_alarm'] == 'False' for row in rows)
