"""A user's mistake on the command line: one line naming the option (or the key and the
file), exit 2, no traceback — unless --debug asks for it."""
from __future__ import annotations

import pytest

from cdpr_bringup.graph import launcher

from cdpr_bringup.reports import robot_summary

from cdpr_bringup.scenario import command
from cdpr_bringup.cli import UsageError

from conftest import MOTIONS, PAPER_ROBOT

RUN = ['--config', str(PAPER_ROBOT), '--motions', str(MOTIONS), '--motion', 'along-2',
       '--engine', 'inprocess']
BAD_OPTIONS = [
    (['--fail-cable', '4', '--epsilon', 'nan'], '--epsilon nan'),
    (['--fail-cable', '4', '--epsilon', '-0.1'], '--epsilon -0.1'),
    (['--fail-cable', '4', '--fail-at', '100'], '--fail-at 100.0'),
    (['--fail-cable', '4', '--fail-at', '-1'], '--fail-at -1.0'),
    (['--fail-cable', '4', '--fail-at', 'nan'], '--fail-at nan'),
    (['--fail-cable', '4', '--fail-at-fraction', '1.5'], '--fail-at-fraction 1.5'),
    (['--fail-cable', '9'], '--fail-cable 9'),
    (['--seed', '-3'], '--seed -3'),
    (['--fail-cable', '4', '--recovery-budget', '0'], '--recovery-budget 0.0'),
    (['--push', '1', '0', '0', '0', '20'], '--push 1 0 0 0 20'),
    (['--push', '1', '0.3', 'nan', '0', '20'], '--push 1 0.3 nan 0 20'),
]


@pytest.mark.parametrize('options, named', BAD_OPTIONS, ids=[named for _, named in BAD_OPTIONS])
def test_a_bad_scenario_option_is_one_line_naming_it(options, named, tmp_path, capsys):
    code = command.main(RUN + options + ['--out', str(tmp_path / 'run')])
    err = capsys.readouterr().err
    assert code == 2
    assert err.startswith(f'cdpr-scenario: {named}:') and err.count('\n') == 1, err
    assert not (tmp_path / 'run' / 'metrics.json').exists()


def test_debug_shows_the_traceback(tmp_path):
    with pytest.raises(UsageError, match='--fail-cable 9'):
        command.main(RUN + ['--fail-cable', '9', '--out', str(tmp_path / 'run'), '--debug'])


@pytest.mark.parametrize('main, name', [(command.main, 'cdpr-scenario'), (launcher.main, 'cdpr-graph'),
                                        (robot_summary.main, 'cdpr-robot')])
def test_a_missing_or_bad_config_is_one_line(main, name, tmp_path, capsys):
    broken = tmp_path / 'broken.yaml'
    broken.write_text('robot: [1, 2]\n')
    for config, named in (('no_such_robot.yaml', 'no config no_such_robot.yaml'),
                          (str(broken), f"{broken}: 'robot' must be a mapping")):
        extra = ['--out', str(tmp_path / 'run')] if main is command.main else []
        assert main(['--config', config] + extra) == 2
        err = capsys.readouterr().err
        assert err.startswith(f'{name}: {named}') and err.count('\n') == 1, err


def test_a_motion_without_tensions_within_the_bounds_is_one_line_naming_what_to_change(tmp_path, capsys):
    """On the pseudo-inverse, a pose where S⁺ w leaves the bounds names the motion, the pose
    and the distribution that has tensions there; on the default distribution the same
    motion runs."""
    setup = tmp_path / 'setup.yaml'
    setup.write_text(f'robot_file: {PAPER_ROBOT}\ncontrol: {{tension_distribution: pseudo_inverse}}\n')
    motions = tmp_path / 'motions.yaml'
    # to a low corner of the frame, where S⁺ w slackens a cable and bounded tensions exist
    motions.write_text('motion_defaults: {peak_speed_m_s: 0.5, rest_before_s: 0.2, rest_after_s: 0.2}\n'
                       'motions:\n  corner: {type: line, start: [0.844, 0.965, 1.25], '
                       'goal: [0.25, 0.25, 0.3]}\n')
    run = ['--motions', str(motions), '--motion', 'corner', '--engine', 'inprocess',
           '--fidelity', 'rigid', '--no-plots']
    assert command.main(['--config', str(setup)] + run + ['--out', str(tmp_path / 'a')]) == 2
    err = capsys.readouterr().err
    assert err.startswith('cdpr-scenario: --motion corner: no feasible cable tensions at p = (')
    assert 'bounded_minimum_norm' in err and err.count('\n') == 1, err
    assert command.main(['--config', str(PAPER_ROBOT)] + run + ['--out', str(tmp_path / 'b')]) == 0


