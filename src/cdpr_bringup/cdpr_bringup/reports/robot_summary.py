"""cdpr-robot: what the model says about a robot — the settings its file resolves to,
geometry, safe points, named motions."""
from __future__ import annotations

import argparse
import dataclasses
from pathlib import Path

import numpy as np

from cdpr_control.config import ConfigError, load_config
from cdpr_control.control.controller import PdGains
from cdpr_control.model.dynamics import inverse_dynamics
from cdpr_control.model.reference_table import tabulate_reference
from cdpr_control.geometry.motions import load_motion, motion_names, settled_motion
from cdpr_control.platform.motion import pose_motion_from_settled
from cdpr_control.setup.robot_file import load_robot
from cdpr_control.point_mass.statics import closed_form_coverage
from cdpr_control.tension_distribution import InfeasibleTensionError, configured_tension_distribution
from cdpr_control.platform.statics import workspace_grid, wrench_feasible_share
from cdpr_control.geometry.rotation import conjugate, from_axis_angle, product, to_rotation_vector
from cdpr_fdi.detection.visibility import hidden_below_n, hidden_spans
from cdpr_fdi.detectors import make_detector
from cdpr_fdi.settings.config import load_fdi_config, load_recovery_config
from cdpr_fdi.recovery_planning.recovery import RecoveryInfeasible, safe_point_for, safe_pose_for
from cdpr_fdi.recovery_strategies import STRATEGIES

from ..cli import command
from ..paths import DEFAULT_MOTIONS, DEFAULT_ROBOT, config_file
from ..runs.settle import calibration_for


def setting(section, name: str, text: str) -> str:
    """`text` for the value of `name`, marked where the defaults gave it."""
    return f'{text} (default)' if section.is_default(name) else text


def print_settings(config, robot):
    """What the robot file resolves to: its own values, the paper's defaults, derived ones.
    Returns the recovery settings, the identification δ (N of tension) and, of each plant
    it has thresholds for, its detector (`detectors`)."""
    settings = load_config(config)
    control = settings.section('control')
    gains = PdGains.from_section(robot, control)
    frequency = gains.natural_frequency_hz(robot)
    asked = control.number('pd_natural_frequency_hz')
    pd = (f'{frequency:.2f} Hz (derived: the default {asked:g} Hz is not stable on these motors)'
          if abs(frequency - asked) > 1e-9 else setting(control, 'pd_natural_frequency_hz', f'{frequency:g} Hz'))
    fdi_section = settings.section('fdi')
    fdi = load_fdi_config(config, robot)
    detectors = {'rigid': make_detector(fdi)}
    recovery = load_recovery_config(config, robot)
    recovery_section = settings.section('recovery')
    try:
        calibration = calibration_for(config, fdi_section, robot, 'elastic', None)
        elastic = load_fdi_config(config, robot, Path(calibration.path))
        elastic_text = f'{Path(calibration.path).name}: ε = {elastic.epsilon_nm:g} N·m'
        detectors = {'rigid': make_detector(fdi), 'elastic': make_detector(elastic)}
    except ConfigError as err:
        elastic_text = (f'cannot be used: {err}' if err.key != 'fdi.elastic_calibration_file'
                        else 'none (cdpr-calibrate makes one; until then --fidelity rigid)')
    except FileNotFoundError as err:
        elastic_text = f'cannot be used: {err}'
    period = setting(control, 'period_s', f"{control.number('period_s') * 1e3:g} ms")
    damping = setting(control, 'pd_damping_ratio', f"{control.number('pd_damping_ratio'):g}")
    distribution = setting(control, 'tension_distribution', control.string('tension_distribution'))
    closed_form, held = closed_form_coverage(robot)
    detector = setting(fdi_section, 'detector', fdi.detector)
    epsilon = setting(fdi_section, 'epsilon_nm', f'{fdi.epsilon_nm:g} N·m')
    heights = [setting(recovery_section, name, f'{value:g} m') for name, value in
               (('safe_height_m', recovery.safe_height_m), ('table_height_m', recovery.table_height_m))]
    move = setting(recovery_section, 'move_peak_speed_m_s', f'{recovery.move_peak_speed_m_s:g} m/s')
    print("settings (the set-up's, else the paper's defaults):")
    print(f'  control period {period}, PD {pd}, damping ratio {damping}, '
          f'tension distribution {distribution}: the paper\'s S+ w, within '
          f'[{robot.tension_min_n:g}, {robot.tension_max_n:g}] N on {closed_form} of the {held} '
          'workspace grid points where the cables can hold the end-effector at rest'
          + ('' if closed_form == held else ', the nearest tensions within the bounds on the others'
             if control.string('tension_distribution') == 'bounded_minimum_norm'
             else ', none on the others: bounded_minimum_norm has tensions there'))
    asked_delta_n = fdi_section.number('identification_delta_n')
    delta_n = fdi.delta_nm / robot.motor.drum_radius_m
    delta = (f'{delta_n:.3g} N ({fdi.delta_nm:.3g} N·m; derived: at most '
             f"{fdi_section.number('identification_delta_weight_share'):g} of each cable's equal "
             "share of the weight)" if delta_n < asked_delta_n - 1e-9 else
             setting(fdi_section, 'identification_delta_n', f'{delta_n:g} N ({fdi.delta_nm:.3g} N·m)'))
    collapse = (f'τ̂ within {fdi.collapse_band_n:g} N of zero while the reference asks at least '
                f'{fdi.collapse_reference_n:g} N, over {fdi.collapse_window_cycles} periods')
    print(f'  FDI {detector}, rigid plant ε {epsilon}, identification δ {delta}, tension collapse '
          f'{collapse}; elastic plant calibration {elastic_text}')
    print(f'  recovery SP height {heights[0]}, table {heights[1]}, move {move}, every remaining '
          f'cable planned {recovery.plan_tension_margin_n:g} N above τ_min '
          f"({recovery_section.number('plan_tension_margin_share'):g} τ_min)")
    return recovery, delta_n, detectors


