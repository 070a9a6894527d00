"""Rigid cables never span more than their length: a slack cable that the end-effector's
swing draws straight is caught by an inelastic jerk (catch_slack of each body's
sub-steps), which shares the momentum between the end-effector and the motor as
Newton's third law does and makes no energy. Before, an acceleration's balance alone
judged such a cable, and a drawn 4-cable point mass hanging on two cables swung 0.23 m
beyond an intact cable's length, which then looked broken to the supervisor."""
from __future__ import annotations

import numpy as np
import pytest
import yaml

from cdpr_control.platform import substeps as platform_substeps
from cdpr_control.point_mass.kinematics import cable_vectors
from cdpr_control.point_mass import substeps as point_mass_substeps
from cdpr_control.setup.robot_file import load_robot
from cdpr_twin.models.rigid_model import RigidModel

from conftest import CONFIG_DIR, DRAWN_FOUR_CABLE_ROBOT, PAPER_ROBOT

PERIOD_S = 0.002
SLACK_M = 1e-3       # the cable caught starts this much longer than its straight line
SPEED_M_S = 0.3      # and the end-effector moves away from its exit point this fast


def spans(robot, model) -> np.ndarray:
    """Per cable, the distance from its exit point to its end less the length its motor
    has paid out (m): above zero, the cable spans more than its length."""
    ends = robot.cable_ends_m(model.position_m, model.orientation)
    paid = robot.cable_length_offset_m + robot.motor.drum_radius_m * model.angle_rad
    return np.linalg.norm(robot.exit_points_m - ends, axis=1) - paid


def slackened(robot, model, cable: int) -> np.ndarray:
    """The model with `cable` paid out SLACK_M beyond its straight line and the
    end-effector moving straight away from that cable's exit point at SPEED_M_S, every
    motor still (the cables it moves towards slacken, those it draws away from are
    caught). The direction of the move (world frame)."""
    end = robot.cable_ends_m(model.position_m, model.orientation)[cable]
    away = (end - robot.exit_points_m[cable]) / np.linalg.norm(end - robot.exit_points_m[cable])
    model.twist = np.concatenate([SPEED_M_S * away, np.zeros(3)])
    model.angular_velocity_rad_s = np.zeros(robot.cable_count)
    model.angle_rad = model.angle_rad.copy()
    model.angle_rad[cable] += SLACK_M / robot.motor.drum_radius_m
    return away


# DRAWN_FOUR_CABLE_ROBOT hanging on cables 1 and 3 after cable 2 broke, swinging away
# from cable 4's exit point: that cable 8 mm slack, its motor still and unpowered, as the
# bench's run had them 10 ms before the swing drew it straight.
SWING_POSITION_M, SWING_VELOCITY_M_S = [2.61414, 3.06647, 0.49578], [-0.0102, 1.2217, 0.2017]
SWING_TORQUE_NM = [-0.3677, 0.0, -0.3466, 0.0]
SWING_SLACK_M = 0.008


def test_a_slack_cable_the_swing_draws_straight_holds_the_end_effector_at_its_length(tmp_path):
    robot_file = tmp_path / 'robot.yaml'
    robot_file.write_text(yaml.safe_dump(DRAWN_FOUR_CABLE_ROBOT))
    robot = load_robot(robot_file)
    radius = robot.motor.drum_radius_m
    model = RigidModel(robot, SWING_POSITION_M)
    model.break_cables([1])
    model.twist = np.concatenate([SWING_VELOCITY_M_S, np.zeros(3)])
    # cables 1 and 3 taut, their motors moving with the end-effector; cable 4 slack and still
    u, d = cable_vectors(robot.exit_points_m, np.array(SWING_POSITION_M))
    model.angle_rad = (d + np.array([0.0, 0.0, 0.0, SWING_SLACK_M]) - robot.cable_length_offset_m) / radius
    model.angular_velocity_rad_s = np.where([True, False, True, False], -(u @ SWING_VELOCITY_M_S) / radius, 0.0)
    assert spans(robot, model)[3] == pytest.approx(-SWING_SLACK_M)
    spanned, paying_out = [], []
    for _ in range(100):
        model.step(np.array(SWING_TORQUE_NM), PERIOD_S)
        spanned.append(spans(robot, model)[3])
        paying_out.append(radius * model.angular_velocity_rad_s[3])
    # drawn straight within the first 10 ms (at 1.2 m/s); from then on the cable holds:
    # over a sub-step an end can pass its length by its rate times h (2.4 mm here), and
    # its motor, taut, is put back on it at the sub-step's end (before: 0.1 m beyond)
    assert np.argmax(np.array(spanned) > -1e-6) <= 5
    assert max(spanned) <= np.linalg.norm(SWING_VELOCITY_M_S) * PERIOD_S, max(spanned)
    # the jerk set its unpowered motor paying out, as the end-effector pulled it
    assert max(paying_out) > 0.1


