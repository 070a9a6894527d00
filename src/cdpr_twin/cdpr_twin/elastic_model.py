"""Elastic-cable robot simulation: the plant's `elastic` and `field` fidelities.

Each cable is a unilateral spring–damper of stiffness EA / l between its drum and the
end-effector (it can go slack, never push); motors carry viscous and Coulomb friction.
Integrated by semi-implicit Euler with sub-steps inside each control period.

The `field` fidelity adds what a real drive train does (`DriveTrain`): the torque loop's
lag, the drive's filtered speed estimate, breakaway friction above Coulomb near
standstill (Stribeck), swivel pulleys whose wrap changes a cable's length with its
direction, and a mass left hanging on a cable's drum side once it breaks (the
electromagnet's half). Its defaults add nothing: that is the `elastic` fidelity.

The sub-steps run on plain floats: 8 of them every 2 ms on m ≈ 4 cables, where numpy's
per-call overhead (~0.3–0.8 µs a call, dozens of calls a sub-step) would be most of
the cost.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from math import exp, sqrt, tanh

import numpy as np

from cdpr_control.kinematics import cable_vectors
from cdpr_control.robot import Robot
from cdpr_control.dynamics import NO_FORCE
from cdpr_control.statics import static_tensions


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

    def __init__(self, robot: Robot, position_m, substeps: int, axial_stiffness_n: float,
                 damping_n_s_m: float, coulomb_friction_nm: float,
                 coulomb_velocity_rad_s: float, drive: DriveTrain = DriveTrain()):
        self.robot = robot
        self.drive = drive
        self.substeps = int(substeps)
        self.axial_stiffness_n = axial_stiffness_n
        self.damping_n_s_m = damping_n_s_m
        self.coulomb_friction_nm = coulomb_friction_nm
        self.coulomb_velocity_rad_s = coulomb_velocity_rad_s
        self.position_m = np.array(position_m, dtype=float)
        self.velocity_m_s = np.zeros(3)
        # A brake holds every drum still (θ̇ = 0), whatever the torque.
        self.drums_locked = False
        self.attached = np.ones(robot.cable_count, dtype=bool)
        # Start in equilibrium: each cable stretched by its static tension.
        tension = np.maximum(static_tensions(robot, self.position_m, self.attached), 0.0)
        _, d = cable_vectors(robot.exit_points_m, self.position_m)
        unstretched = d / (1.0 + tension / axial_stiffness_n)
        radius = robot.motor.drum_radius_m
        self.angle_rad = (unstretched - robot.cable_length_offset_m) / radius
        self.angular_velocity_rad_s = np.zeros(robot.cable_count)
        self.tension_n = tension
        # The drive's speed estimate (rad/s) and the torque its loop applies (N·m): both
        # lag the true speed and the command.
        self.speed_estimate_rad_s = np.zeros(robot.cable_count)
        self.torque_applied_nm = (-radius * tension).tolist()
        # The pulleys lengthen each cable by their wrap; the cable lengths were homed at
        # the start, so only the change since then is felt (m, per control period).
        self.start_pulley_excess_m = self.pulley_excess_m()
        self.pulley_change_m = [0.0] * robot.cable_count
        # Per cable: mass (kg) hanging on its drum once broken (0 while attached).
        self.hanging_kg = [0.0] * robot.cable_count
        # Per cable: exit point A_i and length offset l_i0 (m).
        self.cables = [(ax, ay, az, offset) for (ax, ay, az), offset in
                       zip(robot.exit_points_m.tolist(), robot.cable_length_offset_m.tolist())]
        # The spring–damper tensions (N) of the current state and their net force Σ τ_i u_i
        # on the end-effector (N): each sub-step ends by evaluating them for the next.
        self.spring_tension_n = [0.0] * robot.cable_count
        self.cable_force_n = (0.0, 0.0, 0.0)
        self.evaluate_tensions()

    def pulley_excess_m(self) -> np.ndarray:
        """How much longer (m) each cable is over its pulley than to the exit point."""
        if not self.drive.pulley_radius_m:
            return np.zeros(self.robot.cable_count)
        exits = self.robot.exit_points_m
        return (swivel_pulley_length_m(exits, self.position_m, self.drive.pulley_radius_m)
                - cable_vectors(exits, self.position_m)[1])

    def break_cables(self, cables) -> None:
        for index in cables:
            self.attached[index] = False
            if self.drive.hanging_mass_kg:
                # The mass was carried at the end-effector's end of the cable: it leaves it.
                self.hanging_kg[index] = self.drive.hanging_mass_kg[index]
                self.robot = dataclasses.replace(
                    self.robot, mass_kg=self.robot.mass_kg - self.hanging_kg[index])
        self.evaluate_tensions()

    def evaluate_tensions(self) -> None:
        """The spring–damper tensions of the current state, for the next sub-step."""
        self.integrate([0.0] * self.robot.cable_count, 0.0, 1, NO_FORCE)

    def step(self, torque_nm: np.ndarray, period_s: float, substeps: int | None = None,
             external_force_n=NO_FORCE) -> None:
        """Apply `torque_nm` (N·m) for `period_s` (s), in `substeps` (default: the
        model's) sub-steps, and `external_force_n` (N, world frame) on the end-effector.
        The pulleys' wrap, which changes by micrometres in a period, is evaluated once at
        its start."""
        substeps = substeps or self.substeps
        if self.drive.pulley_radius_m:
            self.pulley_change_m = (self.pulley_excess_m() - self.start_pulley_excess_m).tolist()
        self.integrate(np.asarray(torque_nm, dtype=float).tolist(), period_s / substeps,
                       substeps, tuple(external_force_n))
        self.tension_n = np.array(self.spring_tension_n)

    def integrate(self, torque_nm: list[float], h: float, substeps: int,
                  external_force_n: tuple[float, float, float]) -> None:
        """`substeps` semi-implicit Euler sub-steps of `h` s under `torque_nm` and
        `external_force_n`.

        A sub-step moves the state with the tensions of its start, then evaluates the
        tensions of its end, which the next sub-step starts from. With h = 0 the state
        stays as it is and only its tensions are evaluated.
        """
        motor = self.robot.motor
        radius, inertia = motor.drum_radius_m, motor.inertia_kg_m2
        viscous, coulomb = motor.viscous_friction_nm_s_rad, self.coulomb_friction_nm
        smoothing = self.coulomb_velocity_rad_s
        drive = self.drive
        breakaway, stribeck = drive.breakaway_friction_nm, drive.stribeck_speed_rad_s
        # First-order lags discretised exactly over a sub-step (gain 1: no lag).
        torque_gain = 1.0 - exp(-h / drive.torque_lag_s) if drive.torque_lag_s else 1.0
        speed_gain = 1.0 - exp(-h / drive.speed_filter_s) if drive.speed_filter_s else 1.0
        estimate = self.speed_estimate_rad_s.tolist()
        applied = self.torque_applied_nm
        stiffness, damping = self.axial_stiffness_n, self.damping_n_s_m
        mass = self.robot.mass_kg
        # gravity and the external force, as accelerations of the end-effector
        gx, gy, gz = (g + f / mass for g, f in zip(self.robot.gravity_m_s2.tolist(), external_force_n))
        px, py, pz = self.position_m.tolist()
        vx, vy, vz = self.velocity_m_s.tolist()
        angle = self.angle_rad.tolist()
        speed = self.angular_velocity_rad_s.tolist()
        attached = self.attached.tolist()
        tensions = self.spring_tension_n
        fx, fy, fz = self.cable_force_n
        for _ in range(substeps):
            vx, vy, vz = (vx + h * (fx / mass + gx), vy + h * (fy / mass + gy),
                          vz + h * (fz / mass + gz))
            px, py, pz = px + h * vx, py + h * vy, pz + h * vz
            fx = fy = fz = 0.0
            next_angle, next_speed, next_tensions, next_estimate, next_applied = [], [], [], [], []
            for (ax, ay, az, offset), theta, w, c, tension, is_attached, w_est, c_applied, \
                    hanging, pulley in zip(self.cables, angle, speed, torque_nm, tensions,
                                           attached, estimate, applied, self.hanging_kg,
                                           self.pulley_change_m):
                c_applied += torque_gain * (c - c_applied)
                if self.drums_locked:
                    w = 0.0
                else:
                    # Motor: J θ̈ = c − (b θ̇ + f_c tanh(θ̇ / ω_c)) + ρ τ, with f_c raised by
                    # the breakaway excess near standstill, and a broken cable's hanging
                    # mass m_h on the drum: (J + m_h ρ²) θ̈ = … + ρ m_h g.
                    friction = coulomb
                    if breakaway:
                        ratio = w / stribeck
                        friction += breakaway * exp(-ratio * ratio)
                    w += h * ((c_applied - (viscous * w + friction * tanh(w / smoothing))
                               + radius * (tension - hanging * gz))
                              / (inertia + hanging * radius * radius))
                    theta += h * w
                w_est += speed_gain * (w - w_est)
                next_speed.append(w)
                next_angle.append(theta)
                next_estimate.append(w_est)
                next_applied.append(c_applied)
                # Cable: stiffness EA / l on the stretch beyond its unstretched length
                # l = l_0 + ρ θ, damping on the stretch rate; it pulls, never pushes.
                # Over a pulley the path to the end-effector is longer by its wrap's change.
                rx, ry, rz = ax - px, ay - py, az - pz
                d = sqrt(rx * rx + ry * ry + rz * rz)
                length = offset + radius * theta
                stretch = d + pulley - length
                tension = 0.0
                if stretch > 0.0 and is_attached:
                    ux, uy, uz = rx / d, ry / d, rz / d
                    stretch_rate = -(ux * vx + uy * vy + uz * vz) - radius * w
                    tension = (stiffness / length) * stretch + damping * stretch_rate
                    if tension > 0.0:
                        fx += tension * ux
                        fy += tension * uy
                        fz += tension * uz
                    else:
                        tension = 0.0
                next_tensions.append(tension)
            angle, speed, tensions = next_angle, next_speed, next_tensions
            estimate, applied = next_estimate, next_applied
        self.speed_estimate_rad_s = np.array(estimate)
        self.torque_applied_nm = applied
        self.position_m = np.array((px, py, pz))
        self.velocity_m_s = np.array((vx, vy, vz))
        self.angle_rad = np.array(angle)
        self.angular_velocity_rad_s = np.array(speed)
        self.spring_tension_n = tensions
        self.cable_force_n = (fx, fy, fz)
