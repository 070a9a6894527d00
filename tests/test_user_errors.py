"""A user's mistake on the command line: one line naming the option (or the key and the
file), exit 2, no traceback — unless --debug asks for it."""
from __future__ import annotations

import pytest

from cdpr_bringup import graph, robot_summary, scenario
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
    code = scenario.main(RUN + options + ['--out', str(tmp_path / 'run')])
    err = capsys.readouterr().err
    assert code == 2
    assert err.startswith(f'cdpr-scenario: {named}:') and err.count('\n') == 1, err
    assert not (tmp_path / 'run' / 'metrics.json').exists()


def test_debug_shows_the_traceback(tmp_path):
    with pytest.raises(UsageError, match='--fail-cable 9'):
        scenario.main(RUN + ['--fail-cable', '9', '--out', str(tmp_path / 'run'), '--debug'])


@pytest.mark.parametrize('main, name', [(scenario.main, 'cdpr-scenario'), (graph.main, 'cdpr-graph'),
                                        (robot_summary.main, 'cdpr-robot')])
def test_a_missing_or_bad_config_is_one_line(main, name, tmp_path, capsys):
    broken = tmp_path / 'broken.yaml'
    broken.write_text('robot: [1, 2]\n')
    for config, named in (('no_such_robot.yaml', 'no config no_such_robot.yaml'),
                          (str(broken), f"{broken}: 'robot' must be a mapping")):
        extra = ['--out', str(tmp_path / 'run')] if main is scenario.main else []
        assert main(['--config', config] + extra) == 2
        err = capsys.readouterr().err
        assert err.startswith(f'{name}: {named}') and err.count('\n') == 1, err
