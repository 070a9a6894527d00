"""cdpr-bench: benchmarks of the project, printing figures (and JSON on request).

model: median µs per call of the model functions. graph: the node graph's and the
in-process engine's speed against their targets (cdpr_bringup.bench.graph). fdi: each
detector's figures on a campaign (cdpr_bringup.bench.fdi). roc: detection delay against
false alarms per hour (cdpr_bringup.bench.roc). far: each detector's false alarms per hour
(95 % upper bound) and ARL₀ on pushed failure-free runs of --hours per plant, against its
delay on the failure matrix, per sensitivity (cdpr_bringup.bench.far). sweep: the detectors on plants that differ
from the one they were calibrated on (cdpr_bringup.bench.sweep). soak: a long realtime run.
campaign: simulated hours per wall hour of a campaign on a local Dask scheduler with 1, 2
workers (cdpr_bringup.bench.campaign). run: one whole cdpr-scenario run, and its stages
(cdpr_bringup.bench.run). cycle: the in-process engine with the elastic sub-steps compiled
and in pure Python, and the µs of each stage of a cycle (cdpr_bringup.bench.cycle).
recorder: whether the bag keeps every tick in realtime with outside readers frozen or
reading (cdpr_bringup.bench.recorder). robots: robots drawn from --seed, calibrated, every
cable broken at --instants random instants, the stack judged on them (cdpr_bringup.family).
"""
from __future__ import annotations

import argparse
import importlib
import json
import platform
import os
import time

import numpy as np

from cdpr_control.config import load_config
from cdpr_control.model.dynamics import inverse_dynamics
from cdpr_control.point_mass.dynamics import direct_dynamics
from cdpr_control.platform import dynamics as pose_dynamics
from cdpr_control.platform import kinematics as pose_kinematics
from cdpr_control.point_mass.kinematics import forward_kinematics, inverse_kinematics, structure_matrix
from cdpr_control.geometry.pose_trajectories import PoseSample
from cdpr_control.setup.robot_file import load_robot
from cdpr_control.geometry.rotation import from_axis_angle, product
from cdpr_control.platform.steered_approach import SteeredApproach
from cdpr_control.tension_distribution import METHODS, make_tension_distribution
from cdpr_fdi.settings.config import load_recovery_config

from cdpr_twin.models.plant import FIDELITIES

from .roc import FACTORS
from ..cli import command
from ..paths import DEFAULT_ROBOT, config_file

REPEATS = 31
CALLS_PER_REPEAT = 200


def median_us(call, *args) -> float:
    """Median over REPEATS batches of the mean time (µs) of one call."""
    samples = []
    for _ in range(REPEATS):
        start = time.perf_counter()
        for _ in range(CALLS_PER_REPEAT):
            call(*args)
        samples.append((time.perf_counter() - start) / CALLS_PER_REPEAT * 1e6)
    return float(np.median(samples))


def bench_model(config: str) -> dict:
    """µs per call of the model functions at a pose in the middle of a motion."""
    path = config_file(config)
    robot = load_robot(path)
    return MODEL_BENCHES[robot.body.kind](robot, path)


def bench_point_mass_model(robot, path) -> dict:
    """µs per call of a point mass's model functions at a pose off home, moving; forward
    kinematics with every cable and with the last one broken."""
    position = robot.home_position_m + np.array([0.11, -0.07, 0.05])
    velocity = np.array([0.2, -0.3, 0.1])
    acceleration = np.array([0.5, 0.4, -0.3])
    angles = inverse_kinematics(robot, position)
    all_cables = robot.cable_mask()
    after_failure = robot.cable_mask([robot.cable_count - 1])
    structure, _ = structure_matrix(robot, position)
    wrench = robot.mass_kg * (acceleration - robot.gravity_m_s2)
    pseudo_inverse = make_tension_distribution('pseudo_inverse', robot.tension_min_n,
                                               robot.tension_max_n)
    torque = inverse_dynamics(robot, pseudo_inverse, position, velocity, acceleration)
    figures = {
        'inverse_kinematics_us': median_us(inverse_kinematics, robot, position),
        'forward_kinematics_us': median_us(forward_kinematics, robot, angles, all_cables),
        'forward_kinematics_after_failure_us': median_us(forward_kinematics, robot, angles,
                                                         after_failure),
    }
    for name in METHODS:
        method = make_tension_distribution(name, robot.tension_min_n, robot.tension_max_n)
        figures[f'tension_{name}_us'] = median_us(method.distribute, structure, wrench)
    figures['inverse_dynamics_us'] = median_us(inverse_dynamics, robot, pseudo_inverse, position,
                                               velocity, acceleration)
    figures['direct_dynamics_us'] = median_us(direct_dynamics, robot, position, velocity,
                                              torque.torque_nm, torque.joint_velocity_rad_s)
    return figures


