"""cdpr-report: every figure from a bag of a run, and metrics recomputed from the bag equal
to those of the run's own Recording; bags without ground truth or supervisor, and the
bag of a killed recorder, still give a report."""
from __future__ import annotations

import dataclasses
import json
import shutil

import matplotlib.image
import numpy as np
import pytest
import yaml

from cdpr_control.geometry.rotation import difference

from cdpr_bringup.reports import plots
from cdpr_bringup.scenario import command as scenario_cli
from cdpr_bringup.bags.bag_io import BagWriter, recording_from_bag, write_recording
from cdpr_bringup.runs.engine import run_inprocess
from cdpr_bringup.reports.summary import summary_lines
from cdpr_bringup.paths import LAST_DIAGNOSTICS
from cdpr_bringup.runs.metrics import metrics_json, missing_against_the_plant, twin_kpis
from cdpr_msgs_py.contract import RUN_FIGURES_KEY
from cdpr_bringup.reports.report import (SETTLED_RUN, load_run, main, run_of_recording, run_settings, write_report,
                                 write_run_report)
from cdpr_bringup.runs.settle import ScenarioOptions, build_scenario

from conftest import CONFIG_DIR, MOTIONS, PAPER_ROBOT, assert_close_figures, every_tick_scenario

DESIGN_KEYS = {'failure_time_s', 'detection_time_s', 'detection_delay_ms', 'identified_cables',
               'true_broken_cables', 'false_alarm', 'recovery', 'kpi', 'cycles', 'wall_time_s'}
RECOVERY_KEYS = {'reached_safe_point', 'final_error_m', 'min_tension_n', 'max_tension_n', 'min_height_m',
                 'duration_s'}
KPI_KEYS = {'K_c_m', 'K_j_rad', 'K_t_nm'}
# DESIGN_KEYS as flat() names them: what two reports compared key for key must hold
FLAT_DESIGN_KEYS = (DESIGN_KEYS - {'recovery', 'kpi'} | {f'recovery.{key}' for key in RECOVERY_KEYS}
                    | {f'kpi.{key}' for key in KPI_KEYS})
# README, cdpr-report: the paper's figures
PAPER_FIGURES = ('torques', 'residuals', 'detection', 'position', 'path_3d', 'path_top', 'tensions')


def write_bag(recording, bag):
    writer = BagWriter(bag)
    writer.open()
    write_recording(writer, recording)
    writer.close()
    return bag


@pytest.fixture(scope='module')
def failure_run(tmp_path_factory):
    """Cable 4 breaks mid-way along cable 4 on the rigid plant; the in-process supervisor
    detects it and recovers. (scenario, recording, run folder, returned metrics)"""
    scenario = build_scenario(ScenarioOptions(config=str(PAPER_ROBOT), motions=str(MOTIONS),
                                              motion='along-4', fail_cables=[4], fidelity='rigid'))
    recording = run_inprocess(scenario)
    folder = tmp_path_factory.mktemp('failure')
    bag = write_bag(recording, folder / 'bag')
    # the rigid plant has no Coulomb friction, so the tension estimate must assume none
    return scenario, recording, folder, write_report(bag, folder / 'plots', run_settings(
        bag, PAPER_ROBOT, coulomb_friction_nm=0.0))


def assert_figure(path):
    """A PNG that shows something: large enough, and not one colour."""
    assert path.exists(), f'{path.name} missing'
    assert path.stat().st_size > 20_000, f'{path.name} is nearly empty'
    image = matplotlib.image.imread(path)
    assert image.shape[0] > 400 and image.shape[1] > 600
    assert image[..., :3].std() > 0.05


def test_every_figure_of_a_failure_run_is_written(failure_run):
    _, _, folder, _ = failure_run
    assert sorted(plots.FIGURES) == sorted(PAPER_FIGURES)
    for name in PAPER_FIGURES:
        assert_figure(folder / 'plots' / f'{name}.png')


