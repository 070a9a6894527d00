"""cdpr-report BAG --out DIR: the paper's figures and the metrics of one run, from its bag.

Any bag of the graph will do, simulated or from the real robot: a figure or a figure
element whose topic is missing (ground truth on the real robot, FDI topics without the
supervisor) is left out with a note. Writes into DIR one PNG per figure, metrics.json
recomputed from the bag, and report.md, which shows them.

The run's settings (robot, thresholds, friction, recovery) are those cdpr-scenario settled
and wrote beside the bag (run.yaml); for another bag, those of the robot file given.

Times are the control ticks' stamps (sim time in lockstep, s). The verdict and the mode
carry no stamp: their receive time in the bag places them on the tick the supervisor
judged (see tick_time).
"""
from __future__ import annotations

import argparse
import json
import sys
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path

import numpy as np

from cdpr_control.config import Section, load_yaml
from cdpr_control.model.friction import FrictionModel
from cdpr_control.model.robot import Robot
from cdpr_control.setup.robot_file import load_robot, robot_from_section
from cdpr_fdi.settings.config import load_fdi_config, load_recovery_config, settled_fdi
from cdpr_fdi.recovery_planning.recovery import RecoveryInfeasible, safe_point_for
from cdpr_fdi.detection.residual import sensorless_tensions
from cdpr_msgs_py import contract
from cdpr_msgs_py.contract import NOMINAL
from cdpr_msgs_py.stamps import NANOSECONDS

from . import plots
from ..bags.bag_io import missing_ticks, read_messages, recording_from_bag, stamp_ns
from ..cli import command
from ..runs.metrics import (KnownRun, RunSettings, figures_from_rows, metrics_json, period_of, statuses_beside,
                            take_statuses, view_figures)
from ..paths import DEFAULT_ROBOT, SETTLED_RUN, config_file
from ..runs.recording import Recording, holes_said


def run_settings(bag: str | Path, config_path: str | Path | None = None,
                 epsilon_nm: float | None = None, coulomb_friction_nm: float | None = None) -> RunSettings:
    """The settled run beside `bag` (SETTLED_RUN) unless a robot file is given; else the
    robot file `config_path` (default the paper's). `epsilon_nm` and `coulomb_friction_nm`
    replace the FDI's (0 friction for the rigid plant, which has none)."""
    settled = Path(bag).parent / SETTLED_RUN
    if config_path is None and settled.exists():
        settings = settled_run_settings(Section(load_yaml(settled), settled),
                                        f'settings: the run\'s own, {settled}')
        robot, fdi, recovery, source = settings.robot, settings.fdi, settings.recovery, settings.source
    else:
        path = config_file(config_path or DEFAULT_ROBOT)
        robot = load_robot(path)
        fdi, recovery = load_fdi_config(path, robot), load_recovery_config(path, robot)
        source = f'settings: {path}'
    return RunSettings(robot, fdi.with_overrides(epsilon_nm=epsilon_nm,
                                                 coulomb_friction_nm=coulomb_friction_nm),
                       recovery, source)


def settled_run_settings(settings: Section, source: str) -> RunSettings:
    """What a report needs of a settled run (`settings`: its document)."""
    robot = robot_from_section(settings.section('robot'))
    fdi, recovery = settled_fdi(settings, robot)
    return RunSettings(robot, fdi, recovery, source)


