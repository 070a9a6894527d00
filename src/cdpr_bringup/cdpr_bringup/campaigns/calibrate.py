"""cdpr-calibrate: detector thresholds for a target false-alarm rate, from failure-free runs.

Runs every named motion (both directions, each seed) without a failure on the chosen
plant fidelity, in-process and in parallel; fits the motors' Coulomb friction and the
nominal residual spread; runs them again with a supervisor watching on the fitted
friction, every alarm out of reach, for the tension-collapse test's floor; and writes the
thresholds of both detectors (and that floor, where a run read a loaded motor free) into
a YAML file the supervisor loads (`cdpr-scenario --calibration FILE`, ROS parameter calibration_file).

--from-far FAR_CSV runs nothing: from a `cdpr-bench far` run's false alarms it takes, for
each detector on the plant, the most sensitive swept thresholds whose 95 % upper bound
on false alarms per hour is below the target (campaigns.operating_point.choose), and writes
the calibration they were scaled from with those thresholds.
"""
from __future__ import annotations

import argparse
import dataclasses
import datetime
import math
import os
import sys
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import yaml

from cdpr_control.config import load_config, load_section
from cdpr_control.control.controller import PdGains
from cdpr_control.geometry.motions import motion_names
from cdpr_control.setup.robot_file import load_robot
from cdpr_fdi.detection.calibration import FailureFreeRun, calibrate, collapse_reference_level
from cdpr_twin.models.plant import FIDELITIES

from ..cli import command
from ..runs.engine import run_inprocess
from ..paths import DEFAULT_MOTIONS, DEFAULT_ROBOT, config_file
from ..runs.settle import NO_CALIBRATION, ScenarioOptions, build_scenario


def parse_args(argv=None):
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument('--config', default=DEFAULT_ROBOT, help='robot YAML')
    parser.add_argument('--motions', default=DEFAULT_MOTIONS, help='motions YAML')
    parser.add_argument('--fidelity', choices=FIDELITIES, default='elastic')
    parser.add_argument('--seeds', default='0,1,2', help='comma-separated plant seeds')
    parser.add_argument('--false-alarms-per-hour', type=float, default=0.1,
                        help='target rate (default 0.1: one per 10 hours)')
    parser.add_argument('--drift', type=float, help='CUSUM drift ν in σ (default: the config\'s)')
    parser.add_argument('--jobs', type=int, default=os.cpu_count())
    parser.add_argument('--from-far', metavar='FAR_CSV',
                        help='run nothing: choose ε and the CUSUM\'s h for --false-alarms-per-hour on '
                             '--fidelity from a cdpr-bench far run (its far.csv)')
    parser.add_argument('--out', required=True, help='calibration YAML to write')
    return parser.parse_args(argv)


def scenario_of(job):
    """The failure-free scenario of a job (UsageError or ConfigError where it is refused)."""
    config, motions, motion, reverse, fidelity, seed = job
    # no supervisor runs, so no thresholds are needed: a new robot calibrates from nothing
    return build_scenario(ScenarioOptions(config=config, motions=motions, motion=motion, reverse=reverse,
                                          fidelity=fidelity, seed=seed, calibration=NO_CALIBRATION))


def failure_free_run(job) -> tuple[FailureFreeRun, float]:
    """The run's residuals and the largest torque (N·m) its motors were commanded."""
    recording = run_inprocess(scenario_of(job), supervised=False)
    return (FailureFreeRun(recording.command_nm - recording.twin_torque_nm, recording.twin_angular_velocity_rad_s),
            float(abs(recording.command_nm).max()))


def free_reference(job_and_friction) -> float | None:
    """The most a reference asked (N) of a motor whose τ̂, with the Coulomb friction (N·m)
    fitted, read free in the job's failure-free run: a supervisor watches it, every alarm
    out of reach (None: none did)."""
    job, coulomb_friction_nm = job_and_friction
    scenario = scenario_of(job)
    fdi = scenario.fdi.with_overrides(coulomb_friction_nm=coulomb_friction_nm).watching()
    return run_inprocess(dataclasses.replace(scenario, fdi=fdi)).fdi['collapse_free_reference_n']


def collapse_reference_share(level_n: float | None, robot, fdi) -> float | None:
    """fdi.collapse_reference_share for a calibrated level (N): a thousandth of τ_min
    above it (the test alarms from the floor on), at least the robot file's; None where no
    run read a loaded motor free."""
    if level_n is None:
        return None
    configured = fdi.number('collapse_reference_share', positive=True)
    return max(configured, (math.floor(level_n / robot.tension_min_n * 1000.0) + 1) / 1000.0)