def test_recomputed_metrics_equal_those_of_the_recording(failure_run):
    """The bag's metrics: the KPIs from its loop topics, the figures of the end-effector
    the plant's from every tick (its last status, in the bag's /diagnostics), the failure
    the instant it parted the cable."""
    scenario, recording, folder, metrics = failure_run
    assert DESIGN_KEYS <= set(metrics) and RECOVERY_KEYS <= set(metrics['recovery'])
    assert json.loads((folder / 'plots' / 'metrics.json').read_text()) == metrics
    failure_tick = int(np.ceil(scenario.failure_time_s / scenario.period_s - 1e-9))
    before = slice(0, failure_tick)
    kpis = twin_kpis(scenario.robot, recording, before)
    assert set(kpis) == set(metrics['kpi']) == KPI_KEYS
    for key, value in kpis.items():
        assert metrics['kpi'][key] == pytest.approx(value, rel=1e-12, abs=1e-15)
    figures = recording.figures
    assert figures['failure_tick'] == failure_tick
    assert metrics['tracking_error_m'] == figures['failure']['tracking_error_m'] > 0.0
    assert metrics['cycles'] == recording.time_s.size
    assert metrics['failure_time_s'] == recording.broken_at_s[3] == pytest.approx(scenario.failure_time_s)
    assert metrics['true_broken_cables'] == [4]
    fdi = recording.fdi
    assert metrics['identified_cables'] == fdi['broken_cables'] == [4]
    assert metrics['detection_time_s'] == pytest.approx(recording.time_s[fdi['identified_tick']])
    assert metrics['false_alarm'] is False
    ticks = fdi['phase_ticks']
    assert metrics['recovery']['duration_s'] == pytest.approx(
        (ticks['SAFE_HOLD'] - fdi['identified_tick']) * scenario.period_s)
    assert metrics['recovery']['min_height_m'] == figures['lowest_point_m']
    # of every tick, not only the view ticks: as low as their lowest, or lower
    assert figures['lowest_point_m'] <= recording.true_position_m[:, 2].min()
    assert metrics['recovery']['min_tension_n'] == figures['failure']['min_tension_n']
    assert metrics['safe_point_m'] == pytest.approx(fdi['safe_point_m'])
    final = np.linalg.norm(np.array(figures['final_position_m']) - np.array(fdi['safe_point_m']))
    assert metrics['recovery']['final_error_m'] == pytest.approx(final, abs=1e-12)
    assert metrics['recovery']['reached_safe_point'] is True


def flat(metrics: dict, prefix: str = '') -> dict:
    """{'recovery.final_error_m': …} for {'recovery': {'final_error_m': …}}."""
    items = {}
    for key, value in metrics.items():
        if isinstance(value, dict) and key != 'phase_times_s':
            items.update(flat(value, f'{prefix}{key}.'))
        else:
            items[f'{prefix}{key}'] = value
    return items


def test_scenario_and_report_compute_the_same_metrics_of_one_run(failure_run, tmp_path):
    """cdpr-scenario's metrics.json from the run itself, and cdpr-report's from its bag
    with that metrics.json beside it, as `make demo` leaves them: every key alike but the
    wall time (the run's, against the span of the bag)."""
    scenario, recording, folder, _ = failure_run
    own = scenario_cli.metrics_of(scenario, recording, wall_time_s=1.0)
    run = tmp_path / 'run'
    shutil.copytree(folder / 'bag', run / 'bag')
    (run / 'metrics.json').write_text(json.dumps(own))
    (run / SETTLED_RUN).write_text(yaml.safe_dump(scenario.settings.data))
    recomputed = write_report(run / 'bag', run / 'plots', run_settings(run / 'bag'))
    own, recomputed = flat(own), flat(recomputed)
    assert FLAT_DESIGN_KEYS <= set(recomputed)
    # what the scenario knows beyond its bag: its options, when the failure was commanded,
    # and what its reference asked of the cable as it parted
    assert set(own) - set(recomputed) == {'motion', 'fidelity', 'detector', 'failure_signal_time_s',
                                          'detection_delay_from_signal_ms', 'break.cable',
                                          'break.reference_tension_n', 'break.hidden_below_n',
                                          'break.late_detection_expected'}
    assert set(recomputed) <= set(own)
    differ = {key: (own[key], recomputed[key]) for key in sorted(set(recomputed) - {'wall_time_s'})
              if not (recomputed[key] == own[key] if own[key] is None or isinstance(own[key], (bool, str))
                      else recomputed[key] == pytest.approx(own[key], rel=1e-12, abs=1e-12))}
    assert not differ, differ


