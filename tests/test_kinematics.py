"""Kinematics against finite differences and geometry (DESIGN §4 sign conventions)."""
from __future__ import annotations

from itertools import combinations

import numpy as np
import pytest
from scipy.optimize import least_squares

from cdpr_control.point_mass.kinematics import (KinematicsError, cable_vectors, forward_kinematics,
                                     inverse_kinematics, joint_acceleration, joint_velocity,
                                     structure_matrix, structure_matrix_rate)
from conftest import cable_masks, random_positions, random_unit_vectors


def _lengths(robot, p):
    return np.linalg.norm(robot.exit_points_m - p, axis=1)


def _angles_for_lengths(robot, lengths):
    return (lengths - robot.cable_length_offset_m) / robot.motor.drum_radius_m


def test_structure_matrix_is_unit_vectors_towards_exit_points(robot, rng):
    for p in random_positions(robot, rng, 10):
        s, d = structure_matrix(robot, p)
        assert s.shape == (3, robot.cable_count)
        np.testing.assert_allclose(d, _lengths(robot, p), rtol=1e-14)
        np.testing.assert_allclose(np.linalg.norm(s, axis=0), 1.0, rtol=1e-14)
        # u_i points from the end-effector to A_i: p + d_i u_i = A_i
        np.testing.assert_allclose(p[:, None] + s * d, robot.exit_points_m.T, atol=1e-12)


def test_inverse_kinematics_zero_at_home_and_sign(robot):
    np.testing.assert_allclose(inverse_kinematics(robot, robot.home_position_m), 0.0, atol=1e-12)
    # moving down pays out every cable: l grows, so θ grows (θ grows when the cable pays out)
    lower = robot.home_position_m - np.array([0.0, 0.0, 0.2])
    assert np.all(inverse_kinematics(robot, lower) > 0.0)
    expected = (_lengths(robot, lower) - _lengths(robot, robot.home_position_m)) / robot.motor.drum_radius_m
    np.testing.assert_allclose(inverse_kinematics(robot, lower), expected, rtol=1e-12)


def test_structure_matrix_rate_matches_finite_differences(robot, rng):
    h = 1e-6
    positions = random_positions(robot, rng, 8)
    velocities = 0.8 * random_unit_vectors(rng, 8)
    for p0, v in zip(positions, velocities):
        s, d = structure_matrix(robot, p0)
        s_plus, _ = structure_matrix(robot, p0 + v * h)
        s_minus, _ = structure_matrix(robot, p0 - v * h)
        numeric = (s_plus - s_minus) / (2 * h)
        np.testing.assert_allclose(structure_matrix_rate(s, d, v), numeric, atol=1e-8)


def _curved_path(robot):
    """p(t) with analytic ṗ, p̈: a tilted ellipse plus a slow vertical parabola."""
    centre = 0.5 * (robot.workspace_min_m + robot.workspace_max_m)
    w = 2.3

    def path(t):
        p = centre + np.array([0.3 * np.cos(w * t), 0.25 * np.sin(w * t), 0.1 * np.sin(2 * w * t) + 0.05 * t * t])
        v = np.array([-0.3 * w * np.sin(w * t), 0.25 * w * np.cos(w * t),
                      0.2 * w * np.cos(2 * w * t) + 0.1 * t])
        a = np.array([-0.3 * w * w * np.cos(w * t), -0.25 * w * w * np.sin(w * t),
                      -0.4 * w * w * np.sin(2 * w * t) + 0.1])
        return p, v, a
    return path


@pytest.mark.parametrize('t', [0.0, 0.37, 1.1, 2.05])
def test_joint_rates_match_finite_differences_of_inverse_kinematics(robot, t):
    path = _curved_path(robot)
    p, v, a = path(t)
    # the path itself: its analytic derivatives are right
    h = 1e-5
    np.testing.assert_allclose((path(t + h)[0] - path(t - h)[0]) / (2 * h), v, atol=1e-8)
    s, d = structure_matrix(robot, p)
    rho = robot.motor.drum_radius_m
    theta_dot = joint_velocity(s, v, rho)
    theta_ddot = joint_acceleration(s, structure_matrix_rate(s, d, v), v, a, rho)
    ik = [inverse_kinematics(robot, path(t + k * h)[0]) for k in (-1, 0, 1)]
    np.testing.assert_allclose(theta_dot, (ik[2] - ik[0]) / (2 * h), rtol=1e-7, atol=1e-7)
    h2 = 1e-4
    ik2 = [inverse_kinematics(robot, path(t + k * h2)[0]) for k in (-1, 0, 1)]
    np.testing.assert_allclose(theta_ddot, (ik2[2] - 2 * ik2[1] + ik2[0]) / h2 ** 2,
                               rtol=1e-5, atol=1e-4)


def test_forward_inverse_round_trip_all_and_one_broken(robot, rng):
    positions = random_positions(robot, rng, 25, margin_m=0.02)
    checked = 0
    for label, cables in cable_masks(robot):
        for p in positions:
            checked += 1
            theta = inverse_kinematics(robot, p)
            p_fk = forward_kinematics(robot, theta, cables)
            np.testing.assert_allclose(p_fk, p, atol=1e-9, err_msg=f'{label}, p = {p}')
            # the angles of the cables not used are irrelevant to FK
            noisy = theta.copy()
            noisy[~cables] += 123.0
            np.testing.assert_allclose(forward_kinematics(robot, noisy, cables), p, atol=1e-9)
            np.testing.assert_allclose(inverse_kinematics(robot, p_fk), theta, atol=1e-7)
    # every cable, then each one broken
    assert checked == len(positions) * (robot.cable_count + 1)


