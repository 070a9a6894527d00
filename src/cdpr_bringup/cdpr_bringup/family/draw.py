"""Robots drawn from a seed: point masses on 4–8 cables and rigid 6-DOF platforms on 6–8,
suspended (and, for platforms, crossed as CoGiRo's), in frames 1–8 m wide and 1–6 m high
with exit points at mixed heights, end-effectors and motors within datasheet-like ranges.

Each is a robot-only document (`robot:` as in config/robots/*.yaml); whether the project
accepts it is the robot reader's word (`accepted`), not this module's.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import yaml

from cdpr_control.config import ConfigError, load_config
from cdpr_control.control.controller import PdGains
from cdpr_control.setup.robot_file import load_robot
from cdpr_fdi.settings.config import load_recovery_config

# ---- the ranges of the drawing (each a (low, high) of a uniform draw) ----------------
POINT_MASS_CABLES = (4, 8)
PLATFORM_CABLES = (6, 8)
# the share of the drawn robots that are platforms
PLATFORM_SHARE = 0.5
FRAME_WIDTH_M = (1.0, 8.0)          # each side of the frame's footprint
FRAME_HEIGHT_M = (1.0, 6.0)
# exit points' heights, as a share of the frame's height: mixed heights
EXIT_HEIGHT_SHARE = (0.8, 1.0)
# a point's angle around the frame, off its even spacing, as a share of that spacing
EXIT_ANGLE_JITTER_SHARE = 0.3
# the workspace box: inside the footprint by this share of each side, and this far under
# the lowest exit point (the larger of a share of the frame's height and a length)
WORKSPACE_MARGIN_SHARE = 0.15
WORKSPACE_CLEARANCE_SHARE = 0.2
WORKSPACE_CLEARANCE_M = 0.2
POINT_MASS_KG = (1.0, 10.0)
PLATFORM_MASS_KG = (1.0, 10.0)
# a platform's box: each side, never more than this share of the narrower frame side
PLATFORM_SIDE_M = (0.1, 0.4)
PLATFORM_SIDE_SHARE_MAX = 0.2
# the crossed layout (CoGiRo): a post's two cables leave it this share of the narrower
# side apart, along the two sides of the frame
CROSSED_OFFSET_SHARE = 0.05
MOTOR_INERTIA_KG_M2 = (2.0e-4, 1.5e-3)
DRUM_RADIUS_M = (0.02, 0.06)
NOMINAL_TORQUE_NM = (1.0, 4.0)
# the torque limit as a multiple of the nominal torque (peak / continuous of servo data)
TORQUE_LIMIT_PER_NOMINAL = (2.5, 3.5)
NOMINAL_SPEED_RPM = (2000.0, 4000.0)
VISCOUS_FRICTION_NM_S_RAD = (0.001, 0.003)
STATIC_FRICTION_NM = (0.05, 0.15)
TENSION_MIN_N = (1.0, 3.0)
# tension_max_n as a share of what a motor pulls at its torque limit (limit / drum radius)
TENSION_MAX_SHARE = (0.5, 0.9)
GRAVITY_M_S2 = (0.0, 0.0, -9.81)
POINT_MASS_RADIUS_M = 0.05

# a suspended platform's attachment, off its exit point's direction, as a share of the
# spacing of the exit points around the frame
SUSPENDED_TWIST_SHARE = 0.5
LAYOUTS = ('suspended', 'crossed')

# The crossed layout on a unit frame (x, y in 0..1): each cable's post corner, the side it
# leaves along (unit step from the corner), and the platform corner it ends at (signs of
# the box's half sides: beside the neighbouring post, top and bottom face in turn), as
# robots/crossed_platform_robot.yaml has them.
CROSSED = (
    ((0, 0), (0, 1), (1, -1, 1)), ((0, 0), (1, 0), (-1, 1, -1)),
    ((1, 0), (-1, 0), (-1, -1, 1)), ((1, 0), (0, 1), (1, 1, -1)),
    ((1, 1), (0, -1), (-1, 1, 1)), ((1, 1), (-1, 0), (1, -1, -1)),
    ((0, 1), (1, 0), (1, 1, 1)), ((0, 1), (0, -1), (-1, -1, -1)),
)


def uniform(rng: np.random.Generator, bounds) -> float:
    return float(rng.uniform(*bounds))


def on_rectangle(width_x_m: float, width_y_m: float, angle_rad: float) -> np.ndarray:
    """Where the ray from the footprint's centre at `angle_rad` meets its border (x, y)."""
    direction = np.array([np.cos(angle_rad), np.sin(angle_rad)])
    reach = min(width_x_m / 2.0 / max(abs(direction[0]), 1e-12), width_y_m / 2.0 / max(abs(direction[1]), 1e-12))
    return np.array([width_x_m / 2.0, width_y_m / 2.0]) + reach * direction