def test_a_campaign_whose_runs_are_refused_says_why_once_in_one_line(tmp_path, capsys):
    """A robot without a calibration for the elastic plant: every run is refused in its
    worker; the campaign says it once, naming options cdpr-campaign has, and exits 2."""
    from cdpr_bringup.campaigns import campaign
    robot = tmp_path / 'unseen.yaml'
    robot.write_text(PAPER_ROBOT.read_text().replace('mass_kg: 2.941', 'mass_kg: 3.2'))
    code = campaign.main(['--config', str(robot), '--motions', str(MOTIONS), '--motion-set',
                          'along-1,along-2', '--fidelities', 'elastic', '--detectors', 'threshold',
                          '--directions', 'forward', '--no-failure-free', '--jobs', '1',
                          '--out', str(tmp_path / 'campaign')])
    lines = capsys.readouterr().err.strip().splitlines()
    assert code == 2
    said = [line for line in lines if line.startswith('cdpr-campaign:')]
    assert len(said) == 1 and 'no shipped calibration was made on this robot' in said[0], lines
    assert 'pass --calibration FILE' in said[0]
    assert campaign.parse_args(['--out', 'x', '--calibration', 'mine.yaml']).calibration == 'mine.yaml'


def refused_robot(tmp_path):
    """The paper robot asked for more tension than its motors pull (3.9 N·m on a 36 mm drum)."""
    robot = tmp_path / 'strong.yaml'
    text = PAPER_ROBOT.read_text()
    assert 'tension_max_n: 100.0' in text
    robot.write_text(text.replace('tension_max_n: 100.0', 'tension_max_n: 1000.0'))
    return robot


@pytest.mark.parametrize('tool', ['cdpr-calibrate', 'cdpr-campaign', 'cdpr-bench fdi', 'cdpr-bench roc',
                                  'cdpr-bench sweep'])
def test_a_tool_that_runs_workers_refuses_a_robot_in_one_line(tool, tmp_path, capsys):
    """Said before any worker starts: the key, the file and the bound, no traceback."""
    from cdpr_bringup.bench import main as bench
    from cdpr_bringup.campaigns import calibrate, campaign
    robot = refused_robot(tmp_path)
    mains = {'cdpr-calibrate': calibrate.main, 'cdpr-campaign': campaign.main}
    name, *suite = tool.split()
    main = bench.main if suite else mains[name]
    code = main(suite + ['--config', str(robot), '--jobs', '2', '--out', str(tmp_path / 'out')])
    err = capsys.readouterr().err
    assert code == 2
    assert err == f"{name}: {robot}: 'robot.cables.tension_max_n' must be at most 108.333, got 1000.0\n", err


def _refuse(path):
    from cdpr_control.config import ConfigError
    raise ConfigError(path, 'robot.mass_kg', 'must be positive, got -1')


def test_an_error_raised_in_a_worker_is_re_raised_as_itself(tmp_path):
    """A ConfigError crosses the process boundary whole (pickle would otherwise rebuild it
    from its message alone and break the pool)."""
    from concurrent.futures import ProcessPoolExecutor
    from cdpr_control.config import ConfigError
    with ProcessPoolExecutor(1) as pool:
        with pytest.raises(ConfigError) as raised:
            list(pool.map(_refuse, [str(tmp_path / 'robot.yaml')]))
    assert raised.value.key == 'robot.mass_kg'
    assert str(raised.value) == f"{tmp_path / 'robot.yaml'}: 'robot.mass_kg' must be positive, got -1"