VIEW_ROWS = ('view_time_s', 'twin_position_m', 'reference_position_m', 'true_position_m', 'true_tension_n',
             'true_orientation', 'twin_orientation', 'reference_orientation')


def first_ticks(recording, kept: int, **changes):
    """`recording`'s first `kept` ticks: its loop rows, and its view rows of those ticks."""
    viewed = recording.view_time_s < recording.time_s[kept - 1] + 1e-9
    return dataclasses.replace(recording, **{
        field.name: getattr(recording, field.name)[viewed if field.name in VIEW_ROWS else slice(0, kept)]
        for field in dataclasses.fields(recording) if isinstance(getattr(recording, field.name), np.ndarray)},
        **changes)


def with_the_tail_lost(recording, kept: int):
    """`recording` as a bag whose recorder lost every tick from `kept` on (it lagged when
    the graph stopped): its first `kept` ticks, and with them the plant's last status."""
    return first_ticks(recording, kept, figures=None)


def kept_ticks(scenario, recording) -> int:
    """A recorder that lost everything from 0.2 s after the detection on."""
    return recording.fdi['identified_tick'] + round(0.2 / scenario.period_s)


def test_a_bag_that_lost_the_runs_last_seconds_changes_neither_where_the_run_ended_nor_what_is_said(
        failure_run):
    """A graph run's recorder that lags when the graph stops loses the last ticks: the
    run's final pose then comes from the plant's own last status and the ticks the bag
    lacks from the plant's count of its states, and the summary says them (issue 26)."""
    scenario, recording, _, _ = failure_run
    whole = scenario_cli.metrics_of(scenario, recording, wall_time_s=1.0)
    kept, ticks = kept_ticks(scenario, recording), recording.time_s.size
    cut = with_the_tail_lost(recording, kept)
    held = {topic: kept for topic in ('joint_states', 'effort_command')}
    # the recorder's own count: no hole between its first tick and its last
    cut.missing_ticks = missing_against_the_plant(dict.fromkeys(held, 0), ticks, held)
    # the plant's last status, written as it stopped, gives its figures
    cut.figures = recording.figures
    metrics = scenario_cli.metrics_of(scenario, cut, wall_time_s=1.0)
    assert whole['recovery']['reached_safe_point'] is True
    assert metrics['recovery']['final_error_m'] == whole['recovery']['final_error_m']
    assert metrics['identified_cables'] == [4] and metrics['mode'] == 'SAFE_HOLD'
    lost = ticks - kept
    assert metrics['bag_missing_ticks'] == {'joint_states': lost, 'effort_command': 0}
    said = '\n'.join(summary_lines(metrics))
    assert f'joint_states {lost}' in said and 'lacks ticks' in said
    # the bag's last view tick alone would have said the safe point was not reached
    alone = scenario_cli.metrics_of(scenario, dataclasses.replace(cut, figures=None), 1.0)
    assert alone['recovery']['reached_safe_point'] is False


