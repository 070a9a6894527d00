"""Everything one scenario run needs, built from the config files and the CLI options."""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

from cdpr_control.config import load_section
from cdpr_control.controller import PdGains
from cdpr_control.motions import Motion, load_motion
from cdpr_control.reference import ReferenceTable, tabulate_reference
from cdpr_control.robot import Robot, load_robot
from cdpr_control.tension_distribution import configured_tension_distribution
from cdpr_control.tension_distribution import TensionDistribution
from cdpr_fdi.config import FdiConfig, RecoveryConfig, load_fdi_config, load_recovery_config
from cdpr_fdi.recovery import RecoveryInfeasible, safe_point_for
from cdpr_twin.plant import PlantConfig

from .cli import UsageError
from .paths import DEFAULT_MOTIONS, DEFAULT_ROBOT, config_file


# ScenarioOptions.calibration for a run that needs no thresholds (cdpr-calibrate's).
NO_CALIBRATION = 'none'


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


@dataclass
class Scenario:
    options: ScenarioOptions
    config_path: Path
    motions_path: Path
    robot: Robot
    period_s: float
    gains: PdGains
    twin_substeps: int
    motion: Motion
    reference: ReferenceTable
    plant: PlantConfig
    failures: list[tuple[float, int]]
    calibration_path: Path | None
    distribution: TensionDistribution
    fdi: FdiConfig
    recovery: RecoveryConfig

    @property
    def failure_time_s(self) -> float | None:
        return self.failures[0][0] if self.failures else None

    @property
    def cycles(self) -> int:
        """The motion, and after a failure the recovery budget (the reference holds its end):
        the most a run may take."""
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
        return self.recovery.budget_s(position, self.reference.velocity_m_s[row], safe_point)

    @property
    def duration_s(self) -> float:
        """The scheduled length (s); a run whose recovery ends sooner ends sooner."""
        return (self.cycles - 1) * self.period_s

    @property
    def hold_after_cycles(self) -> int:
        """Ticks a run goes on once its recovery is over (recovery.hold_after_s)."""
        return int(round(self.recovery.hold_after_s / self.period_s))

    def node_parameters(self, clock_mode: str) -> dict:
        """The ROS parameters every node of the graph gets for this run."""
        options = self.options
        parameters = {
            'config_file': str(self.config_path.resolve()),
            'motions_file': str(self.motions_path.resolve()),
            'motion': options.motion, 'reverse': options.reverse, 'clock_mode': clock_mode,
            'fail_cables': options.fail_cables or [0],
            'fail_at_s': -1.0 if options.fail_at_s is None else options.fail_at_s,
            'fail_at_fraction': -1.0 if options.fail_at_fraction is None else options.fail_at_fraction,
            'duration_s': self.duration_s,
            'end_after_recovery_s': self.hold_after_cycles * self.period_s,
            'fidelity': self.plant.fidelity,
            'detector': self.fdi.detector,
            'epsilon_nm': self.fdi.epsilon_nm,
            'coulomb_friction_nm': self.fdi.friction.coulomb_nm,
        }
        if self.calibration_path is not None:
            parameters['calibration_file'] = str(self.calibration_path.resolve())
        if options.seed is not None:
            parameters['seed'] = options.seed
        return parameters


def build_scenario(options: ScenarioOptions) -> Scenario:
    config_path = config_file(options.config)
    motions_path = config_file(options.motions)
    robot = load_robot(config_path)
    control = load_section(config_path, 'control')
    period = control.number('period_s', positive=True)
    distribution = configured_tension_distribution(control, robot)
    motion = load_motion(motions_path, options.motion, options.reverse)
    reference = tabulate_reference(robot, distribution, motion.trajectory, period)
    check_options(options, robot, motion)
    failures = [(motion.failure_time(options.fail_at_s, options.fail_at_fraction), cable - 1)
                for cable in options.fail_cables]
    plant = PlantConfig.from_section(load_section(config_path, 'plant'), options.fidelity, options.seed)
    calibration = calibration_for(config_path, plant, options.calibration)
    fdi = load_fdi_config(config_path, robot, calibration).with_overrides(
        options.detector, options.epsilon_nm, rigid_plant_friction(plant))
    return Scenario(
        options=options,
        config_path=config_path,
        motions_path=motions_path,
        robot=robot,
        period_s=period,
        gains=PdGains.from_section(robot, control),
        twin_substeps=load_section(config_path, 'twin').integer('substeps', minimum=1),
        motion=motion,
        reference=reference,
        plant=plant,
        failures=failures,
        calibration_path=calibration,
        distribution=distribution,
        fdi=fdi,
        recovery=load_recovery_config(config_path, robot),
    )


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


def calibration_for(config_path: Path, plant: PlantConfig, calibration: str | None) -> Path | None:
    """The given calibration file; else, on the elastic plant, the robot file's
    `fdi.elastic_calibration_file`; the rigid plant keeps the paper's noise-free values.
    NO_CALIBRATION: the robot file's own thresholds (a run without a supervisor)."""
    if calibration == NO_CALIBRATION:
        return None
    if calibration:
        return config_file(calibration)
    if plant.fidelity == 'elastic':
        fdi = load_section(config_path, 'fdi')
        if not fdi.has('elastic_calibration_file'):
            raise fdi.error('elastic_calibration_file', (
                'is missing: the elastic plant needs thresholds measured on this robot; make '
                f'them with cdpr-calibrate --config {config_path} --motions MOTIONS.yaml --out '
                'FILE and name FILE here (or run --fidelity rigid, on the noise-free defaults)'))
        return config_file(fdi.string('elastic_calibration_file'))
    return None


def rigid_plant_friction(plant: PlantConfig) -> float | None:
    """The rigid plant is the twin's model, without Coulomb friction: the FDI must know."""
    return 0.0 if plant.fidelity == 'rigid' else None