@dataclass
class Run:
    """What one bag tells about a run, on its control ticks (SI units, times in s)."""

    robot: Robot
    recording: Recording
    residual_nm: np.ndarray
    epsilon_nm: float
    friction: FrictionModel                # the Coulomb friction the FDI assumes
    verdicts: list[tuple[float, int]]      # /fdi/broken_cable: (time, 0 or cable k)
    modes: list[tuple[float, str]]         # /mode: (time, mode) at each change
    failure_time_s: float | None
    true_broken_cables: list[int] | None   # 1-based; None when nothing tells
    wall_time_s: float
    supervisor: dict = field(default_factory=dict)  # its last summary on /diagnostics
    safe_point_m: np.ndarray | None = None
    reached_tolerance_m: float | None = None
    notes: list[str] = field(default_factory=list)

    @property
    def time_s(self) -> np.ndarray:
        return self.recording.time_s

    @property
    def has_ground_truth(self) -> bool:
        return self.recording.has_ground_truth

    @property
    def detection_time_s(self) -> float | None:
        """When the detection signal first named a cable (s)."""
        return next((t for t, cable in self.verdicts if cable), None)

    @property
    def identified_cables(self) -> list[int]:
        return sorted({cable for _, cable in self.verdicts if cable})

    @property
    def broken_cables(self) -> list[int]:
        """Cables known to be broken: identified, else the truth (1-based)."""
        return self.identified_cables or list(self.true_broken_cables or [])

    @property
    def attached(self) -> np.ndarray:
        return self.robot.cable_mask([cable - 1 for cable in self.broken_cables])

    @property
    def event_time_s(self) -> float | None:
        return self.known.event_time_s

    @property
    def position_label(self) -> str:
        return 'true (ground truth)' if self.has_ground_truth else 'measured (forward kinematics)'

    @property
    def pose_time_s(self) -> np.ndarray:
        """The times (s) of `pose`'s rows: the view ticks' with ground truth, else every tick's."""
        return self.recording.view_time_s if self.has_ground_truth else self.recording.time_s

    @property
    def position_m(self) -> np.ndarray:
        """The end-effector's position (m): `pose`'s."""
        return self.pose[0]

    @property
    def orientation(self) -> np.ndarray | None:
        """A platform's orientation (unit quaternions, a row per `pose_time_s`): `pose`'s;
        None for a point mass."""
        return self.pose[1]

    @cached_property
    def pose(self) -> tuple[np.ndarray, np.ndarray | None]:
        """The end-effector's positions (m) and a platform's orientations: ground truth on
        the view ticks, else forward kinematics of the measured angles on every tick, over
        the remaining cables once a failure was detected."""
        if self.has_ground_truth:
            return self.recording.true_position_m, self.recording.true_orientation
        angles = self.recording.angle_rad
        after = (self.time_s >= self.detection_time_s if self.detection_time_s is not None
                 else np.zeros(self.time_s.size, dtype=bool))
        position = np.empty((angles.shape[0], 3))
        orientation = np.empty((angles.shape[0], 4)) if self.robot.body.has_orientation else None
        for ticks, cables in ((~after, None), (after, self.attached)):
            if ticks.any():
                position[ticks], turned = self.robot.body.poses_of_angles(self.robot, angles[ticks], cables)
                if orientation is not None:
                    orientation[ticks] = turned
        return position, orientation

    @cached_property
    def tension_estimate_n(self) -> tuple[np.ndarray, np.ndarray]:
        """Sensorless τ̂ = (J θ̈ + b θ̇ + f_c(θ̇) − c) / ρ over each control period, θ̈
        from two measured speeds, f_c the FDI's Coulomb friction: (period start times s, τ̂ N)."""
        recording = self.recording
        period = np.diff(recording.time_s)[:, None]
        speed = recording.angular_velocity_rad_s
        return recording.time_s[:-1], sensorless_tensions(
            self.robot.motor, self.friction, recording.command_nm[:-1],
            speed[:-1], speed[1:], period)

    @cached_property
    def figures(self) -> dict:
        """The figures of the end-effector (cdpr_twin.models.run_figures): the plant's from every
        tick where it said them; else from what the bag holds — the view ticks' truth, or a
        real robot's pose and tensions as measured and estimated at every tick (noted)."""
        if self.recording.figures is not None:
            return self.recording.figures
        if self.has_ground_truth:
            self.notes.append('figures of the end-effector from the view ticks\' ground truth (the plant '
                              'simulator\'s own, from every tick, are not beside the bag)')
            return view_figures(self.robot, self.recording, self.failure_time_s,
                                self.true_broken_cables or [], self.detection_time_s)
        times, tensions = self.tension_estimate_n
        return figures_from_rows(self.robot, period_of(self.recording), times, self.position_m[:-1],
                                 None if self.orientation is None else self.orientation[:-1], tensions,
                                 None, None, self.failure_time_s, self.broken_cables, self.detection_time_s)

    @property
    def known(self) -> KnownRun:
        """What the bag tells about the run, as `metrics_json` takes it: the recovery
        phases from the mode changes, the figures of the end-effector (`figures`), the
        safe point the supervisor's (/diagnostics) or else the config's."""
        phase_times = {}
        for t, mode in self.modes:
            if mode != NOMINAL:
                phase_times.setdefault(mode, t)
        return KnownRun(
            robot=self.robot, recording=self.recording, figures=self.figures,
            epsilon_nm=self.epsilon_nm, failure_time_s=self.failure_time_s,
            true_broken_cables=self.true_broken_cables, detection_time_s=self.detection_time_s,
            identified_cables=self.identified_cables,
            mode=self.modes[-1][1] if self.modes else None, phase_times_s=phase_times,
            safe_point_m=self.safe_point_m, reached_tolerance_m=self.reached_tolerance_m,
            supervisor=self.supervisor, wall_time_s=self.wall_time_s)


