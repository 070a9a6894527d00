"""Recovery strategies chosen per robot in YAML (recovery.strategy,
docs/recovery-strategies.md): the docs' example strategy, `line`, run through a failure
in the in-process engine as cdpr-scenario runs it, and judged by what the end-effector
does; `auto` resolving to the strategy that fits the robot; a strategy that cannot
recover the robot's degrees of freedom refused when the file is read."""
from __future__ import annotations

import numpy as np
import pytest

from cdpr_bringup.runs.engine import run_inprocess
from cdpr_bringup.runs.settle import ScenarioOptions, build_scenario
from cdpr_control.config import ConfigError
from cdpr_control.setup.robot_file import load_robot
from cdpr_fdi.settings.config import load_recovery_config
from cdpr_fdi.recovery_planning.recovery import safe_point_for
from cdpr_fdi.recovery_strategies import STRATEGIES
from cdpr_msgs_py.contract import RECOVERY_MOVE, RECOVERY_TENSION, SAFE_HOLD, VERDICT_DELAY_TICKS

from conftest import CONFIG_DIR, PAPER_ROBOT

PLATFORM_ROBOT = CONFIG_DIR / 'robots' / 'crossed_platform_robot.yaml'


def with_strategy(tmp_path, robot_file, strategy: str):
    """A copy of `robot_file` whose recovery section chooses `strategy`."""
    path = tmp_path / robot_file.name
    path.write_text(robot_file.read_text() + f'\nrecovery:\n  strategy: {strategy}\n')
    return path


def test_the_line_strategy_brings_the_paper_robot_to_rest_at_its_safe_point(tmp_path):
    """Cable 1 breaks halfway along along-1 (elastic plant): the end-effector is inside
    what the three cables left hold, and `line` moves it straight to SP under position
    control from the tick after the naming, with no tension phase. It comes to rest
    there, above the table, every remaining cable within [tension_min_n, tension_max_n]
    of the robot file from the takeover on."""
    config = with_strategy(tmp_path, PAPER_ROBOT, 'line')
    scenario = build_scenario(ScenarioOptions(config=str(config), motion='along-1', fail_cables=[1],
                                              fail_at_fraction=0.5))
    assert scenario.recovery.strategy == 'line'
    recording = run_inprocess(scenario)
    fdi, robot = recording.fdi, scenario.robot
    assert fdi['broken_cables'] == [1] and fdi['mode'] == SAFE_HOLD, fdi['fault']
    named = fdi['identified_tick']
    assert fdi['phase_ticks'][RECOVERY_MOVE] == named and RECOVERY_TENSION not in fdi['phase_ticks']
    safe = safe_point_for(robot, scenario.recovery, robot.cable_mask([0]))
    assert fdi['safe_point_m'] == pytest.approx(safe.tolist())
    # at rest at SP, held there to the end of the run
    held = recording.view_time_s >= fdi['phase_ticks'][SAFE_HOLD] * scenario.period_s
    assert np.count_nonzero(held) > 10
    position, time = recording.true_position_m[held], recording.view_time_s[held]
    assert np.max(np.linalg.norm(position - safe, axis=1)) < scenario.recovery.reached_tolerance_m
    speed = np.linalg.norm(np.diff(position, axis=0), axis=1) / np.diff(time)
    assert speed.max() < 1e-3 and np.ptp(position, axis=0).max() < 1e-4, (speed.max(), np.ptp(position, axis=0))
    assert recording.true_position_m[:, 2].min() > scenario.recovery.table_height_m
    # the remaining cables taut and within their bounds from the takeover on
    takeover = recording.view_time_s >= (named + VERDICT_DELAY_TICKS) * scenario.period_s
    remaining = recording.true_tension_n[takeover][:, robot.cable_mask([0])]
    assert remaining.min() >= robot.tension_min_n and remaining.max() <= robot.tension_max_n, (
        remaining.min(), remaining.max())


def test_the_line_strategy_gives_up_where_the_cables_left_cannot_pull_it_straight_to_sp(tmp_path):
    """Cable 3 breaks a fifth of the way along along-1: outside what the three cables left
    hold, no line to SP keeps their tensions within the bounds. `line` does not start
    (FAULT, saying why), where the paper's strategy recovers the end-effector."""
    config = with_strategy(tmp_path, PAPER_ROBOT, 'line')
    recording = run_inprocess(build_scenario(ScenarioOptions(config=str(config), motion='along-1',
                                                             fail_cables=[3], fail_at_fraction=0.2)))
    assert recording.fdi['broken_cables'] == [3] and recording.fdi['mode'] == 'FAULT'
    assert 'no straight line to SP' in recording.fdi['fault']
    paper = run_inprocess(build_scenario(ScenarioOptions(config=str(PAPER_ROBOT), motion='along-1',
                                                         fail_cables=[3], fail_at_fraction=0.2)))
    assert paper.fdi['mode'] == SAFE_HOLD


@pytest.mark.parametrize('robot_file, fitting', [(PAPER_ROBOT, 'paper'), (PLATFORM_ROBOT, 'steered')])
def test_auto_is_the_strategy_fitting_the_robot(robot_file, fitting):
    """The shipped files leave recovery.strategy `auto`: the paper's for a point mass,
    steered for a platform, as before strategies could be chosen."""
    robot = load_robot(robot_file)
    strategy = load_recovery_config(robot_file, robot).strategy
    assert strategy == fitting and STRATEGIES[strategy].degrees_of_freedom == robot.degrees_of_freedom


@pytest.mark.parametrize('robot_file, strategy, freedom', [
    (PAPER_ROBOT, 'steered', 3), (PAPER_ROBOT, 'braked', 3), (PLATFORM_ROBOT, 'paper', 6),
    (PLATFORM_ROBOT, 'line', 6)])
def test_a_strategy_that_cannot_recover_the_robot_is_refused_naming_the_key_and_file(
        tmp_path, robot_file, strategy, freedom):
    config = with_strategy(tmp_path, robot_file, strategy)
    with pytest.raises(ConfigError) as refused:
        load_recovery_config(config, load_robot(config))
    message = str(refused.value)
    assert message.startswith(f"{config}: 'recovery.strategy' is {strategy}") and '\n' not in message
    assert f'has {freedom} DOF' in message


def test_an_unknown_strategy_is_refused_with_the_registered_ones(tmp_path):
    config = with_strategy(tmp_path, PAPER_ROBOT, 'teleport')
    with pytest.raises(ConfigError, match=r"'recovery.strategy' must be one of auto, paper, steered, braked, line"):
        load_recovery_config(config, load_robot(config))


def test_the_key_strategy_replaced_is_refused_not_dropped(tmp_path):
    """A file of before recovery.strategy, with recovery.platform_recovery: braked, would
    otherwise run steered without a word."""
    config = tmp_path / 'old.yaml'
    config.write_text(PLATFORM_ROBOT.read_text() + '\nrecovery:\n  platform_recovery: braked\n')
    with pytest.raises(ConfigError) as refused:
        load_recovery_config(config, load_robot(config))
    assert str(refused.value).startswith(f"{config}: 'recovery.platform_recovery' is gone: recovery.strategy")
