"""cdpr-identify: the twin fitted to the robot it watches, from failure-free bags.

Reads the motor angles, speeds and commands of one or more failure-free runs of a robot
(bags of the real robot through the hardware bridge, or of any plant), fits each motor's
inertia, viscous and Coulomb friction and the end-effector's mass by least squares on
the end-effector's wrench balance (cdpr_twin.models.fitting), and writes the robot file
with the fitted values, which `--config` takes: the twin (with the motors' Coulomb friction,
`twin.coulomb_friction_nm`), the controller and the supervisor then model the robot as
it is. The robot file's simulated plant stays the
machine it was: its `plant.elastic.mismatch` factors are restated against the fitted
values. Refuses, naming the parameter, where the motions do not excite one.
"""
from __future__ import annotations

import argparse
import copy
import datetime
import sys
from pathlib import Path

import numpy as np
import yaml

from cdpr_control.config import load_config, load_yaml
from cdpr_control.setup.robot_file import robot_from_section
from cdpr_twin.models.fitting import BREAKAWAY, MOTOR_PARAMETERS, FitOptions, NotExcited, fit_twin
from cdpr_twin.models.plant import FIDELITIES, PlantConfig

from ..bags.bag_io import recording_from_bag
from ..cli import UsageError, command
from ..paths import DEFAULT_ROBOT, config_file
from ..runs.settle import calibration_file_key

# The fit's uncertainties are stated expanded by this coverage factor (k = 3: ~99.7 % for a
# normal error), from the least-squares standard uncertainties.
COVERAGE = FitOptions().coverage
# The robot file's values the fit replaces, and the plant's mismatch factor of each.
FITTED = {'inertia_kg_m2': 'inertia', 'viscous_friction_nm_s_rad': 'viscous_friction',
          'static_friction_nm': 'static_friction'}


def parse_args(argv=None):
    defaults = FitOptions()
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('bags', nargs='+', help='failure-free runs: bag folders, or run folders holding bag/')
    parser.add_argument('--config', default=DEFAULT_ROBOT, help='the robot file the runs were made with')
    parser.add_argument('--out', required=True, help='the fitted robot file to write')
    parser.add_argument('--smoothing', type=float, default=defaults.smoothing_s,
                        help=f'σ of the Gaussian window the measurements are smoothed by (s, default '
                             f'{defaults.smoothing_s:g})')
    parser.add_argument('--largest-uncertainty', type=float, default=defaults.largest_relative_uncertainty,
                        help='refuse a value whose expanded relative uncertainty is above this (default '
                             f'{defaults.largest_relative_uncertainty:g})')
    return parser.parse_args(argv)


def bag_of(path: str) -> Path:
    path = Path(path)
    if (path / 'bag').is_dir():
        return path / 'bag'
    if not path.exists():
        raise UsageError(f'{path}: no such bag or run folder')
    return path


def measurements(bag: Path):
    """(θ, θ̇, c) of a bag's ticks; UsageError for a bag that lacks ticks or holds a failure."""
    try:
        recording = recording_from_bag(bag)
    except ValueError as err:
        raise UsageError(str(err)) from None
    figures = (recording.angle_rad, recording.angular_velocity_rad_s, recording.command_nm)
    steps = np.diff(recording.time_s)
    if not all(np.isfinite(figure).all() for figure in figures) or (steps.size and steps.max() > 1.5 * steps.min()):
        raise UsageError(f'{bag}: ticks are missing; the fit needs every tick of a run')
    return figures