def load_run(bag: str | Path, settings: RunSettings,
             namespace: str = contract.DEFAULT_NAMESPACE, recording: Recording | None = None) -> Run:
    """The run in `bag`, recorded with `settings`; `recording`: the bag's, where the caller
    has read it already (cdpr-scenario's graph run)."""
    bag = Path(bag)
    robot, fdi = settings.robot, settings.fdi
    if recording is None:
        recording = recording_from_bag(bag, namespace, robot.body.has_orientation)
    if recording.angle_rad.shape[1] != robot.cable_count:
        raise ValueError(f'{bag} has {recording.angle_rad.shape[1]} motors, robot {robot.name} '
                         f'{robot.cable_count} ({settings.source}): pass the robot the bag was '
                         f'recorded with')
    topics = {key: f'{namespace}/{key}' for key in (
        contract.JOINT_STATES, contract.FDI_RESIDUAL, contract.FDI_BROKEN_CABLE, contract.MODE)}
    topics[contract.DIAGNOSTICS] = contract.DIAGNOSTICS
    found = read_messages(bag, list(topics.values()))
    notes = [settings.source]
    residual = recording.residual_nm
    if residual is None or np.isnan(residual).all():
        residual = recording.command_nm - recording.twin_torque_nm
        notes.append(f'no {topics[contract.FDI_RESIDUAL]}: residual computed as c − c_DT '
                     f'from the commanded and the twin torques')
    to_tick = (tick_time(found[topics[contract.FDI_RESIDUAL]], following=True)
               if found[topics[contract.FDI_RESIDUAL]]
               else tick_time(found[topics[contract.JOINT_STATES]], following=False))
    verdicts = [(to_tick(t), int(m.data)) for t, m in found[topics[contract.FDI_BROKEN_CABLE]]]
    modes = mode_changes((to_tick(t), message.data) for t, message in found[topics[contract.MODE]])
    if not verdicts:
        notes.append(f'no {topics[contract.FDI_BROKEN_CABLE]} (no supervisor): no detection signal')
    if not modes:
        notes.append(f'no {topics[contract.MODE]}: recovery phases unknown')
    if not recording.has_ground_truth:
        notes.append('no ground truth (real robot): end-effector from forward kinematics of the '
                     'measured angles, tensions only as estimated')
    take_statuses(recording, statuses_beside(bag, found[contract.DIAGNOSTICS]), missing_ticks(bag))
    failure_time, true_broken, source = failure_of(bag, recording)
    notes.append(source)
    holes = holes_said(recording.missing_ticks)
    if holes:
        notes.append(holes)
    bag_times = [t for t, _ in found[topics[contract.JOINT_STATES]]]
    return with_safe_point(Run(
        robot=robot, recording=recording, residual_nm=residual,
        epsilon_nm=fdi.epsilon_nm, friction=fdi.friction, verdicts=verdicts, modes=modes,
        failure_time_s=failure_time, true_broken_cables=true_broken,
        wall_time_s=(bag_times[-1] - bag_times[0]) / NANOSECONDS,
        supervisor=recording.fdi, notes=notes), settings)


