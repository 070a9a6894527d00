"""The robot model: geometry, end-effector and motors of a cable-suspended robot.

Described in YAML (section `robot`, see config/robots/paper_robot.yaml of cdpr_bringup),
separate from the analyses and controllers that use it.
"""
from __future__ import annotations

import hashlib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .config import ConfigError, Section, load_section
from .rotation import normalised, rotation_matrix

# Exit points closer than this (m) are one point; spreads below FLAT_RATIO of the
# largest are flat (a line, a plane).
DISTINCT_EXIT_POINTS_M = 1e-3
FLAT_RATIO = 1e-6
MIN_CABLES = 4
# A platform has 6 DOF: six taut cables with gravity, and one more to lose one.
MIN_PLATFORM_CABLES = 7
# An inertia tensor this far from symmetric (relative) is a typing mistake.
SYMMETRY_TOLERANCE = 1e-9
# Hex digits of Robot.fingerprint(): 2^64 robots before two share one by chance.
FINGERPRINT_DIGITS = 16


@dataclass(frozen=True)
class Motor:
    """One winch: motor, drum and the friction the model knows about."""

    inertia_kg_m2: float
    drum_radius_m: float
    viscous_friction_nm_s_rad: float
    static_friction_nm: float
    nominal_torque_nm: float
    nominal_speed_rad_s: float
    torque_limit_nm: float


@dataclass(frozen=True)
class Platform:
    """A rigid platform (docs/platform.md): cable i is attached at b_i; the centre of mass
    c and the inertia tensor about it, all in the platform frame, whose origin is the
    platform's position p. `home_orientation` is the unit quaternion (w, x, y, z) of the
    home pose."""

    attachment_points_m: np.ndarray
    centre_of_mass_m: np.ndarray
    inertia_kg_m2: np.ndarray
    home_orientation: np.ndarray

    def __post_init__(self):
        for array in (self.attachment_points_m, self.centre_of_mass_m, self.inertia_kg_m2,
                      self.home_orientation):
            array.setflags(write=False)

    def numbers(self) -> np.ndarray:
        return np.concatenate([self.attachment_points_m.ravel(), self.centre_of_mass_m,
                               self.inertia_kg_m2.ravel(), self.home_orientation])


@dataclass(frozen=True)
class Robot:
    """A cable-suspended robot with m cables: a point mass (3 DOF), or with `platform` a
    rigid platform (6 DOF: position and orientation).

    Cable i runs from exit point A_i to the end-effector (to its attachment point b_i on a
    platform); indices are 0-based in code (motor_1 is index 0). Joint angle θ_i grows as
    cable i pays out: l_i = l_i0 + ρ θ_i with θ = 0 at the home pose (`home_position_m`,
    and the platform's `home_orientation`).
    """

    name: str
    exit_points_m: np.ndarray
    mass_kg: float
    gravity_m_s2: np.ndarray
    motor: Motor
    tension_min_n: float
    tension_max_n: float
    workspace_min_m: np.ndarray
    workspace_max_m: np.ndarray
    home_position_m: np.ndarray
    platform: Platform | None = None
    cable_length_offset_m: np.ndarray = field(init=False)

    def __post_init__(self):
        offset = np.linalg.norm(self.exit_points_m - self.cable_ends_m(
            self.home_position_m, None if self.platform is None else self.platform.home_orientation), axis=1)
        object.__setattr__(self, 'cable_length_offset_m', offset)
        for array in (self.exit_points_m, self.gravity_m_s2, self.workspace_min_m,
                      self.workspace_max_m, self.home_position_m, offset):
            array.setflags(write=False)

    def cable_ends_m(self, position_m, orientation) -> np.ndarray:
        """Where each cable ends on the end-effector at the pose (m × 3, world frame): the
        point mass's position, or a platform's attachment points p + R(q) b_i."""
        if self.platform is None:
            return np.broadcast_to(np.asarray(position_m, dtype=float), (self.cable_count, 3))
        return position_m + self.platform.attachment_points_m @ rotation_matrix(orientation).T

    @property
    def cable_count(self) -> int:
        return self.exit_points_m.shape[0]

    @property
    def degrees_of_freedom(self) -> int:
        return 3 if self.platform is None else 6

    @property
    def weight_wrench_n(self) -> np.ndarray:
        """External wrench w_e = m_e g on the end-effector (N)."""
        return self.mass_kg * self.gravity_m_s2

    def fingerprint(self) -> str:
        """A short hash of everything the model of this robot is made of (geometry, mass,
        motors, tension bounds), not of its name or how its file is written: what a
        calibration made on it is bound to."""
        numbers = np.concatenate([
            self.exit_points_m.ravel(), [self.mass_kg], self.gravity_m_s2,
            [getattr(self.motor, name) for name in Motor.__dataclass_fields__],
            [self.tension_min_n, self.tension_max_n], self.workspace_min_m,
            self.workspace_max_m, self.home_position_m,
            [] if self.platform is None else self.platform.numbers()])
        text = ','.join(f'{value:.9g}' for value in numbers)
        return hashlib.sha256(text.encode()).hexdigest()[:FINGERPRINT_DIGITS]

    def cable_mask(self, broken=()) -> np.ndarray:
        """Boolean mask of the cables still attached, given 0-based broken indices."""
        mask = np.ones(self.cable_count, dtype=bool)
        for index in broken:
            if not 0 <= index < self.cable_count:
                raise IndexError(f'cable index {index} outside 0..{self.cable_count - 1}')
            mask[index] = False
        return mask


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


