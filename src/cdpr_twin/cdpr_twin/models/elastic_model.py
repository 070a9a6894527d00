"""Elastic-cable robot simulation: the plant's `elastic` and `field` fidelities.

Each cable is a unilateral spring–damper of stiffness EA / l between its drum and the
end-effector (it can go slack, never push); motors carry viscous and Coulomb friction.
Integrated by semi-implicit Euler with sub-steps inside each control period.

The `field` fidelity adds what a real drive train does (`DriveTrain`): the torque loop's
lag, the drive's filtered speed estimate, breakaway friction above Coulomb near
standstill (Stribeck), swivel pulleys whose wrap changes a cable's length with its
direction, and a mass left hanging on a cable's drum side once it breaks (the
electromagnet's half). Its defaults add nothing: that is the `elastic` fidelity.

The sub-steps are `elastic_substeps.integrate`: plain Python, or compiled by numba when
installed (`kernel`, the plant's `plant.elastic.kernel`).
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from math import exp

import numpy as np

from cdpr_control.point_mass.kinematics import cable_vectors
from cdpr_control.model.robot import Robot
from cdpr_control.geometry.rotation import IDENTITY
from cdpr_control.point_mass.dynamics import NO_FORCE
from cdpr_control.point_mass.statics import static_tensions

from cdpr_twin.models.elastic_substeps import kernel as substep_kernel


@dataclass(frozen=True)
class DriveTrain:
    """A real drive train's effects on the elastic plant; the defaults add none."""

    torque_lag_s: float = 0.0            # time constant of the drive's torque loop
    speed_filter_s: float = 0.0          # time constant of the drive's speed estimate
    breakaway_friction_nm: float = 0.0   # friction at standstill beyond Coulomb's
    stribeck_speed_rad_s: float = 1.0    # speed over which that excess fades
    pulley_radius_m: float = 0.0         # swivel pulley at each exit point (0: a point)
    # Per cable: the mass (kg) left on its drum side once it breaks; () for none.
    hanging_mass_kg: tuple[float, ...] = ()


def swivel_pulley_length_m(exit_points_m: np.ndarray, position_m: np.ndarray,
                           radius_m: float) -> np.ndarray:
    """Length (m) of each cable from where it meets its swivel pulley to the end-effector.

    The cable rises vertically along the pulley's swivel axis (through the exit point A_i),
    wraps the pulley, of radius r, whose plane turns with the cable about that axis, and
    leaves it on the tangent towards the end-effector: r β + sqrt(|C − p|² − r²), C the
    pulley centre (r from the axis towards p, at A_i's height) and β the wrap angle.
    """
    r = radius_m
    rel = position_m - exit_points_m
    horizontal = np.hypot(rel[:, 0], rel[:, 1]) - r    # from C towards p, in the pulley plane
    vertical = rel[:, 2]                               # below C: negative
    centre_distance = np.hypot(horizontal, vertical)
    # Wrap from the top of the incoming vertical (angle π in the pulley plane) over the
    # pulley to the tangent point, at the angle of p plus arccos(r / |C − p|).
    wrap = np.pi - np.arctan2(vertical, horizontal) - np.arccos(r / centre_distance)
    return r * wrap + np.sqrt(centre_distance ** 2 - r * r)


