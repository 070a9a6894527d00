"""Joint-space PD + inverse-dynamics feed-forward controller and its modes (paper Fig. 2)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from cdpr_msgs_py.contract import FAULT, MODES, NOMINAL, RECOVERY_TENSION, SAFE_HOLD

from cdpr_control.control import tracking
from cdpr_control.config import Section
from cdpr_control.model.friction import FrictionModel
from cdpr_control.model.robot import Robot

# A sampled PD loop counts as stable with every pole inside this radius: 1 − a margin
# that keeps its slowest-decaying mode from ringing for hundreds of periods.
STABILITY_RADIUS = 0.98
GAIN_BISECTIONS = 30
# A control period is of milliseconds; beyond a second the sampled PD means nothing.
MAX_PERIOD_S = 1.0


@dataclass(frozen=True)
class PdGains:
    """Joint PD gains: stiffness (N·m/rad) and damping (N·m·s/rad).

    `tension_damping_nm_s_rad` damps the motors while tensions, not positions, are
    controlled (recovery phase 1): without it nothing brings the end-effector to rest.
    """

    stiffness_nm_rad: float
    damping_nm_s_rad: float
    tension_damping_nm_s_rad: float = 0.0

    @classmethod
    def from_bandwidth(cls, robot: Robot, frequency_hz: float, damping_ratio: float,
                       tension_damping_nm_s_rad: float = 0.0) -> 'PdGains':
        """Gains placing a joint loaded by J + m_e ρ² at `frequency_hz` with `damping_ratio`."""
        inertia = robot.motor.inertia_kg_m2 + robot.mass_kg * robot.motor.drum_radius_m ** 2
        omega = 2.0 * np.pi * frequency_hz
        return cls(inertia * omega ** 2, 2.0 * damping_ratio * inertia * omega,
                   tension_damping_nm_s_rad)

    @classmethod
    def from_section(cls, robot: Robot, control: Section) -> 'PdGains':
        """The configured gains (`settled`)."""
        return cls.settled(robot, control)[0]

    @classmethod
    def settled(cls, robot: Robot, control: Section) -> tuple['PdGains', float, bool]:
        """The configured gains, the natural frequency they place a loaded joint at (Hz),
        and whether that frequency was derived rather than the one configured. The PD,
        sampled every `period_s`, must be stable on a motor carrying its share of the
        load *and* on a motor alone: on the elastic plant (and a real drive) the cable is
        a spring, and the motor's own inertia sets the fastest mode. A
        `pd_natural_frequency_hz` the file sets that is not is a ConfigError naming the
        highest it may be; the default (the paper's), where it is not, gives way to that
        highest stable frequency."""
        frequency = control.number('pd_natural_frequency_hz', positive=True)
        damping = control.number('pd_damping_ratio', positive=True)
        period = control.number('period_s', positive=True, maximum=MAX_PERIOD_S)
        if frequency >= 0.5 / period and not control.is_default('pd_natural_frequency_hz'):
            raise control.error('pd_natural_frequency_hz', f'must be below the Nyquist frequency of '
                                f'period_s {period:g} s ({0.5 / period:g} Hz), got {frequency!r}')
        tension_damping = control.number('recovery_tension_damping_nm_s_rad', non_negative=True)
        gains = cls.from_bandwidth(robot, frequency, damping, tension_damping)
        if gains.sampled_stable(robot, period):
            return gains, frequency, False
        highest = cls.highest_stable_frequency_hz(robot, frequency, damping, period)
        if highest <= 0.0:
            # K_p = K_d = 0 would be no control at all: the robot cannot be run so
            motor = robot.motor
            raise control.error('pd_natural_frequency_hz', (
                f'no frequency is stable at a period of {period:g} s with pd_damping_ratio {damping:g} on this '
                f'robot\'s motors: a motor alone (J = {motor.inertia_kg_m2:g} kg·m²) is '
                f'{robot.mass_kg * motor.drum_radius_m ** 2 / motor.inertia_kg_m2:.0f} times lighter than its '
                f'share of the end-effector (m ρ² = {robot.mass_kg * motor.drum_radius_m ** 2:.3g} kg·m²), '
                f'whatever the period (the ratio sets it): heavier motors (or a gear), smaller drums or a lighter '
                f'end-effector'))
        if control.is_default('pd_natural_frequency_hz'):
            return cls.from_bandwidth(robot, highest, damping, tension_damping), highest, True
        raise control.error('pd_natural_frequency_hz', (
            f'{frequency:g} Hz is not stable at a period of {period:g} s on this robot\'s '
            f'motors (inertia {robot.motor.inertia_kg_m2:g} kg·m² alone): at most '
            f'{highest:.2f} Hz with pd_damping_ratio {damping:g}'))

    def natural_frequency_hz(self, robot: Robot) -> float:
        """The frequency these gains place the loaded joint at (from_bandwidth's inverse)."""
        inertia = robot.motor.inertia_kg_m2 + robot.mass_kg * robot.motor.drum_radius_m ** 2
        return float(np.sqrt(self.stiffness_nm_rad / inertia) / (2.0 * np.pi))

    @classmethod
    def highest_stable_frequency_hz(cls, robot: Robot, unstable_hz: float, damping: float,
                                    period_s: float) -> float:
        """The highest natural frequency below `unstable_hz` whose sampled PD is stable
        (bisection, from below: the value returned is stable)."""
        low, high = 0.0, unstable_hz
        for _ in range(GAIN_BISECTIONS):
            middle = 0.5 * (low + high)
            low, high = ((middle, high) if cls.from_bandwidth(robot, middle, damping)
                         .sampled_stable(robot, period_s) else (low, middle))
        return low

    def sampled_stable(self, robot: Robot, period_s: float) -> bool:
        """The PD held over each period (zero-order hold) keeps a motor of inertia J,
        and one of J + m_e ρ², from diverging: the spectral radius of the sampled loop
        x⁺ = A x, x = (θ, θ̇), is below 1 with a margin."""
        motor = robot.motor
        for inertia in (motor.inertia_kg_m2, motor.inertia_kg_m2 + robot.mass_kg * motor.drum_radius_m ** 2):
            a = self.stiffness_nm_rad * period_s ** 2 / inertia
            b = self.damping_nm_s_rad * period_s / inertia
            loop = np.array([[1.0 - a / 2.0, period_s * (1.0 - b / 2.0)],
                             [-a / period_s, 1.0 - b]])
            if np.max(np.abs(np.linalg.eigvals(loop))) >= STABILITY_RADIUS:
                return False
        return True


@dataclass
class JointReference:
    """What the controller tracks: θ_d (rad), θ̇_d (rad/s) and the feed-forward c_ID (N·m)."""

    angle_rad: np.ndarray
    angular_velocity_rad_s: np.ndarray
    feedforward_nm: np.ndarray

    def at_rest(self) -> 'JointReference':
        return JointReference(self.angle_rad.copy(), np.zeros_like(self.angular_velocity_rad_s),
                              self.feedforward_nm.copy())


def command_lead_periods(drive_delay_s: float, period_s: float) -> float:
    """How far after its tick (control periods) a command acts, on average over the period
    it is held: the drives' delay (fdi.drive_delay_s), then half a period."""
    return drive_delay_s / period_s + 0.5


class JointController:
    """c = c_ID + K_p (θ_d − θ) + K_d (θ̇_d − θ̇), within the torque limit, per mode.

    NOMINAL and RECOVERY_MOVE track a joint reference (the trajectory's, or the
    recovery's); RECOVERY_TENSION applies tension setpoints t as
    c = −ρ t + b θ̇ + f_c tanh(θ̂ / v) − D max(θ̇, 0) (friction compensated, damping D
    against paying out), θ̂ the speed extrapolated `command_lead_periods` ahead from the
    last two measured: the Coulomb term, a step of 2 f_c where a drum reverses, is meant
    for the period the command acts over, which a drive's delay puts after the tick. Given
    the old direction's compensation until then, a drum reversing under a drive 1–4 ms
    late took up to 2 f_c / ρ (5.4 N on the paper robot) off its cable's tension, and a
    lightly loaded cable went slack for a few periods (docs/recovery-tensions.md);
    SAFE_HOLD holds the last tracked reference at rest (the recovery's end). FAULT, and
    SAFE_HOLD entered from tension control, hold the drums where they are at that instant,
    with the torque last applied (within the cables' tension bounds) as feed-forward: no
    jump in torque, and no return to a reference tracked before the failure, which would
    pay out or wind in the remaining cables far from where they hang now. A motor whose
    cable is broken gets zero torque in every mode: freed of its load it would ring under
    loaded gains.
    """

    def __init__(self, robot: Robot, gains: PdGains, friction: FrictionModel | None = None,
                 command_lead_periods: float = 0.0):
        self.robot = robot
        self.gains = gains
        self.friction = friction or FrictionModel(0.0, 1.0)
        self.command_lead_periods = command_lead_periods
        self.previous_speed: np.ndarray | None = None
        self.torque_limit_nm = robot.motor.torque_limit_nm
        self.mode = NOMINAL
        self.broken_mask = np.zeros(robot.cable_count)    # 1.0 for a broken cable, as the tracking kernel takes it
        self.kernel = tracking.kernel().load_all()
        self.tension_setpoint_n: np.ndarray | None = None
        self.hold: JointReference | None = None
        self.tracked: JointReference | None = None
        self.applied_nm = np.zeros(robot.cable_count)

    @staticmethod
    def check_mode(mode: str) -> None:
        """ValueError for a mode that is none of the contract's."""
        if mode not in MODES:
            raise ValueError(f'unknown mode {mode!r}; one of {", ".join(MODES)}')

    def set_mode(self, mode: str) -> None:
        self.check_mode(mode)
        self.mode = mode

    def set_broken(self, cables) -> None:
        """Mark the 0-based `cables` as broken (their motors get zero torque from now on)."""
        for index in cables:
            self.broken_mask[index] = 1.0

    @property
    def broken(self) -> np.ndarray:
        """Which motors' cables are broken (bool per motor)."""
        return self.broken_mask != 0.0

    def set_tension_setpoint(self, tensions_n: np.ndarray) -> None:
        self.tension_setpoint_n = np.asarray(tensions_n, dtype=float)

    def command(self, angle_rad, angular_velocity_rad_s, reference: JointReference | None) -> np.ndarray:
        """Motor torques c (N·m) for the measured θ, θ̇ in the current mode."""
        speed = np.array(angular_velocity_rad_s, dtype=float)
        previous = speed if self.previous_speed is None else self.previous_speed
        self.previous_speed = speed
        if self.mode == RECOVERY_TENSION and self.tension_setpoint_n is not None:
            self.tracked = self.hold = None
            torque = self.tension_control(speed, previous)
        else:
            if self.mode in (SAFE_HOLD, FAULT) or reference is None:
                if self.hold is None:
                    self.hold = self.hold_point(angle_rad, reference)
                reference = self.hold
            else:
                self.hold = None
                self.tracked = reference
            torque = np.empty(self.robot.cable_count)
            self.kernel.tracking_torques(
                self.gains.stiffness_nm_rad, self.gains.damping_nm_s_rad, self.torque_limit_nm,
                np.ascontiguousarray(angle_rad, dtype=float), np.ascontiguousarray(reference.angle_rad, dtype=float),
                speed, np.ascontiguousarray(reference.angular_velocity_rad_s, dtype=float),
                np.ascontiguousarray(reference.feedforward_nm, dtype=float), self.broken_mask, torque)
        self.applied_nm = torque
        return torque

    def tension_control(self, speed: np.ndarray, previous_speed: np.ndarray) -> np.ndarray:
        """RECOVERY_TENSION's torques (N·m), within the limit, 0 on broken cables' motors."""
        motor = self.robot.motor
        ahead = speed + self.command_lead_periods * (speed - previous_speed)
        # Damping only resists paying out: on a cable winding in it would lower the
        # tension, and a cable that loses its tension goes slack.
        torque = (-motor.drum_radius_m * self.tension_setpoint_n + self.friction.torque_nm(ahead)
                  + motor.viscous_friction_nm_s_rad * speed
                  - self.gains.tension_damping_nm_s_rad * np.maximum(speed, 0.0))
        # ndarray.clip: np.clip's dispatch costs twice as much on a few entries
        torque = torque.clip(-self.torque_limit_nm, self.torque_limit_nm)
        torque[self.broken] = 0.0
        return torque

    def hold_point(self, angle_rad, reference: JointReference | None) -> JointReference:
        """What SAFE_HOLD or FAULT holds from now on (see the class docstring)."""
        if self.mode == SAFE_HOLD and (self.tracked or reference) is not None:
            return (self.tracked or reference).at_rest()
        radius = self.robot.motor.drum_radius_m
        feedforward = self.applied_nm.clip(-radius * self.robot.tension_max_n,
                                           -radius * self.robot.tension_min_n)
        feedforward[self.broken] = 0.0
        return JointReference(np.array(angle_rad, dtype=float), np.zeros(self.robot.cable_count),
                              feedforward)