def run_of_recording(recording: Recording, settings: RunSettings, failure_time_s: float | None,
                     true_broken_cables: list[int]) -> Run:
    """The run of an in-process engine's `recording`, as `load_run` reads it back from its
    bag, without reading it: the verdicts and mode changes from the supervisor's summary
    (`recording.fdi`), the failure as the plant recorded it (1-based cables)."""
    summary, time_s = recording.fdi, recording.time_s
    notes = [settings.source, 'failure time: the plant\'s own record']
    verdicts, modes = [], []
    if summary:
        verdicts = [(float(time_s[0]), 0)]
        if summary['identified_tick'] is not None:
            verdicts += [(float(time_s[summary['identified_tick']]), cable)
                         for cable in summary['broken_cables']]
        # by tick only: two phases entered on one tick stay in the order they were entered
        changes = [(0, NOMINAL)] + sorted(((tick, mode) for mode, tick in summary['phase_ticks'].items()),
                                          key=lambda change: change[0])
        modes = mode_changes((float(time_s[tick]), mode) for tick, mode in changes)
    else:
        notes.append('no supervisor: no detection signal, recovery phases unknown')
    residual = recording.residual_nm
    if residual is None:
        residual = recording.command_nm - recording.twin_torque_nm
        notes.append('no supervisor: residual computed as c − c_DT from the commanded and the '
                     'twin torques')
    return with_safe_point(Run(
        robot=settings.robot, recording=recording, residual_nm=residual,
        epsilon_nm=settings.fdi.epsilon_nm, friction=settings.fdi.friction, verdicts=verdicts,
        modes=modes, failure_time_s=failure_time_s, true_broken_cables=true_broken_cables,
        wall_time_s=float(time_s[-1] - time_s[0]), supervisor=dict(summary),
        notes=notes), settings)


def mode_changes(modes) -> list[tuple[float, str]]:
    """Of (time s, mode) in time order, those where the mode changes (the first included)."""
    changes = []
    for t, mode in modes:
        if not changes or changes[-1][1] != mode:
            changes.append((t, mode))
    return changes


def with_safe_point(run: Run, settings: RunSettings) -> Run:
    """`run` with the safe point the supervisor reported, else the one its settings give
    for the broken cables (or a note why there is none)."""
    robot, notes = settings.robot, run.notes
    if run.supervisor.get('safe_point_m') is not None:
        run.safe_point_m = np.array(run.supervisor['safe_point_m'])
    if run.broken_cables:
        run.reached_tolerance_m = settings.recovery.reached_tolerance_m
        if run.safe_point_m is None:
            try:
                run.safe_point_m = safe_point_for(robot, settings.recovery, run.attached)
            except RecoveryInfeasible as err:
                notes.append(f'no safe point: {err}')
    return run


def tick_time(clock: list[tuple[int, object]], following: bool):
    """Bag time (ns) → the stamp (s) of the tick an unstamped verdict belongs to.

    The supervisor publishes a tick's verdict and mode just before that tick's residual,
    so on the residual `clock` the tick is that of the first residual recorded at or
    after the verdict (`following`); on the state clock, that of the last state
    recorded before it, the state it judged.
    """
    bag_times = np.array([t for t, _ in clock], dtype=np.int64)
    stamps = np.array([stamp_ns(m) for _, m in clock], dtype=np.int64) / NANOSECONDS

    def to_tick(bag_time_ns: int) -> float:
        index = (np.searchsorted(bag_times, bag_time_ns, side='left') if following
                 else np.searchsorted(bag_times, bag_time_ns, side='right') - 1)
        return float(stamps[min(max(index, 0), stamps.size - 1)])
    return to_tick


def failure_of(bag: Path, recording: Recording) -> tuple[float | None, list[int] | None, str]:
    """(failure time s, broken cables 1-based, where that came from): metrics.json beside
    the bag; else the instant the plant simulator parted a cable, as it said
    (`recording.broken_at_s`, metrics.take_statuses); else the first tick from which a
    cable's true tension stays 0 to the end."""
    written = bag.parent / 'metrics.json'
    if written.exists():
        metrics = json.loads(written.read_text())
        if 'failure_time_s' in metrics:
            return (metrics['failure_time_s'], metrics.get('true_broken_cables'),
                    f'failure time from {written}')
    parted = recording.broken_at_s
    if parted:
        return (min(parted.values()), sorted(cable + 1 for cable in parted),
                'failure time: the instant the plant simulator parted the cable (its last status)')
    tension = recording.true_tension_n
    if not np.isfinite(tension).all():
        return None, None, 'failure time unknown (no metrics.json beside the bag, no ground truth)'
    taut = tension > 0.0
    # index of the first tick of the final run of zero tension, per cable
    last_taut = np.where(taut.any(axis=0), taut.shape[0] - 1 - np.argmax(taut[::-1], axis=0), -1)
    broke = np.flatnonzero((last_taut >= 0) & (last_taut < taut.shape[0] - 1))
    if broke.size == 0:
        return None, [], 'no failure: every cable taut at the end of the run (ground truth)'
    tick = int(np.min(last_taut[broke])) + 1
    return (float(recording.view_time_s[tick]), [int(c) + 1 for c in broke],
            'failure time: first view tick from which a true cable tension stays 0 (ground truth)')


