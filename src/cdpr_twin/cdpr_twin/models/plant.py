"""The plant simulator: a stand-in for the hardware, with failure injection.

Fidelity `rigid` is the twin's own model (noise-free, no mismatch); `elastic` has
spring–damper cables that can go slack, Coulomb friction, resolver noise and
quantisation, and the plant's parameters off the controller's by configured factors;
`field` is the elastic plant with a real drive train and the paper's test rig (§4):
the command's transport delay, the torque loop's lag and noise, the drive's filtered
speed estimate, breakaway friction, swivel pulleys, Dyneema cables, and the
electromagnet that opens cable 4 (its mass on the cable, its drum-side half left
hanging once open).
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from cdpr_control.config import Section
from cdpr_control.point_mass.dynamics import NO_FORCE
from cdpr_control.model.robot import Robot

from cdpr_twin.models.elastic_model import DriveTrain, ElasticCableRobot
from cdpr_twin.models.elastic_platform import ElasticPlatform
from cdpr_control.kernels import KERNELS
from cdpr_twin.models.rigid_model import RigidModel

FIDELITIES = ('rigid', 'elastic', 'field')
# Instants closer than this (s) are one: summed 2 ms periods drift by ~1e-13 s.
TICK_GRID_S = 1e-9


@dataclass(frozen=True)
class Push:
    """A force `force_n` (N, world frame) on the end-effector for `duration_s` (s) from
    `start_s` (s): a hand pushing it, a brief contact with an obstacle. Applied on the
    control periods that start within it."""

    start_s: float
    duration_s: float
    force_n: tuple[float, float, float]

    def acts_at(self, time_s: float) -> bool:
        return self.start_s - TICK_GRID_S <= time_s < self.start_s + self.duration_s - TICK_GRID_S


def settled_pushes(run: Section) -> list[Push]:
    """The pushes of a settled run's `run` section: `push_start_s`, `push_duration_s` and
    `push_force_n` (three numbers a push, flat: ROS parameters are flat arrays)."""
    starts, durations = run.raw('push_start_s', []), run.raw('push_duration_s', [])
    forces = run.raw('push_force_n', [])
    if not (len(starts) == len(durations) and 3 * len(starts) == len(forces)):
        raise run.error('push_force_n', f'must hold 3 numbers per push start, got {forces!r} for {starts!r}')
    forces = run.vector('push_force_n', len(forces)).reshape(-1, 3) if forces else []
    return [Push(float(start), float(duration), tuple(force.tolist()))
            for start, duration, force in zip(starts, durations, forces)]


@dataclass(frozen=True)
class PlantConfig:
    fidelity: str
    substeps: int
    axial_stiffness_n: float
    damping_n_s_m: float
    coulomb_velocity_rad_s: float
    mass_factor: float
    # per motor: a real drive's values differ from one motor to the next
    inertia_factors: tuple[float, ...]
    viscous_friction_factors: tuple[float, ...]
    static_friction_factors: tuple[float, ...]
    angle_noise_rad: float
    velocity_noise_rad_s: float
    counts_per_revolution: int
    seed: int
    kernel: str = 'compiled'    # of the elastic sub-steps: elastic_substeps.KERNELS
    # The field fidelity's drive train and rig (no effect on the others).
    drive: DriveTrain = DriveTrain()
    command_delay_s: float = 0.0
    torque_noise_nm: float = 0.0
    electromagnet_cable: int | None = None    # 0-based
    electromagnet_mass_kg: float = 0.0
    electromagnet_drum_side_kg: float = 0.0
    electromagnet_holding_force_n: float = 0.0
    electromagnet_release_time_constant_s: float = 0.0
    electromagnet_spring_force_n: float = 0.0

    @classmethod
    def from_section(cls, plant: Section, cable_count: int, fidelity: str | None = None,
                     seed: int | None = None) -> 'PlantConfig':
        """The `plant` section of a robot with `cable_count` cables (and motors), at
        `fidelity` and `seed` (default: the section's)."""
        elastic = plant.section('elastic')
        mismatch = elastic.section('mismatch')
        resolver = elastic.section('resolver')
        field = plant.section('field')
        magnet = field.section('electromagnet')
        fidelity = fidelity or plant.string('fidelity', choices=FIDELITIES)
        if fidelity not in FIDELITIES:
            raise plant.error('fidelity', f'must be one of {", ".join(FIDELITIES)}, got {fidelity!r}')
        # Every value is read whatever the fidelity, so that each is checked and bounded.
        substeps = {'rigid': plant.integer('rigid_substeps', minimum=1),
                    'elastic': elastic.integer('substeps', minimum=1)}
        stiffness = {'elastic': elastic.number('cable_axial_stiffness_n', positive=True),
                     'field': field.number('cable_axial_stiffness_n', positive=True)}
        damping = {'elastic': elastic.number('cable_damping_n_s_m', non_negative=True),
                   'field': field.number('cable_damping_n_s_m', non_negative=True)}
        magnet_kg = magnet.number('mass_kg', non_negative=True)
        field_values = dict(
            drive=DriveTrain(
                torque_lag_s=field.number('torque_lag_s', non_negative=True, maximum=0.1),
                speed_filter_s=field.number('speed_filter_s', non_negative=True, maximum=0.1),
                breakaway_friction_nm=field.number('breakaway_friction_nm', non_negative=True),
                stribeck_speed_rad_s=field.number('stribeck_speed_rad_s', positive=True),
                pulley_radius_m=field.number('pulley_radius_m', non_negative=True, maximum=0.1)),
            command_delay_s=field.number('command_delay_s', non_negative=True, maximum=0.1),
            torque_noise_nm=field.number('torque_noise_nm', non_negative=True),
            electromagnet_cable=magnet.integer('cable', minimum=1) - 1,
            electromagnet_mass_kg=magnet_kg,
            electromagnet_drum_side_kg=magnet.number('drum_side_mass_kg', non_negative=True,
                                                     maximum=magnet_kg),
            electromagnet_holding_force_n=magnet.number('holding_force_n', positive=True),
            electromagnet_release_time_constant_s=magnet.number(
                'release_time_constant_s', positive=True, maximum=10.0),
            electromagnet_spring_force_n=magnet.number('spring_force_n', non_negative=True),
        )
        cables = 'field' if fidelity == 'field' else 'elastic'
        return cls(
            fidelity=fidelity,
            substeps=substeps['rigid' if fidelity == 'rigid' else 'elastic'],
            axial_stiffness_n=stiffness[cables],
            damping_n_s_m=damping[cables],
            coulomb_velocity_rad_s=elastic.number('coulomb_smoothing_rad_s', positive=True),
            mass_factor=mismatch.number('mass', positive=True),
            inertia_factors=tuple(mismatch.per_cable('inertia', cable_count, positive=True).tolist()),
            viscous_friction_factors=tuple(
                mismatch.per_cable('viscous_friction', cable_count, non_negative=True).tolist()),
            static_friction_factors=tuple(
                mismatch.per_cable('static_friction', cable_count, non_negative=True).tolist()),
            angle_noise_rad=resolver.number('angle_noise_rad', non_negative=True),
            velocity_noise_rad_s=resolver.number('velocity_noise_rad_s', non_negative=True),
            counts_per_revolution=resolver.integer('counts_per_revolution', minimum=1),
            seed=plant.integer('seed', minimum=0) if seed is None else seed,
            kernel=elastic.string('kernel', choices=KERNELS),
            **(field_values if fidelity == 'field' else {}),
        )


def mismatched_robot(robot: Robot, config: PlantConfig) -> Robot:
    """The robot as the plant carries it: the end-effector's mass off by its factor, the
    electromagnet (on its cable next to the end-effector) carried with it. Its `motor` is
    the model's, one for all; the true motors, each its own, come from `true_motors`."""
    return dataclasses.replace(robot, mass_kg=robot.mass_kg * config.mass_factor
                               + config.electromagnet_mass_kg)


def true_motors(robot: Robot, config: PlantConfig) -> np.ndarray:
    """The plant's motors as the elastic models take them, a column per motor: rows of
    the inertia J_i (kg·m²), the viscous friction b_i (N·m·s/rad) and the Coulomb
    friction f_c,i (N·m), the model's values times that motor's factors."""
    motor = robot.motor
    return np.array([motor.inertia_kg_m2 * np.array(config.inertia_factors),
                     motor.viscous_friction_nm_s_rad * np.array(config.viscous_friction_factors),
                     motor.static_friction_nm * np.array(config.static_friction_factors)])


def drive_train(robot: Robot, config: PlantConfig) -> DriveTrain:
    """The plant's drive train, with the electromagnet's drum-side half as the mass its
    cable leaves hanging on the drum when it opens."""
    if config.electromagnet_cable is None:
        return config.drive
    if not 0 <= config.electromagnet_cable < robot.cable_count:
        raise ValueError(f'plant.field.electromagnet.cable {config.electromagnet_cable + 1}: '
                         f'the robot has cables 1..{robot.cable_count}')
    hanging = [0.0] * robot.cable_count
    hanging[config.electromagnet_cable] = config.electromagnet_drum_side_kg
    return dataclasses.replace(config.drive, hanging_mass_kg=tuple(hanging))


def point_mass_elastic_model(robot: Robot, config: PlantConfig, position_m, orientation):
    """A point-mass robot's elastic model, with the field fidelity's drive train."""
    return ElasticCableRobot(
        mismatched_robot(robot, config), true_motors(robot, config), position_m, config.substeps,
        config.axial_stiffness_n, config.damping_n_s_m, config.coulomb_velocity_rad_s,
        drive_train(robot, config), config.kernel)


def platform_elastic_model(robot: Robot, config: PlantConfig, position_m, orientation):
    """A platform robot's elastic model (docs/platform.md); it has no field fidelity."""
    if config.fidelity == 'elastic':
        return ElasticPlatform(mismatched_robot(robot, config), true_motors(robot, config), position_m,
                               orientation, config)
    raise ValueError(f'plant.fidelity {config.fidelity}: the field plant models the paper\'s rig, a point '
                     'mass; a platform runs on the rigid or the elastic plant')


# The elastic model of each body (Body.kind). Not the body's to supply, as it does its rigid
# model's part: the point mass's carries the field rig's drive train and runs this room's
# elastic_substeps, which the body rooms may not import.
ELASTIC_MODELS = {'point_mass': point_mass_elastic_model, 'platform': platform_elastic_model}


class PlantSimulator:
    """Steps the plant under commanded torques, breaks cables on schedule, measures θ, θ̇.
    A platform robot starts at `start_orientation` (its home orientation when None)."""

    def __init__(self, robot: Robot, config: PlantConfig, start_position_m, failures=(), pushes=(),
                 start_orientation=None):
        self.robot = robot
        self.config = config
        # the twin's rigid model, or the body's elastic one
        self.model = (RigidModel(robot, start_position_m, start_orientation, config.substeps)
                      if config.fidelity == 'rigid'
                      else ELASTIC_MODELS[robot.body.kind](robot, config, start_position_m, start_orientation))
        self.failures = sorted((float(t), int(c)) for t, c in failures)
        self.pushes = list(pushes)
        self.broken: list[int] = []
        # 0-based cable → when it really parted (s); when its electromagnet was switched off.
        self.broken_at_s: dict[int, float] = {}
        self.switched_off_s: dict[int, float] = {}
        self.elapsed_s = 0.0    # into the current period (s)
        # Commands sent but not yet applied by the drives: (due time s, torque N·m). Until
        # the first arrives, they hold the load as they did before the run.
        self.commands_in_flight: list[tuple[float, np.ndarray]] = []
        self.torque_nm = self.holding_torque_nm()
        self.external_force = NO_FORCE   # the pushes' sum over the current period (N)
        self.time_s = 0.0
        self.rng = np.random.default_rng(config.seed)
        self.angle_step_rad = 2.0 * np.pi / config.counts_per_revolution

    def lock_drums(self, locked: bool) -> None:
        """Engage (True) or release the motor brakes: locked drums neither pay out nor wind."""
        self.model.drums_locked = locked

    @property
    def drums_locked(self) -> bool:
        return self.model.drums_locked

    def inject_failure(self, cable: int) -> None:
        """Break the 0-based `cable` now; the electromagnet's cable opens once the
        magnet, switched off now, no longer holds its tension (`opens`)."""
        if cable == self.config.electromagnet_cable:
            self.switched_off_s.setdefault(cable, self.time_s + self.elapsed_s)
        else:
            self.break_cable(cable)

    def break_cable(self, cable: int) -> None:
        """The 0-based `cable` parts now (the instant is kept in `broken_at_s`)."""
        if cable not in self.broken:
            self.broken.append(cable)
            self.broken_at_s[cable] = self.time_s + self.elapsed_s
            self.model.break_cables([cable])

    def opens(self, cable: int) -> bool:
        """Whether the electromagnet switched off on `cable` lets go now: its holding
        force, decaying from F_0 as exp(−t / T_r) since switch-off, no longer exceeds the
        cable's tension plus its separating spring's force."""
        config = self.config
        holding = config.electromagnet_holding_force_n * math.exp(
            -(self.time_s + self.elapsed_s - self.switched_off_s[cable])
            / config.electromagnet_release_time_constant_s)
        return holding < self.model.spring_tension_n[cable] + config.electromagnet_spring_force_n

    def measure(self):
        """Resolver angle (rad) and speed (rad/s) as the drive reports them."""
        angle = self.model.angle_rad
        speed = (self.model.speed_estimate_rad_s if self.config.drive.speed_filter_s
                 else self.model.angular_velocity_rad_s)
        if self.config.fidelity == 'rigid':
            return angle.copy(), speed.copy()
        angle_noise, speed_noise = self.rng.standard_normal((2, self.robot.cable_count)).tolist()
        # Plain floats: on m entries numpy's per-call cost exceeds the arithmetic. round()
        # rounds half to even, as np.round does.
        step, angle_sigma, speed_sigma = (self.angle_step_rad, self.config.angle_noise_rad,
                                          self.config.velocity_noise_rad_s)
        return (np.array([round((theta + angle_sigma * n) / step) * step
                          for theta, n in zip(angle.tolist(), angle_noise)]),
                np.array([w + speed_sigma * n for w, n in zip(speed.tolist(), speed_noise)]))

    def holding_torque_nm(self) -> np.ndarray:
        """c = −ρ t (N·m), t the static tensions of the cables still attached where the
        end-effector is: what the drive holds the load with before its first command."""
        return self.robot.body.holding_torques_nm(self.robot, self.position_m, self.model.orientation,
                                                  self.robot.cable_mask(self.broken))

    def applied_torque_nm(self, command_nm) -> np.ndarray:
        """The torque (N·m) the motors apply, and the drive reports as applied, for
        `command_nm`: never beyond their limit."""
        limit = self.robot.motor.torque_limit_nm
        # as clip does it (NaN stays NaN), at a third of ndarray.clip's cost on a few entries
        return np.minimum(np.maximum(np.asarray(command_nm, dtype=float), -limit), limit)

    def step(self, torque_nm: np.ndarray, period_s: float) -> None:
        """Send `torque_nm` to the drives and step one period. The drives apply it (as the
        motors can, with their noise) `command_delay_s` later; a failure due within the
        period happens at its scheduled instant: the period is integrated up to each such
        instant, so a delay measured from a failure is the true one."""
        torque = self.applied_torque_nm(torque_nm)
        self.external_force = self.external_force_n()
        if self.config.torque_noise_nm:
            torque = torque + self.config.torque_noise_nm * self.rng.standard_normal(torque.size)
        start, end = self.time_s, self.time_s + period_s
        self.commands_in_flight.append((start + self.config.command_delay_s, torque))
        events = sorted([(at, 0, cable) for at, cable in self.failures
                         if start - TICK_GRID_S <= at < end - TICK_GRID_S]
                        + [(due, 1, i) for i, (due, _) in enumerate(self.commands_in_flight)
                           if due < end - TICK_GRID_S])
        arrived = [i for _, kind, i in events if kind == 1]
        self.elapsed_s = 0.0    # into the period, where advance() has integrated to
        done_s = 0.0    # of the period (offsets, not instants: summing instants drifts)
        for at, kind, what in events:
            before_s = at - start - done_s
            if before_s > TICK_GRID_S:
                self.advance(before_s, period_s)
                done_s += before_s
            if kind == 0:
                self.inject_failure(what)
            else:
                self.torque_nm = self.commands_in_flight[what][1]
        self.commands_in_flight = [command for i, command in enumerate(self.commands_in_flight)
                                   if i not in arrived]
        self.advance(period_s - done_s, period_s)
        self.time_s += period_s
        self.elapsed_s = 0.0

    def advance(self, duration_s: float, period_s: float) -> None:
        """Integrate `duration_s` under the torque the drives apply: on the model's own
        sub-steps, but for a delayed command's part of a period, which gets its share,
        and while an electromagnet lets go, which is checked on every sub-step."""
        releasing = [cable for cable in self.switched_off_s if cable not in self.broken]
        force = self.external_force
        if not (releasing or self.config.command_delay_s):
            self.model.step(self.torque_nm, duration_s, external_force_n=force)
            self.elapsed_s += duration_s
            return
        substeps = max(1, round(duration_s / period_s * self.config.substeps))
        if not releasing:
            self.model.step(self.torque_nm, duration_s, substeps, force)
            self.elapsed_s += duration_s
            return
        for _ in range(substeps):
            for cable in releasing:
                if cable not in self.broken and self.opens(cable):
                    self.break_cable(cable)
            self.model.step(self.torque_nm, duration_s / substeps, 1, force)
            self.elapsed_s += duration_s / substeps

    def external_force_n(self) -> tuple[float, float, float]:
        """The pushes acting now, summed (N)."""
        acting = [push.force_n for push in self.pushes if push.acts_at(self.time_s)]
        return tuple(float(sum(axis)) for axis in zip(*acting)) if acting else NO_FORCE

    @property
    def position_m(self) -> np.ndarray:
        return self.model.position_m

    @property
    def tension_n(self) -> np.ndarray:
        return self.model.tension_n

    @property
    def angular_velocity_rad_s(self) -> np.ndarray:
        """The drums' true angular velocities (rad/s): zero while braked."""
        return self.model.angular_velocity_rad_s

    @property
    def orientation(self) -> np.ndarray:
        """The platform's orientation (unit quaternion); the identity for a point mass."""
        return self.model.orientation