def test_the_report_of_a_run_folder_takes_the_nodes_last_statuses_beside_its_bag(failure_run, tmp_path):
    """cdpr-report of a graph run's bag that lost the run's last seconds, in its
    cdpr-scenario folder: the nodes' last statuses beside it (last_diagnostics/, as the
    nodes write them) give where the run ended and the ticks the bag lacks, as
    cdpr-scenario's metrics have them; from the bag alone, the safe point not reached."""
    scenario, recording, _, _ = failure_run
    kept, ticks = kept_ticks(scenario, recording), recording.time_s.size
    bag = write_bag(with_the_tail_lost(recording, kept), tmp_path / 'bag')
    settings = run_settings(bag, PAPER_ROBOT, coulomb_friction_nm=0.0)
    alone = metrics_json(load_run(bag, settings).known)
    said = tmp_path / LAST_DIAGNOSTICS
    said.mkdir()
    statuses = {'plant_simulator': {'states total': str(ticks), RUN_FIGURES_KEY: json.dumps(recording.figures)},
                'supervisor': {f'fdi {key}': json.dumps(value) for key, value in recording.fdi.items()}}
    for node, values in statuses.items():
        (said / f'{node}.json').write_text(json.dumps({'values': values}))
    run = load_run(bag, settings)
    metrics = metrics_json(run.known)
    whole = scenario_cli.metrics_of(scenario, recording, wall_time_s=1.0)
    assert alone['recovery']['reached_safe_point'] is False
    assert metrics['recovery']['reached_safe_point'] is True
    assert metrics['recovery']['final_error_m'] == pytest.approx(whole['recovery']['final_error_m'], abs=1e-12)
    assert run.recording.missing_ticks['joint_states'] == ticks - kept
    assert any(f'joint_states {ticks - kept}' in note for note in run.notes)


def test_the_report_of_a_run_in_memory_is_that_of_its_bag(failure_run, tmp_path):
    """cdpr-scenario reports an in-process run from memory, cdpr-report from its bag: the
    same metrics, key for key (times to the bag's 1 ns), and the same figures. The bag has
    the run's metrics.json beside it, as cdpr-scenario leaves it."""
    scenario, recording, folder, _ = failure_run
    run = tmp_path / 'run'
    shutil.copytree(folder / 'bag', run / 'bag')
    own = scenario_cli.metrics_of(scenario, recording, wall_time_s=1.0)
    (run / 'metrics.json').write_text(json.dumps(own))
    settings = run_settings(run / 'bag', PAPER_ROBOT, coulomb_friction_nm=0.0)
    from_bag = write_report(run / 'bag', run / 'plots', settings)
    from_memory = write_run_report(run_of_recording(recording, settings, own['failure_time_s'],
                                                    own['true_broken_cables']),
                                   run / 'bag', tmp_path / 'plots')
    from_bag, from_memory = flat(from_bag), flat(from_memory)
    assert set(from_bag) == set(from_memory) >= FLAT_DESIGN_KEYS
    differ = {key: (from_bag[key], from_memory[key]) for key in sorted(from_bag)
              if not (from_memory[key] == from_bag[key]
                      if from_bag[key] is None or isinstance(from_bag[key], (bool, str, list))
                      else from_memory[key] == pytest.approx(from_bag[key], rel=1e-9, abs=1e-9))}
    assert not differ, differ
    assert sorted(path.name for path in (tmp_path / 'plots').glob('*.png')) == \
        sorted(path.name for path in (run / 'plots').glob('*.png'))


