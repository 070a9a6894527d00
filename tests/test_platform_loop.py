"""The platform's closed loop without DDS: the PD + feed-forward controller on the rigid
platform plant through the shipped robot's motions, each with its reference tabulated
from the pose trajectory; the plant simulator and the twin on a platform; and the
in-process engine on the elastic plant, as cdpr-scenario runs it."""
from __future__ import annotations

import numpy as np
import pytest

from cdpr_control.config import load_config
from cdpr_control.control.controller import JointController, JointReference, PdGains
from cdpr_control.geometry.motions import motion_names, settled_motion
from cdpr_control.platform.motion import pose_motion_from_settled
from cdpr_control.model.reference_table import tabulate_reference
from cdpr_control.setup.robot_file import load_robot
from cdpr_control.geometry.rotation import difference, rotation_matrix, tilt_rad
from cdpr_control.tension_distribution import configured_tension_distribution
from cdpr_twin.models.plant import PlantConfig, PlantSimulator
from cdpr_twin.models.rigid_model import RigidModel
from cdpr_twin.models.twin import DigitalTwin

from conftest import CONFIG_DIR, every_tick_scenario

ROBOT = CONFIG_DIR / 'robots' / 'crossed_platform_robot.yaml'
MOTIONS = CONFIG_DIR / 'crossed_platform_motions.yaml'
# The bounds for a failure-free run on the rigid plant (m, rad).
POSITION_BOUND_M = 2e-3
ORIENTATION_BOUND_RAD = np.radians(0.2)


def setup(motion_name: str, reverse: bool = False):
    robot = load_robot(ROBOT)
    settings = load_config(ROBOT)
    control = settings.section('control')
    motion = pose_motion_from_settled(settled_motion(MOTIONS, motion_name, reverse),
                                      robot.body.home_orientation)
    reference = tabulate_reference(robot, configured_tension_distribution(control, robot),
                                   motion.pose_trajectory, control.number('period_s', positive=True))
    return robot, settings, motion, reference


def run(robot, plant, gains, reference):
    """Tracking errors (m, rad) and tensions (N) of every tick after the first."""
    controller = JointController(robot, gains)
    errors, turns, tensions = [], [], []
    for k in range(len(reference)):
        errors.append(np.linalg.norm(plant.position_m - reference.position_m[k]))
        turns.append(np.linalg.norm(difference(plant.orientation, reference.orientation[k])))
        torque = controller.command(plant.angle_rad, plant.angular_velocity_rad_s, JointReference(
            reference.angle_rad[k], reference.angular_velocity_rad_s[k], reference.feedforward_nm[k]))
        plant.step(torque, reference.period_s)
        tensions.append(plant.tension_n.copy())
    return np.array(errors), np.array(turns), np.array(tensions)


def test_the_motions_turn_the_platform_as_their_files_say():
    robot, _, motion, reference = setup('climb-tilt')
    assert np.degrees(tilt_rad(reference.orientation[-1])) == pytest.approx(15.0, abs=1e-9)
    assert np.degrees(tilt_rad(reference.orientation[0])) == pytest.approx(0.0, abs=1e-9)
    # the turn and the path start and stop together, at rest
    moving = np.linalg.norm(reference.platform_angular_velocity_rad_s, axis=1) > 0.0
    assert np.array_equal(moving, np.linalg.norm(reference.velocity_m_s, axis=1) > 0.0)
    _, _, _, backward = setup('climb-tilt', reverse=True)
    assert np.allclose(backward.position_m[0], reference.position_m[-1])
    assert np.linalg.norm(difference(backward.orientation[0], reference.orientation[-1])) < 1e-12
    assert np.linalg.norm(difference(backward.orientation[-1], reference.orientation[0])) < 1e-12
    assert set(motion_names(MOTIONS)) == {'climb-tilt', 'across-yaw', 'along', 'circle'}


@pytest.mark.parametrize('motion_name', ['climb-tilt', 'across-yaw', 'along', 'circle'])
def test_the_rigid_platform_tracks_each_motion_within_the_bounds(motion_name):
    robot, settings, _, reference = setup(motion_name)
    gains = PdGains.from_section(robot, settings.section('control'))
    assert gains.sampled_stable(robot, reference.period_s)
    plant = RigidModel(robot, reference.position_m[0], reference.orientation[0])
    errors, turns, tensions = run(robot, plant, gains, reference)
    assert errors.max() < POSITION_BOUND_M and turns.max() < ORIENTATION_BOUND_RAD
    assert tensions.min() >= robot.tension_min_n and tensions.max() <= robot.tension_max_n
    assert plant.taut.all()


