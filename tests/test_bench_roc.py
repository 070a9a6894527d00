"""cdpr-bench roc judges one simulated run offline for every detector and sensitivity: that
judgement must be the one the supervisor makes in a run, and sensitivity must trade
false alarms for delay. cdpr-bench sweep changes the plant alone."""
from __future__ import annotations

import pytest

from cdpr_bringup.bench.roc import judge, roc_points, sensitivity
from cdpr_bringup.bench.sweep import AXES, cells
from cdpr_bringup.runs.engine import run_inprocess
from cdpr_bringup.paths import config_file
from cdpr_bringup.runs.settle import ScenarioOptions, build_scenario
from cdpr_fdi.detectors import DETECTORS

from conftest import MOTIONS, PAPER_ROBOT


def elastic(**options):
    return build_scenario(ScenarioOptions(config=str(PAPER_ROBOT), motions=str(MOTIONS),
                                          fidelity='elastic', seed=10, **options))


@pytest.fixture(scope='module')
def failure():
    """Cable 4 breaks mid-way along orthogonal-2, simulated once with nothing judging."""
    scenario = elastic(motion='orthogonal-2', fail_cables=[4])
    return scenario, run_inprocess(scenario, supervised=False)


@pytest.mark.parametrize('detector', DETECTORS)
def test_the_offline_judgement_names_the_tick_and_cable_the_running_supervisor_names(failure, detector):
    scenario, unjudged = failure
    supervised = elastic(motion='orthogonal-2', fail_cables=[4], detector=detector)
    recording = run_inprocess(supervised)
    ((tick, cables),) = judge(scenario, unjudged, supervised.fdi, first_only=True).namings
    assert tick == recording.fdi['identified_tick']
    assert cables == recording.fdi['broken_cables'] == [4]


@pytest.mark.parametrize('detector', DETECTORS)
def test_lower_thresholds_alarm_on_a_healthy_robot_that_the_calibrated_ones_leave_alone(detector):
    scenario = elastic(motion='circle')
    recording = run_inprocess(scenario, supervised=False)
    settled = scenario.fdi.with_overrides(detector=detector)
    calibrated = judge(scenario, recording, settled, first_only=False)
    assert calibrated.namings == [] and calibrated.alarm_ticks == 0
    alarmed = [judge(scenario, recording, sensitivity(settled, factor), first_only=False).alarm_ticks
               for factor in (0.5, 0.3, 0.2)]
    assert 0 < alarmed[0] <= alarmed[1] <= alarmed[2]


def test_the_points_count_false_alarms_per_hour_and_medians_per_family():
    rows = [dict(detector=d, factor=f, cable=None, family='along', hours=0.5, false_alarms=a,
                 alarm_time_pct=p)
            for d in DETECTORS for f, a, p in ((1.0, 0, 0.0), (0.5, 3, 2.0), (0.5, 0, 4.0))]
    rows += [dict(detector=d, factor=f, cable=4, family=family, hours=0.01, false_alarms=0,
                  delay_ms=delay, identified=delay is not None)
             for d in DETECTORS for f in (1.0, 0.5)
             for family, delay in (('along', 40.0), ('along', 60.0), ('along', None),
                                   ('orthogonal', 200.0))]
    points = {d: {p['factor']: p for p in curve} for d, curve in roc_points(rows).items()}
    # a curve for each of the paper's two detectors
    assert set(points) == set(DETECTORS) == {'threshold', 'cusum'}
    for detector in DETECTORS:
        assert points[detector][0.5]['false_alarms_per_hour'] == 3.0
        assert points[detector][0.5]['alarm_time_pct'] == 3.0
        assert points[detector][1.0]['false_alarms_per_hour'] == 0.0
        assert points[detector][1.0]['along_delay_median_ms'] == 50.0
        assert points[detector][1.0]['orthogonal_delay_median_ms'] == 200.0
        assert points[detector][1.0]['circle_delay_median_ms'] is None
        assert points[detector][1.0]['identification_pct'] == 75.0
        assert points[detector][1.0]['missed'] == 1


def test_a_sweep_cell_changes_the_plant_alone(tmp_path):
    made = cells(config_file(str(PAPER_ROBOT)), tmp_path, 'elastic')
    assert len(made) == 1 + sum(len(axis.factors) for axis in AXES if 'elastic' in axis.keys)
    nominal, stiff = (build_scenario(ScenarioOptions(config=str(made[label]), motions=str(MOTIONS),
                                                     fidelity='elastic'))
                      for label in ('nominal', 'cable stiffness ×3'))
    assert stiff.plant.axial_stiffness_n == pytest.approx(3.0 * nominal.plant.axial_stiffness_n)
    # the robot, hence the calibration and every model setting, is the nominal one
    assert stiff.robot.fingerprint() == nominal.robot.fingerprint()
    assert stiff.fdi == nominal.fdi and stiff.calibration_path == nominal.calibration_path
    assert stiff.gains == nominal.gains