def bench_platform_model(robot, path) -> dict:
    """µs per call of a platform's model functions at a pose off home, turned 8.6° and
    moving; forward kinematics as a node calls it, from the pose of the tick before
    (0.6 mm and 0.06° away: 0.3 m/s and 0.5 rad/s for 2 ms), and cold, from home. And a
    row of the steered approach (a recovery's, the last cable gone: the nearest wrench,
    the rigid body, one period on), its first 6200 rows from there towards home."""
    recovery = load_recovery_config(path, robot)
    period_s = load_config(path).section('control').number('period_s', positive=True)
    position = robot.home_position_m + np.array([0.11, -0.07, 0.05])
    orientation = from_axis_angle([1.0, 2.0, 0.5], 0.15)
    velocity, angular_velocity = np.array([0.2, -0.3, 0.1]), np.array([0.1, 0.2, -0.1])
    acceleration, angular_acceleration = np.array([0.5, 0.4, -0.3]), np.array([0.3, -0.2, 0.1])
    angles = pose_kinematics.inverse_kinematics(robot, position, orientation)
    before = (position - np.array([0.0006, 0.0, 0.0]),
              product(from_axis_angle([0.0, 0.0, 1.0], 0.001), orientation))
    structure, _ = pose_kinematics.wrench_matrix(robot, position, orientation)
    body = pose_dynamics.rigid_body(robot, orientation, angular_velocity)
    wrench = body.mass_matrix @ np.concatenate([acceleration, angular_acceleration]) - body.free_wrench
    pseudo_inverse = make_tension_distribution('pseudo_inverse', robot.tension_min_n, robot.tension_max_n)
    motion = (position, orientation, velocity, angular_velocity)
    sample = PoseSample(*motion, acceleration, angular_acceleration)
    torque = inverse_dynamics(robot, pseudo_inverse, *sample.motion)
    figures = {
        'inverse_kinematics_us': median_us(pose_kinematics.inverse_kinematics, robot, position, orientation),
        'forward_kinematics_us': median_us(lambda: pose_kinematics.forward_kinematics(robot, angles, start=before)),
        'forward_kinematics_from_home_us': median_us(pose_kinematics.forward_kinematics, robot, angles),
        'wrench_matrix_us': median_us(pose_kinematics.wrench_matrix, robot, position, orientation),
    }
    for name in METHODS:
        method = make_tension_distribution(name, robot.tension_min_n, robot.tension_max_n)
        figures[f'tension_{name}_us'] = median_us(method.distribute, structure, wrench)
    figures['inverse_dynamics_us'] = median_us(inverse_dynamics, robot, pseudo_inverse, *sample.motion)
    figures['direct_dynamics_us'] = median_us(robot.body.direct_dynamics, robot, sample.pose, sample.twist,
                                              torque.torque_nm, torque.joint_velocity_rad_s)
    attached = robot.cable_mask([robot.cable_count - 1])
    approach = SteeredApproach(robot, attached, sample,
                               robot.home_position_m, robot.body.home_orientation, recovery.approach_gains,
                               robot.tension_min_n + recovery.approach_tension_margin_n, robot.tension_max_n,
                               period_s)
    figures['steered_approach_row_us'] = median_us(lambda: approach.extend(approach.count + 1))
    return figures


