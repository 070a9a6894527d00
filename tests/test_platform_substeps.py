"""The platform's equations compiled by numba give CPython's numbers to the last bit (one
source, cdpr_control.platform.substeps), on every path of both models: a break, slack
cables, a push, locked drums; and the direct dynamics' slack cables against the reduced
system solved here with numpy."""
from __future__ import annotations

import numpy as np
import pytest

from cdpr_control.platform import substeps as platform_substeps
from cdpr_control.platform import dynamics as pose_dynamics
from cdpr_control.platform import kinematics as pose_kinematics
from cdpr_control.kernels import KERNELS
from cdpr_control.config import load_config
from cdpr_control.setup.robot_file import load_robot
from cdpr_control.geometry.rotation import from_axis_angle
from cdpr_twin.models.elastic_platform import ElasticPlatform
from cdpr_twin.models.plant import PlantConfig, true_motors
from cdpr_twin.models.rigid_model import RigidModel

from conftest import CONFIG_DIR

pytest.importorskip('numba')

ROBOT = CONFIG_DIR / 'robots' / 'crossed_platform_robot.yaml'
STATE = ('position_m', 'orientation', 'velocity_m_s', 'platform_angular_velocity_rad_s', 'angle_rad',
         'angular_velocity_rad_s', 'tension_n')
PERIOD_S = 0.002


@pytest.fixture(scope='module')
def robot():
    return load_robot(ROBOT)


def drive(model, robot, holding):
    """Held, then a cable broken, pushed up (cables go slack), then the drums locked:
    the state after each phase."""
    states = []
    for phase in range(4):
        if phase == 1:
            model.break_cables([2])
        if phase == 3:
            model.drums_locked = True
        for _ in range(15):
            model.step(holding * (0.3 if phase == 2 else 1.0), PERIOD_S,
                       external_force_n=(10.0, 0.0, 150.0) if phase == 2 else (0.0, 0.0, 0.0))
        states.append({name: np.array(getattr(model, name)) for name in STATE})
    return states


@pytest.mark.parametrize('model_name', ['rigid', 'elastic'])
def test_both_kernels_give_the_same_numbers_on_every_path(robot, model_name):
    position = robot.home_position_m + np.array([0.1, -0.05, 0.1])
    orientation = from_axis_angle([1.0, 0.5, 0.0], 0.1)
    config = PlantConfig.from_section(load_config(ROBOT).section('plant'), robot.cable_count, fidelity='elastic')
    holding = -robot.motor.drum_radius_m * np.full(robot.cable_count, robot.mass_kg * 9.81 / 6)

    def model(kernel):
        if model_name == 'rigid':
            return RigidModel(robot, position, orientation, 2, kernel)
        return ElasticPlatform(robot, true_motors(robot, config), position, orientation, config, kernel)

    python, compiled = drive(model('python'), robot, holding), drive(model('compiled'), robot, holding)
    # each path ran: the broken cable carries nothing, the push slackened a cable, the
    # locked drums held their angles
    assert np.all(python[1]['tension_n'][2] == 0.0)
    assert np.count_nonzero(python[2]['tension_n'] == 0.0) > 1
    assert np.array_equal(python[3]['angular_velocity_rad_s'], np.zeros(robot.cable_count))
    for phase, (ours, theirs) in enumerate(zip(python, compiled)):
        for name in STATE:
            assert np.array_equal(ours[name], theirs[name]), (phase, name)


def test_a_cable_paid_out_goes_slack_and_the_rest_solve_as_without_it(robot):
    """One motor driven to pay out hard: its cable comes out slack, its motor spins free,
    and the platform's accelerations are those of the seven other cables, solved here
    from (M + (J/ρ²) W Wᵀ) (a, α) = w_g − h + W ((J/ρ²) κ + (b/ρ) θ̇ − c/ρ)."""
    motor = robot.motor
    position, orientation = robot.home_position_m + np.array([0.05, 0.02, -0.1]), from_axis_angle([0, 1, 0], 0.1)
    velocity, omega = np.array([0.1, -0.05, 0.02]), np.array([0.05, 0.1, -0.2])
    joint_velocity = pose_kinematics.joint_velocity(robot, position, orientation, velocity, omega)
    torque = np.full(robot.cable_count, -0.6)
    torque[5] = 2.0
    result = pose_dynamics.direct_dynamics(robot, np.concatenate([position, orientation]),
                                           np.concatenate([velocity, omega]), torque, joint_velocity)
    assert not result.taut[5] and result.taut.sum() == 7 and result.tension_n[5] == 0.0
    assert result.joint_acceleration_rad_s2[5] == pytest.approx(
        (torque[5] - motor.viscous_friction_nm_s_rad * joint_velocity[5]) / motor.inertia_kg_m2)

    u, d, r = pose_kinematics.cable_vectors(robot, position, orientation)
    structure = pose_kinematics.structure_of(u, r)[:, result.taut]
    kappa = pose_kinematics.velocity_product(u, d, r, velocity, omega)[result.taut]
    body = pose_dynamics.rigid_body(robot, orientation, omega)
    coupling = motor.inertia_kg_m2 / motor.drum_radius_m ** 2
    pull = (coupling * kappa + motor.viscous_friction_nm_s_rad / motor.drum_radius_m * joint_velocity[result.taut]
            - torque[result.taut] / motor.drum_radius_m)
    accelerations = np.linalg.solve(body.mass_matrix + coupling * structure @ structure.T,
                                    body.free_wrench + structure @ pull)
    np.testing.assert_allclose(np.concatenate([result.acceleration_m_s2, result.angular_acceleration_rad_s2]),
                               accelerations, atol=1e-10)
    np.testing.assert_allclose(result.tension_n[result.taut], pull - coupling * structure.T @ accelerations,
                               atol=1e-9)
    assert result.tension_n.min() >= 0.0


