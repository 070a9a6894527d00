"""A run settled once, from the config files and the CLI options, and everything it needs.

The settled run (`settle`) is the one place where files are read and merged and options
applied; the cores' settings and every node's parameters are made from it.
"""
from __future__ import annotations

import copy
import math
from dataclasses import dataclass, field
from pathlib import Path

from cdpr_control.config import Section, load_config, load_yaml
from cdpr_control.control.controller import PdGains
from cdpr_control.geometry.motions import Motion, settled_motion
from cdpr_control.model.friction import FrictionModel
from cdpr_control.model.reference_table import ReferenceTable, tabulate_reference
from cdpr_control.model.robot import Robot
from cdpr_control.setup.robot_file import robot_from_section
from cdpr_control.setup.settings import ROBOT_DESCRIPTION, flatten, robot_description
from cdpr_control.tension_distribution import (InfeasibleTensionError, PseudoInverse,
                                               TensionDistribution, configured_tension_distribution)
from cdpr_fdi.settings.config import FdiConfig, RecoveryConfig, calibrated_fdi, settled_fdi
from cdpr_fdi.view.markers import Frame, MarkerStyle
from cdpr_fdi.recovery_planning.recovery import RecoveryInfeasible, safe_point_for
from cdpr_msgs_py.contract import SETTINGS_OF, SETTINGS_OF_EVERY_NODE, ViewTicks
from cdpr_msgs_py.scheduling import NICE_RANGE, PRIORITY_RANGE
from cdpr_twin.models.plant import FIDELITIES, PlantConfig, Push, settled_pushes

from ..cli import UsageError
from ..paths import DEFAULT_MOTIONS, DEFAULT_ROBOT, config_file, shipped_calibration_document


# ScenarioOptions.calibration for a run that needs no thresholds (cdpr-calibrate's).
NO_CALIBRATION = 'none'
# Realtime: the nodes a command waits on; the FDI, whose recovery setpoints a command
# waits on after a failure; and what may lag without harm.
CONTROL_LOOP = ('plant_simulator', 'controller', 'trajectory_generator')
FDI = ('digital_twin', 'supervisor')
BACKGROUND = ('bag_recorder', 'markers')


@dataclass
class ScenarioOptions:
    """One run as `cdpr-scenario` describes it; cables are 1-based as on the CLI."""

    config: str = DEFAULT_ROBOT
    motions: str = DEFAULT_MOTIONS
    motion: str = 'circle'
    reverse: bool = False
    fail_cables: list[int] = field(default_factory=list)
    fail_at_s: float | None = None
    fail_at_fraction: float | None = None
    fidelity: str | None = None
    seed: int | None = None
    detector: str | None = None
    epsilon_nm: float | None = None
    calibration: str | None = None
    recovery_budget_s: float | None = None
    # The run's length (s), as given: a realtime run that outlasts its motion, and does
    # not end early when a recovery is over.
    duration_s: float | None = None
    # Forces on the end-effector: (start s, duration s, f_x, f_y, f_z N) each.
    pushes: list[tuple[float, float, float, float, float]] = field(default_factory=list)