def write_report(bag_path: str | Path, out_dir: str | Path, settings: RunSettings,
                 namespace: str = contract.DEFAULT_NAMESPACE, recording: Recording | None = None) -> dict:
    """Plots (out_dir/*.png), metrics.json and report.md of the run in `bag_path`, recorded
    with `settings` (`recording`: the bag's, read already); the metrics."""
    bag, out = Path(bag_path), Path(out_dir)
    if out.resolve() == bag.parent.resolve():
        raise ValueError(f'{out}: the run\'s own metrics.json is there; choose another folder')
    return write_run_report(load_run(bag, settings, namespace, recording), bag, out)


def write_run_report(run: Run, bag: Path, out: Path) -> dict:
    """Plots (out/*.png), metrics.json and report.md of `run`, whose bag is `bag`; the
    metrics."""
    out.mkdir(parents=True, exist_ok=True)
    figures = []
    for name, draw in plots.FIGURES.items():
        caption = draw(run, out / f'{name}.png')
        if caption is None:
            run.notes.append(f'{name}.png left out: nothing to plot')
        else:
            figures.append((f'{name}.png', caption))
    metrics = metrics_json(run.known)
    (out / 'metrics.json').write_text(json.dumps(metrics, indent=2))
    (out / 'report.md').write_text(markdown(bag, run, metrics, figures))
    return metrics


def markdown(bag: Path, run: Run, metrics: dict, figures: list[tuple[str, str]]) -> str:
    rows = [(key, value) for key, value in metrics.items() if not isinstance(value, dict)]
    rows += [(f'{group}.{key}', value) for group in ('recovery', 'kpi')
             for key, value in metrics[group].items()]
    lines = [f'# Run report: `{bag}`', '',
             f'{run.time_s.size} control ticks, {run.time_s[-1] - run.time_s[0]:.2f} s of run, '
             f'{run.robot.cable_count} cables ({run.robot.name}).', '']
    lines += [f'- {note}' for note in run.notes]
    lines += ['', '| metric | value |', '|---|---|']
    lines += [f'| {key} | {format_value(value)} |' for key, value in rows]
    for file, caption in figures:
        lines += ['', f'![{Path(file).stem}]({file})', '', f'*{caption}*']
    return '\n'.join(lines) + '\n'


def format_value(value) -> str:
    if value is None:
        return '—'
    if isinstance(value, float):
        return f'{value:.4g}'
    if isinstance(value, dict):
        return ', '.join(f'{key} {format_value(item)}' for key, item in value.items()) or '—'
    if isinstance(value, list):
        return '[' + ', '.join(format_value(item) for item in value) + ']'
    return str(value)


@command('cdpr-report')
def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('bag', help='rosbag2 folder (or a killed recorder\'s folder)')
    parser.add_argument('--out', required=True, help='output folder')
    parser.add_argument('--config', help=f'robot YAML the bag was recorded with (default: the '
                                         f'settled run beside the bag, {SETTLED_RUN}, else {DEFAULT_ROBOT})')
    parser.add_argument('--epsilon', type=float, metavar='NM',
                        help='detection threshold ε to draw (N·m; default: the run\'s)')
    parser.add_argument('--coulomb-friction', type=float, metavar='NM',
                        help='Coulomb friction of the motors for the tension estimate (N·m; '
                             'default: the run\'s; 0 for the rigid plant)')
    parser.add_argument('--namespace', default=contract.DEFAULT_NAMESPACE)
    args = parser.parse_args(argv)
    try:
        settings = run_settings(args.bag, args.config, args.epsilon, args.coulomb_friction)
        metrics = write_report(args.bag, args.out, settings, args.namespace)
    except (OSError, ValueError) as err:
        print(f'cdpr-report: {err}', file=sys.stderr)
        return 1
    print(f'report: {Path(args.out) / "report.md"}')
    print(json.dumps(metrics, indent=2))
    return 0


if __name__ == '__main__':
    sys.exit(main())