def test_the_bag_is_written_beside_the_report_and_what_fails_is_said(failure_run, tmp_path,
                                                                    monkeypatch, capfd):
    """cdpr-scenario has a forked process draw an in-process run's report while it writes
    the bag: the bag must read back as the run, the report be the one drawn here; a bag
    the machine cannot take, or a drawer that dies, fails the run in a line that says so,
    and the other output is still written."""
    scenario, recording, folder, _ = failure_run
    settings = run_settings(folder / 'bag', PAPER_ROBOT, coulomb_friction_nm=0.0)
    own = scenario_cli.metrics_of(scenario, recording, wall_time_s=1.0)
    frame = scenario.marker_frame()
    out = tmp_path / 'run'
    assert scenario_cli.record_beside_report(scenario_cli.ReportDrawer(), recording, settings, own,
                                             out, '/cdpr', frame)
    back = recording_from_bag(out / 'bag')
    for name in ('time_s', 'angle_rad', 'command_nm', 'twin_torque_nm', 'true_position_m'):
        np.testing.assert_allclose(getattr(back, name), getattr(recording, name), rtol=0.0, atol=1e-9,
                                   err_msg=name)
    here = run_of_recording(recording, settings, own['failure_time_s'], own['true_broken_cables'])
    assert json.loads((out / 'plots' / 'metrics.json').read_text()) == \
        json.loads(json.dumps(metrics_json(here.known)))
    assert len(list((out / 'plots').glob('*.png'))) == len(PAPER_FIGURES)

    def disk_full(recording, bag, namespace, frame):
        raise OSError(28, 'No space left on device')
    with monkeypatch.context() as patched:
        patched.setattr(scenario_cli, 'record', disk_full)
        out = tmp_path / 'full'
        assert not scenario_cli.record_beside_report(scenario_cli.ReportDrawer(), recording, settings,
                                                     own, out, '/cdpr', frame)
    err = capfd.readouterr().err
    assert err == f'cdpr-scenario: writing the bag {out / "bag"}: [Errno 28] No space left on device\n'
    assert (out / 'plots' / 'report.md').exists()

    def dies(*args):
        raise SystemExit(3)
    with monkeypatch.context() as patched:
        patched.setattr('cdpr_bringup.reports.report.write_run_report', dies)
        out = tmp_path / 'dead'
        assert not scenario_cli.record_beside_report(scenario_cli.ReportDrawer(), recording, settings,
                                                     own, out, '/cdpr', frame)
    err = capfd.readouterr().err
    assert err == f'cdpr-scenario: no whole report in {out / "plots"}: its drawer ended with exit code 3\n'
    assert recording_from_bag(out / 'bag').time_s.size == recording.time_s.size


def test_phases_entered_on_one_tick_keep_their_order_in_a_run_in_memory(failure_run):
    """On some robots recovery phase 2 starts on the tick of phase 1 (the tensions need
    no settling): the report shows phase 1, then 2, as the supervisor entered them."""
    scenario, recording, folder, _ = failure_run
    ticks = recording.fdi['phase_ticks']
    assert list(ticks) == ['RECOVERY_TENSION', 'RECOVERY_MOVE', 'SAFE_HOLD']
    same_tick = dict(ticks, RECOVERY_MOVE=ticks['RECOVERY_TENSION'])
    run = run_of_recording(dataclasses.replace(recording, fdi=dict(recording.fdi, phase_ticks=same_tick)),
                           run_settings(folder / 'bag', PAPER_ROBOT, coulomb_friction_nm=0.0),
                           scenario.failure_time_s, [4])
    assert [mode for _, mode in run.modes] == ['NOMINAL', 'RECOVERY_TENSION', 'RECOVERY_MOVE',
                                              'SAFE_HOLD']


def test_report_md_shows_every_figure_and_metric(failure_run):
    _, _, folder, metrics = failure_run
    text = (folder / 'plots' / 'report.md').read_text()
    for name in PAPER_FIGURES:
        assert f']({name}.png)' in text
    for key in ('detection_time_s', 'recovery.final_error_m', 'kpi.K_t_nm'):
        assert f'| {key} |' in text


def test_metrics_json_beside_the_bag_gives_the_failure_time(failure_run, tmp_path):
    scenario, _, folder, _ = failure_run
    run = tmp_path / 'run'
    shutil.copytree(folder / 'bag', run / 'bag')
    (run / 'metrics.json').write_text(json.dumps(
        {'failure_time_s': scenario.failure_time_s, 'true_broken_cables': [4]}))
    metrics = write_report(run / 'bag', run / 'plots', run_settings(run / 'bag', PAPER_ROBOT))
    assert metrics['failure_time_s'] == scenario.failure_time_s
    assert metrics['detection_delay_ms'] == pytest.approx(
        (metrics['detection_time_s'] - scenario.failure_time_s) * 1000.0)
    assert 0.0 <= metrics['detection_delay_ms'] < 10.0