def around_the_frame(rng, count: int, width_x_m: float, width_y_m: float, height_m: float):
    """(exit points count × 3, their angles): spread around the footprint's border with a
    jitter, each at its own height."""
    spacing = 2.0 * np.pi / count
    angles = (np.arange(count) + rng.uniform(-EXIT_ANGLE_JITTER_SHARE, EXIT_ANGLE_JITTER_SHARE, count)) * spacing
    heights = height_m * rng.uniform(*EXIT_HEIGHT_SHARE, count)
    points = np.array([[*on_rectangle(width_x_m, width_y_m, angle), z] for angle, z in zip(angles, heights)])
    return points, angles


def motor_and_cables(rng) -> tuple[dict, dict]:
    drum = uniform(rng, DRUM_RADIUS_M)
    nominal = uniform(rng, NOMINAL_TORQUE_NM)
    limit = nominal * uniform(rng, TORQUE_LIMIT_PER_NOMINAL)
    motor = {
        'inertia_kg_m2': float(f'{uniform(rng, MOTOR_INERTIA_KG_M2):.3g}'),
        'drum_radius_m': round(drum, 4),
        'viscous_friction_nm_s_rad': round(uniform(rng, VISCOUS_FRICTION_NM_S_RAD), 4),
        'static_friction_nm': round(uniform(rng, STATIC_FRICTION_NM), 3),
        'nominal_torque_nm': round(nominal, 3),
        'nominal_speed_rpm': round(uniform(rng, NOMINAL_SPEED_RPM)),
        'torque_limit_nm': round(limit, 3),
    }
    cables = {'tension_min_n': round(uniform(rng, TENSION_MIN_N), 2),
              'tension_max_n': round(uniform(rng, TENSION_MAX_SHARE) * motor['torque_limit_nm']
                                     / motor['drum_radius_m'], 1)}
    return motor, cables


def workspace(width_x_m: float, width_y_m: float, lowest_exit_m: float, frame_height_m: float,
              body_m: float = 0.0) -> tuple[list, list]:
    margin = np.array([width_x_m, width_y_m]) * WORKSPACE_MARGIN_SHARE + body_m
    top = lowest_exit_m - max(WORKSPACE_CLEARANCE_SHARE * frame_height_m, WORKSPACE_CLEARANCE_M) - body_m
    low = [round(float(margin[0]), 3), round(float(margin[1]), 3), round(float(body_m), 3)]
    high = [round(float(width_x_m - margin[0]), 3), round(float(width_y_m - margin[1]), 3), round(float(top), 3)]
    return low, high


def box_inertia(mass_kg: float, sides_m) -> list[list[float]]:
    a, b, c = (float(side) for side in sides_m)
    diagonal = [mass_kg * (b * b + c * c) / 12.0, mass_kg * (a * a + c * c) / 12.0, mass_kg * (a * a + b * b) / 12.0]
    return [[round(value, 7) if i == j else 0.0 for j in range(3)] for i, value in enumerate(diagonal)]


