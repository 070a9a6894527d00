"""Reference trajectories: derivatives, rest-to-rest ends, speeds, and the paper's motions."""
from __future__ import annotations

import numpy as np
import pytest

from cdpr_control.config import load_section
from cdpr_control.point_mass.kinematics import structure_matrix
from cdpr_control.geometry.motions import load_motion, motion_names
from cdpr_control.tension_distribution import minimum_norm
from cdpr_control.geometry.trajectories import Circle, HermiteQuintic, Hold, Sequence, StraightLine
from conftest import MOTIONS, PAPER_ROBOT

LINE = StraightLine([0.4, 0.5, 1.0], [1.3, 1.5, 1.8], 2.5)
CIRCLE = Circle([0.844, 0.965, 1.25], 0.4, np.radians(30.0), np.radians(-250.0), 4.0)
SEQUENCE = Sequence([Hold(LINE.start, 0.7), LINE, Hold(LINE.end, 0.4),
                     StraightLine(LINE.end, [0.9, 0.4, 1.3], 1.5), Hold([0.9, 0.4, 1.3], 0.3)])
# a brake taking over a swinging end-effector: with its velocity and acceleration
BRAKE = HermiteQuintic([0.5, 0.6, 1.1], [0.2, -0.1, 0.05], [0.6, 0.55, 1.12], [0.0, 0.0, 0.0], 0.8,
                       [-1.5, 0.4, 2.0], [0.3, 0.0, -0.2])
TRAJECTORIES = {'line': LINE, 'circle': CIRCLE, 'sequence': SEQUENCE}
# ... and those that may start or end moving
SEGMENTS = {**TRAJECTORIES, 'brake': BRAKE}


def _speeds(trajectory, dt=1e-3):
    times = np.arange(0.0, trajectory.duration_s + dt / 2, dt)
    return times, np.array([np.linalg.norm(trajectory.sample(t)[1]) for t in times])


@pytest.mark.parametrize('name', list(SEGMENTS))
def test_derivatives_match_central_differences(name):
    trajectory = SEGMENTS[name]
    h = 1e-5
    times = np.linspace(0.0, trajectory.duration_s, 37)[1:-1] + 0.0137
    for t in times:
        p, v, a = trajectory.sample(t)
        p_minus, v_minus, _ = trajectory.sample(t - h)
        p_plus, v_plus, _ = trajectory.sample(t + h)
        np.testing.assert_allclose((p_plus - p_minus) / (2 * h), v, atol=1e-7, err_msg=f't = {t}')
        np.testing.assert_allclose((v_plus - v_minus) / (2 * h), a, atol=1e-6, err_msg=f't = {t}')


@pytest.mark.parametrize('name', list(TRAJECTORIES))
def test_starts_and_ends_at_rest(name):
    trajectory = TRAJECTORIES[name]
    for t in (0.0, trajectory.duration_s, -1.0, trajectory.duration_s + 1.0):
        _, v, a = trajectory.sample(t)
        np.testing.assert_allclose(v, 0.0, atol=1e-12)
        np.testing.assert_allclose(a, 0.0, atol=1e-12)
    np.testing.assert_allclose(trajectory.sample(-1.0)[0], trajectory.start, atol=1e-12)
    np.testing.assert_allclose(trajectory.sample(trajectory.duration_s + 1.0)[0], trajectory.end, atol=1e-12)


def test_line_ends_and_path():
    np.testing.assert_allclose(LINE.start, [0.4, 0.5, 1.0], atol=1e-15)
    np.testing.assert_allclose(LINE.end, [1.3, 1.5, 1.8], atol=1e-15)
    direction = (LINE.goal_m - LINE.start_m) / np.linalg.norm(LINE.goal_m - LINE.start_m)
    for t in np.linspace(0.0, LINE.duration_s, 11):
        offset = LINE.sample(t)[0] - LINE.start_m
        np.testing.assert_allclose(offset - (offset @ direction) * direction, 0.0, atol=1e-14)


def test_circle_stays_on_its_circle():
    for t in np.linspace(0.0, CIRCLE.duration_s, 23):
        p, v, _ = CIRCLE.sample(t)
        offset = p - CIRCLE.centre_m
        assert offset[2] == pytest.approx(0.0, abs=1e-15)
        assert np.linalg.norm(offset) == pytest.approx(0.4, rel=1e-14)
        assert offset @ v == pytest.approx(0.0, abs=1e-12)
    start = CIRCLE.centre_m + 0.4 * np.array([np.cos(np.radians(30.0)), np.sin(np.radians(30.0)), 0.0])
    end = CIRCLE.centre_m + 0.4 * np.array([np.cos(np.radians(-220.0)), np.sin(np.radians(-220.0)), 0.0])
    np.testing.assert_allclose(CIRCLE.start, start, atol=1e-14)
    np.testing.assert_allclose(CIRCLE.end, end, atol=1e-14)