def test_a_broken_cable_frees_its_motor_and_the_others_take_the_load():
    """Cable 1 detached in the rigid platform at rest under the holding torques: its motor,
    no longer held by the cable, spins up under its own torque; the others take the load."""
    robot, settings, _, reference = setup('along')
    plant = RigidModel(robot, reference.position_m[0], reference.orientation[0])
    holding = reference.feedforward_nm[0]
    plant.step(holding, reference.period_s)
    assert np.linalg.norm(plant.velocity_m_s) < 1e-9
    plant.break_cables([0])
    plant.step(holding, reference.period_s)
    assert not plant.taut[0] and plant.tension_n[0] == 0.0
    # the holding torque, no longer met by the cable: the freed drum winds in, J θ̈ = c
    assert plant.angular_velocity_rad_s[0] == pytest.approx(holding[0] / robot.motor.inertia_kg_m2
                                                          * reference.period_s, rel=1e-12)
    assert np.linalg.norm(plant.velocity_m_s) > 1e-4


def test_the_plant_simulator_and_the_twin_take_a_platform_and_a_break_shows_on_its_motor():
    """The graph's plant and twin cores on the platform: on the rigid plant, failure-free,
    the twin's torque is the controller's to rounding (the same model); cable 3, broken
    0.7 ms into a period, parts at that instant, and the residual c − c_DT grows on its
    motor first, as the paper's on a point mass."""
    robot, settings, _, reference = setup('climb-tilt')
    gains = PdGains.from_section(robot, settings.section('control'))
    config = PlantConfig.from_section(settings.section('plant'), robot.cable_count, fidelity='rigid')
    period = reference.period_s
    failure_s = 600 * period + 0.0007
    plant = PlantSimulator(robot, config, reference.position_m[0], failures=[(failure_s, 2)],
                           start_orientation=reference.orientation[0])
    twin = DigitalTwin(robot, gains, reference.position_m[0], 1, reference.orientation[0])
    controller = JointController(robot, gains)
    assert np.allclose(plant.holding_torque_nm(), reference.feedforward_nm[0], atol=1e-9)
    residuals = []
    for k in range(700):
        joint_reference = JointReference(reference.angle_rad[k], reference.angular_velocity_rad_s[k],
                                         reference.feedforward_nm[k])
        angle, speed = plant.measure()
        command = controller.command(angle, speed, joint_reference)
        residuals.append(command - twin.step(joint_reference, period).torque_nm)
        plant.step(command, period)
    residuals = np.abs(np.array(residuals))
    assert residuals[:601].max() < 1e-9
    assert plant.broken_at_s == {2: pytest.approx(failure_s, abs=1e-12)}
    grown = residuals[601:].max(axis=0)
    assert int(np.argmax(grown)) == 2 and grown[2] > 0.1
    assert np.linalg.norm(difference(plant.orientation, reference.orientation[699])) > 0.0


def test_the_field_plant_is_refused_for_a_platform_naming_why():
    robot, settings, _, reference = setup('along')
    config = PlantConfig.from_section(settings.section('plant'), robot.cable_count, fidelity='field')
    with pytest.raises(ValueError, match='field plant models the paper.s rig, a point mass'):
        PlantSimulator(robot, config, reference.position_m[0])


@pytest.mark.parametrize('motion_name', ['climb-tilt', 'across-yaw', 'along', 'circle'])
def test_the_in_process_engine_runs_a_platform_on_the_elastic_plant_without_a_false_alarm(motion_name):
    """cdpr-scenario's in-process engine, as a user runs it, on every shipped motion: the
    settled run of the platform, its twin and supervisor (the calibration made on it,
    found by its fingerprint), the motion tracked within the bounds with every cable
    within its own, no alarm, and the twin's position, by forward kinematics of the
    platform's angles, where the plant is."""
    from cdpr_bringup.runs.engine import run_inprocess
    from cdpr_bringup.runs.settle import ScenarioOptions
    from cdpr_bringup.scenario.command import metrics_of
    scenario = every_tick_scenario(ScenarioOptions(config=str(ROBOT), motions=str(MOTIONS), motion=motion_name,
                                              fidelity='elastic'))
    assert scenario.calibration_path.name == 'crossed_platform_calibration_elastic.yaml'
    recording = run_inprocess(scenario)
    metrics = metrics_of(scenario, recording, 1.0)
    assert metrics['detection_time_s'] is None and not metrics['false_alarm']
    assert metrics['tracking_error_m'] < POSITION_BOUND_M
    assert metrics['orientation_tracking_error_rad'] < ORIENTATION_BOUND_RAD
    assert metrics['kpi']['K_c_m'] < 1e-3
    tension = recording.true_tension_n[1:]
    assert tension.min() >= scenario.robot.tension_min_n and tension.max() <= scenario.robot.tension_max_n
    turned = np.linalg.norm(difference(recording.true_orientation[-1], recording.true_orientation[0]))
    assert np.degrees(turned) == pytest.approx({'across-yaw': 12.0, 'climb-tilt': 15.0}.get(motion_name, 0.0),
                                               abs=0.2)