@dataclass
class Scenario:
    options: ScenarioOptions
    settings: Section          # the settled run (`settle`)
    config_path: Path
    robot: Robot
    period_s: float
    gains: PdGains
    twin_substeps: int
    twin_friction: FrictionModel | None
    motion: Motion
    reference: ReferenceTable
    plant: PlantConfig
    failures: list[tuple[float, int]]
    pushes: list[Push]
    calibration_path: Path | None
    distribution: TensionDistribution
    fdi: FdiConfig
    recovery: RecoveryConfig
    markers: MarkerStyle
    view_ticks: ViewTicks                    # which ticks the view topics are written on

    @property
    def start_orientation(self):
        """The end-effector's orientation at the start (unit quaternion; the identity for
        a point mass, which has none)."""
        return self.reference.orientation_at(0)

    def marker_frame(self) -> Frame:
        """The markers node's core for this run, as the node settles it (a simulated run:
        the ground truth is drawn)."""
        return Frame(self.robot, self.recovery, self.markers)

    @property
    def failure_time_s(self) -> float | None:
        return self.failures[0][0] if self.failures else None

    @property
    def cycles(self) -> int:
        """The motion, and after a failure the recovery budget (the reference holds its end):
        the most a run may take; or as long as `options.duration_s` says."""
        if self.options.duration_s is not None:
            return int(round(self.options.duration_s / self.period_s)) + 1
        cycles = len(self.reference)
        if self.failures:
            end = self.failure_time_s + self.recovery_budget_s
            cycles = max(cycles, int(round(end / self.period_s)) + 1)
        return cycles

    @property
    def recovery_budget_s(self) -> float:
        """The longest the recovery from the scheduled failures may take (s): as given, else
        from the reference's position and velocity when they happen (no SP: no move)."""
        if self.options.recovery_budget_s is not None:
            return self.options.recovery_budget_s
        attached = self.robot.cable_mask([cable for _, cable in self.failures])
        row = min(int(round(self.failure_time_s / self.period_s)), len(self.reference) - 1)
        position = self.reference.position_m[row]
        try:
            safe_point = safe_point_for(self.robot, self.recovery, attached)
        except RecoveryInfeasible:
            safe_point = position
        return self.recovery.budget_s(position, self.reference.velocity_m_s[row], safe_point,
                                      (self.robot.workspace_min_m, self.robot.workspace_max_m))

    @property
    def duration_s(self) -> float:
        """The scheduled length (s); a run whose recovery ends sooner ends sooner."""
        return (self.cycles - 1) * self.period_s

    @property
    def hold_after_cycles(self) -> int:
        """Ticks a run goes on once its recovery is over (recovery.hold_after_s)."""
        return int(round(self.recovery.hold_after_s / self.period_s))

    def node_parameters(self, clock_mode: str, scheduling: bool = True) -> dict[str, dict]:
        """Per node of the graph, the ROS parameters it is started with: the settled
        sections it reads (cdpr_control.setup.settings) and, in realtime, the OS scheduling the
        `scheduling` section asks for (unless not `scheduling`: the OS's normal one)."""
        document = self.settings.data
        scheduling = (realtime_scheduling(self.settings.section('scheduling'))
                      if clock_mode == 'realtime' and scheduling else {})
        common = {ROBOT_DESCRIPTION: robot_description(document['robot']), 'clock_mode': clock_mode,
                  **flatten({name: document[name] for name in SETTINGS_OF_EVERY_NODE})}
        return {node: dict(common, **scheduling.get(node, {}),
                           **flatten({name: document[name] for name in sections}))
                for node, sections in SETTINGS_OF.items()}


@dataclass
class SettledRun:
    """A run settled in one pass: the document every node is given (`settings`) and the
    values read from it on the way, handed on rather than read again."""

    settings: Section
    config_path: Path
    calibration_path: Path | None
    robot: Robot
    motion: Motion    # the body's (Body.motion): a platform's with its turn
    plant: PlantConfig


def settle(options: ScenarioOptions) -> SettledRun:
    """The run `options` describe, settled once, each file read once: the robot file's
    sections with the paper's settings for what it leaves out; the plant's fidelity and
    seed; the thresholds of the calibration for that plant, the detector and ε given; the
    Coulomb friction the controller and the FDI assume (control.coulomb_friction_nm) and
    the drives' delay (fdi.drive_delay_s, handed to the controller as control.drive_delay_s);
    the motion; when and which cables fail (absolute s, 0-based), the start and the scheduled
    length (`run`). Also the calibration file used, if any."""
    config_path = config_file(options.config)
    loaded = load_config(config_path)
    document = copy.deepcopy(dict(loaded.data))
    settings = Section(document, config_path, defaulted=loaded.defaulted, sources=loaded.sources)
    robot = robot_from_section(settings.section('robot'))
    motion_section = settled_motion(config_file(options.motions), options.motion, options.reverse)
    motion = robot.body.motion(motion_section)
    check_options(options, robot, motion)
    if options.fidelity is not None:
        document['plant']['fidelity'] = options.fidelity
    if options.seed is not None:
        document['plant']['seed'] = options.seed
    plant = PlantConfig.from_section(settings.section('plant'), robot.cable_count)
    fdi_section = settings.section('fdi')
    calibration = calibration_for(config_path, fdi_section, robot, plant.fidelity, options.calibration)
    fdi = dict(calibrated_fdi(fdi_section, robot, calibration).data)
    for fidelity in FIDELITIES:
        fdi.pop(calibration_file_key(fidelity), None)
    friction = fdi.pop('coulomb_friction_nm', robot.motor.static_friction_nm)
    # The rigid plant is the twin's model, without Coulomb friction: the stack must know,
    # and a twin that models friction has none there.
    document['control']['coulomb_friction_nm'] = 0.0 if plant.fidelity == 'rigid' else friction
    if plant.fidelity == 'rigid':
        document['twin'].update(coulomb_friction_nm=0.0, breakaway_friction_nm=0.0)
    document['control']['drive_delay_s'] = fdi['drive_delay_s']
    if options.detector is not None:
        fdi['detector'] = options.detector
    if options.epsilon_nm is not None:
        fdi['epsilon_nm'] = options.epsilon_nm
    document['fdi'] = fdi
    document['motion'] = dict(motion_section.data)
    document['run'] = {
        'start_position_m': motion.trajectory.start.tolist(),
        **({} if motion.start_orientation is None else {'start_orientation': motion.start_orientation.tolist()}),
        'failure_times_s': [motion.failure_time(options.fail_at_s, options.fail_at_fraction)
                            for _ in options.fail_cables],
        'failure_cable_indices': [cable - 1 for cable in options.fail_cables],
        'push_start_s': [float(push[0]) for push in options.pushes],
        'push_duration_s': [float(push[1]) for push in options.pushes],
        'push_force_n': [float(f) for push in options.pushes for f in push[2:]],
    }
    return SettledRun(settings, config_path, None if calibration is None else Path(calibration.path),
                      robot, motion, plant)


