"""cdpr-robot: what the model says about a robot — geometry, safe points, named motions."""
from __future__ import annotations

import argparse

import numpy as np

from cdpr_control.config import load_section
from cdpr_control.dynamics import inverse_dynamics
from cdpr_control.motions import load_motion, motion_names
from cdpr_control.robot import load_robot
from cdpr_control.tension_distribution import InfeasibleTensionError, configured_tension_distribution
from cdpr_control.workspace import safe_point

from .cli import command
from .paths import DEFAULT_MOTIONS, DEFAULT_ROBOT, config_file


def motion_extremes(robot, tension_distribution, motion, period_s):
    """Least and greatest tension (N) and largest |torque| (N·m) along a motion."""
    times = np.arange(0.0, motion.trajectory.duration_s, period_s)
    tensions, torques = [], []
    for t in times:
        result = inverse_dynamics(robot, tension_distribution, *motion.trajectory.sample(t))
        tensions.append(result.tension_n)
        torques.append(result.torque_nm)
    return np.min(tensions), np.max(tensions), np.max(np.abs(torques))


@command('cdpr-robot')
def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument('--config', default=DEFAULT_ROBOT, help='robot YAML')
    parser.add_argument('--motions', default=DEFAULT_MOTIONS, help='motions YAML')
    parser.add_argument('--safe-height', type=float, default=1.2,
                        help='height of the safe points (m)')
    args = parser.parse_args(argv)
    config = config_file(args.config)
    robot = load_robot(config)
    control = load_section(config, 'control')
    period = control.number('period_s', positive=True)
    distribution = configured_tension_distribution(control, robot)

    print(f'robot {robot.name} ({config}): {robot.cable_count} cables, '
          f'end-effector {robot.mass_kg} kg')
    for i, point in enumerate(robot.exit_points_m):
        print(f'  A{i + 1} = ({point[0]:.3f}, {point[1]:.3f}, {point[2]:.3f}) m')
    print(f'safe points at z = {args.safe_height} m (barycentre of the residual SEW):')
    for i in range(robot.cable_count):
        point = safe_point(robot, robot.cable_mask([i]), args.safe_height)
        print(f'  cable {i + 1} broken: SP = ({point[0]:.4f}, {point[1]:.4f}, {point[2]:.4f}) m')
    motions = config_file(args.motions)
    print(f'named motions ({motions}), tensions along each ({type(distribution).__name__}):')
    print(f'  {"motion":<14} {"move s":>7} {"min N":>7} {"max N":>7} {"max |c| N·m":>12}')
    for name in motion_names(motions):
        motion = load_motion(motions, name)
        try:
            low, high, torque = motion_extremes(robot, distribution, motion, period)
        except InfeasibleTensionError as err:
            print(f'  {name:<14} {motion.move.duration_s:7.3f} no tensions within the bounds: {err}')
            continue
        print(f'  {name:<14} {motion.move.duration_s:7.3f} {low:7.2f} {high:7.2f} {torque:12.3f}')


if __name__ == '__main__':
    main()
