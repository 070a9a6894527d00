"""Elastic-cable robot simulation: the plant's `elastic` fidelity.

Each cable is a unilateral spring–damper of stiffness EA / l between its drum and the
end-effector (it can go slack, never push); motors carry viscous and Coulomb friction.
Integrated by semi-implicit Euler with sub-steps inside each control period.

The sub-steps run on plain floats: 8 of them every 2 ms on m ≈ 4 cables, where numpy's
per-call overhead (~0.3–0.8 µs a call, dozens of calls a sub-step) would be most of
the cost.
"""
from __future__ import annotations

from math import sqrt, tanh

import numpy as np

from cdpr_control.kinematics import cable_vectors
from cdpr_control.robot import Robot
from cdpr_control.dynamics import NO_FORCE
from cdpr_control.statics import static_tensions


class ElasticCableRobot:
    """State p, ṗ (m, m/s) and θ, θ̇ (rad, rad/s); tensions τ (N) follow from it.

    A step replaces the state arrays rather than writing into them.
    """

    def __init__(self, robot: Robot, position_m, substeps: int, axial_stiffness_n: float,
                 damping_n_s_m: float, coulomb_friction_nm: float,
                 coulomb_velocity_rad_s: float):
        self.robot = robot
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
        # Per cable: exit point A_i and length offset l_i0 (m).
        self.cables = [(ax, ay, az, offset) for (ax, ay, az), offset in
                       zip(robot.exit_points_m.tolist(), robot.cable_length_offset_m.tolist())]
        # The spring–damper tensions (N) of the current state and their net force Σ τ_i u_i
        # on the end-effector (N): each sub-step ends by evaluating them for the next.
        self.spring_tension_n = [0.0] * robot.cable_count
        self.cable_force_n = (0.0, 0.0, 0.0)
        self.evaluate_tensions()

    def break_cables(self, cables) -> None:
        for index in cables:
            self.attached[index] = False
        self.evaluate_tensions()

    def evaluate_tensions(self) -> None:
        """The spring–damper tensions of the current state, for the next sub-step."""
        self.integrate([0.0] * self.robot.cable_count, 0.0, 1, NO_FORCE)

    def step(self, torque_nm: np.ndarray, period_s: float, external_force_n=NO_FORCE) -> None:
        """Apply `torque_nm` (N·m) for `period_s` (s), and `external_force_n` (N, world
        frame) on the end-effector."""
        self.integrate(np.asarray(torque_nm, dtype=float).tolist(), period_s / self.substeps,
                       self.substeps, tuple(external_force_n))
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
            next_angle, next_speed, next_tensions = [], [], []
            for (ax, ay, az, offset), theta, w, c, tension, is_attached in zip(
                    self.cables, angle, speed, torque_nm, tensions, attached):
                if self.drums_locked:
                    w = 0.0
                else:
                    # Motor: J θ̈ = c − (b θ̇ + f_c tanh(θ̇ / ω_c)) + ρ τ
                    w += h * ((c - (viscous * w + coulomb * tanh(w / smoothing))
                               + radius * tension) / inertia)
                    theta += h * w
                next_speed.append(w)
                next_angle.append(theta)
                # Cable: stiffness EA / l on the stretch beyond its unstretched length
                # l = l_0 + ρ θ, damping on the stretch rate; it pulls, never pushes.
                rx, ry, rz = ax - px, ay - py, az - pz
                d = sqrt(rx * rx + ry * ry + rz * rz)
                length = offset + radius * theta
                stretch = d - length
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
        self.position_m = np.array((px, py, pz))
        self.velocity_m_s = np.array((vx, vy, vz))
        self.angle_rad = np.array(angle)
        self.angular_velocity_rad_s = np.array(speed)
        self.spring_tension_n = tensions
        self.cable_force_n = (fx, fy, fz)
