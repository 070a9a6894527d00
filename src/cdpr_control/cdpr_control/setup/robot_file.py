"""A robot's file: its `robot` section read and checked, the body chosen by it (a point
mass, or with a `platform` section a rigid platform)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from cdpr_control.config import ConfigError, Section, load_section
from cdpr_control.model.robot import Motor, Robot
from cdpr_control.platform.body import platform_from_section
from cdpr_control.point_mass.body import PointMass

# Exit points closer than this (m) are one point; spreads below FLAT_RATIO of the
# largest are flat (a line, a plane).
DISTINCT_EXIT_POINTS_M = 1e-3
FLAT_RATIO = 1e-6


def check_exit_point_geometry(section: Section, exit_points: np.ndarray, low: np.ndarray,
                              high: np.ndarray) -> None:
    """ConfigError for exit points that cannot hold the end-effector in 3 DOF anywhere in
    the workspace: two at one place, all on one line, or all in one plane that crosses
    the workspace box (there every cable pulls in that plane, none out of it)."""
    key = section.key('exit_points_m')
    for j in range(len(exit_points)):
        for i in range(j):
            if np.linalg.norm(exit_points[j] - exit_points[i]) < DISTINCT_EXIT_POINTS_M:
                raise ConfigError(section.path, f'{key}[{j}]',
                                  f'coincides with {key}[{i}] (closer than '
                                  f'{DISTINCT_EXIT_POINTS_M * 1000:g} mm): two cables from one point')
    centred = exit_points - exit_points.mean(axis=0)
    _, spread, axes = np.linalg.svd(centred)
    scale = max(spread[0], DISTINCT_EXIT_POINTS_M)
    if spread[1] < FLAT_RATIO * scale:
        raise ConfigError(section.path, key, 'all lie on one line: the cables cannot hold the '
                          'end-effector in 3 DOF')
    if spread[2] < FLAT_RATIO * scale:
        normal = axes[2]
        corners = np.array([[x, y, z] for x in (low[0], high[0]) for y in (low[1], high[1])
                            for z in (low[2], high[2])])
        side = (corners - exit_points.mean(axis=0)) @ normal
        if side.min() <= 0.0 <= side.max():
            raise ConfigError(section.path, key, 'all lie in one plane that crosses the workspace: '
                              'there the cables cannot pull out of that plane')


def robot_from_section(section: Section) -> Robot:
    """Build and validate a Robot from the `robot` section of a config file: a point mass,
    or with a `platform` section a rigid platform (the one place a robot's body is chosen)."""
    exit_points = section.matrix('exit_points_m', 3)
    body = (platform_from_section(section.section('platform'), exit_points.shape[0])
            if section.has('platform') else PointMass())
    if exit_points.shape[0] < body.minimum_cables:
        raise section.error('exit_points_m', f'must list at least {body.minimum_cables} cables to keep '
                            f'{body.degrees_of_freedom} DOF controllable after one failure, '
                            f'got {exit_points.shape[0]}')
    end_effector = section.section('end_effector')
    mass = end_effector.number('mass_kg', positive=True)
    gravity = section.vector('gravity_m_s2', 3, [0.0, 0.0, -9.81])
    if gravity[2] >= 0.0:
        raise section.error('gravity_m_s2', 'must point down (negative z) for a suspended robot')

    workspace = section.section('workspace_m')
    low = workspace.vector('min', 3)
    high = workspace.vector('max', 3)
    if np.any(high <= low):
        raise workspace.error('max', f'must exceed workspace_m.min on every axis, got {high}')
    for i, point in enumerate(exit_points):
        if point[2] <= high[2]:
            raise ConfigError(section.path, f'{section.key("exit_points_m")}[{i}]',
                              f'must lie above the workspace (z > {high[2]} m), got z = {point[2]} m')
    check_exit_point_geometry(section, exit_points, low, high)
    home = section.vector('home_position_m', 3)
    if np.any(home < low) or np.any(home > high):
        raise section.error('home_position_m', f'must lie inside the workspace, got {home}')

    motors = section.section('motor')
    nominal_speed_rpm = motors.number('nominal_speed_rpm', positive=True)
    motor = Motor(
        inertia_kg_m2=motors.number('inertia_kg_m2', positive=True),
        drum_radius_m=motors.number('drum_radius_m', positive=True),
        viscous_friction_nm_s_rad=motors.number('viscous_friction_nm_s_rad', non_negative=True),
        static_friction_nm=motors.number('static_friction_nm', non_negative=True),
        nominal_torque_nm=motors.number('nominal_torque_nm', positive=True),
        nominal_speed_rad_s=nominal_speed_rpm * 2.0 * np.pi / 60.0,
        torque_limit_nm=motors.number('torque_limit_nm', positive=True),
    )

    cables = section.section('cables')
    tension_min = cables.number('tension_min_n', non_negative=True)
    # no more than a motor can pull
    tension_max = cables.number('tension_max_n', positive=True,
                                maximum=motor.torque_limit_nm / motor.drum_radius_m)
    if tension_max <= tension_min:
        raise cables.error('tension_max_n', f'must exceed tension_min_n ({tension_min} N)')
    if mass * np.linalg.norm(gravity) > len(exit_points) * tension_max:
        raise end_effector.error('mass_kg', f'weighs more than its {len(exit_points)} cables can hold '
                                 f'at tension_max_n ({tension_max:g} N each), got {mass!r}')

    return Robot(
        name=section.string('name'),
        exit_points_m=exit_points,
        mass_kg=mass,
        gravity_m_s2=gravity,
        motor=motor,
        tension_min_n=tension_min,
        tension_max_n=tension_max,
        workspace_min_m=low,
        workspace_max_m=high,
        home_position_m=home,
        body=body,
    )


def load_robot(path: str | Path) -> Robot:
    """Load the `robot` section of the YAML file at `path`."""
    return robot_from_section(load_section(path, 'robot'))
