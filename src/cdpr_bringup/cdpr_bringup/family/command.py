"""`cdpr-bench robots`: N robots drawn from a seed, each written as a robot-only file with
motions inside its wrench-feasible workspace, calibrated from nothing on the elastic
plant (the core of cdpr-calibrate), every cable (or --cables of them) broken at
--instants random instants of its motions on each plant through the campaign machinery
(a local pool, or a Dask scheduler), and the stack judged on them (`judge`).

Writes DIR/robots/<name>.yaml, <name>_motions.yaml and <name>_calibration_elastic.yaml,
the refused draws in DIR/refused/, the runs in DIR/runs/<id>, DIR/summary.csv (a row per
run) and DIR/summary.md.
"""
from __future__ import annotations

import os
import shutil
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from cdpr_control.config import ConfigError
from cdpr_control.model.robot import Robot
from cdpr_control.setup.robot_file import load_robot

from . import judge
from .draw import draw_robot, refusal, write_robot
from .motions import draw_motions
from ..campaigns.calibrate import calibrate_robot, write_calibration
from ..campaigns.campaign import DETECTORS, RANDOM_FRACTION_RANGE, Run, run_campaign, write_summary_csv
from ..campaigns.campaign_run import SchedulerUnreachable
from ..cli import UsageError

# A robot's draws: given up after this many per robot asked for, with most refused.
DRAWS_PER_ROBOT_MOST = 40
DIRECTIONS = ('forward', 'reverse')
# the plants a drawn robot is judged on (the field plant is the paper's rig's alone)
PLANTS = ('rigid', 'elastic')
# where a failure-free run's row says its cable would have broken (it breaks none)
NO_FAILURE_FRACTION = 0.5


@dataclass(frozen=True)
class FamilyOptions:
    """`cdpr-bench robots` as settled: every default here, and nowhere else."""

    count: int = 5
    seed: int = 0
    instants: int = 3
    fidelities: tuple[str, ...] = PLANTS
    # cables broken per robot, drawn from the seed (None: every cable)
    cables: int | None = None
    # the calibration's failure-free runs: its plant seeds, and the first this many motions
    # (None: all) of each robot, both directions
    calibration_seeds: tuple[int, ...] = (0, 1, 2)
    calibration_motions: int | None = None
    detector: str = DETECTORS[0]
    false_alarms_per_hour: float = 0.1
    jobs: int | None = None
    scheduler: str | None = None
    out: str = 'runs/bench-robots'


def settle_family(**given) -> FamilyOptions:
    """The options given (None: not given) over the defaults, each checked once;
    UsageError naming the option of a value that cannot be used."""
    options = FamilyOptions(**{key: value for key, value in given.items() if value is not None})
    positive = {'--count': options.count, '--instants': options.instants, '--cables': options.cables,
                '--calibration-motions': options.calibration_motions, '--jobs': options.jobs}
    for flag, value in positive.items():
        if value is not None and value < 1:
            raise UsageError(f'{flag} {value}: must be 1 or more')
    if options.seed < 0:
        raise UsageError(f'--seed {options.seed}: must be 0 or more')
    if not options.fidelities or not set(options.fidelities) <= set(PLANTS):
        raise UsageError(f'--fidelities {",".join(options.fidelities)}: choose from rigid, elastic, comma-separated')
    if not options.calibration_seeds or min(options.calibration_seeds) < 0:
        raise UsageError(f'--calibration-seeds {",".join(map(str, options.calibration_seeds))}: '
                         'plant seeds, 0 or more, comma-separated')
    return options


@dataclass
class Member:
    """A drawn robot the project accepted, with its motions (and calibration)."""

    name: str
    robot: Robot
    robot_file: Path
    motions_file: Path
    motions: list[str]
    shrinks: int
    calibration: Path | None = None
    runs: list[Run] = field(default_factory=list)