def test_forward_kinematics_is_the_same_with_both_kernels(robot):
    exits, attachments, offsets = platform_substeps.geometry_of(robot)
    position, orientation = robot.home_position_m + np.array([0.2, -0.1, 0.15]), from_axis_angle([1, -1, 2], 0.2)
    lengths = offsets + robot.motor.drum_radius_m * pose_kinematics.inverse_kinematics(robot, position, orientation)
    used = np.ones(robot.cable_count)
    used[4] = 0.0
    poses = []
    for name in KERNELS:
        pose = np.concatenate([robot.home_position_m, robot.body.home_orientation])
        taken = platform_substeps.kernel(name).forward_kinematics(exits, attachments, lengths, used, pose, 30,
                                                                  1e-12, 1e-11)
        assert 2 < taken < 30
        poses.append(pose)
    assert np.array_equal(*poses)
    np.testing.assert_allclose(poses[0][:3], position, atol=1e-10)


def test_a_tabulated_motions_rows_are_the_same_with_both_kernels_and_as_numpy_gives_them(robot):
    """motion_rows, a whole motion per call: both kernels alike to the last bit, and each
    row's W, wrench and joint motion as pose_kinematics and the rigid body give them."""
    rng = np.random.default_rng(3)
    rows = 5
    orientations = np.array([from_axis_angle(axis, angle) for axis, angle in
                             zip(rng.normal(size=(rows, 3)), rng.uniform(-0.2, 0.2, rows))])
    poses = np.concatenate([robot.home_position_m + rng.uniform(-0.1, 0.1, (rows, 3)), orientations], axis=1)
    twists, accelerations = rng.normal(scale=0.3, size=(rows, 6)), rng.normal(scale=2.0, size=(rows, 6))
    exits, attachments, _ = platform_substeps.geometry_of(robot)
    m = robot.cable_count
    results = []
    for name in KERNELS:
        figures = (np.empty((rows, m, 6)), np.empty((rows, m)), np.empty((rows, 6)), np.empty((rows, m)),
                   np.empty((rows, m)))
        platform_substeps.kernel(name).motion_rows(platform_substeps.constants_of(robot), exits, attachments, poses,
                                                   twists, accelerations, *figures)
        results.append(figures)
    for ours, theirs in zip(*results):
        assert np.array_equal(ours, theirs)
    columns, lengths, wrenches, joint_velocity, joint_acceleration = results[0]
    radius = robot.motor.drum_radius_m
    for k in range(rows):
        position, orientation, velocity, omega = poses[k, :3], poses[k, 3:], twists[k, :3], twists[k, 3:]
        u, d, r = pose_kinematics.cable_vectors(robot, position, orientation)
        structure = pose_kinematics.structure_of(u, r)
        body = pose_dynamics.rigid_body(robot, orientation, omega)
        np.testing.assert_allclose(columns[k].T, structure, atol=1e-14)
        np.testing.assert_allclose(lengths[k], d, atol=1e-14)
        np.testing.assert_allclose(wrenches[k], body.mass_matrix @ accelerations[k] - body.free_wrench, atol=1e-12)
        np.testing.assert_allclose(joint_velocity[k] * radius, pose_kinematics.length_rates(structure, twists[k]),
                                   atol=1e-13)
        np.testing.assert_allclose(
            joint_acceleration[k] * radius,
            pose_kinematics.length_accelerations(structure, pose_kinematics.velocity_product(u, d, r, velocity, omega),
                                                 accelerations[k]), atol=1e-12)