def build_scenario(options: ScenarioOptions) -> Scenario:
    """The settled run and the cores' settings made from it (each checked here, before
    any node starts); its scheduled length completes `run`."""
    settled = settle(options)
    settings, robot = settled.settings, settled.robot
    control = settings.section('control')
    period = control.number('period_s', positive=True)
    distribution = configured_tension_distribution(control, robot)
    gains, frequency_hz, derived = PdGains.settled(robot, control)
    if derived:
        # the paper's frequency gave way to the highest stable one on these motors: the
        # nodes, to whom every setting is given, are handed that one, not one they refuse
        settings.data['control']['pd_natural_frequency_hz'] = frequency_hz
    run = settings.section('run')
    failures = list(zip(run.raw('failure_times_s'), run.raw('failure_cable_indices')))
    twin = settings.section('twin')
    fdi, recovery = settled_fdi(settings, robot, twin)
    scenario = Scenario(
        options=options,
        settings=settings,
        config_path=settled.config_path,
        robot=robot,
        period_s=period,
        gains=gains,
        twin_substeps=twin.integer('substeps', minimum=1),
        twin_friction=fdi.twin_friction,
        motion=settled.motion,
        reference=motion_reference(robot, distribution, settled.motion, period),
        plant=settled.plant,
        failures=failures,
        pushes=settled_pushes(run),
        calibration_path=settled.calibration_path,
        distribution=distribution,
        fdi=fdi,
        recovery=recovery,
        markers=MarkerStyle.from_section(settings.section('markers')),
        view_ticks=ViewTicks.of_streams(settings.section('streams'), period),
    )
    settings.data['run']['last_tick'] = scenario.cycles - 1
    if options.duration_s is None:
        settings.data['run']['hold_after_ticks'] = scenario.hold_after_cycles
    return scenario


def motion_reference(robot: Robot, distribution: TensionDistribution, motion, period_s: float) -> ReferenceTable:
    """The reference table of the body's `motion` (Body.motion); UsageError, naming the
    motion, the pose and what to change, where no tensions within the bounds hold the
    end-effector on it."""
    try:
        return tabulate_reference(robot, distribution, motion.pose_trajectory, period_s)
    except InfeasibleTensionError as err:
        remedy = ('set control.tension_distribution: bounded_minimum_norm (the nearest tensions '
                  'within the bounds), or move the motion' if isinstance(distribution, PseudoInverse)
                  else 'move the motion')
        raise UsageError(f'--motion {motion.name}: {err}; {remedy} inside the robot\'s '
                         'wrench-feasible workspace (cdpr-robot shows the tensions along each '
                         'motion)') from None


def realtime_scheduling(section: Section) -> dict[str, dict]:
    """Per node, the scheduling the `scheduling` section asks for in realtime mode:
    SCHED_FIFO for the control loop and, below it, the FDI; niceness for the rest."""
    loop = {'realtime_priority': section.integer('control_loop_priority', minimum=0,
                                                 maximum=PRIORITY_RANGE[1])}
    fdi = {'realtime_priority': section.integer('fdi_priority', minimum=0,
                                                maximum=PRIORITY_RANGE[1])}
    background = {'nice': section.integer('background_nice', minimum=0, maximum=NICE_RANGE[1])}
    return ({name: loop for name in CONTROL_LOOP} | {name: fdi for name in FDI}
            | {name: background for name in BACKGROUND})