def test_forward_kinematics_least_squares_with_noisy_lengths(robot, rng):
    for p in random_positions(robot, rng, 15):
        true_lengths = _lengths(robot, p)
        lengths = true_lengths + rng.normal(scale=3e-3, size=robot.cable_count)
        p_fk = forward_kinematics(robot, _angles_for_lengths(robot, lengths))
        residual_fk = np.linalg.norm(_lengths(robot, p_fk) - lengths)
        residual_true = np.linalg.norm(true_lengths - lengths)
        assert residual_fk <= residual_true + 1e-12
        # first-order optimality of ½‖d(p) − l‖²: Σ (d_i − l_i) u_i = 0
        u, d = cable_vectors(robot.exit_points_m, p_fk)
        np.testing.assert_allclose(u.T @ (d - lengths), 0.0, atol=1e-10)
        # and the same minimum as an independent solver started from the true pose
        reference = least_squares(lambda q: _lengths(robot, q) - lengths, p, xtol=1e-14, ftol=1e-14)
        np.testing.assert_allclose(p_fk, reference.x, atol=1e-7)


def test_three_cable_forward_kinematics_picks_the_hanging_solution(paper_robot, rng):
    h = paper_robot.exit_points_m[0, 2]
    for triple in combinations(range(4), 3):
        cables = np.zeros(4, dtype=bool)
        cables[list(triple)] = True
        for p in random_positions(paper_robot, rng, 10, margin_m=0.02):
            theta = inverse_kinematics(paper_robot, p)
            p_fk = forward_kinematics(paper_robot, theta, cables)
            assert p_fk[2] < h
            np.testing.assert_allclose(p_fk, p, atol=1e-9)
            # the mirror point above the exit-point plane has the same three lengths:
            mirror = np.array([p[0], p[1], 2 * h - p[2]])
            np.testing.assert_allclose(_lengths(paper_robot, mirror)[cables],
                                       _lengths(paper_robot, p)[cables], rtol=1e-12)


def test_three_cable_forward_kinematics_tilted_exit_planes(eight_cable_robot, rng):
    """Eight-cable robot: exit points at different heights, any triple the pose hangs under."""
    robot = eight_cable_robot
    checked = 0
    for triple in combinations(range(robot.cable_count), 3):
        a = robot.exit_points_m[list(triple)]
        normal = np.cross(a[1] - a[0], a[2] - a[0])
        normal /= np.linalg.norm(normal)
        if normal[2] < 0:
            normal = -normal
        if normal[2] < 0.3:        # nearly vertical plane: 'below' is ill-defined
            continue
        cables = np.zeros(robot.cable_count, dtype=bool)
        cables[list(triple)] = True
        for p in random_positions(robot, rng, 4):
            if (p - a[0]) @ normal > -0.3:
                continue
            p_fk = forward_kinematics(robot, inverse_kinematics(robot, p), cables)
            np.testing.assert_allclose(p_fk, p, atol=1e-8, err_msg=f'cables {triple}')
            checked += 1
    assert checked > 50


def test_three_cable_lengths_no_point_reaches_give_the_nearest_point_not_an_error(paper_robot):
    """Lengths too short for the three spheres to meet (stale or inconsistent angles, as a
    loaded realtime graph can hand the supervisor, whose node died of it): a point of the
    exit points' plane that nearly fits them, where the solve used to raise. Gauss–Newton
    on lengths no point fits need not reach the best one; a finite point is what counts."""
    robot = paper_robot
    cables = robot.cable_mask([3])
    h = robot.exit_points_m[0, 2]
    for shrink in (0.3, 0.5):
        lengths = shrink * _lengths(robot, robot.home_position_m)
        p_fk = forward_kinematics(robot, _angles_for_lengths(robot, lengths), cables)
        assert np.all(np.isfinite(p_fk)) and p_fk[2] == pytest.approx(h)
        reference = least_squares(lambda q: _lengths(robot, np.array([q[0], q[1], h]))[cables]
                                  - lengths[cables], p_fk[:2], xtol=1e-14, ftol=1e-14)
        misfit = np.linalg.norm(_lengths(robot, p_fk)[cables] - lengths[cables])
        assert misfit <= 1.05 * np.linalg.norm(reference.fun)


def test_forward_kinematics_of_a_stack_of_angles_is_that_of_each_row(robot, rng):
    """A recorded run is read all its ticks at once: each row must be the pose the angles
    give alone, with exact, noisy and unreachable lengths (no point of three spheres
    shrunk to a third), every cable or one broken, down to where the single pose stops."""
    positions = random_positions(robot, rng, 20, margin_m=0.02)
    lengths = cable_vectors(robot.exit_points_m, positions)[1]
    exact = inverse_kinematics(robot, positions)
    noisy = _angles_for_lengths(robot, lengths + rng.normal(scale=3e-3, size=lengths.shape))
    unreachable = _angles_for_lengths(robot, 0.3 * lengths)
    for label, cables in list(cable_masks(robot))[:3]:
        for name, angles in (('exact', exact), ('noisy', noisy), ('unreachable', unreachable)):
            if name == 'unreachable' and np.count_nonzero(cables) != 3:
                continue
            stack = forward_kinematics(robot, angles, cables)
            assert stack.shape == (angles.shape[0], 3)
            for row, alone in enumerate(forward_kinematics(robot, angle, cables) for angle in angles):
                np.testing.assert_allclose(stack[row], alone, rtol=0.0, atol=1e-12,
                                           err_msg=f'{label}, {name}, row {row}')


def test_forward_kinematics_needs_three_cables(paper_robot):
    with pytest.raises(KinematicsError):
        forward_kinematics(paper_robot, np.zeros(4), np.array([True, True, False, False]))
