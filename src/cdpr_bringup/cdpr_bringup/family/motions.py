"""Motions inside a drawn robot's wrench-feasible workspace: lines through its home
position in drawn directions (a platform's first one turning about a drawn axis), each
shrunk towards home until every sample of its reference has tensions within
[τ_min, τ_max] — as the run's own settling tabulates it (`runs.settle.build_scenario`,
the configured tension distribution), so a motion kept here is one the runs accept."""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import yaml

from cdpr_control.config import ConfigError
from cdpr_control.setup.robot_file import load_robot
from cdpr_control.tension_distribution.base import BOUND_TOLERANCE_N

from ..cli import UsageError
from ..runs.settle import NO_CALIBRATION, ScenarioOptions, build_scenario

LINES = 3
# a line's half length: a share of the workspace box's half size along its direction, at
# most a length (a big frame's motions as long as a small one's: runs of seconds)
LINE_REACH_SHARE = 0.8
LINE_REACH_MOST_M = 0.5
TURN_DEG = (5.0, 15.0)
# each try shrinks the line (and its turn) towards home by this factor, at most so often
SHRINK_FACTOR = 0.6
SHRINKS = 6
# a line shorter than this is not a motion
SHORTEST_LINE_M = 0.05
MOTION_DEFAULTS = {'peak_speed_m_s': 0.4, 'rest_before_s': 0.5, 'rest_after_s': 1.0}


@dataclass
class Drawn:
    """A robot's motions file and what its drawing met: the motions kept, the shrinks
    made, the motions given up (infeasible even shrunk)."""

    path: Path
    names: list[str]
    shrinks: int
    dropped: int


def line(home, direction, reach_m: float, turn=None) -> dict:
    start, goal = home - reach_m * direction, home + reach_m * direction
    motion = {'type': 'line', 'start': np.round(start, 4).tolist(), 'goal': np.round(goal, 4).tolist()}
    if turn is not None:
        axis, angle_deg = turn
        motion['turn'] = {'axis': np.round(axis, 4).tolist(), 'angle_deg': round(angle_deg, 3)}
    return motion


def write_motions(motions: dict, path: Path) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text('# Drawn by cdpr-bench robots (cdpr_bringup.family.motions). Units: m, s, degrees.\n'
                    + yaml.safe_dump({'motion_defaults': MOTION_DEFAULTS, 'motions': motions},
                                     sort_keys=False, default_flow_style=None))
    return path


def within_bounds(scenario) -> bool:
    """Every sample of the run's reference has tensions within the robot's bounds."""
    tension = scenario.reference.tension_n
    robot = scenario.robot
    return bool(np.all(np.isfinite(tension)) and tension.min() >= robot.tension_min_n - BOUND_TOLERANCE_N
                and tension.max() <= robot.tension_max_n + BOUND_TOLERANCE_N)


def feasible(robot_path: Path, motions_path: Path, name: str) -> bool:
    try:
        scenario = build_scenario(ScenarioOptions(config=str(robot_path), motions=str(motions_path), motion=name,
                                                  calibration=NO_CALIBRATION))
    except (UsageError, ConfigError):
        return False
    return within_bounds(scenario)


def draw_motions(rng: np.random.Generator, robot_path: Path, motions_path: Path, prefix: str) -> Drawn:
    """The robot's motions, named `prefix`-line-k, written to `motions_path`."""
    robot = load_robot(robot_path)
    home = robot.home_position_m
    half = (robot.workspace_max_m - robot.workspace_min_m) / 2.0
    kept, shrinks, dropped = {}, 0, 0
    turned = not robot.body.has_orientation   # a platform's first line kept turns
    for k in range(1, LINES + 1):
        name = f'{prefix}-line-{k}'
        direction = rng.normal(size=3)
        direction /= np.linalg.norm(direction)
        # as far as the box allows along the direction, a share of it
        reach = min(LINE_REACH_SHARE * float(np.min(half / np.maximum(np.abs(direction), 1e-12))), LINE_REACH_MOST_M)
        axis = rng.normal(size=3)
        turn = None if turned else [axis / np.linalg.norm(axis), float(rng.uniform(*TURN_DEG))]
        for _ in range(SHRINKS + 1):
            if 2.0 * reach < SHORTEST_LINE_M:
                break
            write_motions({**kept, name: line(home, direction, reach, turn)}, motions_path)
            if feasible(robot_path, motions_path, name):
                kept[name] = line(home, direction, reach, turn)
                turned = turned or turn is not None
                break
            shrinks += 1
            reach *= SHRINK_FACTOR
            if turn is not None:
                turn = [turn[0], turn[1] * SHRINK_FACTOR]
        if name not in kept:
            dropped += 1
    write_motions(kept, motions_path)
    return Drawn(motions_path, list(kept), shrinks, dropped)
