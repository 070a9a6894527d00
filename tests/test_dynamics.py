"""Inverse and direct dynamics against Newton's law, the motor law and energy balance."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from cdpr_control.model.dynamics import inverse_dynamics
from cdpr_control.point_mass.dynamics import direct_dynamics
from cdpr_control.point_mass.kinematics import (inverse_kinematics, joint_acceleration, joint_velocity, structure_matrix,
                                     structure_matrix_rate)
from cdpr_control.tension_distribution import InfeasibleTensionError, make_tension_distribution
from cdpr_control.geometry.trajectories import StraightLine
from conftest import cable_masks, random_positions, random_unit_vectors


def _distribution(robot, method='bounded_minimum_norm'):
    options = {'reference_tension_n': 3.0 * robot.tension_min_n} if method == 'bounded_minimum_norm' else {}
    return make_tension_distribution(method, robot.tension_min_n, robot.tension_max_n, **options)


def _random_states(robot, rng, count, attached, speed=0.8, acceleration=2.0, tries=4000):
    """(p, ṗ, p̈, inverse dynamics) for which the attached cables can hold the motion."""
    distribution = _distribution(robot)
    states = []
    for _ in range(tries):
        p = random_positions(robot, rng, 1, margin_m=0.1)[0]
        v = speed * rng.random() * random_unit_vectors(rng, 1)[0]
        a = acceleration * rng.random() * random_unit_vectors(rng, 1)[0]
        try:
            inverse = inverse_dynamics(robot, distribution, p, v, a, attached)
        except InfeasibleTensionError:
            continue
        states.append((p, v, a, inverse))
        if len(states) == count:
            return states
    raise AssertionError(f'only {len(states)} feasible states in {tries} tries')


def _check_newton_and_motor_laws(robot, p, v, c, theta_dot, result, attached):
    """m p̈ = S τ + m g, J θ̈ = −b θ̇ + c + ρ τ, detached cables carry nothing."""
    motor = robot.motor
    s, _ = structure_matrix(robot, p)
    np.testing.assert_allclose(robot.mass_kg * result.acceleration_m_s2,
                               s @ result.tension_n + robot.weight_wrench_n, atol=1e-9)
    # θ̇ of a taut cable follows the end-effector
    theta_dot = np.where(result.taut, joint_velocity(s, v, motor.drum_radius_m), theta_dot)
    np.testing.assert_allclose(
        motor.inertia_kg_m2 * result.joint_acceleration_rad_s2,
        -motor.viscous_friction_nm_s_rad * theta_dot + c + motor.drum_radius_m * result.tension_n,
        atol=1e-9)
    assert np.all(result.tension_n[~attached] == 0.0)
    assert not np.any(result.taut[~attached])
    assert np.all(result.tension_n >= 0.0)
    assert np.all(result.tension_n[~result.taut] == 0.0)


@pytest.mark.parametrize('method', ['pseudo_inverse', 'bounded_minimum_norm'])
def test_inverse_dynamics_of_a_stack_of_poses_is_that_of_each(robot, rng, method):
    """A reference is tabulated a whole trajectory at once: every row of the stack must
    be the single pose's figures, with a broken cable too, and an infeasible pose in the
    stack must be named as it is alone (the first one)."""
    distribution = _distribution(robot, method)
    stacked = 0
    for _, attached in list(cable_masks(robot))[:3]:
        stacked += 1
        alone, poses = [], []
        for p, v, a, _ in _random_states(robot, rng, 40, attached):
            try:
                alone.append(inverse_dynamics(robot, distribution, p, v, a, attached))
            except InfeasibleTensionError:
                continue
            poses.append((p, v, a))
        assert len(poses) >= 10
        stack = inverse_dynamics(robot, distribution, *map(np.array, zip(*poses)), attached)
        for name in ('torque_nm', 'tension_n', 'joint_velocity_rad_s', 'joint_acceleration_rad_s2'):
            np.testing.assert_allclose(getattr(stack, name), [getattr(one, name) for one in alone],
                                       rtol=1e-12, atol=1e-12, err_msg=name)
    assert stacked == 3     # every cable, cable 1 broken, cable 2 broken
    p, v, a = poses[0]
    # driven down faster than it falls: no cable can push
    downward = np.array([0.0, 0.0, -30.0])
    with pytest.raises(InfeasibleTensionError) as alone_error:
        inverse_dynamics(robot, distribution, p, v, downward, attached)
    with pytest.raises(InfeasibleTensionError) as stack_error:
        inverse_dynamics(robot, distribution, np.array([p, p, p]), np.array([v, v, v]),
                         np.array([a, downward, downward]), attached)
    assert str(stack_error.value) == str(alone_error.value)


def test_inverse_then_direct_round_trip(robot, rng):
    states, checked = 6, 0
    for _, attached in cable_masks(robot):
        for p, v, a, inverse in _random_states(robot, rng, states, attached, acceleration=1.5):
            checked += 1
            result = direct_dynamics(robot, p, v, inverse.torque_nm, inverse.joint_velocity_rad_s,
                                     attached)
            np.testing.assert_allclose(result.acceleration_m_s2, a, atol=1e-9)
            np.testing.assert_array_equal(result.taut, attached)
            np.testing.assert_allclose(result.tension_n, inverse.tension_n, atol=1e-7)
            np.testing.assert_allclose(result.joint_acceleration_rad_s2,
                                       inverse.joint_acceleration_rad_s2, atol=1e-7)
            _check_newton_and_motor_laws(robot, p, v, inverse.torque_nm,
                                         inverse.joint_velocity_rad_s, result, attached)
    # every cable, then each one broken
    assert checked == states * (robot.cable_count + 1)


def test_inverse_dynamics_satisfies_the_model(robot, rng):
    """Independent of direct dynamics: S τ = m(p̈ − g), c = J θ̈ + b θ̇ − ρ τ with θ̇, θ̈ from S."""
    motor = robot.motor
    for p, v, a, inverse in _random_states(robot, rng, 10, np.ones(robot.cable_count, dtype=bool)):
        s, d = structure_matrix(robot, p)
        np.testing.assert_allclose(s @ inverse.tension_n, robot.mass_kg * (a - robot.gravity_m_s2),
                                   atol=1e-9)
        assert np.all(inverse.tension_n >= robot.tension_min_n - 1e-9)
        theta_dot = -(s.T @ v) / motor.drum_radius_m
        theta_ddot = joint_acceleration(s, structure_matrix_rate(s, d, v), v, a, motor.drum_radius_m)
        np.testing.assert_allclose(inverse.joint_velocity_rad_s, theta_dot, atol=1e-12)
        np.testing.assert_allclose(inverse.joint_acceleration_rad_s2, theta_ddot, atol=1e-9)
        np.testing.assert_allclose(
            inverse.torque_nm,
            motor.inertia_kg_m2 * theta_ddot + motor.viscous_friction_nm_s_rad * theta_dot
            - motor.drum_radius_m * inverse.tension_n, atol=1e-12)


def test_broken_cable_reported_idle_by_inverse_dynamics(paper_robot, rng):
    attached = paper_robot.cable_mask([3])
    for _, _, _, inverse in _random_states(paper_robot, rng, 5, attached, acceleration=1.0):
        assert inverse.torque_nm[3] == 0.0 and inverse.tension_n[3] == 0.0
        assert inverse.joint_velocity_rad_s[3] == 0.0 and inverse.joint_acceleration_rad_s2[3] == 0.0


@pytest.mark.parametrize('method', ['pseudo_inverse', 'bounded_minimum_norm'])
def test_at_rest_tensions_balance_gravity(robot, rng, method):
    distribution = _distribution(robot, method)
    zero = np.zeros(3)
    held = 0
    for p in random_positions(robot, rng, 20, margin_m=0.2):
        try:
            inverse = inverse_dynamics(robot, distribution, p, zero, zero)
        except InfeasibleTensionError:
            continue
        held += 1
        s, _ = structure_matrix(robot, p)
        np.testing.assert_allclose(s @ inverse.tension_n, -robot.mass_kg * robot.gravity_m_s2, atol=1e-9)
        np.testing.assert_allclose(inverse.torque_nm, -robot.motor.drum_radius_m * inverse.tension_n,
                                   atol=1e-12)
        assert np.all(inverse.torque_nm < 0.0)       # holding torques are negative
        # and those torques hold it: no acceleration anywhere
        result = direct_dynamics(robot, p, zero, inverse.torque_nm, np.zeros(robot.cable_count))
        np.testing.assert_allclose(result.acceleration_m_s2, 0.0, atol=1e-10)
        np.testing.assert_allclose(result.joint_acceleration_rad_s2, 0.0, atol=1e-7)
    assert held >= 10


def test_free_broken_motor(robot, rng):
    motor = robot.motor
    for broken in range(robot.cable_count):
        attached = robot.cable_mask([broken])
        p, v, a, inverse = _random_states(robot, rng, 1, attached, acceleration=1.0)[0]
        torque = inverse.torque_nm.copy()
        theta_dot = inverse.joint_velocity_rad_s.copy()
        torque[broken] = rng.uniform(-1.0, 1.0)
        theta_dot[broken] = rng.uniform(-20.0, 20.0)
        result = direct_dynamics(robot, p, v, torque, theta_dot, attached)
        expected = (torque[broken] - motor.viscous_friction_nm_s_rad * theta_dot[broken]) / motor.inertia_kg_m2
        assert result.joint_acceleration_rad_s2[broken] == pytest.approx(expected, rel=1e-12)
        assert result.tension_n[broken] == 0.0 and not result.taut[broken]
        # the free motor does not disturb the end-effector
        np.testing.assert_allclose(result.acceleration_m_s2, a, atol=1e-9)


def test_paying_out_hard_makes_the_cable_slack(robot, rng):
    motor = robot.motor
    for cable in range(robot.cable_count):
        p, v, _, inverse = _random_states(robot, rng, 1, np.ones(robot.cable_count, dtype=bool),
                                          speed=0.3, acceleration=0.5)[0]
        torque = inverse.torque_nm.copy()
        torque[cable] = +0.8 * motor.torque_limit_nm       # positive torque pays the cable out
        result = direct_dynamics(robot, p, v, torque, inverse.joint_velocity_rad_s)
        assert not result.taut[cable]
        assert result.tension_n[cable] == 0.0
        assert np.all(result.tension_n >= 0.0)
        _check_newton_and_motor_laws(robot, p, v, torque, inverse.joint_velocity_rad_s, result,
                                     np.ones(robot.cable_count, dtype=bool))
        # slack is consistent: the drum pays out faster than the end-effector takes cable in
        s, d = structure_matrix(robot, p)
        geometric = joint_acceleration(s, structure_matrix_rate(s, d, v), v,
                                       result.acceleration_m_s2, motor.drum_radius_m)
        assert result.joint_acceleration_rad_s2[cable] > geometric[cable]


def test_power_balance(robot, rng):
    """d/dt(½ m|ṗ|² + ½ J Σθ̇² − m g·p) = Σ c_i θ̇_i − b Σ θ̇_i² for taut rigid cables."""
    motor = robot.motor
    attached = np.ones(robot.cable_count, dtype=bool)
    checked = 0
    for p, v, _, inverse in _random_states(robot, rng, 10, attached, speed=1.0, acceleration=2.0):
        # perturb the torques so the state is not the one inverse dynamics was built for
        torque = inverse.torque_nm + rng.normal(scale=0.02, size=robot.cable_count)
        s, _ = structure_matrix(robot, p)
        theta_dot = joint_velocity(s, v, motor.drum_radius_m)
        result = direct_dynamics(robot, p, v, torque, theta_dot)
        if not np.all(result.taut):
            continue
        checked += 1
        energy_rate = (robot.mass_kg * v @ result.acceleration_m_s2
                       + motor.inertia_kg_m2 * theta_dot @ result.joint_acceleration_rad_s2
                       - robot.mass_kg * robot.gravity_m_s2 @ v)
        power = torque @ theta_dot - motor.viscous_friction_nm_s_rad * theta_dot @ theta_dot
        assert energy_rate == pytest.approx(power, abs=1e-9, rel=1e-9)
    assert checked >= 5


def test_feed_forward_torques_reproduce_the_motion(paper_robot):
    """Integrating direct dynamics (RK4) under inverse-dynamics torques retraces the path."""
    robot = paper_robot
    distribution = _distribution(robot, 'pseudo_inverse')
    line = StraightLine.with_peak_speed([0.6, 0.7, 1.1], [1.0, 1.2, 1.4], 0.5)
    ones = np.ones(robot.cable_count, dtype=bool)

    def torque_at(t):
        p, v, a = line.sample(t)
        return inverse_dynamics(robot, distribution, p, v, a).torque_nm

    def rate(state, torque):
        p, v = state[:3], state[3:]
        s, _ = structure_matrix(robot, p)
        theta_dot = joint_velocity(s, v, robot.motor.drum_radius_m)
        result = direct_dynamics(robot, p, v, torque, theta_dot, ones)
        assert np.all(result.taut)
        return np.r_[v, result.acceleration_m_s2]

    dt = 0.004
    state = np.r_[line.sample(0.0)[0], line.sample(0.0)[1]]
    t = 0.0
    while t < line.duration_s - 1e-12:
        c0, c_half, c1 = torque_at(t), torque_at(t + dt / 2), torque_at(t + dt)
        k1 = rate(state, c0)
        k2 = rate(state + dt / 2 * k1, c_half)
        k3 = rate(state + dt / 2 * k2, c_half)
        k4 = rate(state + dt * k3, c1)
        state = state + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        t += dt
    np.testing.assert_allclose(state[:3], line.sample(line.duration_s)[0], atol=1e-6)
    np.testing.assert_allclose(state[3:], 0.0, atol=1e-5)


def test_energy_conserved_without_friction(robot):
    """b = 0 and constant torques c: H = ½m|ṗ|² + ½JΣθ̇² − m g·p − Σ c_i θ_i is constant.

    RK4 over 0.4 s from rest at home with half the holding torques (the end-effector
    sinks and swings while every cable stays taut).
    """
    frictionless = dataclasses.replace(
        robot, motor=dataclasses.replace(robot.motor, viscous_friction_nm_s_rad=0.0))
    motor = frictionless.motor
    zero = np.zeros(3)
    home = robot.home_position_m + np.array([0.1, -0.05, 0.0])
    holding = inverse_dynamics(frictionless, _distribution(robot), home, zero, zero).torque_nm
    torque = 0.5 * holding * np.linspace(0.8, 1.2, robot.cable_count)

    def rate(state):
        p, v = state[:3], state[3:]
        s, _ = structure_matrix(frictionless, p)
        result = direct_dynamics(frictionless, p, v, torque, joint_velocity(s, v, motor.drum_radius_m))
        assert np.all(result.taut)
        return np.r_[v, result.acceleration_m_s2]

    def energy(state):
        p, v = state[:3], state[3:]
        s, _ = structure_matrix(frictionless, p)
        theta_dot = joint_velocity(s, v, motor.drum_radius_m)
        return (0.5 * frictionless.mass_kg * v @ v + 0.5 * motor.inertia_kg_m2 * theta_dot @ theta_dot
                - frictionless.mass_kg * frictionless.gravity_m_s2 @ p
                - torque @ inverse_kinematics(frictionless, p))

    state = np.r_[home, zero]
    start_energy = energy(state)
    dt = 1e-3
    for _ in range(400):
        k1 = rate(state)
        k2 = rate(state + dt / 2 * k1)
        k3 = rate(state + dt / 2 * k2)
        k4 = rate(state + dt * k3)
        state = state + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    assert np.linalg.norm(state[3:]) > 0.05          # it really moved
    assert energy(state) == pytest.approx(start_energy, abs=1e-8 * frictionless.mass_kg * 9.81)