def check_options(options: ScenarioOptions, robot: Robot, motion: Motion) -> None:
    """UsageError, naming the option, for a value the run cannot use: a failure must happen
    during the motion, a threshold must be a positive number."""
    for cable in options.fail_cables:
        if not 1 <= cable <= robot.cable_count:
            raise UsageError(f'--fail-cable {cable}: the robot has cables 1..{robot.cable_count}')
    if options.fail_at_s is not None and not 0.0 <= options.fail_at_s <= motion.trajectory.duration_s:
        raise UsageError(f'--fail-at {options.fail_at_s}: must be a time during the motion '
                         f'{motion.name}, 0..{motion.trajectory.duration_s:.3f} s')
    if options.fail_at_fraction is not None and not 0.0 <= options.fail_at_fraction <= 1.0:
        raise UsageError(f'--fail-at-fraction {options.fail_at_fraction}: must be between 0 and 1')
    if options.epsilon_nm is not None and not 0.0 < options.epsilon_nm < math.inf:
        raise UsageError(f'--epsilon {options.epsilon_nm}: must be a positive number of N·m')
    if options.recovery_budget_s is not None and not 0.0 < options.recovery_budget_s < math.inf:
        raise UsageError(f'--recovery-budget {options.recovery_budget_s}: must be a positive number of s')
    if options.seed is not None and options.seed < 0:
        raise UsageError(f'--seed {options.seed}: must be 0 or more')
    for push in options.pushes:
        start, duration, *force = push
        if not (len(force) == 3 and all(map(math.isfinite, push)) and start >= 0.0 and duration > 0.0):
            raise UsageError(f'--push {" ".join(f"{v:g}" for v in push)}: must be START_S (0 or more) '
                             'DURATION_S (positive) and the force FX FY FZ (N), finite')


# How the graph's nodes are spread over processes (docs/graph.md, "Graph forms").
GRAPH_FORMS = ('separate', 'composed')
DEFAULT_GRAPH_FORM = 'separate'


def add_graph_form_option(options) -> None:
    """--graph-form, for every command that starts the node graph."""
    options.add_argument('--graph-form', choices=GRAPH_FORMS, default=DEFAULT_GRAPH_FORM,
                         help='separate: every node its own process; composed: the control loop '
                              '(generator, controller, twin, supervisor, plant) in one process on one '
                              f'executor, the recorder and markers apart (default {DEFAULT_GRAPH_FORM})')


def add_push_option(parser) -> None:
    """--push, for every command that runs a scenario."""
    parser.add_argument('--push', type=float, nargs=5, action='append', default=[],
                        metavar=('START_S', 'DURATION_S', 'FX_N', 'FY_N', 'FZ_N'),
                        help='push the end-effector with force (FX, FY, FZ) N, world frame, for '
                             'DURATION_S from START_S (s); repeat for several. A disturbance, '
                             'not a failure: no cable is to be named for it')


def calibration_file_key(fidelity: str) -> str:
    """The set-up's fdi key naming its calibration for the plant `fidelity`."""
    return f'{fidelity}_calibration_file'


def calibration_for(config_path: Path, fdi: Section, robot: Robot, fidelity: str,
                    calibration: str | None) -> Section | None:
    """The given calibration file, as read; else, on the elastic or field plant, the one the set-up
    names (`fdi.elastic_calibration_file`, `fdi.field_calibration_file`), else the shipped
    calibration made on this robot for that plant; the rigid plant keeps the paper's
    noise-free values. NO_CALIBRATION: the set-up's own thresholds (a run without a
    supervisor)."""
    if calibration == NO_CALIBRATION or (not calibration and fidelity == 'rigid'):
        return None
    if calibration:
        return read_calibration(config_file(calibration))
    key = calibration_file_key(fidelity)
    if fdi.has(key):
        return read_calibration(config_file(fdi.string(key)))
    shipped = shipped_calibration_document(robot.fingerprint(), fidelity)
    if shipped is None:
        raise fdi.error(key, (
            f'is missing, and no shipped calibration was made on this robot ({robot.name}, '
            f'{robot.fingerprint()}) for the {fidelity} plant: it needs thresholds measured on '
            f'it; make them with cdpr-calibrate --config {config_path} --fidelity {fidelity} '
            '--motions MOTIONS.yaml --out FILE and name FILE here, or pass --calibration FILE, '
            'or run on the rigid plant (the noise-free defaults)'))
    return shipped


def read_calibration(path: Path) -> Section:
    return Section(load_yaml(path), path)
