"""The plant simulator: a stand-in for the hardware, with failure injection.

Fidelity `rigid` is the twin's own model (noise-free, no mismatch); `elastic` has
spring–damper cables that can go slack, Coulomb friction, resolver noise and
quantisation, and the plant's parameters off the controller's by configured factors.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from cdpr_control.config import Section
from cdpr_control.dynamics import NO_FORCE
from cdpr_control.robot import Robot
from cdpr_control.statics import holding_torque_nm

from .elastic_model import ElasticCableRobot
from .rigid_model import RigidCableRobot

FIDELITIES = ('rigid', 'elastic')
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
    inertia_factor: float
    viscous_friction_factor: float
    static_friction_factor: float
    angle_noise_rad: float
    velocity_noise_rad_s: float
    counts_per_revolution: int
    seed: int

    @classmethod
    def from_section(cls, plant: Section, fidelity: str | None = None,
                     seed: int | None = None) -> 'PlantConfig':
        elastic = plant.section('elastic')
        mismatch = elastic.section('mismatch')
        resolver = elastic.section('resolver')
        fidelity = fidelity or plant.string('fidelity', choices=FIDELITIES)
        if fidelity not in FIDELITIES:
            raise plant.error('fidelity', f'must be one of {", ".join(FIDELITIES)}, got {fidelity!r}')
        substeps = (plant.integer('rigid_substeps', minimum=1) if fidelity == 'rigid'
                    else elastic.integer('substeps', minimum=1))
        return cls(
            fidelity=fidelity,
            substeps=substeps,
            axial_stiffness_n=elastic.number('cable_axial_stiffness_n', positive=True),
            damping_n_s_m=elastic.number('cable_damping_n_s_m', non_negative=True),
            coulomb_velocity_rad_s=elastic.number('coulomb_smoothing_rad_s', positive=True),
            mass_factor=mismatch.number('mass', positive=True),
            inertia_factor=mismatch.number('inertia', positive=True),
            viscous_friction_factor=mismatch.number('viscous_friction', non_negative=True),
            static_friction_factor=mismatch.number('static_friction', non_negative=True),
            angle_noise_rad=resolver.number('angle_noise_rad', non_negative=True),
            velocity_noise_rad_s=resolver.number('velocity_noise_rad_s', non_negative=True),
            counts_per_revolution=resolver.integer('counts_per_revolution', minimum=1),
            seed=plant.integer('seed', minimum=0) if seed is None else seed,
        )


def mismatched_robot(robot: Robot, config: PlantConfig) -> Robot:
    """The robot as the plant really is: the controller's model off by the factors."""
    motor = dataclasses.replace(
        robot.motor,
        inertia_kg_m2=robot.motor.inertia_kg_m2 * config.inertia_factor,
        viscous_friction_nm_s_rad=robot.motor.viscous_friction_nm_s_rad * config.viscous_friction_factor,
        static_friction_nm=robot.motor.static_friction_nm * config.static_friction_factor)
    return dataclasses.replace(robot, mass_kg=robot.mass_kg * config.mass_factor, motor=motor)


class PlantSimulator:
    """Steps the plant under commanded torques, breaks cables on schedule, measures θ, θ̇."""

    def __init__(self, robot: Robot, config: PlantConfig, start_position_m, failures=(), pushes=()):
        self.robot = robot
        self.config = config
        if config.fidelity == 'rigid':
            self.model = RigidCableRobot(robot, start_position_m, config.substeps)
        else:
            true_robot = mismatched_robot(robot, config)
            self.model = ElasticCableRobot(
                true_robot, start_position_m, config.substeps, config.axial_stiffness_n,
                config.damping_n_s_m, true_robot.motor.static_friction_nm,
                config.coulomb_velocity_rad_s)
        self.failures = sorted((float(t), int(c)) for t, c in failures)
        self.pushes = list(pushes)
        self.broken: list[int] = []
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
        """Break the 0-based `cable` now."""
        if cable not in self.broken:
            self.broken.append(cable)
            self.model.break_cables([cable])

    def measure(self):
        """Resolver angle (rad) and speed (rad/s) as the drive reports them."""
        angle = self.model.angle_rad
        speed = self.model.angular_velocity_rad_s
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
        return holding_torque_nm(self.robot, self.position_m, self.robot.cable_mask(self.broken))

    def applied_torque_nm(self, command_nm) -> np.ndarray:
        """The torque (N·m) the motors apply, and the drive reports as applied, for
        `command_nm`: never beyond their limit."""
        limit = self.robot.motor.torque_limit_nm
        # ndarray.clip: np.clip's dispatch costs twice as much on a few entries
        return np.asarray(command_nm, dtype=float).clip(-limit, limit)

    def step(self, torque_nm: np.ndarray, period_s: float) -> None:
        """Apply `torque_nm` (as the motors can) for one period; a failure due within it
        happens at its scheduled instant: the period is integrated up to it, then on
        without the cable, so a delay measured from that instant is the true one."""
        torque = self.applied_torque_nm(torque_nm)
        force = self.external_force_n()
        done_s = 0.0
        for time_s, cable in self.failures:
            if self.time_s - TICK_GRID_S <= time_s < self.time_s + period_s - TICK_GRID_S:
                before_s = time_s - self.time_s - done_s
                if before_s > TICK_GRID_S:
                    self.model.step(torque, before_s, force)
                    done_s += before_s
                self.inject_failure(cable)
        self.model.step(torque, period_s - done_s, force)
        self.time_s += period_s

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