def test_real_robot_bag_without_ground_truth_or_supervisor(failure_run, tmp_path):
    """What a real robot without the supervisor records: no truth, no FDI topics (the
    first 5 s of the failure run, through the failure at 3.59 s)."""
    scenario, recording, _, _ = failure_run
    first = first_ticks(recording, 2500)
    real = dataclasses.replace(first, true_position_m=np.full_like(first.true_position_m, np.nan),
                               true_tension_n=np.full_like(first.true_tension_n, np.nan),
                               residual_nm=None, fdi={}, figures=None, broken_at_s=None)
    bag = write_bag(real, tmp_path / 'bag')
    assert main([str(bag), '--out', str(tmp_path / 'plots'), '--config', str(PAPER_ROBOT),
                 '--epsilon', '0.3']) == 0
    metrics = json.loads((tmp_path / 'plots' / 'metrics.json').read_text())
    assert metrics['failure_time_s'] is None and metrics['true_broken_cables'] is None
    assert metrics['detection_time_s'] is None and metrics['false_alarm'] is None
    assert metrics['tracking_error_m'] is None and metrics['epsilon_nm'] == 0.3
    assert metrics['kpi'] == pytest.approx(twin_kpis(scenario.robot, recording_from_bag(bag)))
    assert metrics['mode'] is None and metrics['safe_point_m'] is None
    assert not (tmp_path / 'plots' / 'detection.png').exists()
    for name in set(PAPER_FIGURES) - {'detection'}:
        assert_figure(tmp_path / 'plots' / f'{name}.png')
    text = (tmp_path / 'plots' / 'report.md').read_text()
    assert 'no ground truth' in text and 'no /cdpr/fdi/broken_cable' in text