def kinetic_energy(robot, mass_matrix, twist, speed) -> float:
    """½ ξᵀ M ξ + ½ J Σ θ̇² (J)."""
    return 0.5 * twist @ mass_matrix @ twist + 0.5 * robot.motor.inertia_kg_m2 * float(speed @ speed)


def test_the_point_mass_jerk_is_newtons_third_law_and_makes_no_energy(paper_robot):
    robot, cable = paper_robot, 0
    model = RigidModel(robot, robot.home_position_m)
    away = slackened(robot, model, cable)
    constants = point_mass_substeps.constants_of(robot)
    directions = np.empty((robot.cable_count, 4))
    point_mass_substeps.cable_directions(robot.exit_points_m, model.position_m, directions)
    velocity, speed = model.twist[:3].copy(), model.angular_velocity_rad_s.copy()
    caught = np.empty(robot.cable_count)
    point_mass_substeps.catch_slack(constants, directions, velocity, speed, np.ones(robot.cable_count), caught)
    radius, inertia = robot.motor.drum_radius_m, robot.motor.inertia_kg_m2
    u = directions[:, :3]
    rate_before = -u @ model.twist[:3] - radius * model.angular_velocity_rad_s
    # caught: cable 1, drawn straight; not those the move slackens (their ends come nearer
    # their exit points), whose motors go on
    assert caught[cable] == 1.0 and rate_before[cable] == pytest.approx(SPEED_M_S)
    slackening = rate_before < -1e-9
    assert slackening.any() and not caught[slackening].any()
    np.testing.assert_array_equal(speed[slackening], model.angular_velocity_rad_s[slackening])
    # every caught motor now pays out as fast as its cable's end draws away
    np.testing.assert_allclose(radius * speed[caught == 1.0], (-u @ velocity)[caught == 1.0], atol=1e-12)
    # the impulses P_i the cables gave the motors (J Δθ̇_i = ρ P_i, P_i ≥ 0: they pull)
    # they gave the end-effector along u_i, towards their exit points: m Δṗ = Σ P_i u_i
    impulse = inertia * (speed - model.angular_velocity_rad_s) / radius
    assert impulse[cable] > 0.0 and np.all(impulse >= -1e-12)
    np.testing.assert_allclose(robot.mass_kg * (velocity - model.twist[:3]), u.T @ impulse, atol=1e-12)
    assert velocity @ away < SPEED_M_S
    mass_matrix = robot.mass_kg * np.eye(3)
    assert (kinetic_energy(robot, mass_matrix, velocity, speed)
            < kinetic_energy(robot, mass_matrix, model.twist[:3], model.angular_velocity_rad_s))


def test_the_platform_jerk_makes_no_energy_and_leaves_the_cable_at_its_rate():
    robot = load_robot(CONFIG_DIR / 'robots' / 'crossed_platform_robot.yaml')
    model, cable = RigidModel(robot, robot.home_position_m), 0
    slackened(robot, model, cable)
    constants = platform_substeps.constants_of(robot)
    exits, attachments, _ = platform_substeps.geometry_of(robot)
    rotation, columns = np.empty((3, 3)), np.empty((robot.cable_count, 6))
    lengths, arms = np.empty(robot.cable_count), np.empty((robot.cable_count, 3))
    platform_substeps.rotation_of(model.pose, rotation)
    platform_substeps.cables_at(model.pose, rotation, exits, attachments, columns, lengths, arms)
    twist, speed = model.twist.copy(), model.angular_velocity_rad_s.copy()
    caught = np.empty(robot.cable_count)
    platform_substeps.catch_slack(constants, rotation, columns, twist, speed, np.ones(robot.cable_count), caught)
    assert caught[cable] == 1.0
    radius = robot.motor.drum_radius_m
    for i in np.flatnonzero(caught):
        assert radius * speed[i] == pytest.approx(-columns[i] @ twist, abs=1e-12)
    mass_matrix, free = np.empty((6, 6)), np.empty(6)
    platform_substeps.rigid_body(constants, rotation, model.twist, mass_matrix, free)
    assert (kinetic_energy(robot, mass_matrix, twist, speed)
            < kinetic_energy(robot, mass_matrix, model.twist, model.angular_velocity_rad_s))