# The model functions benched of each body (Body.kind).
MODEL_BENCHES = {'point_mass': bench_point_mass_model, 'platform': bench_platform_model}


def machine() -> str:
    return f'{platform.machine()} {os.cpu_count()} cores, Python {platform.python_version()}, numpy {np.__version__}'


def _factors(text: str) -> tuple[float, ...]:
    factors = tuple(sorted(float(item) for item in text.split(',') if item.strip()))
    if not factors or min(factors) <= 0.0:
        raise argparse.ArgumentTypeError('factors are positive numbers, e.g. 0.7,1,1.5')
    return factors


def _plants(text: str) -> list[str]:
    plants = [item.strip() for item in text.split(',') if item.strip()]
    if not plants or not set(plants) <= set(FIDELITIES):
        raise argparse.ArgumentTypeError(f'plants are some of {", ".join(FIDELITIES)}, comma-separated')
    return plants


def _list(text: str) -> tuple[str, ...]:
    return tuple(item.strip() for item in text.split(',') if item.strip())


def _seeds(text: str) -> tuple[int, ...]:
    try:
        return tuple(int(item) for item in _list(text))
    except ValueError:
        raise argparse.ArgumentTypeError('plant seeds are integers, comma-separated, e.g. 0,1,2') from None


def _counts(text: str) -> list[int]:
    counts = [int(item) for item in text.split(',') if item.strip()]
    if not counts or min(counts) < 1:
        raise argparse.ArgumentTypeError('worker counts are positive integers, e.g. 1,2')
    return counts


# suite → (its bench function's arguments from the options and the output folder, heading)
SUITES = {
    'fdi': (lambda a, out: (a.config, out, a.jobs, a.fidelity),
            '{fidelity} plant; campaigns in {out} (summary.md)'),
    'roc': (lambda a, out: (a.config, out, a.fidelity, a.jobs),
            '{fidelity} plant; {out}/roc.csv, {out}/roc.png'),
    'far': (lambda a, out: (a.config, out, a.plants or [a.fidelity], a.hours, a.jobs, a.scheduler,
                            a.factors),
            '{plants} plant; {hours:g} h failure-free per plant; {out}/far.csv, {out}/far.png'),
    'sweep': (lambda a, out: (a.config, out, a.fidelity, a.jobs),
              '{fidelity} plant; {out}/sweep.csv, {out}/sweep.png'),
    'campaign': (lambda a, out: (a.config, out, a.fidelity, a.workers),
                 '{fidelity} plant; campaigns in {out}'),
    'run': (lambda a, out: (a.config, out), 'seconds, the best of its repeats; {out}'),
    'cycle': (lambda a, out: (a.config,), 'in-process engine, elastic circle with the supervisor'),
    'graph': (lambda a, out: (a.config,), 'ROS_DOMAIN_ID {domain}'),
    'recorder': (lambda a, out: (a.config,), 'ROS_DOMAIN_ID {domain}'),
}