def test_bag_of_a_killed_recorder_gives_a_report_of_its_prefix(failure_run, tmp_path):
    _, recording, folder, _ = failure_run
    data = next((folder / 'bag').glob('*.mcap')).read_bytes()
    (tmp_path / 'bag').mkdir()
    (tmp_path / 'bag' / 'bag.mcap').write_bytes(data[:len(data) // 2])
    metrics = write_report(tmp_path / 'bag', tmp_path / 'plots', run_settings(tmp_path / 'bag', PAPER_ROBOT))
    assert 0.3 * recording.time_s.size < metrics['cycles'] < 0.7 * recording.time_s.size


def test_report_refuses_to_overwrite_the_runs_own_metrics(failure_run):
    _, _, folder, _ = failure_run
    with pytest.raises(ValueError, match='metrics.json'):
        write_report(folder / 'bag', folder, run_settings(folder / 'bag', PAPER_ROBOT))


def test_a_platforms_report_plots_its_orientation_beside_its_position(tmp_path):
    """A platform's bag without ground truth, as a real robot records it: the report finds
    the platform's pose by forward kinematics of the angles, where the rigid plant had it,
    and plots the orientation beside the position."""
    platform = CONFIG_DIR / 'robots' / 'crossed_platform_robot.yaml'
    scenario = build_scenario(ScenarioOptions(config=str(platform), motion='climb-tilt', fidelity='rigid',
                                              motions=str(CONFIG_DIR / 'crossed_platform_motions.yaml'),
                                              duration_s=4.0))
    recording = run_inprocess(scenario)
    real = dataclasses.replace(recording, true_position_m=np.full_like(recording.true_position_m, np.nan),
                               true_tension_n=np.full_like(recording.true_tension_n, np.nan), figures=None)
    bag = write_bag(real, tmp_path / 'bag')
    assert main([str(bag), '--out', str(tmp_path / 'plots'), '--config', str(platform)]) == 0
    run = load_run(bag, run_settings(bag, platform))
    assert not run.has_ground_truth and run.orientation.shape == (recording.time_s.size, 4)
    # every tick's pose found; compared with the truth on the view ticks
    viewed = np.round(recording.view_time_s / scenario.period_s).astype(int)
    np.testing.assert_allclose(run.position_m[viewed], recording.true_position_m, atol=1e-8)
    assert np.max(np.linalg.norm(difference(run.orientation[viewed], recording.true_orientation), axis=-1)) < 1e-8
    assert np.degrees(np.linalg.norm(difference(run.orientation[-1], run.orientation[0]))) > 5.0
    assert_figure(tmp_path / 'plots' / 'position.png')
    assert matplotlib.image.imread(tmp_path / 'plots' / 'position.png').shape[1] > 1500   # two columns
    assert 'orientation as the rotation vector' in (tmp_path / 'plots' / 'report.md').read_text()


SHIPPED_ROBOTS = [('paper_robot', 'motions', 4), ('six_cable_robot', 'six_cable_motions', 2),
                  ('eight_cable_robot', 'eight_cable_motions', 3), ('tall_frame_robot', 'tall_frame_motions', 1),
                  ('crossed_platform_robot', 'crossed_platform_motions', 5)]


@pytest.mark.parametrize('robot, motions, cable', SHIPPED_ROBOTS, ids=[robot for robot, _, _ in SHIPPED_ROBOTS])
def test_the_figures_from_every_tick_are_those_of_a_full_rate_bag(robot, motions, cable):
    """metrics.json from the plant's figures of every tick (cdpr_twin.models.run_figures) gives,
    key for key, what the full-rate truth of every tick gives (the view topics on every
    tick, streams.view_rate_hz 0, counted as a bag of it is): on every shipped robot,
    a cable broken on its circle and recovered."""
    scenario = every_tick_scenario(ScenarioOptions(config=str(CONFIG_DIR / 'robots' / f'{robot}.yaml'),
                                                   motions=str(CONFIG_DIR / f'{motions}.yaml'), motion='circle',
                                                   fail_cables=[cable], fidelity='rigid'))
    recording = run_inprocess(scenario)
    assert recording.view_time_s.size == recording.time_s.size
    ticked = scenario_cli.metrics_of(scenario, recording, wall_time_s=0.0)
    full_rate = scenario_cli.metrics_of(scenario, dataclasses.replace(recording, figures=None), wall_time_s=0.0)
    assert ticked['identified_cables'] == [cable] and ticked['recovery']['min_tension_n'] is not None
    assert_close_figures(ticked, full_rate)


def test_the_ticks_a_cable_left_is_under_tension_min_are_counted_before_the_detection_in_its_jolt_and_after():
    """Of three cables (τ_min 1 N), cable 1 parts at 0.1 s (2 ms ticks) and is named on the
    next tick: its own slack is not counted; cable 2 under τ_min on the parting's tick
    (undetected), on 3 ticks of the JOLT_S from the naming and on 1 later one, cable 3 on
    one tick before the parting (not counted) — row by row as the plant node adds them, and
    as one stack, alike."""
    from cdpr_twin.models.run_figures import JOLT_S, RunFigures
    period, ticks = 0.002, 400
    parting = round(0.1 / period)
    tension = np.full((ticks, 3), 5.0)
    tension[parting:, 0] = 0.0
    jolt = parting + round(JOLT_S / period)
    tension[[parting, parting + 1, jolt - 1], 1] = 0.5
    tension[[jolt, jolt + 100], 1] = 0.9
    tension[parting - 1, 2] = 0.2
    position = np.zeros((ticks, 3))
    by_row, stacked = (RunFigures(3, period, False, tension_min_n=1.0) for _ in range(2))
    for figures in (by_row, stacked):
        figures.failure_at(parting * period, 0)
        figures.detection_at(parting + 1)
    for tick in range(ticks):
        by_row.add(tick, position[tick], None, tension[tick])
    stacked.add_rows(np.arange(ticks), position, None, tension)
    for figures in (by_row, stacked):
        window = figures.summary()['failure']
        assert window['ticks_under_tension_min'] == {'undetected': 1, 'jolt': 3, 'after_jolt': 1}
        assert window['min_tension_n'] == 0.5
    assert RunFigures(3, period, False).summary()['failure']['ticks_under_tension_min'] is None