def platform_from_section(platform: Section, cable_count: int) -> Platform:
    """A Platform from a robot's `platform` section; ConfigError, naming the key, for
    attachment points that do not match the cables, or an inertia tensor no rigid body has."""
    attachment = platform.matrix('attachment_points_m', 3)
    if attachment.shape[0] != cable_count:
        raise platform.error('attachment_points_m', f'must list one point per cable ({cable_count}), '
                             f'got {attachment.shape[0]}')
    inertia = platform.matrix('inertia_kg_m2', 3)
    if inertia.shape != (3, 3) or not np.allclose(inertia, inertia.T, rtol=0.0,
                                                  atol=SYMMETRY_TOLERANCE * np.abs(inertia).max()):
        raise platform.error('inertia_kg_m2', f'must be a symmetric 3 × 3 tensor, got {inertia.tolist()}')
    principal = np.linalg.eigvalsh(inertia)
    if principal[0] <= 0.0 or principal[2] > principal[0] + principal[1] + SYMMETRY_TOLERANCE * principal[2]:
        raise platform.error('inertia_kg_m2', f'has principal moments {principal.round(6).tolist()}: '
                             'a rigid body\'s are positive and each at most the sum of the other two')
    try:
        home = normalised(platform.vector('home_orientation', 4, [1.0, 0.0, 0.0, 0.0]))
    except ValueError:
        raise platform.error('home_orientation', 'must be a quaternion (w, x, y, z) of non-zero norm') from None
    return Platform(attachment_points_m=attachment,
                    centre_of_mass_m=platform.vector('centre_of_mass_m', 3, [0.0, 0.0, 0.0]),
                    inertia_kg_m2=inertia, home_orientation=home)


def robot_from_section(section: Section) -> Robot:
    """Build and validate a Robot from the `robot` section of a config file: a point mass,
    or with a `platform` section a rigid platform."""
    exit_points = section.matrix('exit_points_m', 3)
    platform = (platform_from_section(section.section('platform'), exit_points.shape[0])
                if section.has('platform') else None)
    least, dof = (MIN_CABLES, 3) if platform is None else (MIN_PLATFORM_CABLES, 6)
    if exit_points.shape[0] < least:
        raise section.error('exit_points_m', f'must list at least {least} cables to keep '
                            f'{dof} DOF controllable after one failure, got {exit_points.shape[0]}')
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
        platform=platform,
    )


def load_robot(path: str | Path) -> Robot:
    """Load the `robot` section of the YAML file at `path`."""
    return robot_from_section(load_section(path, 'robot'))
