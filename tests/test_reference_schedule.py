"""The generator's splicing of goal moves (ReferenceSchedule), without ROS: where each move
starts, from where, what it tabulates, what is rejected and what is dropped."""
from __future__ import annotations

import numpy as np
import pytest

from cdpr_control.config import load_section
from cdpr_control.model.dynamics import inverse_dynamics
from cdpr_control.point_mass.kinematics import inverse_kinematics
from cdpr_control.geometry.motions import load_motion
from cdpr_control.geometry.pose_trajectories import PoseTrajectory
from cdpr_control.model.reference_table import tabulate_reference
from cdpr_control.control.reference_schedule import GoalRejected, PlannedMove, ReferenceSchedule
from cdpr_control.tension_distribution import configured_tension_distribution
from cdpr_control.geometry.trajectories import QUINTIC_PEAK_SPEED_RATIO, Hold, quintic_profile
from conftest import MOTIONS, PAPER_ROBOT

PERIOD_S = 0.002
PEAK_SPEED_M_S = 0.5
FIRST_ROWS = 51   # the first table: 0.1 s of rest at home
GOAL_A = np.array([1.1, 0.8, 1.35])
GOAL_B = np.array([0.6, 1.2, 1.1])
COLUMNS = ('position_m', 'velocity_m_s', 'angle_rad', 'angular_velocity_rad_s', 'feedforward_nm')


@pytest.fixture(scope='module')
def distribution(paper_robot):
    return configured_tension_distribution(load_section(PAPER_ROBOT, 'control'), paper_robot)


@pytest.fixture
def schedule(paper_robot, distribution):
    first = tabulate_reference(paper_robot, distribution,
                               PoseTrajectory(Hold(paper_robot.home_position_m, (FIRST_ROWS - 1) * PERIOD_S)), PERIOD_S)
    return ReferenceSchedule(paper_robot, distribution, PERIOD_S, PEAK_SPEED_M_S, first)


@pytest.mark.parametrize('broken', [None, 3])
def test_a_tabulated_reference_is_each_tick_s_inverse_kinematics_and_dynamics(paper_robot, distribution,
                                                                            broken):
    """The table is computed for all its rows at once; each row must be what the tick's
    pose gives alone (a part of the motion, with cable 4 detached too)."""
    trajectory = load_motion(MOTIONS, 'circle').pose_trajectory
    attached = None if broken is None else paper_robot.cable_mask([broken])
    start_s, rows = 1.0, 400
    table = tabulate_reference(paper_robot, distribution, trajectory, PERIOD_S, start_s,
                               (rows - 1) * PERIOD_S, attached)
    assert len(table) == rows
    for row in range(0, rows, 7):
        position, velocity, acceleration = trajectory.path.sample(start_s + row * PERIOD_S)
        alone = inverse_dynamics(paper_robot, distribution, position, velocity, acceleration, attached)
        angle = inverse_kinematics(paper_robot, position)
        if attached is not None:
            angle[~attached] = 0.0
        for column, expected in zip(COLUMNS, (position, velocity, angle, alone.joint_velocity_rad_s,
                                              alone.torque_nm)):
            np.testing.assert_allclose(getattr(table, column)[row], expected, rtol=1e-12, atol=1e-12,
                                       err_msg=f'{column}, row {row}')


def move_duration_s(start_m, goal_m) -> float:
    return QUINTIC_PEAK_SPEED_RATIO * np.linalg.norm(goal_m - start_m) / PEAK_SPEED_M_S


def position_at(schedule, tick) -> np.ndarray:
    table, row = schedule.sample(tick)
    return table.position_m[row]