def draw_family(options: FamilyOptions, out: Path) -> tuple[list[Member], dict]:
    """`options.count` robots the project accepts, each with at least one wrench-feasible
    motion and, on the elastic plant, calibrated (calibrate_member: refused where the
    controller does not hold it), drawn from `options.seed`; and the drawing's tally
    (draws, refusals by why)."""
    rng = np.random.default_rng(options.seed)
    members, refused, draws = [], Counter(), 0
    # absolute: a Dask worker (--scheduler) reads them from its own working folder
    robots, rejected = out.resolve() / 'robots', out.resolve() / 'refused'
    while len(members) < options.count:
        if draws >= DRAWS_PER_ROBOT_MOST * options.count:
            raise UsageError(f'--count {options.count}: {draws} robots drawn from --seed {options.seed}, only '
                             f'{len(members)} accepted ({dict(refused)})')
        document = draw_robot(rng, f'family{options.seed}_{draws:03d}')
        name = document['robot']['name']
        path = write_robot(document, robots / f'{name}.yaml')
        motions = robots / f'{name}_motions.yaml'
        draws += 1
        error = refusal(path)
        drawn = None if error else draw_motions(rng, path, motions, f'{draws - 1:03d}')
        why = f"'{error.key}'" if error else None if drawn.names else 'no wrench-feasible motion'
        member = None if why else Member(name, load_robot(path), path, motions, drawn.names, drawn.shrinks)
        if member is not None and 'elastic' in options.fidelities:
            try:
                calibrate_member(member, options)
            except ConfigError as err:   # check_held: the controller does not hold it
                why, member = f"'{err.key}' (calibration)", None
        if member is None:
            refused[why] += 1
            rejected.mkdir(parents=True, exist_ok=True)
            for kept in (path, motions):
                if kept.exists():
                    shutil.move(kept, rejected / kept.name)
            continue
        members.append(member)
    return members, {'draws': draws, 'refused': dict(refused)}


def calibrate_member(member: Member, options: FamilyOptions) -> None:
    """The member's elastic-plant thresholds from nothing: cdpr-calibrate's core on its
    motions, written beside its robot file."""
    motions = member.motions[:options.calibration_motions]
    calibrated = calibrate_robot(member.robot_file, member.motions_file, 'elastic', list(options.calibration_seeds),
                                 options.jobs or os.cpu_count(), options.false_alarms_per_hour, motion_set=motions)
    member.calibration = member.robot_file.with_name(f'{member.name}_calibration_elastic.yaml')
    write_calibration(member.calibration, calibrated.document)


def member_runs(member: Member, options: FamilyOptions, rng: np.random.Generator) -> list[Run]:
    """Each chosen cable broken at `options.instants` instants, each on a motion of the
    member's and a point of its move drawn from `rng`, on every plant; then the
    calibration's failure-free runs, supervised on the calibrated thresholds."""
    def run(motion, direction, cable, fidelity, seed, fraction):
        return Run(motion, direction, cable, fidelity, options.detector, seed, fraction, config=str(member.robot_file),
                   motions_file=str(member.motions_file),
                   calibration=str(member.calibration) if fidelity == 'elastic' else None)

    cables = np.arange(1, member.robot.cable_count + 1)
    if options.cables is not None:
        cables = np.sort(rng.choice(cables, min(options.cables, cables.size), replace=False))
    runs = []
    for cable in cables:
        for instant in range(options.instants):
            motion = member.motions[int(rng.integers(len(member.motions)))]
            fraction = round(float(rng.uniform(*RANDOM_FRACTION_RANGE)), 4)
            runs += [run(motion, 'forward', int(cable), fidelity, instant, fraction) for fidelity in options.fidelities]
    if member.calibration is not None:
        runs += [run(motion, direction, None, 'elastic', seed, NO_FAILURE_FRACTION)
                 for motion in member.motions[:options.calibration_motions] for direction in DIRECTIONS
                 for seed in options.calibration_seeds]
    return runs


def bench_robots(options: FamilyOptions, heading: str = '', show_progress: bool = True) -> dict:
    """Draw, calibrate, break and judge (module docstring); the judged rows, the members,
    the drawing's tally and the runs not done right."""
    out = Path(options.out)
    for stale in ('robots', 'refused'):
        shutil.rmtree(out / stale, ignore_errors=True)   # a family is drawn anew; its runs resume
    members, drawing = draw_family(options, out)
    rng = np.random.default_rng([options.seed, 1])
    for member in members:
        member.runs = member_runs(member, options, rng)
    runs = [run for member in members for run in member.runs]
    try:
        rows = run_campaign(runs, out, options.jobs, show_progress=show_progress, scheduler=options.scheduler)
    except SchedulerUnreachable as err:
        raise UsageError(f'--scheduler {options.scheduler}: {err}') from None
    owner = {run.id: member for member in members for run in member.runs}
    judged = [judge.judged(row, owner[row['run_id']]) for row in rows]
    write_summary_csv(judged, out / 'summary.csv', judge.COLUMNS)
    (out / 'summary.md').write_text(judge.summary_markdown(judged, members, drawing, heading))
    return {'rows': judged, 'members': members, 'drawing': drawing, 'cases': judge.cases(judged), 'out': out}


def table(found: dict) -> list[str]:
    lines = [f'  {found["drawing"]["draws"]} drawn, {len(found["members"])} kept, refused: {found["drawing"]["refused"]}']
    lines += ['  ' + line for line in judge.table(found['rows'], found['members'])]
    lines += ['  runs not done right:'] + (['  ' + judge.case_line(row) for row in found['cases']] or ['  none'])
    lines += [f'  written: {found["out"]}/summary.md, {found["out"]}/summary.csv, {found["out"]}/robots/']
    return lines
