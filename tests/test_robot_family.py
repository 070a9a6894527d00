"""cdpr-bench robots: robots drawn from a seed are robots the project accepts, with motions
inside their wrench-feasible workspace; and on a small family the stack names the right
cable, FAULTs only where the cables left cannot hold the pose, and reaches the safe point
where they can."""
from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest
import yaml

from cdpr_bringup.bench import main as bench
from cdpr_bringup.family.command import bench_robots, draw_family, settle_family
from cdpr_bringup.family.draw import refusal
from cdpr_bringup.runs.settle import NO_CALIBRATION, ScenarioOptions, build_scenario
from cdpr_control.geometry.motions import motion_names
from cdpr_msgs_py.contract import FAULT

# Drawn here: a point mass and two platforms (a suspended and a crossed one).
SEED = 0
# The small family judged, its cable (one per robot) and instant drawn from SEED; few
# failure-free calibration runs (one motion, both directions, one plant seed).
SMALL = dict(count=3, seed=SEED, instants=1, cables=1, calibration_motions=1, calibration_seeds=(0,), jobs=2)


def test_every_drawn_robot_is_accepted_and_every_drawn_motion_is_wrench_feasible(tmp_path):
    # calibrated on one motion and seed, as the small family is: this test judges the drawing
    members, drawing = draw_family(settle_family(count=4, seed=SEED, calibration_motions=1, calibration_seeds=(0,)),
                                   tmp_path)
    assert len(members) == 4 and drawing['draws'] >= 4
    assert {member.robot.body.kind for member in members} == {'point_mass', 'platform'}
    for member in members:
        assert list(yaml.safe_load(member.robot_file.read_text())) == ['robot']
        assert refusal(member.robot_file) is None
        assert motion_names(member.motions_file) == member.motions
        turned = []
        for name in member.motions:
            scenario = build_scenario(ScenarioOptions(config=str(member.robot_file), motions=str(member.motions_file),
                                                      motion=name, calibration=NO_CALIBRATION))
            robot, tension = scenario.robot, scenario.reference.tension_n
            assert np.all(np.isfinite(tension)), (member.robot_file, name)
            assert tension.min() >= robot.tension_min_n - 1e-9 and tension.max() <= robot.tension_max_n + 1e-9, \
                (member.robot_file, name, tension.min(), tension.max())
            spread = np.ptp(scenario.reference.orientation, axis=0) if scenario.reference.orientation.size else [0.0]
            turned.append(float(np.max(spread)) > 1e-6)
        # a platform's motions include one that turns it; a point mass has no orientation
        assert any(turned) == member.robot.body.has_orientation, member.robot_file
    # what was refused stays refused, each with its reason counted
    assert sum(drawing['refused'].values()) == drawing['draws'] - len(members)
    for refused in (tmp_path / 'refused').glob('*.yaml'):
        motions = refused.with_name(f'{refused.stem}_motions.yaml')
        if not refused.stem.endswith('_motions'):
            assert refusal(refused) is not None or motion_names(motions) == [], refused


def test_a_small_family_is_judged_by_the_rules(tmp_path):
    found = bench_robots(settle_family(**SMALL, out=str(tmp_path)), show_progress=False)
    kinds = [member.robot.body.kind for member in found['members']]
    assert 'point_mass' in kinds and 'platform' in kinds
    failures = [row for row in found['rows'] if row['cable'] is not None]
    assert len(failures) == 3 * 2   # one cable of each robot, on both plants
    for row in failures:
        case = (row['robot_file'], row['cable'], row['motion'], row['fail_at_fraction'], row['fidelity'])
        assert row['error'] is None, case
        assert row['outcome'] == 'right', case
        assert row['cables_could_hold'] is not None, case
        if row['cables_could_hold']:
            assert row['mode'] != FAULT and row['reached_safe_point'], case
    free = [row for row in found['rows'] if row['cable'] is None]
    assert len(free) == 3 * 2 and not any(row['false_alarm'] for row in free)
    assert found['cases'] == []
    for member in found['members']:
        assert member.robot_file.parent == tmp_path.resolve() / 'robots' and member.calibration.exists()
    assert (tmp_path / 'summary.csv').read_text().count('\n') == len(found['rows']) + 1
    assert '| **all** | all |' in (tmp_path / 'summary.md').read_text()


def test_the_tension_allowance_is_judged_from_the_naming_on_and_apart_where_the_cables_cannot_hold():
    """Periods under τ_min before the naming are the detection's; from it, more than the
    allowance counts against the recovery where the cables left could hold the pose of the
    break, apart where they cannot, and not at all in a FAULT (the brakes hold then)."""
    from cdpr_bringup.family.judge import (ALLOWED_TICKS_AFTER_JOLT, ALLOWED_TICKS_IN_JOLT, beyond_allowance,
                                           figures, unavoidably_under)

    def row(undetected, jolt, after, could_hold, mode='SAFE_HOLD'):
        return {'cable': 1, 'error': None, 'mode': mode, 'cables_could_hold': could_hold,
                'ticks_under_tension_min_undetected': undetected, 'ticks_under_tension_min_jolt': jolt,
                'ticks_under_tension_min_after_jolt': after}
    late = row(5000, ALLOWED_TICKS_IN_JOLT, ALLOWED_TICKS_AFTER_JOLT, True)
    ringing = row(0, ALLOWED_TICKS_IN_JOLT + 1, 0, True)
    lingering = row(0, 0, ALLOWED_TICKS_AFTER_JOLT + 1, True)
    cannot = row(0, 0, 400, False)
    braked = row(0, 40, 400, True, FAULT)
    assert [beyond_allowance(r) for r in (late, ringing, lingering, cannot, braked)] == [False, True, True, False,
                                                                                        False]
    assert [unavoidably_under(r) for r in (late, ringing, lingering, cannot, braked)] == [False, False, False, True,
                                                                                         False]
    found = figures([{**r, 'outcome': 'right', 'detection_delay_ms': 3.0, 'reached_safe_point': True,
                      'min_tension_n': 0.5, 'tension_min_bound_n': 1.0, 'false_alarm': False}
                     for r in (late, ringing, lingering, cannot, braked)])
    assert (found['beyond_allowance'], found['unavoidably_under']) == (2, 1)


@pytest.mark.parametrize('options, named', [
    (['--count', '0'], '--count 0'), (['--instants', '-1'], '--instants -1'), (['--cables', '0'], '--cables 0'),
    (['--fidelities', 'field'], '--fidelities field'), (['--seed', '-2'], '--seed -2')])
def test_a_bad_option_is_one_line_naming_it(options, named, tmp_path, capsys):
    assert bench.main(['robots', *options, '--out', str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f'cdpr-bench: {named}:') and err.count('\n') == 1, err


def test_the_drawing_and_judging_import_no_rclpy():
    code = ('import sys, cdpr_bringup.family.command, cdpr_bringup.family.judge; '
            'sys.exit("rclpy" in sys.modules)')
    assert subprocess.run([sys.executable, '-c', code]).returncode == 0