def assert_straight_quintic(schedule, start_tick, start_m, goal_m) -> None:
    """The positions from `start_tick` on are those of p_0 + s(t) (p_1 − p_0), then rest at p_1."""
    duration_s = move_duration_s(start_m, goal_m)
    ticks = int(round(duration_s / PERIOD_S))
    for k in (0, 1, ticks // 4, ticks // 2, 3 * ticks // 4, ticks - 1, ticks, ticks + 1):
        s = quintic_profile(k * PERIOD_S, duration_s)[0]
        np.testing.assert_allclose(position_at(schedule, start_tick + k),
                                   start_m + s * (goal_m - start_m), atol=1e-12, err_msg=f'k = {k}')


def plan_by_rows(schedule, rows) -> tuple[list, int]:
    """plan(rows) until nothing is being planned: what settled, and in how many calls."""
    settled, calls = schedule.plan(rows), 1
    while schedule.planning is not None:
        settled += schedule.plan(rows)
        calls += 1
    return settled, calls


def test_a_goal_is_spliced_where_the_current_segment_ends(schedule, paper_robot):
    home = paper_robot.home_position_m
    schedule.add_goal(GOAL_A)
    [move] = schedule.plan()
    assert isinstance(move, PlannedMove) and move.start_tick == FIRST_ROWS
    np.testing.assert_array_equal(move.goal_m, GOAL_A)
    # the move, then one period of rest at the goal: T + 2 periods of rows, within rounding
    assert abs(move.duration_s - (move_duration_s(home, GOAL_A) + 2 * PERIOD_S)) <= PERIOD_S / 2
    assert move.duration_s == pytest.approx(len(schedule.segments[-1][1]) * PERIOD_S)
    for tick in (0, FIRST_ROWS - 1):
        np.testing.assert_array_equal(position_at(schedule, tick), home)
    assert_straight_quintic(schedule, FIRST_ROWS, home, GOAL_A)
    # and rests there until the next goal
    np.testing.assert_array_equal(position_at(schedule, FIRST_ROWS + 10 ** 6), GOAL_A)
    np.testing.assert_array_equal(schedule.end_m, GOAL_A)


def test_a_goal_never_starts_in_the_past(schedule, paper_robot):
    lead = 10
    assert list(schedule.due(0, lead)) == list(range(0, 11))
    assert list(schedule.due(100, lead)) == list(range(100, 111))   # 11 … 99 jumped over
    assert list(schedule.due(99, lead)) == []                      # every one of them is out
    assert schedule.next_tick == 111
    schedule.add_goal(GOAL_A)
    [move] = schedule.plan()
    assert move.start_tick == 111
    assert_straight_quintic(schedule, 111, paper_robot.home_position_m, GOAL_A)


def test_goals_queue_in_order_each_from_where_the_previous_move_ends(schedule, paper_robot):
    schedule.add_goal(GOAL_A)
    assert schedule.plan(8) == []   # still planning the first move
    schedule.add_goal(GOAL_B)
    first, second = plan_by_rows(schedule, 8)[0]
    np.testing.assert_array_equal(first.goal_m, GOAL_A)
    np.testing.assert_array_equal(second.goal_m, GOAL_B)
    assert second.start_tick == first.start_tick + len(schedule.segments[1][1])
    assert_straight_quintic(schedule, first.start_tick, paper_robot.home_position_m, GOAL_A)
    assert_straight_quintic(schedule, second.start_tick, GOAL_A, GOAL_B)


def test_a_goal_where_the_motion_ends_is_no_move(schedule, paper_robot):
    segments = list(schedule.segments)
    schedule.add_goal(paper_robot.home_position_m)
    assert schedule.plan() == [] and schedule.planning is None
    assert schedule.segments == segments
    # nor is a goal queued behind a move to the same point
    schedule.add_goal(GOAL_A)
    schedule.add_goal(GOAL_A)
    assert len(schedule.plan()) == 1 and len(schedule.segments) == 2


def test_planning_by_rows_tabulates_what_planning_at_once_does(schedule, paper_robot, distribution):
    at_once = ReferenceSchedule(paper_robot, distribution, PERIOD_S, PEAK_SPEED_M_S,
                                schedule.segments[0][1])
    at_once.add_goal(GOAL_A)
    [whole] = at_once.plan()
    schedule.add_goal(GOAL_A)
    rows_per_call = 8
    [by_rows], calls = plan_by_rows(schedule, rows_per_call)
    rows = len(at_once.segments[-1][1])
    assert calls == -(-rows // rows_per_call)
    assert by_rows.start_tick == whole.start_tick and by_rows.duration_s == whole.duration_s
    for name in COLUMNS:
        np.testing.assert_allclose(getattr(schedule.segments[-1][1], name),
                                   getattr(at_once.segments[-1][1], name), rtol=0, atol=1e-9)


@pytest.mark.parametrize('goal', [[0.844, 0.965, 2.3], [-0.01, 0.965, 1.25], [np.nan, 0.9, 1.2]])
def test_a_goal_outside_the_workspace_is_rejected(schedule, goal):
    with pytest.raises(GoalRejected, match='outside the workspace'):
        schedule.add_goal(goal)
    assert not schedule.goals and schedule.plan() == [] and len(schedule.segments) == 1


@pytest.mark.parametrize('rows', [None, 8])
def test_a_goal_whose_tensions_are_infeasible_is_rejected_and_the_next_planned(schedule, paper_robot,
                                                                               rows):
    corner = np.array([0.0, 0.0, 2.2])   # in the workspace; no positive tensions hold it there
    schedule.add_goal(corner)
    schedule.add_goal(GOAL_A)
    rejected, move = plan_by_rows(schedule, rows)[0]
    assert isinstance(rejected, GoalRejected)
    assert str(rejected).startswith(f'goal {corner} cannot be reached: ')
    assert move.start_tick == FIRST_ROWS and len(schedule.segments) == 2
    assert_straight_quintic(schedule, FIRST_ROWS, paper_robot.home_position_m, GOAL_A)


def test_segments_wholly_out_are_dropped(schedule):
    schedule.add_goal(GOAL_A)
    [to_a] = schedule.plan()
    move_a = schedule.segments[-1]
    # out: the first table, and part of the move to A
    schedule.due(FIRST_ROWS + 10, 0)
    schedule.add_goal(GOAL_B)
    [to_b] = schedule.plan()
    assert schedule.segments[0] is move_a and len(schedule.segments) == 2
    # out: everything planned; the move back to A starts now, from B
    now = to_b.start_tick + len(schedule.segments[-1][1]) + 100
    schedule.due(now, 0)
    schedule.add_goal(GOAL_A)
    [back] = schedule.plan()
    assert back.start_tick == now + 1
    assert [start for start, _ in schedule.segments] == [now + 1]
    assert_straight_quintic(schedule, now + 1, GOAL_B, GOAL_A)