class ElasticCableRobot:
    """State p, ṗ (m, m/s) and θ, θ̇ (rad, rad/s); tensions τ (N) follow from it.

    A step replaces the state arrays rather than writing into them.
    """

    # a point mass has no orientation to tell: the identity, as a platform's model has one
    orientation = IDENTITY

    def __init__(self, robot: Robot, motor_values, position_m, substeps: int, axial_stiffness_n: float,
                 damping_n_s_m: float, coulomb_velocity_rad_s: float, drive: DriveTrain = DriveTrain(),
                 kernel: str = 'compiled'):
        """`robot` as the plant carries it, its motors `motor_values`: rows of each one's
        inertia J_i (kg·m²), viscous friction b_i (N·m·s/rad) and Coulomb friction f_c,i
        (N·m) (plant.true_motors); robot.motor gives the drums' radius."""
        self.robot = robot
        self.kernel = substep_kernel(kernel).load_all()
        self.drive = drive
        self.substeps = int(substeps)
        self.axial_stiffness_n = axial_stiffness_n
        self.damping_n_s_m = damping_n_s_m
        self.coulomb_velocity_rad_s = coulomb_velocity_rad_s
        self.position_m = np.array(position_m, dtype=float)
        self.velocity_m_s = np.zeros(3)
        # A brake holds every drum still (θ̇ = 0), whatever the torque.
        self.drums_locked = False
        # Rows per cable, the sub-steps' inputs: the torque commanded (N·m), 1 while
        # attached, the mass (kg) hanging on its drum once broken, the pulleys' length
        # change (m).
        self.inputs = np.zeros((4, robot.cable_count))
        self.inputs[1] = 1.0
        # Start in equilibrium: each cable stretched by its static tension.
        tension = np.maximum(static_tensions(robot, self.position_m, self.attached), 0.0)
        _, d = cable_vectors(robot.exit_points_m, self.position_m)
        unstretched = d / (1.0 + tension / axial_stiffness_n)
        radius = robot.motor.drum_radius_m
        self.tension_n = tension
        # Rows per motor, replaced by each step: θ (rad), θ̇ (rad/s), the spring–damper
        # tension τ (N) of the current state (each sub-step ends by evaluating it for the
        # next), and the drive's speed estimate (rad/s) and the torque its loop applies
        # (N·m), which lag the true speed and the command.
        self.motors = np.array([(unstretched - robot.cable_length_offset_m) / radius,
                                np.zeros(robot.cable_count), np.zeros(robot.cable_count),
                                np.zeros(robot.cable_count), -radius * tension])
        # The pulleys lengthen each cable by their wrap; the cable lengths were homed at
        # the start, so only the change since then is felt (m, per control period).
        self.start_pulley_excess_m = self.pulley_excess_m()
        # Per cable, as the kernel takes them: exit point A_i and length offset l_i0 (m),
        # its motor's J_i, b_i and f_c,i.
        self.cables = self.kernel.view(np.array([*robot.exit_points_m.T, robot.cable_length_offset_m,
                                                 *np.asarray(motor_values, dtype=float)]))
        # The net force Σ τ_i u_i (N) of the tensions on the end-effector.
        self.cable_force_n = (0.0, 0.0, 0.0)
        # the kernel's constants, and what they were made for (substep_constants)
        self.constants: tuple = ()
        self.constants_key: tuple | None = None
        self.evaluate_tensions()

    @property
    def attached(self) -> np.ndarray:
        """Which cables are still attached (bool per cable)."""
        return self.inputs[1] != 0.0

    @property
    def angle_rad(self) -> np.ndarray:
        return self.motors[0]

    @property
    def angular_velocity_rad_s(self) -> np.ndarray:
        return self.motors[1]

    @property
    def spring_tension_n(self) -> np.ndarray:
        return self.motors[2]

    @property
    def speed_estimate_rad_s(self) -> np.ndarray:
        return self.motors[3]

    def pulley_excess_m(self) -> np.ndarray:
        """How much longer (m) each cable is over its pulley than to the exit point."""
        if not self.drive.pulley_radius_m:
            return np.zeros(self.robot.cable_count)
        exits = self.robot.exit_points_m
        return (swivel_pulley_length_m(exits, self.position_m, self.drive.pulley_radius_m)
                - cable_vectors(exits, self.position_m)[1])

    def break_cables(self, cables) -> None:
        for index in cables:
            self.inputs[1, index] = 0.0
            if self.drive.hanging_mass_kg:
                # The mass was carried at the end-effector's end of the cable: it leaves it.
                self.inputs[2, index] = self.drive.hanging_mass_kg[index]
                self.robot = dataclasses.replace(
                    self.robot, mass_kg=self.robot.mass_kg - self.drive.hanging_mass_kg[index])
        self.evaluate_tensions()

    def evaluate_tensions(self) -> None:
        """The spring–damper tensions of the current state, for the next sub-step."""
        self.integrate(np.zeros(self.robot.cable_count), 0.0, 1, NO_FORCE)

    def step(self, torque_nm: np.ndarray, period_s: float, substeps: int | None = None,
             external_force_n=NO_FORCE) -> None:
        """Apply `torque_nm` (N·m) for `period_s` (s), in `substeps` (default: the
        model's) sub-steps, and `external_force_n` (N, world frame) on the end-effector.
        The pulleys' wrap, which changes by micrometres in a period, is evaluated once at
        its start."""
        substeps = substeps or self.substeps
        if self.drive.pulley_radius_m:
            self.inputs[3] = self.pulley_excess_m() - self.start_pulley_excess_m
        self.integrate(torque_nm, period_s / substeps, substeps, tuple(external_force_n))
        self.tension_n = self.spring_tension_n

    def substep_constants(self, h: float, external_force_n: tuple[float, float, float]) -> tuple:
        """The kernel's `constants` for sub-steps of `h` s under `external_force_n` (N)."""
        drive, mass = self.drive, self.robot.mass_kg
        # First-order lags discretised exactly over a sub-step (gain 1: no lag).
        torque_gain = 1.0 - exp(-h / drive.torque_lag_s) if drive.torque_lag_s else 1.0
        speed_gain = 1.0 - exp(-h / drive.speed_filter_s) if drive.speed_filter_s else 1.0
        # gravity and the external force, as accelerations of the end-effector
        gx, gy, gz = (g + f / mass for g, f in zip(self.robot.gravity_m_s2.tolist(), external_force_n))
        return (self.robot.motor.drum_radius_m, self.coulomb_velocity_rad_s, drive.breakaway_friction_nm,
                drive.stribeck_speed_rad_s, torque_gain, speed_gain, self.axial_stiffness_n, self.damping_n_s_m,
                mass, gx, gy, gz, self.drums_locked)

    def integrate(self, torque_nm, h: float, substeps: int,
                  external_force_n: tuple[float, float, float]) -> None:
        """`substeps` semi-implicit Euler sub-steps of `h` s under `torque_nm` (N·m) and
        `external_force_n` (N); h = 0 only evaluates the tensions of the current state."""
        # the same from one period to the next but for a break, a push or the brakes
        key = (h, external_force_n, self.drums_locked, self.robot.mass_kg)
        if key != self.constants_key:
            self.constants, self.constants_key = self.substep_constants(h, external_force_n), key
        self.inputs[0] = torque_nm
        motors = self.kernel.view(self.motors.copy())
        px, py, pz, vx, vy, vz, fx, fy, fz = self.kernel.integrate(
            substeps, h, self.constants, self.cables, self.kernel.view(self.inputs), motors,
            (*self.position_m.tolist(), *self.velocity_m_s.tolist(), *self.cable_force_n))
        self.position_m = np.array((px, py, pz))
        self.velocity_m_s = np.array((vx, vy, vz))
        self.motors = np.asarray(motors, dtype=float)
        self.cable_force_n = (fx, fy, fz)