def motion_extremes(robot, tension_distribution, motion, period_s):
    """Least and greatest tension (N), largest |torque| (N·m) and the tensions (N, rows of
    `period_s` × cables) along a motion."""
    times = np.arange(0.0, motion.trajectory.duration_s, period_s)
    # the whole motion as one stack (each row what its pose alone gives)
    result = inverse_dynamics(robot, tension_distribution, *motion.trajectory.sample(times))
    return np.min(result.tension_n), np.max(result.tension_n), np.max(np.abs(result.torque_nm)), result.tension_n


def hidden_break_lines(robot, tension_n: np.ndarray, detectors: dict) -> list[str]:
    """Where along a motion (its tensions, N, rows × cables) a break would leave the
    residual below what each plant's detector alarms on (cdpr_fdi.detection.visibility):
    per cable, the spans as fractions of the motion; such a break is found late, by the
    tension collapse or once another cable slackens."""
    lines = []
    rows = max(len(tension_n) - 1, 1)
    radius = robot.motor.drum_radius_m
    for plant, detector in detectors.items():
        below = hidden_below_n(detector.least_alarming_nm, radius)
        spans = [(cable, ', '.join(f'{first / rows:.2f}–{last / rows:.2f}' for first, last in cable_spans))
                 for cable, cable_spans in enumerate(hidden_spans(tension_n, detector.least_alarming_nm, radius))
                 if cable_spans]
        level = f'{below.min():.2f}' if np.ptp(below) < 0.005 else f'{below.min():.2f}–{below.max():.2f}'
        if spans:
            lines.append(f'      {plant} plant, {detector.name}: below {level} N (a break found late): '
                         + '; '.join(f'cable {cable + 1} at {where}' for cable, where in spans))
    return lines


# The grid the platform's wrench-feasible workspace is sampled on (m), and the turns it is
# sampled at besides the nominal orientation: 15° about x, y and z.
PLATFORM_GRID_SPACING_M = 0.15
PLATFORM_TURN_RAD = np.radians(15.0)


