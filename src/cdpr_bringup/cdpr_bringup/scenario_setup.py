"""Everything one scenario run needs, built from the config files and the CLI options."""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from cdpr_control.config import load_section
from cdpr_control.controller import PdGains
from cdpr_control.motions import Motion, load_motion
from cdpr_control.reference import ReferenceTable, tabulate_reference
from cdpr_control.robot import Robot, load_robot
from cdpr_control.tension_distribution import make_tension_distribution
from cdpr_twin.plant import PlantConfig

from .paths import DEFAULT_MOTIONS, DEFAULT_ROBOT, config_file


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

    @property
    def failure_time_s(self) -> float | None:
        return self.failures[0][0] if self.failures else None

    @property
    def cycles(self) -> int:
        return len(self.reference)


def build_scenario(options: ScenarioOptions) -> Scenario:
    config_path = config_file(options.config)
    motions_path = config_file(options.motions)
    robot = load_robot(config_path)
    control = load_section(config_path, 'control')
    period = control.number('period_s', positive=True)
    distribution = make_tension_distribution(
        control.string('tension_distribution'), robot.tension_min_n, robot.tension_max_n)
    motion = load_motion(motions_path, options.motion, options.reverse)
    reference = tabulate_reference(robot, distribution, motion.trajectory, period)
    failures = []
    for cable in options.fail_cables:
        if not 1 <= cable <= robot.cable_count:
            raise ValueError(f'--fail-cable {cable}: the robot has cables 1..{robot.cable_count}')
        failures.append((motion.failure_time(options.fail_at_s, options.fail_at_fraction), cable - 1))
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
        plant=PlantConfig.from_section(load_section(config_path, 'plant'), options.fidelity,
                                       options.seed),
        failures=failures,
    )