@command('cdpr-bench')
def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument('suite', choices=['model', 'soak', *SUITES, 'robots'], help='what to measure')
    parser.add_argument('--minutes', type=float, default=10.0, help='soak: how long')
    parser.add_argument('--config', default=DEFAULT_ROBOT, help='robot YAML')
    parser.add_argument('--json', action='store_true', help='print one JSON object last')
    parser.add_argument('--out', help='fdi, roc, sweep, far, campaign, run: output folder (default runs/bench-SUITE)')
    parser.add_argument('--fidelity', choices=FIDELITIES, default='elastic',
                        help='fdi, roc, sweep, campaign, far: the plant')
    parser.add_argument('--workers', type=_counts, default=[1, 2],
                        help='campaign: Dask worker counts, comma-separated (default 1,2)')
    parser.add_argument('--jobs', type=int, default=None,
                        help='fdi, roc, sweep, far, robots: parallel runs (default: cores)')
    parser.add_argument('--hours', type=float, default=1.0,
                        help='far: simulated hours of failure-free motion per plant (default 1)')
    parser.add_argument('--plants', type=_plants,
                        help='far: the plants, comma-separated (default: --fidelity)')
    parser.add_argument('--factors', type=_factors, default=FACTORS,
                        help='far: the sensitivities, factors on the calibrated thresholds, comma-separated '
                             f'(default {",".join(f"{f:g}" for f in FACTORS)})')
    parser.add_argument('--scheduler', metavar='ADDRESS',
                        help='far, robots: run on the workers of this Dask scheduler (tcp://HOST:PORT) '
                             'instead of local processes')
    # robots: every default is FamilyOptions'
    parser.add_argument('--count', type=int, help='robots: how many robots to draw (default 5)')
    parser.add_argument('--seed', type=int, help='robots: the seed they are drawn from (default 0)')
    parser.add_argument('--instants', type=int,
                        help='robots: random instants each cable breaks at, on each plant (default 3)')
    parser.add_argument('--fidelities', type=_list, help='robots: the plants, comma-separated (default rigid,elastic)')
    parser.add_argument('--cables', type=int, help='robots: cables broken per robot, drawn (default: every cable)')
    parser.add_argument('--calibration-seeds', type=_seeds,
                        help="robots: the calibration's plant seeds, comma-separated (default 0,1,2)")
    parser.add_argument('--calibration-motions', type=int,
                        help="robots: the calibration's first N motions of each robot (default: all)")
    args = parser.parse_args(argv)
    # a refused robot is said here, in one line, before any suite starts its workers
    load_robot(config_file(args.config))
    out = args.out or f'runs/bench-{args.suite}'
    if args.suite == 'soak':
        from .soak import bench_soak, targets
        figures = bench_soak(args.config, args.minutes)
        print(f'cdpr-bench soak on {machine()}: {args.minutes:g} min, realtime, failure-free')
        for key, value in figures.items():
            print(f'  {key:<28} {value}')
        for label, value, target, met in targets(figures):
            print(f'  {label:<38} {value:>24}  {target:<10} {"yes" if met else "NO"}')
    elif args.suite == 'robots':
        from ..family.command import bench_robots, settle_family, table
        options = settle_family(count=args.count, seed=args.seed, instants=args.instants, fidelities=args.fidelities,
                                cables=args.cables, calibration_seeds=args.calibration_seeds,
                                calibration_motions=args.calibration_motions, jobs=args.jobs,
                                scheduler=args.scheduler, out=out)
        heading = (f'cdpr-bench robots on {machine()}: --count {options.count} --seed {options.seed} '
                   f'--instants {options.instants} --fidelities {",".join(options.fidelities)}')
        found = bench_robots(options, heading)
        print(heading)
        print('\n'.join(table(found)))
        figures = {'robots': len(found['members']), 'draws': found['drawing']['draws'],
                   'cases': len(found['cases']), 'runs': len(found['rows'])}
    elif args.suite in SUITES:
        arguments, heading = SUITES[args.suite]
        # imported only for its suite (bench_graph loads rclpy, bench_campaign Dask)
        module = importlib.import_module(f'.{args.suite}', __package__)
        figures = getattr(module, f'bench_{args.suite}')(*arguments(args, out))
        print(f'cdpr-bench {args.suite} on {machine()}, ' + heading.format(
            fidelity=args.fidelity, out=out, domain=os.environ.get('ROS_DOMAIN_ID', '0'),
            plants=','.join(args.plants or [args.fidelity]), hours=args.hours))
        print('\n'.join(module.table(figures)))
    else:
        figures = bench_model(args.config)
        print(f'cdpr-bench model on {machine()}; median of {REPEATS} x {CALLS_PER_REPEAT} calls')
        for key, value in figures.items():
            print(f'  {key:<40} {value:9.2f}')
    if args.json:
        print(json.dumps(figures))


if __name__ == '__main__':
    main()