def test_a_goal_position_is_refused_for_a_platform_saying_why():
    from cdpr_control.control.reference_schedule import GoalRejected, ReferenceSchedule
    robot, settings, _, reference = setup('along')
    schedule = ReferenceSchedule(robot, configured_tension_distribution(settings.section('control'), robot),
                                 reference.period_s, 0.3, reference)
    with pytest.raises(GoalRejected, match='needs its orientation too'):
        schedule.add_goal(robot.home_position_m)


def test_the_markers_draw_a_platforms_cables_to_its_attachment_points():
    """The markers' core on the platform's true pose: each cable ends at its attachment
    point p + R b_i of the pose, and the platform's body joins its origin to them."""
    from cdpr_fdi.view.markers import Frame, MarkerStyle
    robot, settings, _, reference = setup('climb-tilt')
    row = len(reference) - 1
    frame = Frame(robot, None, MarkerStyle.from_section(settings.section('markers')))
    pose = (reference.position_m[row], reference.orientation[row])
    for name, value in (('twin', pose), ('reference', pose), ('true_pose', pose), ('true_tension', np.full(8, 20.0))):
        frame.on_view(name, 0, value)
    shapes = {(shape.namespace, shape.id): shape for shape in frame.take()[1]}
    attachment = (reference.position_m[row]
                  + robot.body.attachment_points_m @ rotation_matrix(reference.orientation[row]).T)
    for cable in range(8):
        np.testing.assert_allclose(shapes[('cables', cable + 1)].points_m[1], attachment[cable], atol=1e-9)
    assert len(shapes[('platform', 0)].points_m) == 16


# How long the unpushed platform is watched at rest (s).
REST_S = 0.1
# What rounding leaves of rest (m/s, m).
ROUNDING = 1e-9


@pytest.mark.parametrize('fidelity', ['rigid', 'elastic'])
def test_a_push_moves_the_platform_its_way_and_only_a_push(fidelity):
    """A force on the platform (a plant's push) at its origin: at rest under the holding
    torques nothing moves; pushed along +x for a period it moves along +x.

    At rest is judged on the unpushed platform itself, over REST_S: the holding torques
    are the model's, so all that may move it is the weight they leave unheld, that of the
    plant's mass beyond the model's (the elastic plant's mismatch; none on the rigid
    plant). Its speed and its way stay within what that force gives a free body,
    F t / m and F t² / 2 m (a spring holding it only slows it)."""
    robot, settings, _, reference = setup('along')
    config = PlantConfig.from_section(settings.section('plant'), robot.cable_count, fidelity=fidelity)
    still, pushed = (PlantSimulator(robot, config, reference.position_m[0]).model for _ in range(2))
    holding = PlantSimulator(robot, config, reference.position_m[0]).holding_torque_nm()
    start = still.position_m.copy()
    period = reference.period_s
    unheld_n = abs(still.robot.mass_kg - robot.mass_kg) * np.linalg.norm(robot.gravity_m_s2)
    acceleration = unheld_n / still.robot.mass_kg
    for tick in range(1, round(REST_S / period) + 1):
        still.step(holding, period)
        if tick == 1:
            pushed.step(holding, period, external_force_n=(20.0, 0.0, 0.0))
            moved = pushed.velocity_m_s - still.velocity_m_s
            assert moved[0] > 1e-3 and abs(moved[0]) > 10 * np.abs(moved[1:]).max()
        speed, way = np.linalg.norm(still.velocity_m_s), np.linalg.norm(still.position_m - start)
        at_s = tick * period
        assert speed <= acceleration * at_s + ROUNDING, f'unpushed, {speed:.3g} m/s after {at_s:.3f} s'
        assert way <= acceleration * at_s ** 2 / 2 + ROUNDING, f'unpushed, {way * 1e3:.3g} mm off after {at_s:.3f} s'