def check_held(config: Path, robot, work: list, peaks_nm: list[float]) -> None:
    """ConfigError where a failure-free run drove a motor to its torque limit: the
    controller does not hold the robot on that plant (a drawn 8.3 kg point mass at the
    stable PD's edge, 11 Hz, rang on the elastic cables: tensions 0–62 N, τ_max 49), and
    thresholds measured on such runs would lie above any break (ε/ρ 83 N)."""
    limit = robot.motor.torque_limit_nm
    saturated = [job for job, peak in zip(work, peaks_nm) if peak >= limit]
    if saturated:
        _, _, motion, reverse, fidelity, seed = saturated[0]
        config_data = load_config(config)
        _, frequency_hz, _ = PdGains.settled(robot, config_data.section('control'))
        raise config_data.section('robot').section('motor').error('torque_limit_nm', (
            f'({limit:g} N·m) is reached on the failure-free motion {motion}{" reversed" if reverse else ""} '
            f'(seed {seed}, {fidelity} plant; {len(saturated)} of {len(work)} runs): the controller does not '
            f'hold this robot there, and thresholds measured so would hide its breaks; a lower '
            f'control.pd_natural_frequency_hz (now {frequency_hz:.2f} Hz) or stronger motors'))


def write_calibration(out: Path, document: dict) -> None:
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text('# Written by cdpr-calibrate; load with cdpr-scenario --calibration.\n'
                   + yaml.safe_dump(document, sort_keys=False))


def from_far(path: str, fidelity: str, target_per_hour: float, out: Path) -> int:
    """The calibration a cdpr-bench far run was judged with, its thresholds those chosen for
    `target_per_hour`; 1 with one line where no swept sensitivity meets it."""
    from .operating_point import CONFIDENCE, choose, far_points, read_rows
    rows = [row for row in read_rows(path) if row['fidelity'] == fidelity]
    chosen = {}
    for (_, detector), curve in far_points(rows).items():
        point = choose(curve, target_per_hour)
        if point is None:
            # zero false alarms bound the rate below the target only after this many hours
            needed_h = -math.log(1.0 - CONFIDENCE) / target_per_hour
            lowest = min((p['upper_per_hour'] for p in curve if p['upper_per_hour'] is not None),
                         default=math.inf)
            print(f'cdpr-calibrate: --from-far {path}: no swept threshold of the {detector} detector '
                  f'on the {fidelity} plant has its 95 % upper bound below {target_per_hour:g} false '
                  f'alarms per hour (lowest {lowest:.3g} /h in '
                  f'{curve[0]["failure_free_hours"]:.2f} h; that takes none in {needed_h:.0f} h)',
                  file=sys.stderr)
            return 1
        chosen[detector] = next(row for row in rows if row['detector'] == detector
                                and row['factor'] == point['factor']), point
    if set(chosen) != {'threshold', 'cusum'} or not rows[0]['calibration']:
        print(f'cdpr-calibrate: --from-far {path}: needs both detectors judged on the {fidelity} '
              'plant with a calibration (the rigid plant has none)', file=sys.stderr)
        return 1
    (threshold, threshold_point), (cusum, cusum_point) = chosen['threshold'], chosen['cusum']
    document = yaml.safe_load(Path(rows[0]['calibration']).read_text())
    document['fdi']['epsilon_nm'] = round(threshold['epsilon_nm'], 5)
    document['fdi']['cusum'].update(threshold=round(cusum['cusum_threshold'], 3),
                                    limit=round(cusum['cusum_limit'], 3),
                                    epsilon_nm=round(cusum['cusum_epsilon_nm'], 5))
    document['calibration'].update(
        date=datetime.date.today().isoformat(), target_false_alarms_per_hour=target_per_hour,
        from_far=str(path), far_hours=round(threshold_point['failure_free_hours'], 4),
        far_calibration=rows[0]['calibration'],
        threshold_factor=threshold_point['factor'], cusum_factor=cusum_point['factor'],
        threshold_upper_per_hour=round(threshold_point['upper_per_hour'], 4),
        cusum_upper_per_hour=round(cusum_point['upper_per_hour'], 4))
    write_calibration(out, document)
    for name, point in (('threshold', threshold_point), ('cusum', cusum_point)):
        h = '' if point['cusum_h'] is None else f', h = {point["cusum_h"]:.3f}'
        print(f'  {name}: ×{point["factor"]:g} of {rows[0]["calibration"]}: ε = {point["epsilon_nm"]:.4f} N·m'
              f'{h}; {point["false_alarms"]} false alarms in {point["failure_free_hours"]:.2f} h, '
              f'< {point["upper_per_hour"]:.3g} /h (95 %)')
    print(f'written: {out}')
    return 0


@dataclass
class Calibrated:
    """What `calibrate_robot` found: the calibration document (as written to FILE), the
    fit it came from, the friction the twin models (N·m) and the number of runs."""

    document: dict
    result: object
    twin_friction_nm: float
    # collapse_reference_level's (N; None: no run read a loaded motor free)
    collapse_level_n: float | None = None