def print_platform(robot, config, distribution, motions, period_s: float, safe_height: float | None) -> None:
    """A platform robot: its geometry, and where tensions within the bounds hold it at rest
    (the wrench-feasible workspace) at its nominal orientation, turned 15° about each axis,
    and with each cable broken; the least and greatest tension along each of `motions`;
    its safe pose after each single break (at `safe_height`, default
    recovery.safe_height_m)."""
    platform = robot.body
    print(f'robot {robot.name} ({config}): {robot.cable_count} cables, a platform of '
          f'{robot.mass_kg} kg, 6 DOF (position and orientation)')
    principal = np.linalg.eigvalsh(platform.inertia_kg_m2)
    print(f'  centre of mass ({", ".join(f"{value:.3f}" for value in platform.centre_of_mass_m)}) m, principal moments '
          f'{", ".join(f"{value:.4g}" for value in principal)} kg·m² (platform frame)')
    for i, (exit_point, attachment) in enumerate(zip(robot.exit_points_m, platform.attachment_points_m)):
        print(f'  A{i + 1} = ({exit_point[0]:.3f}, {exit_point[1]:.3f}, {exit_point[2]:.3f}) m   '
              f'b{i + 1} = ({attachment[0]:.3f}, {attachment[1]:.3f}, {attachment[2]:.3f}) m')
    points = workspace_grid(robot, PLATFORM_GRID_SPACING_M)
    nominal = platform.home_orientation
    print(f'wrench-feasible workspace ({type(distribution).__name__}, tensions in '
          f'[{robot.tension_min_n:g}, {robot.tension_max_n:g}] N), share of {len(points)} grid points '
          f'{PLATFORM_GRID_SPACING_M:g} m apart:')
    turns = [('nominal orientation', nominal)] + [
        (f'turned {sign}{np.degrees(PLATFORM_TURN_RAD):.0f}° about {axis}',
         product(from_axis_angle(np.eye(3)[k], float(f'{sign}1') * PLATFORM_TURN_RAD), nominal))
        for k, axis in enumerate('xyz') for sign in '+-']
    for label, orientation in turns:
        print(f'  {label:<24} {wrench_feasible_share(robot, distribution, orientation, points):6.1%}')
    print('with one cable broken, nominal orientation:')
    for i in range(robot.cable_count):
        share = wrench_feasible_share(robot, distribution, nominal, points, robot.cable_mask([i]))
        print(f'  cable {i + 1} broken: {share:6.1%}')
    detectors = {'rigid': make_detector(load_fdi_config(config, robot))}
    print(f'named motions ({motions}), tensions along each ({type(distribution).__name__}), and where a break '
          'would leave the residual below what the detector sees (rigid plant; fractions of the motion):')
    print(f'  {"motion":<14} {"move s":>7} {"turn °":>7} {"min N":>7} {"max N":>7} {"max |c| N·m":>12}')
    for name in motion_names(motions):
        motion = pose_motion_from_settled(settled_motion(motions, name), nominal)
        try:
            reference = tabulate_reference(robot, distribution, motion.pose_trajectory, period_s)
        except InfeasibleTensionError as err:
            print(f'  {name:<14} {motion.move.duration_s:7.3f} no tensions within the bounds: {err}')
            continue
        turn = np.degrees(abs(motion.turn.angle_rad))
        print(f'  {name:<14} {motion.move.duration_s:7.3f} {turn:7.1f} {reference.tension_n.min():7.2f} '
              f'{reference.tension_n.max():7.2f} {np.abs(reference.feedforward_nm).max():12.3f}')
        for line in hidden_break_lines(robot, reference.tension_n, detectors):
            print(line)
    recovery = load_recovery_config(config, robot)
    if safe_height is not None:
        recovery = dataclasses.replace(recovery, safe_height_m=safe_height)
    print(f'safe poses at z = {recovery.safe_height_m} m (the residual workspace\'s barycentre at the orientation '
          f'that holds it with the largest tension margin, docs/design.md §5):')
    for i in range(robot.cable_count):
        try:
            pose = safe_pose_for(robot, recovery, robot.cable_mask([i]))
        except RecoveryInfeasible as err:
            print(f'  after cable {i + 1}: none ({err})')
            continue
        turn = np.degrees(to_rotation_vector(product(pose.orientation, conjugate(nominal))))
        print(f'  after cable {i + 1}: p = ({pose.position_m[0]:.3f}, {pose.position_m[1]:.3f}, '
              f'{pose.position_m[2]:.3f}) m, turned ({turn[0]:.1f}, {turn[1]:.1f}, {turn[2]:.1f})° from the '
              f'nominal orientation, margin {pose.tension_margin_n:.2f} N')
    print(f'after a break: {STRATEGIES[recovery.strategy].description} (recovery.strategy; '
          f'docs/recovery-strategies.md)')