def fitted_document(document: dict, settled, robot, fit) -> dict:
    """The robot file's document with the fitted values, and the plant restated so that it
    is the same machine: each mismatch factor times the file's value over the fitted one."""
    fitted = copy.deepcopy(document)
    if 'robot_file' in fitted:
        # a set-up naming its robot file: the fitted file holds the robot itself
        del fitted['robot_file']
        fitted['robot'] = copy.deepcopy(settled.section('robot').data)
    section, motor = fitted['robot'], fitted['robot']['motor']
    plant_config = PlantConfig.from_section(settled.section('plant'), robot.cable_count)
    factors = {'mass': round(plant_config.mass_factor * robot.mass_kg / fit.mass_kg, 6)}
    section['end_effector']['mass_kg'] = round(fit.mass_kg, 6)
    for name, factor in FITTED.items():
        value = float(f'{fit.common(name)[0]:.6g}')
        motor[name] = value
        # each motor's own factor (PlantConfig's, one per motor), restated
        restated = [round(old * getattr(robot.motor, name) / value, 6) if value else 0.0
                    for old in getattr(plant_config, f'{factor}_factors')]
        factors[factor] = restated[0] if len(set(restated)) == 1 else restated
    # thresholds calibrated on the robot as it was modelled are not the fitted twin's
    # (their fingerprint says so): the fitted file is calibrated anew (cdpr-calibrate)
    for fidelity in FIDELITIES:
        fitted.get('fdi', {}).pop(calibration_file_key(fidelity), None)
    # the twin feels the motors' Coulomb friction too (its default is none), and the
    # break-away excess where the data showed one
    twin = fitted.setdefault('twin', {})
    twin['coulomb_friction_nm'] = motor['static_friction_nm']
    if fit.stribeck_speed_rad_s is not None:
        twin['breakaway_friction_nm'] = float(f'{fit.common(BREAKAWAY)[0]:.6g}')
        twin['stribeck_speed_rad_s'] = fit.stribeck_speed_rad_s
    plant = fitted.setdefault('plant', {}).setdefault('elastic', {})
    plant['mismatch'] = {**plant.get('mismatch', {}), **factors}
    return fitted


def report(robot, fit) -> list[str]:
    lines = [f'end-effector mass {fit.mass_kg:.5f} ± {COVERAGE * fit.mass_uncertainty_kg:.5f} kg '
             f'(robot file {robot.mass_kg:g})']
    for name in fit.motors:
        common, sigma = fit.common(name)
        per_motor = ', '.join(f'{value:.4g} ± {COVERAGE * error:.2g}'
                              for value, error in zip(fit.motors[name], fit.uncertainties[name]))
        known = (f'robot file {getattr(robot.motor, name):g}' if name in MOTOR_PARAMETERS
                 else f'Stribeck speed {fit.stribeck_speed_rad_s:g} rad/s')
        lines.append(f'{name}: {common:.5g} ± {COVERAGE * sigma:.2g} ({known}); per motor {per_motor}')
    lines.append(f'residual of the wrench balance {fit.residual_rms_n:.4f} N rms over {fit.equations} equations')
    return lines


@command('cdpr-identify')
def main(argv=None):
    args = parse_args(argv)
    if not args.smoothing > 0.0 or not args.largest_uncertainty > 0.0:
        raise UsageError('--smoothing and --largest-uncertainty must be positive')
    path = config_file(args.config)
    settled = load_config(path)
    robot = robot_from_section(settled.section('robot'))
    control, fdi = settled.section('control'), settled.section('fdi')
    period_s = control.number('period_s', positive=True)
    options = FitOptions(smoothing_s=args.smoothing, coulomb_smoothing_rad_s=control.number(
                             'coulomb_smoothing_rad_s', positive=True),
                         drive_delay_s=fdi.number('drive_delay_s', non_negative=True),
                         largest_relative_uncertainty=args.largest_uncertainty)
    bags = [bag_of(bag) for bag in args.bags]
    try:
        fit = fit_twin(robot, [measurements(bag) for bag in bags], period_s, options)
    except NotExcited as err:
        raise UsageError(f'{", ".join(map(str, bags))}: {err}') from None
    lines = report(robot, fit)
    document = fitted_document(load_yaml(path), settled, robot, fit)
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    header = [f'Written by cdpr-identify on {datetime.date.today().isoformat()} from {path} and',
              *(f'  {bag}' for bag in bags),
              f'Uncertainties expanded, k = {COVERAGE:g}. The twin models one motor type: each motor value',
              'below is the motors\' weighted mean; plant.elastic.mismatch is restated so that the',
              'simulated plant is the machine it was.', *lines]
    out.write_text(''.join(f'# {line}\n' for line in header) + yaml.safe_dump(document, sort_keys=False))
    print('\n'.join(f'cdpr-identify: {line}' if k == 0 else f'  {line}' for k, line in enumerate(lines)))
    print(f'written: {out}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