@pytest.mark.parametrize('speed', [0.1, 0.5, 1.3])
def test_line_peak_speed(speed):
    line = StraightLine.with_peak_speed([0.2, 0.3, 0.9], [1.4, 1.1, 1.7], speed)
    _, speeds = _speeds(line, dt=line.duration_s / 2000)   # an even count samples the middle
    assert speeds.max() == pytest.approx(speed, rel=1e-9)
    # the mean speed is length / duration
    length = np.linalg.norm([1.2, 0.8, 0.8])
    assert np.trapezoid(speeds, dx=line.duration_s / 2000) == pytest.approx(length, rel=1e-6)


@pytest.mark.parametrize('speed', [0.2, 0.5])
def test_circle_peak_speed(speed):
    circle = Circle.with_peak_speed([0.8, 0.9, 1.2], 0.4, 0.0, np.radians(360.0), speed)
    _, speeds = _speeds(circle, dt=circle.duration_s / 2000)
    assert speeds.max() == pytest.approx(speed, rel=1e-9)
    assert np.trapezoid(speeds, dx=circle.duration_s / 2000) == pytest.approx(2 * np.pi * 0.4, rel=1e-6)


@pytest.mark.parametrize('name', list(SEGMENTS))
def test_reversed_swaps_the_ends(name):
    trajectory = SEGMENTS[name]
    backward = trajectory.reversed()
    assert backward.duration_s == pytest.approx(trajectory.duration_s)
    np.testing.assert_allclose(backward.start, trajectory.end, atol=1e-12)
    np.testing.assert_allclose(backward.end, trajectory.start, atol=1e-12)
    # same path, run backward in time: p_r(t) = p(T − t), ṗ_r(t) = −ṗ(T − t)
    for t in np.linspace(0.0, trajectory.duration_s, 17)[1:-1] + 0.011:
        p, v, a = trajectory.sample(trajectory.duration_s - t)
        p_r, v_r, a_r = backward.sample(t)
        np.testing.assert_allclose(p_r, p, atol=1e-9)
        np.testing.assert_allclose(v_r, -v, atol=1e-9)
        np.testing.assert_allclose(a_r, a, atol=1e-9)


def test_a_hermite_quintic_meets_its_ends_in_position_velocity_and_acceleration():
    for t, position, velocity, acceleration in (
            (0.0, BRAKE.start_m, BRAKE.start_velocity_m_s, BRAKE.start_acceleration_m_s2),
            (BRAKE.duration_s, BRAKE.goal_m, BRAKE.goal_velocity_m_s, BRAKE.goal_acceleration_m_s2)):
        for figure, expected in zip(BRAKE.sample(t), (position, velocity, acceleration)):
            np.testing.assert_allclose(figure, expected, atol=1e-12)


def test_sequence_must_be_continuous():
    with pytest.raises(ValueError):
        Sequence([LINE, StraightLine([0.0, 0.0, 1.0], [1.0, 1.0, 1.0], 1.0)])
    with pytest.raises(ValueError):
        Sequence([])


def test_sequence_segments_follow_each_other():
    assert SEQUENCE.duration_s == pytest.approx(0.7 + 2.5 + 0.4 + 1.5 + 0.3)
    np.testing.assert_allclose(SEQUENCE.sample(0.7 + 1.25)[0], 0.5 * (LINE.start + LINE.end), atol=1e-12)
    np.testing.assert_allclose(SEQUENCE.sample(0.7 + 2.5 + 0.2)[0], LINE.end, atol=1e-12)


@pytest.mark.parametrize('trajectory', [
    *SEGMENTS.values(), Hold(LINE.end, 0.5),
    HermiteQuintic([0.5, 0.6, 1.1], [0.2, -0.1, 0.05], [1.0, 1.1, 1.3], [0.0, 0.1, 0.0], 1.5)],
    ids=[*SEGMENTS, 'hold', 'hermite'])
def test_an_array_of_times_samples_each_time_as_alone(trajectory):
    """A reference is tabulated by sampling all its times at once: each row must be the
    sample of its time, at the ends, before and after the motion and on the seams of a
    sequence."""
    times = np.concatenate([np.linspace(-0.3, trajectory.duration_s + 0.3, 301),
                            SEQUENCE.starts_s, [0.0, trajectory.duration_s]])
    rows = trajectory.sample(times)
    for figure in rows:
        assert figure.shape == (times.size, 3)
    for index, t in enumerate(times):
        for figure, alone in zip(rows, trajectory.sample(float(t))):
            np.testing.assert_allclose(figure[index], alone, rtol=0.0, atol=1e-12)


# ---- the paper's named motions --------------------------------------------------------

NAMES = motion_names(MOTIONS)
CONTROL_PERIOD_S = load_section(PAPER_ROBOT, 'control').number('period_s')