def calibrate_robot(config: Path, motions: Path, fidelity: str, seeds: list[int], jobs: int,
                    false_alarms_per_hour: float, drift: float | None = None,
                    motion_set: list[str] | None = None) -> Calibrated:
    """The core of cdpr-calibrate: every motion of `motions` (or those of `motion_set`), both
    directions, each seed, run failure-free on the `fidelity` plant in `jobs` processes, and
    the thresholds fitted to them, then run again watched for the tension-collapse floor
    (free_reference); every run settled first, so that a refused robot or
    motion is said (ConfigError, UsageError) before a worker starts, and a robot the
    controller does not hold on the plant after them (check_held)."""
    work = [(str(config), str(motions), motion, reverse, fidelity, seed)
             for motion in (motion_set or motion_names(motions)) for reverse in (False, True) for seed in seeds]
    robot = load_robot(config)
    friction = [scenario_of(job) for job in work][0].twin_friction
    twin_friction_nm = 0.0 if friction is None else friction.coulomb_nm
    control, fdi = load_section(config, 'control'), load_section(config, 'fdi')
    drift = drift if drift is not None else fdi.section('cusum').number('drift', non_negative=True)
    with ProcessPoolExecutor(max(jobs, 1)) as pool:
        runs, peaks = zip(*pool.map(failure_free_run, work))
        check_held(config, robot, work, peaks)
        runs = list(runs)
        result = calibrate(runs, control.number('period_s', positive=True),
                           control.number('coulomb_smoothing_rad_s', positive=True), drift,
                           false_alarms_per_hour, twin_friction_nm)
        seen = list(pool.map(free_reference, [(job, result.coulomb_friction_nm) for job in work]))
    collapse_level_n = collapse_reference_level(seen, result.hours * 3600.0 / result.runs, false_alarms_per_hour)
    document = {
        'fdi': {
            'coulomb_friction_nm': round(result.coulomb_friction_nm, 5),
            'epsilon_nm': round(result.epsilon_nm, 5),
            'cusum': {'sigma_nm': [round(s, 6) for s in result.cusum_sigma_nm],
                      'drift': round(result.cusum_drift, 3),
                      'threshold': round(result.cusum_threshold, 3),
                      'limit': round(result.cusum_limit, 3),
                      'epsilon_nm': round(result.cusum_epsilon_nm, 5)},
        },
        'calibration': {
            'robot': robot.name, 'robot_fingerprint': robot.fingerprint(),
            'date': datetime.date.today().isoformat(),
            'fidelity': fidelity, 'seeds': list(seeds), 'runs': len(runs),
            'hours': round(result.hours, 4),
            'target_false_alarms_per_hour': false_alarms_per_hour,
            'largest_residual_nm': round(result.largest_residual_nm, 5),
            'largest_cusum': round(result.largest_cusum, 3),
        },
    }
    share = collapse_reference_share(collapse_level_n, robot, fdi)
    if share is not None:
        document['fdi']['collapse_reference_share'] = share
    return Calibrated(document, result, twin_friction_nm, collapse_level_n)


@command('cdpr-calibrate')
def main(argv=None):
    args = parse_args(argv)
    if args.from_far:
        return from_far(args.from_far, args.fidelity, args.false_alarms_per_hour, Path(args.out))
    config, motions = config_file(args.config), config_file(args.motions)
    seeds = [int(seed) for seed in args.seeds.split(',')]
    runs = len(motion_names(motions)) * 2 * len(seeds)
    print(f'cdpr-calibrate: {runs} failure-free runs on the {args.fidelity} plant', flush=True)
    calibrated = calibrate_robot(config, motions, args.fidelity, seeds, args.jobs, args.false_alarms_per_hour,
                                 args.drift)
    document, result, twin_friction_nm = calibrated.document, calibrated.result, calibrated.twin_friction_nm
    out = Path(args.out)
    write_calibration(out, document)
    print(f'  {result.hours * 60:.1f} min of failure-free motion in {result.runs} runs')
    print(f'  the motors\' Coulomb friction: {result.coulomb_friction_nm:.4f} N·m (the twin models '
          f'{twin_friction_nm:.4f}, the residual shows the rest)')
    print(f'  threshold ε = {result.epsilon_nm:.4f} N·m (largest |r| seen {result.largest_residual_nm:.4f})')
    print(f'  CUSUM: σ = {", ".join(f"{s:.4f}" for s in result.cusum_sigma_nm)} N·m, '
          f'ν = {result.cusum_drift:.2f}, h = {result.cusum_threshold:.2f} (largest sum seen '
          f'{result.largest_cusum:.2f}), z limit = {result.cusum_limit:.2f}, '
          f'ε = {result.cusum_epsilon_nm:.4f} N·m')
    if calibrated.collapse_level_n is not None:
        print(f'  tension collapse: a loaded motor read free where the reference asked up to '
              f'{calibrated.collapse_level_n:.3f} N: the floor is '
              f'{document["fdi"]["collapse_reference_share"]:g} × τ_min')
    print(f'written: {out}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
