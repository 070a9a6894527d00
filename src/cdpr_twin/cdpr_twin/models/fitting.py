"""The twin fitted to the robot it watches: each motor's inertia J_i, viscous friction b_i
and Coulomb friction f_i, and the end-effector's mass m, from failure-free recordings of
the motor angles θ, speeds θ̇ and commanded torques c alone (docs/twin-fitting.md).

The tensions τ are not measured; each motor's equation gives them,

    ρ τ_i = J_i θ̈_i + b_i θ̇_i + (f_i + g_i exp(−(θ̇_i / v_s)²)) tanh(θ̇_i / v) − c_i,

and the end-effector's wrench balance, W τ = w(m) (the wrench its motion asks of the
cables: m (p̈ − g) for a point mass, affine in m for a platform, body.motion_terms), then
reads, per tick and degree of freedom,

    w(m) − Σ_i W_i (J_i θ̈_i + b_i θ̇_i + f_i tanh(θ̇_i / v)) / ρ = −Σ_i W_i c_i / ρ,

linear in (m, J_1…J_n, b_1…b_n, f_1…f_n, g_1…g_n): least squares over every tick of
every recording. The break-away excess g near standstill, fading over the Stribeck speed
v_s, is kept where the data supports it: at the candidate v_s that explains the most, if
it leaves a tenth less unexplained than none and every g is told apart. The pose comes from the measured angles (forward kinematics), its twist and
twist rate from their differences; angles, speeds and commands are first smoothed by one
Gaussian window (the equation is linear, so it holds for the smoothed signals as the
structure matrix varies slowly), and the command is taken where the drives apply it
(`drive_delay_s`, then the half period a held command acts on average).
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from cdpr_control.geometry.rotation import conjugate, product
from cdpr_control.model.robot import Robot

# The parameters fitted per motor, as the robot file's motor names them, and the
# break-away friction, fitted where the data supports it.
MOTOR_PARAMETERS = ('inertia_kg_m2', 'viscous_friction_nm_s_rad', 'static_friction_nm')
BREAKAWAY = 'breakaway_friction_nm'
LABELS = {'inertia_kg_m2': 'inertia', 'viscous_friction_nm_s_rad': 'viscous friction',
          'static_friction_nm': 'Coulomb friction', BREAKAWAY: 'break-away friction'}
# A break-away term is kept if it leaves at most this share of the residual without it.
BREAKAWAY_GAIN = 0.9


@dataclass(frozen=True)
class FitOptions:
    """How the recordings are read: the Gaussian window's σ (s), the rows kept (one tick
    in `decimation`; by default two σ apart, so that the rows' errors are nearly
    independent and the least squares' uncertainties mean what they say), the speed
    (rad/s) over which Coulomb friction reaches its value, the drives' delay (s), the Stribeck speeds (rad/s) a break-away term is tried at; the
    coverage factor k the uncertainties are stated expanded by, and the largest expanded
    relative uncertainty a fitted value may have (above it the motions did not excite
    that parameter)."""

    smoothing_s: float = 0.02
    decimation: int | None = None
    coulomb_smoothing_rad_s: float = 0.1
    drive_delay_s: float = 0.0
    coverage: float = 3.0
    largest_relative_uncertainty: float = 0.3
    stribeck_speeds_rad_s: tuple[float, ...] = (0.25, 0.5, 1.0, 2.0)


@dataclass(frozen=True)
class TwinFit:
    """The fitted values and their standard uncertainties: `mass_kg`, and per motor
    (arrays of the cable count) each of MOTOR_PARAMETERS, and BREAKAWAY where it was kept
    (with its Stribeck speed, rad/s; None without); the fit's residual (rms, N) and its
    number of equations."""

    mass_kg: float
    mass_uncertainty_kg: float
    motors: dict[str, np.ndarray]
    uncertainties: dict[str, np.ndarray]
    residual_rms_n: float
    equations: int
    stribeck_speed_rad_s: float | None = None

    def common(self, name: str) -> tuple[float, float]:
        """One value for every motor (the twin's model has one motor type): the mean of
        the motors' weighted by their uncertainties, and its uncertainty."""
        weights = 1.0 / self.uncertainties[name] ** 2
        return (float(np.sum(weights * self.motors[name]) / np.sum(weights)),
                float(1.0 / np.sqrt(np.sum(weights))))


class NotExcited(ValueError):
    """The motions do not excite a parameter enough to fit it; the message names it."""


def smoothed(signal: np.ndarray, sigma_ticks: float) -> np.ndarray:
    """`signal` (rows per tick) convolved with a unit Gaussian of σ `sigma_ticks`, each end
    padded with its first or last row (a recording starts and ends at rest)."""
    half = int(np.ceil(4.0 * sigma_ticks))
    window = np.exp(-0.5 * (np.arange(-half, half + 1) / sigma_ticks) ** 2)
    window /= window.sum()
    padded = np.concatenate([np.repeat(signal[:1], half, axis=0), signal, np.repeat(signal[-1:], half, axis=0)])
    return np.apply_along_axis(lambda column: np.convolve(column, window, mode='valid'), 0, padded)


def applied(command_nm: np.ndarray, period_s: float, drive_delay_s: float) -> np.ndarray:
    """The torque the drives apply at each tick's instant, of commands held one period each
    from `drive_delay_s` after their tick: on average the command of (delay + T/2) earlier,
    interpolated between ticks."""
    lag = (drive_delay_s + 0.5 * period_s) / period_s
    ticks = np.arange(len(command_nm)) - lag
    return np.stack([np.interp(ticks, np.arange(len(command_nm)), column) for column in command_nm.T], axis=1)


def twist_of(poses: np.ndarray, period_s: float) -> np.ndarray:
    """The twist (v, and ω in the world frame for an orientation) of each row of a stack of
    poses, by central differences (ω = 2 q̇ q* of the unit quaternion q)."""
    rate = np.gradient(poses, period_s, axis=0)
    if poses.shape[1] == 3:
        return rate
    omega = 2.0 * product(rate[:, 3:], conjugate(poses[:, 3:]))[:, 1:]
    return np.concatenate([rate[:, :3], omega], axis=1)


class Regression:
    """The rows (A, y) of the module docstring's equation for one recording, A's columns m,
    J_1…J_n, b_1…b_n, f_1…f_n (`design`, `target`), and the break-away columns g_1…g_n at
    a Stribeck speed (`breakaway`), formed from the same poses. Each term is formed tick by
    tick from the measurements, then smoothed (a product smoothed is not the product of
    the smoothed factors); the wrench, whose differences of the pose need it, from the
    smoothed pose."""

    def __init__(self, robot: Robot, angle_rad, speed_rad_s, command_nm, period_s: float, options: FitOptions):
        self.sigma = options.smoothing_s / period_s
        radius = robot.motor.drum_radius_m
        positions, orientations = robot.body.poses_of_angles(robot, angle_rad)
        poses = positions if orientations is None else np.concatenate([positions, orientations], axis=1)
        rest = np.zeros((len(poses), robot.body.degrees_of_freedom))
        self.structure = robot.body.motion_terms(robot, poses, rest, rest).structure / radius   # n × dof × m, over ρ
        smooth_poses = smoothed(poses, self.sigma)
        if orientations is not None:
            smooth_poses[:, 3:] /= np.linalg.norm(smooth_poses[:, 3:], axis=1, keepdims=True)
        twists = twist_of(smooth_poses, period_s)
        rates = np.gradient(twists, period_s, axis=0)
        torque = applied(np.clip(command_nm, -robot.motor.torque_limit_nm, robot.motor.torque_limit_nm),
                         period_s, options.drive_delay_s)
        self.speed_rad_s = speed_rad_s
        self.coulomb = np.tanh(speed_rad_s / options.coulomb_smoothing_rad_s)
        motor_terms = (np.gradient(speed_rad_s, period_s, axis=0), speed_rad_s, self.coulomb)
        ticks = self.structure.shape[0]
        # the ends, where differences are one-sided and the padding shows
        self.keep = slice(int(4 * self.sigma) + 2, ticks - int(4 * self.sigma) - 2,
                          options.decimation or max(1, round(2.0 * self.sigma)))
        # the wrench is affine in the mass: w(m) = w(0) + m (w(1) − w(0))
        weightless = robot.body.motion_terms(dataclasses.replace(robot, mass_kg=0.0), smooth_poses, twists, rates)
        per_kg = robot.body.motion_terms(dataclasses.replace(robot, mass_kg=1.0), smooth_poses, twists, rates).wrench_n
        columns = [(per_kg - weightless.wrench_n)[..., None]] + [-self.smoothed_product(figure) for figure in motor_terms]
        design = np.concatenate(columns, axis=2)
        self.design = design[self.keep].reshape(-1, design.shape[2])
        self.target = (-self.smoothed_product(torque).sum(axis=2) - weightless.wrench_n)[self.keep].ravel()

    def smoothed_product(self, figure: np.ndarray) -> np.ndarray:
        """S_i (over ρ) times a per-motor figure, tick by tick, then smoothed (ticks × dof × m)."""
        ticks, dof, m = self.structure.shape
        return smoothed((self.structure * figure[:, None, :]).reshape(ticks, -1), self.sigma).reshape(ticks, dof, m)

    def breakaway(self, stribeck_speed_rad_s: float) -> np.ndarray:
        """The columns g_1…g_n at that Stribeck speed (rad/s), rows as `design`'s."""
        excess = self.coulomb * np.exp(-(self.speed_rad_s / stribeck_speed_rad_s) ** 2)
        return -self.smoothed_product(excess)[self.keep].reshape(-1, self.structure.shape[2])


def least_squares(design: np.ndarray, target: np.ndarray):
    """The solution, its standard uncertainties, the residual's rms and the rank."""
    scale = np.linalg.norm(design, axis=0)
    solution, _, rank, _ = np.linalg.lstsq(design / scale, target, rcond=None)
    values = solution / scale
    residual = target - design @ values
    dof = max(len(target) - len(values), 1)
    covariance = np.linalg.pinv((design / scale).T @ (design / scale)) * (residual @ residual / dof)
    return values, np.sqrt(np.diag(covariance)) / scale, float(np.sqrt(residual @ residual / len(target))), rank


def fit_twin(robot: Robot, recordings, period_s: float, options: FitOptions = FitOptions()) -> TwinFit:
    """Least squares of the module docstring over every `recordings` (each (θ, θ̇, c) of a
    failure-free run, rows per tick), with the break-away term where the data supports
    it; NotExcited, naming the parameter, where the motions do not excite one (its
    expanded relative uncertainty above the option's)."""
    m = robot.cable_count
    # the poses and terms of each recording, formed once for every candidate below
    regressions = [Regression(robot, *recording, period_s, options) for recording in recordings]
    design = np.concatenate([regression.design for regression in regressions])
    target = np.concatenate([regression.target for regression in regressions])
    idle = np.flatnonzero(np.linalg.norm(design, axis=0) == 0.0)
    if idle.size:
        names = ['the end-effector\'s mass'] + [f'motor {i + 1}\'s {LABELS[name]}' for name in MOTOR_PARAMETERS
                                                 for i in range(m)]
        raise NotExcited(f'the motions do not excite {names[idle[0]]}: record motions that move every motor')
    fit = least_squares(design, target)
    parameters, stribeck, plain_rms = MOTOR_PARAMETERS, None, fit[2]
    breakaway = slice(1 + 3 * m, 1 + 4 * m)
    for speed in options.stribeck_speeds_rad_s:
        candidate = least_squares(np.concatenate([design, np.concatenate([regression.breakaway(speed)
                                                                          for regression in regressions])], axis=1),
                                  target)
        told = np.all(options.coverage * candidate[1][breakaway]
                      < options.largest_relative_uncertainty * np.abs(candidate[0][breakaway]))
        if told and candidate[2] < min(BREAKAWAY_GAIN * plain_rms, fit[2]):
            fit, parameters, stribeck = candidate, MOTOR_PARAMETERS + (BREAKAWAY,), speed
    values, sigma, residual_rms, rank = fit
    names = ['the end-effector\'s mass'] + [f'motor {i + 1}\'s {LABELS[name]}' for name in parameters
                                             for i in range(m)]
    judged = options.coverage * sigma / np.maximum(np.abs(values), np.finfo(float).tiny)
    # friction may truly be nil: judged on its uncertainty against the largest motor's
    for k in range(2, len(parameters)):
        part = slice(1 + k * m, 1 + (k + 1) * m)
        judged[part] = options.coverage * sigma[part] / max(float(np.max(np.abs(values[part]))), 1e-3)
    worst = int(np.argmax(judged))
    if rank < len(values) or judged[worst] > options.largest_relative_uncertainty:
        raise NotExcited(f'the motions do not excite {names[worst]} enough to fit it (expanded relative '
                         f'uncertainty {judged[worst]:.0%}, at most {options.largest_relative_uncertainty:.0%}): '
                         'record motions that accelerate, and move both ways, every motor')
    motors = {name: values[1 + k * m:1 + (k + 1) * m] for k, name in enumerate(parameters)}
    uncertainties = {name: sigma[1 + k * m:1 + (k + 1) * m] for k, name in enumerate(parameters)}
    return TwinFit(float(values[0]), float(sigma[0]), motors, uncertainties, residual_rms, len(target), stribeck)