def test_motion_file_lists_the_paper_motions():
    expected = {f'along-{k}' for k in range(1, 5)} | {f'orthogonal-{k}' for k in range(1, 5)} | {'circle'}
    assert expected <= set(NAMES)


@pytest.mark.parametrize('reverse', [False, True], ids=['forward', 'reverse'])
@pytest.mark.parametrize('name', NAMES)
def test_motion_keeps_cables_taut_and_inside_workspace(paper_robot, name, reverse):
    motion = load_motion(MOTIONS, name, reverse)
    trajectory = motion.trajectory
    lowest = np.inf
    g = paper_robot.gravity_m_s2
    for t in np.arange(0.0, trajectory.duration_s + CONTROL_PERIOD_S / 2, CONTROL_PERIOD_S):
        p, _, a = trajectory.sample(t)
        assert np.all(p >= paper_robot.workspace_min_m) and np.all(p <= paper_robot.workspace_max_m), \
            f'{name} leaves the workspace at t = {t:.3f} s, p = {p}'
        s, _ = structure_matrix(paper_robot, p)
        tensions = minimum_norm(s, paper_robot.mass_kg * (a - g))
        lowest = min(lowest, tensions.min())
        assert tensions.min() >= paper_robot.tension_min_n, f'{name}: τ = {tensions} at t = {t:.3f} s'
        assert tensions.max() <= paper_robot.tension_max_n
    # DESIGN §4: no pseudo-inverse tension below 2.4 N on the Table 4/6 paths at 0.5 m/s
    if name != 'circle':
        assert lowest > 2.4


@pytest.mark.parametrize('name', NAMES)
def test_motion_rests_then_moves_at_the_default_peak_speed(name):
    motion = load_motion(MOTIONS, name)
    defaults = load_section(MOTIONS, 'motion_defaults')
    assert motion.move_start_s == pytest.approx(defaults.number('rest_before_s'))
    assert motion.trajectory.duration_s - motion.move_end_s == pytest.approx(defaults.number('rest_after_s'))
    _, speeds = _speeds(motion.move, dt=motion.move.duration_s / 2000)
    assert speeds.max() == pytest.approx(defaults.number('peak_speed_m_s'), rel=1e-9)
    for t in (0.0, 0.5 * motion.move_start_s, motion.move_end_s + 0.1, motion.trajectory.duration_s):
        np.testing.assert_allclose(motion.trajectory.sample(t)[1], 0.0, atol=1e-12)


@pytest.mark.parametrize('name', [n for n in NAMES if n.startswith(('along', 'orthogonal'))])
def test_time_at_half_fraction_is_the_line_midpoint(name):
    motion = load_motion(MOTIONS, name)
    section = load_section(MOTIONS, 'motions').section(name)
    midpoint = 0.5 * (section.vector('start', 3) + section.vector('goal', 3))
    np.testing.assert_allclose(motion.trajectory.sample(motion.time_at_fraction(0.5))[0], midpoint, atol=1e-9)
    # fraction 0 and 1 are the ends of the move
    np.testing.assert_allclose(motion.trajectory.sample(motion.time_at_fraction(0.0))[0],
                               section.vector('start', 3), atol=1e-9)
    np.testing.assert_allclose(motion.trajectory.sample(motion.time_at_fraction(1.0))[0],
                               section.vector('goal', 3), atol=1e-9)


def test_time_at_fraction_on_the_circle():
    motion = load_motion(MOTIONS, 'circle')
    section = load_section(MOTIONS, 'motions').section('circle')
    centre = section.vector('centre', 3)
    start = np.radians(section.number('start_angle_deg'))
    # 135° of arc (the paper's failure point, DESIGN §6)
    fraction = 135.0 / section.number('sweep_deg')
    p = motion.trajectory.sample(motion.time_at_fraction(fraction))[0]
    angle = start + np.radians(135.0)
    np.testing.assert_allclose(p, centre + 0.4 * np.array([np.cos(angle), np.sin(angle), 0.0]), atol=1e-9)


@pytest.mark.parametrize('name', [n for n in NAMES if n.startswith(('along', 'orthogonal'))])
def test_motions_relative_to_cable_4(paper_robot, name):
    """Table 4 lines aim at A4; Table 6 lines are horizontal and cross cable 4 at right
    angles at their midpoint (the paper's table rounds orthogonal-1 to about 0.7°)."""
    section = load_section(MOTIONS, 'motions').section(name)
    start, goal = section.vector('start', 3), section.vector('goal', 3)
    direction = (goal - start) / np.linalg.norm(goal - start)
    if name.startswith('along'):
        u4 = paper_robot.exit_points_m[3] - start
        assert direction @ u4 / np.linalg.norm(u4) == pytest.approx(1.0, abs=1e-4)
    else:
        u4 = paper_robot.exit_points_m[3] - 0.5 * (start + goal)
        assert direction[2] == 0.0
        assert direction @ u4 / np.linalg.norm(u4) == pytest.approx(0.0, abs=0.015)
