"""The /diagnostics levels (cdpr_msgs_py.health) and the per-cycle writers' QoS, without
DDS: each rule at and around its limit."""
from __future__ import annotations

import pytest
from rclpy.qos import DurabilityPolicy, HistoryPolicy, ReliabilityPolicy

from cdpr_control.config import ConfigError, Section, load_config
from cdpr_msgs_py import qos
from cdpr_msgs_py.health import (ERROR, OK, WARN, AcknowledgementWatch, Health, HealthLimits,
                                 loop_problem, unjudged_problem, verdict_problems)

from conftest import PAPER_ROBOT

LIMITS = HealthLimits(warning_hold_s=30.0, reader_lag_limit_s=10.0, unjudged_limit=0.01,
                      tick_rate_min=0.95, deadline_miss_limit=0.02)
PERIOD_S = 0.002


def section(**values) -> Section:
    return Section(values, 'robot.yaml', 'health')


def test_limits_come_from_the_config_with_a_default_for_each_missing_key():
    shipped = HealthLimits.from_section(load_config(PAPER_ROBOT).section('health'))
    assert shipped == LIMITS
    assert HealthLimits.from_section(section(warning_hold_s=5.0)) == HealthLimits(warning_hold_s=5.0)
    assert HealthLimits.from_section(section()) == HealthLimits()


@pytest.mark.parametrize('key, value', [('unjudged_limit', 1.5), ('deadline_miss_limit', -0.1),
                                        ('warning_hold_s', 'long'), ('tick_rate_min', float('nan'))])
def test_a_bad_limit_is_refused_naming_its_key(key, value):
    with pytest.raises(ConfigError, match=f"'health.{key}'"):
        HealthLimits.from_section(section(**{key: value}))


def test_levels_from_conditions_errors_first():
    health = Health(LIMITS)
    assert health.assess(0.0, ['', ''], ['']) == (OK, 'ok')
    assert health.assess(0.0, [''], ['3 of 100 ticks unjudged']) == (WARN, '3 of 100 ticks unjudged')
    assert health.assess(0.0, ['FDI unavailable'], ['a warning']) == (ERROR, 'FDI unavailable; a warning')


def test_an_event_warns_for_the_hold_time_after_it_was_last_seen():
    health = Health(LIMITS)
    health.warn('rejected goal', 'rejected messages on goal', 100.0)
    health.warn('rejected goal', 'rejected messages on goal (again)', 110.0)
    assert health.assess(110.0 + LIMITS.warning_hold_s, [], []) == (WARN, 'rejected messages on goal (again)')
    assert health.assess(110.0 + LIMITS.warning_hold_s + 0.1, [], []) == (OK, 'ok')
    # an error outranks a held warning, which is still told
    health.warn('lagging /t', 'a reader of /t lags', 200.0)
    assert health.assess(201.0, ['SAFE_HOLD'], []) == (ERROR, 'SAFE_HOLD; a reader of /t lags')


def test_the_loop_keeps_its_period_down_to_the_limits():
    nominal = 1.0 / PERIOD_S
    assert loop_problem(LIMITS, PERIOD_S, 0, 0.0, 0) == '', 'nothing to judge'
    assert loop_problem(LIMITS, PERIOD_S, 500, 1.0, 0) == ''
    at_rate_limit = 500 / (LIMITS.tick_rate_min * nominal)   # s for 500 intervals
    assert loop_problem(LIMITS, PERIOD_S, 500, at_rate_limit, 0) == ''
    assert 'tick rate 475 Hz of 500 Hz' in loop_problem(LIMITS, PERIOD_S, 500, at_rate_limit * 1.0001, 0)
    assert loop_problem(LIMITS, PERIOD_S, 500, 1.0, 10) == '', '2 % of deadlines missed'
    assert loop_problem(LIMITS, PERIOD_S, 500, 1.0, 11) == \
        'the loop does not keep its period: 11 of 500 deadlines missed'
    # a loop that stalled for a second in a window: one interval, one miss
    assert 'tick rate 1 Hz' in loop_problem(LIMITS, PERIOD_S, 1, 1.0, 1)


def test_more_than_the_limit_of_unjudged_ticks_is_a_warning():
    assert unjudged_problem(LIMITS, 0, 0) == ''
    assert unjudged_problem(LIMITS, 500, 5) == '', 'exactly 1 %'
    assert unjudged_problem(LIMITS, 500, 6) == '6 of 500 ticks unjudged (1.2 %)'
    assert unjudged_problem(LIMITS, 500, 365) == '365 of 500 ticks unjudged (73.0 %)'


def test_fault_is_an_error_and_a_handled_broken_cable_a_warning():
    assert verdict_problems('NOMINAL', [], '') == ('', '')
    assert verdict_problems('RECOVERY_TENSION', [4], '') == ('', 'cable(s) 4 broken: RECOVERY_TENSION')
    assert verdict_problems('FAULT', [1, 2], 'fewer than 3 cables') == ('FAULT: fewer than 3 cables', '')


def test_a_writer_lags_only_with_a_reader_from_outside_the_graph_unacknowledged_beyond_the_limit():
    watch = AcknowledgementWatch(LIMITS.reader_lag_limit_s)
    watch.acknowledged('/cdpr/joint_states', 0.0)
    watch.acknowledged('/cdpr/effort_command', 0.0)
    graph_only = {'/cdpr/joint_states': (4, 4), '/cdpr/effort_command': (3, 3)}
    outside = {'/cdpr/joint_states': (5, 4), '/cdpr/effort_command': (3, 3)}
    assert watch.lagging(30.0, graph_only) == {}, "the graph's own readers are never blamed"
    assert watch.lagging(10.0, outside) == {}, 'at the limit'
    assert watch.lagging(10.5, outside) == {'/cdpr/joint_states': 10.5}
    watch.acknowledged('/cdpr/joint_states', 11.0)
    assert watch.lagging(12.0, outside) == {}
    # a node started alone knows no graph: any reader may be the one
    assert watch.lagging(30.0, {'/cdpr/joint_states': (1, None), '/cdpr/effort_command': (0, None)}) == \
        {'/cdpr/joint_states': 19.0}


def test_stream_writers_keep_the_configured_seconds_of_ticks_and_never_keep_all():
    writer = qos.stream_writer(load_config(PAPER_ROBOT).section('streams'), PERIOD_S)
    assert (writer.history, writer.depth) == (HistoryPolicy.KEEP_LAST, 5000)
    assert (writer.reliability, writer.durability) == (ReliabilityPolicy.RELIABLE, DurabilityPolicy.VOLATILE)
    assert qos.stream_writer(Section({}, 'robot.yaml', 'streams'), PERIOD_S).depth == \
        round(qos.HISTORY_S / PERIOD_S)
    assert qos.stream_writer(Section({'history_s': 0.0031}, 'robot.yaml', 'streams'), PERIOD_S).depth == 2
    with pytest.raises(ConfigError, match="'streams.history_s'"):
        qos.stream_writer(Section({'history_s': 0}, 'robot.yaml', 'streams'), PERIOD_S)