@command('cdpr-robot')
def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument('--config', default=DEFAULT_ROBOT, help='robot YAML')
    parser.add_argument('--motions', default=DEFAULT_MOTIONS, help='motions YAML')
    parser.add_argument('--safe-height', type=float,
                        help='height of the safe points (m; default recovery.safe_height_m)')
    args = parser.parse_args(argv)
    config = config_file(args.config)
    robot = load_robot(config)
    control = load_config(config).section('control')
    period = control.number('period_s', positive=True)
    distribution = configured_tension_distribution(control, robot)

    SUMMARIES[robot.body.kind](robot, config, distribution, config_file(args.motions), period, args.safe_height)
    return 0


def print_point_mass(robot, config, distribution, motions, period: float, safe_height: float | None) -> None:
    """A point-mass robot: its settings and exit points, its safe point after each single
    break (at `safe_height`, default recovery.safe_height_m), and the least and greatest
    tension along each of `motions`."""
    print(f'robot {robot.name} ({config}): {robot.cable_count} cables, '
          f'end-effector {robot.mass_kg} kg')
    recovery, delta_n, detectors = print_settings(config, robot)
    if safe_height is not None:
        recovery = dataclasses.replace(recovery, safe_height_m=safe_height)
    for i, point in enumerate(robot.exit_points_m):
        print(f'  A{i + 1} = ({point[0]:.3f}, {point[1]:.3f}, {point[2]:.3f}) m')
    print(f'safe points at z = {recovery.safe_height_m} m (the supervisor\'s: recovery.safe_points_m, else the '
          f'barycentre of the residual SEW where the cables left hold it within [τ_min, τ_max], else of the '
          f'section where they do, docs/design.md):')
    for i in range(robot.cable_count):
        try:
            point = safe_point_for(robot, recovery, robot.cable_mask([i]))
        except RecoveryInfeasible as err:
            print(f'  cable {i + 1} broken: none ({err})')
            continue
        print(f'  cable {i + 1} broken: SP = ({point[0]:.4f}, {point[1]:.4f}, {point[2]:.4f}) m')
    print(f'named motions ({motions}), tensions along each ({type(distribution).__name__}), and where a break '
          'would leave the residual below what the detector sees (fractions of the motion):')
    print(f'  {"motion":<14} {"move s":>7} {"min N":>7} {"max N":>7} {"max |c| N·m":>12}')
    for name in motion_names(motions):
        motion = load_motion(motions, name)
        try:
            low, high, torque, tension = motion_extremes(robot, distribution, motion, period)
        except InfeasibleTensionError as err:
            print(f'  {name:<14} {motion.move.duration_s:7.3f} no tensions within the bounds: {err}')
            continue
        # a loaded cable below δ looks free to the identification (eq. 21)
        warning = (f'  below the identification δ {delta_n:g} N: a loaded cable can look free'
                   if low < delta_n else '')
        print(f'  {name:<14} {motion.move.duration_s:7.3f} {low:7.2f} {high:7.2f} {torque:12.3f}{warning}')
        for line in hidden_break_lines(robot, tension, detectors):
            print(line)



# What cdpr-robot prints of each body (Body.kind).
SUMMARIES = {'point_mass': print_point_mass, 'platform': print_platform}

if __name__ == '__main__':
    main()