def draw_robot(rng: np.random.Generator, name: str) -> dict:
    """One robot document ({'robot': …}) drawn from `rng`; its layout is named in a
    comment-free key of its own (`robot.name` ends with it)."""
    width_x, width_y = uniform(rng, FRAME_WIDTH_M), uniform(rng, FRAME_WIDTH_M)
    height = uniform(rng, FRAME_HEIGHT_M)
    platform = rng.uniform() < PLATFORM_SHARE
    motor, cables = motor_and_cables(rng)
    robot = {'name': name, 'gravity_m_s2': list(GRAVITY_M_S2)}
    if not platform:
        count = int(rng.integers(POINT_MASS_CABLES[0], POINT_MASS_CABLES[1] + 1))
        exits, _ = around_the_frame(rng, count, width_x, width_y, height)
        low, high = workspace(width_x, width_y, exits[:, 2].min(), height)
        robot['end_effector'] = {'mass_kg': round(uniform(rng, POINT_MASS_KG), 3), 'radius_m': POINT_MASS_RADIUS_M}
    else:
        count = int(rng.integers(PLATFORM_CABLES[0], PLATFORM_CABLES[1] + 1))
        layout = LAYOUTS[int(rng.integers(len(LAYOUTS)))]
        side_max = min(PLATFORM_SIDE_M[1], PLATFORM_SIDE_SHARE_MAX * min(width_x, width_y))
        sides = np.sort(rng.uniform(PLATFORM_SIDE_M[0], max(side_max, PLATFORM_SIDE_M[0]), 3))[::-1]
        half = sides / 2.0
        if layout == 'crossed':
            offset = CROSSED_OFFSET_SHARE * min(width_x, width_y)
            post_heights = height * rng.uniform(*EXIT_HEIGHT_SHARE, 4)
            posts = {(0, 0): 0, (1, 0): 1, (1, 1): 2, (0, 1): 3}
            exits = np.array([[corner[0] * width_x + step[0] * offset, corner[1] * width_y + step[1] * offset,
                               post_heights[posts[corner]]] for corner, step, _ in CROSSED[:count]])
            attachments = np.array([np.array(signs) * half for _, _, signs in CROSSED[:count]])
        else:
            exits, angles = around_the_frame(rng, count, width_x, width_y, height)
            # on the edge of the box's top face, off its exit point's direction by
            # SUSPENDED_TWIST_SHARE of the spacing, to one side and the other in turn: it
            # hangs below them, and their pulls turn it both ways about the vertical
            twist = SUSPENDED_TWIST_SHARE * 2.0 * np.pi / count
            attachments = np.array([[*on_rectangle(2.0 * half[0], 2.0 * half[1], angle + twist * (-1) ** i) - half[:2],
                                     half[2]] for i, angle in enumerate(angles)])
        low, high = workspace(width_x, width_y, exits[:, 2].min(), height, float(np.linalg.norm(half)))
        mass = round(uniform(rng, PLATFORM_MASS_KG), 3)
        robot['name'] = f'{name}_{layout}'
        robot['end_effector'] = {'mass_kg': mass, 'radius_m': round(float(np.linalg.norm(half)), 3)}
        robot['platform'] = {'attachment_points_m': np.round(attachments, 4).tolist(),
                             'centre_of_mass_m': [0.0, 0.0, 0.0],
                             'inertia_kg_m2': box_inertia(mass, sides), 'home_orientation': [1.0, 0.0, 0.0, 0.0]}
    robot['exit_points_m'] = np.round(exits, 3).tolist()
    robot['workspace_m'] = {'min': low, 'max': high}
    robot['home_position_m'] = [round(float(a + b) / 2.0, 3) for a, b in zip(low, high)]
    robot['motor'] = motor
    robot['cables'] = cables
    return {'robot': robot}


def write_robot(document: dict, path: Path) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text('# Drawn by cdpr-bench robots (cdpr_bringup.family.draw). Units: SI.\n'
                    + yaml.safe_dump(document, sort_keys=False, default_flow_style=None))
    return path


def refusal(path: Path) -> ConfigError | None:
    """Why the project refuses the robot file (its ConfigError), None where it accepts
    it: read as `cdpr-robot --config` reads it — the whole file with the defaults, its
    robot, the recovery settings that robot takes (the safe height inside its workspace)
    and the joint PD its motors keep stable."""
    try:
        control = load_config(path).section('control')
        robot = load_robot(path)
        load_recovery_config(path, robot)
        PdGains.settled(robot, control)
    except ConfigError as err:
        return err
    return None
