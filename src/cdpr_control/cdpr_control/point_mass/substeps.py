"""A point mass on rigid cables, one control period in sub-steps: one source, run by
CPython or compiled by numba (the twin's model and the plant's `rigid` fidelity).

The equations are dynamics.py's (docs/design.md §4): taut cables obey
(m_e I + (J/ρ²) S Sᵀ) p̈ = m_e g + f − (J/ρ²) S Ṡᵀ ṗ − (b/ρ²) S Sᵀ ṗ − (1/ρ) S c, the
motors of slack and detached cables J θ̈ = −b θ̇ + c. Written on floats element by
element, the form numba compiles to ~1 µs a period, where CPython on a handful of
cables spent ~15 µs (docs/performance.md). CPython runs the same functions as they are
(the `python` kernel: for a machine without numba, and to check the compiled one
against); both do the same operations in the same order.

Arrays in, arrays updated in place: `constants` is `constants_of(robot)`; `exits` the
exit points A (m × 3), `offsets` the length offsets l_0 (m); `directions` holds
(u_x, u_y, u_z, d_i) per cable (m × 4, u_i from the end-effector to A_i, d_i in m); a
mask holds 1.0 for yes and 0.0 for no.
"""
from __future__ import annotations

from math import sqrt

import numpy as np

from cdpr_control.kernels import chooser, python_kernel

# the slots of `constants`
MASS, WEIGHT, MOTOR_INERTIA, VISCOUS, RADIUS, RETAUT = 0, 1, 4, 5, 6, 7
CONSTANT_COUNT = 8
# A cable at its length whose end draws away from its exit point faster than its motor
# pays out by more than this (m/s) is caught: an inelastic jerk (catch_slack). A taut
# cable's rate is rounding (its motor is put on its constraint every sub-step).
CATCH_RATE_M_S = 1e-9


def constants_of(robot, retaut_tolerance_m: float = 0.0) -> np.ndarray:
    """The numbers a kernel needs of a point-mass robot: its mass m_e (kg) and weight
    m_e g (N), the motors' J (kg·m²), b (N·m·s/rad) and ρ (m), and the length within
    which a slack cable's motor, wound in to its straight line, makes it taut again (m)."""
    motor = robot.motor
    constants = np.empty(CONSTANT_COUNT)
    constants[MASS] = robot.mass_kg
    constants[WEIGHT:WEIGHT + 3] = robot.mass_kg * robot.gravity_m_s2
    constants[MOTOR_INERTIA:RETAUT + 1] = (motor.inertia_kg_m2, motor.viscous_friction_nm_s_rad,
                                           motor.drum_radius_m, retaut_tolerance_m)
    return constants


def cable_directions(exits, position, directions) -> None:
    """(u_x, u_y, u_z, d_i) of each cable at `position` (m), into `directions`."""
    for i in range(exits.shape[0]):
        rx, ry, rz = exits[i, 0] - position[0], exits[i, 1] - position[1], exits[i, 2] - position[2]
        d = sqrt(rx * rx + ry * ry + rz * rz)
        directions[i, 0], directions[i, 1], directions[i, 2], directions[i, 3] = rx / d, ry / d, rz / d, d


def direct_dynamics(constants, directions, velocity, torque, speed, candidates, external_force,
                    acceleration, joint_acceleration, tension, taut) -> None:
    """p̈ (m/s², into `acceleration`), and per cable θ̈ (rad/s²), τ (N) and taut flags
    under the torques c (N·m) at ṗ (m/s) and θ̇ (rad/s), with `external_force` (N, world
    frame) on the end-effector besides its weight. The `candidates` may be taut; of them,
    the cable of the most negative tension goes slack and the rest is solved again, until
    every taut cable pulls."""
    m = directions.shape[0]
    mass, inertia, viscous, radius = constants[MASS], constants[MOTOR_INERTIA], constants[VISCOUS], constants[RADIUS]
    radius_squared = radius * radius
    # J/ρ² (kg): a motor's inertia as the cable feels it
    reflected = inertia / radius_squared
    vx, vy, vz = velocity[0], velocity[1], velocity[2]
    speed_squared = vx * vx + vy * vy + vz * vz
    # Per cable, ṗ·u_i (m/s) and ṗ·u̇_i = ((u_i·ṗ)² − |ṗ|²) / d_i (m/s², u̇_i of
    # docs/design.md §4); the motor law then gives τ_i = −(J/ρ²) u_i·p̈ − pull_i, pull_i
    # (N) free of p̈.
    cable_speed, cable_rate, pull = np.empty(m), np.empty(m), np.empty(m)
    for i in range(m):
        along = directions[i, 0] * vx + directions[i, 1] * vy + directions[i, 2] * vz
        rate = (along * along - speed_squared) / directions[i, 3]
        cable_speed[i], cable_rate[i] = along, rate
        pull[i] = (inertia * rate + viscous * along) / radius_squared + torque[i] / radius
        taut[i] = candidates[i]
    wx, wy, wz = (constants[WEIGHT] + external_force[0], constants[WEIGHT + 1] + external_force[1],
                  constants[WEIGHT + 2] + external_force[2])
    while True:
        sxx, sxy, sxz, syy, syz, szz, fx, fy, fz = taut_sums(directions, taut, pull)
        ax, ay, az = solve_positive_definite3(mass + reflected * sxx, reflected * sxy, reflected * sxz,
                                              mass + reflected * syy, reflected * syz, mass + reflected * szz,
                                              wx - fx, wy - fy, wz - fz)
        acceleration[0], acceleration[1], acceleration[2] = ax, ay, az
        # The cable of the most negative tension goes slack, and the taut set is solved again.
        most_negative, slack = 0.0, -1
        for i in range(m):
            if taut[i] != 0.0:
                joint_acceleration[i] = -(ax * directions[i, 0] + ay * directions[i, 1] + az * directions[i, 2]
                                          + cable_rate[i]) / radius
                tension[i] = (inertia * joint_acceleration[i] - viscous * cable_speed[i] / radius - torque[i]) / radius
                if tension[i] < most_negative:
                    most_negative, slack = tension[i], i
            else:
                joint_acceleration[i] = (torque[i] - viscous * speed[i]) / inertia
                tension[i] = 0.0
        if slack < 0:
            return
        taut[slack] = 0.0


def catch_slack(constants, directions, velocity, speed, candidates, caught) -> None:
    """Where a `candidates` cable's end draws away from its exit point faster than its
    motor pays out (−u_iᵀ ṗ > ρ θ̇_i: a slack cable pulled straight by the end-effector's
    swing), the inelastic jerk that ends it, in place: ṗ and the `caught` cables' θ̇ (a
    mask, written) projected onto their constraint ρ θ̇_i = −u_iᵀ ṗ in the kinetic energy's
    metric, (m_e I + (J/ρ²) Σ u_i u_iᵀ) ṗ⁺ = m_e ṗ − (J/ρ) Σ u_i θ̇_i. A cable whose jerk
    J (θ̇_i⁺ − θ̇_i) / ρ would push lets go, the most negative first. Without the jerk an
    acceleration's balance alone judged such a cable, and could keep it slack while the
    end-effector swung 0.23 m beyond its length (a drawn 4-cable point mass hanging on
    two). Nothing changes where no cable is drawn so."""
    m = directions.shape[0]
    mass, inertia, radius = constants[MASS], constants[MOTOR_INERTIA], constants[RADIUS]
    reflected = inertia / (radius * radius)
    vx, vy, vz = velocity[0], velocity[1], velocity[2]
    drawn = False
    for i in range(m):
        caught[i] = 0.0
        if candidates[i] != 0.0:
            rate = -(directions[i, 0] * vx + directions[i, 1] * vy + directions[i, 2] * vz) - radius * speed[i]
            if rate > -CATCH_RATE_M_S:
                caught[i] = 1.0
                drawn = drawn or rate > CATCH_RATE_M_S
    if not drawn:
        return
    pay = inertia / radius
    while True:
        sxx, sxy, sxz, syy, syz, szz, fx, fy, fz = taut_sums(directions, caught, speed)
        ax, ay, az = solve_positive_definite3(mass + reflected * sxx, reflected * sxy, reflected * sxz,
                                              mass + reflected * syy, reflected * syz, mass + reflected * szz,
                                              mass * vx - pay * fx, mass * vy - pay * fy, mass * vz - pay * fz)
        most_negative, pushing = 0.0, -1
        for i in range(m):
            if caught[i] != 0.0:
                jerk = inertia * (-(directions[i, 0] * ax + directions[i, 1] * ay + directions[i, 2] * az) / radius
                                  - speed[i]) / radius
                if jerk < most_negative:
                    most_negative, pushing = jerk, i
        if pushing < 0:
            break
        caught[pushing] = 0.0
    velocity[0], velocity[1], velocity[2] = ax, ay, az
    for i in range(m):
        if caught[i] != 0.0:
            speed[i] = -(directions[i, 0] * ax + directions[i, 1] * ay + directions[i, 2] * az) / radius


def taut_sums(directions, mask, weights):
    """Over the cables of `mask`: the six entries of S Sᵀ = Σ u_i u_iᵀ (xx, xy, xz, yy,
    yz, zz) and the three of Σ u_i w_i, `weights` w per cable."""
    sxx = sxy = sxz = syy = syz = szz = 0.0
    fx = fy = fz = 0.0
    for i in range(directions.shape[0]):
        if mask[i] != 0.0:
            ux, uy, uz, w = directions[i, 0], directions[i, 1], directions[i, 2], weights[i]
            sxx += ux * ux
            sxy += ux * uy
            sxz += ux * uz
            syy += uy * uy
            syz += uy * uz
            szz += uz * uz
            fx += ux * w
            fy += uy * w
            fz += uz * w
    return sxx, sxy, sxz, syy, syz, szz, fx, fy, fz


def solve_positive_definite3(a, b, c, d, e, f, x, y, z):
    """(p, q, r) with [[a, b, c], [b, d, e], [c, e, f]] (p, q, r) = (x, y, z), the matrix
    symmetric positive definite (m_e I + (J/ρ²) S Sᵀ: never singular), by cofactors."""
    co_a, co_b, co_c = d * f - e * e, c * e - b * f, b * e - c * d
    det = a * co_a + b * co_b + c * co_c
    return ((co_a * x + co_b * y + co_c * z) / det,
            (co_b * x + (a * f - c * c) * y + (b * c - a * e) * z) / det,
            (co_c * x + (b * c - a * e) * y + (a * d - b * b) * z) / det)


def rigid_substeps(substeps, h, constants, exits, offsets, attached, torque, external_force,
                   position, velocity, angle, speed, tension, taut, directions) -> None:
    """`substeps` semi-implicit Euler sub-steps of `h` s, the state updated in place: each
    solves the direct dynamics with the attached cables not paid out beyond their
    straight-line length (those drawn straight caught first: catch_slack), moves, and
    puts the taut motors back on the kinematic constraint l = d, θ̇ = −uᵀ ṗ / ρ.
    `directions` are those at `position` on the way in, and on the way out."""
    m = exits.shape[0]
    radius, tolerance = constants[RADIUS], constants[RETAUT]
    candidates, joint_acceleration, acceleration = np.empty(m), np.empty(m), np.empty(3)
    for _ in range(substeps):
        for i in range(m):
            length = offsets[i] + radius * angle[i]    # l_i = l_i0 + ρ θ_i, paid out
            candidates[i] = 1.0 if attached[i] != 0.0 and length <= directions[i, 3] + tolerance else 0.0
        catch_slack(constants, directions, velocity, speed, candidates, taut)
        direct_dynamics(constants, directions, velocity, torque, speed, candidates, external_force,
                        acceleration, joint_acceleration, tension, taut)
        for k in range(3):
            velocity[k] += h * acceleration[k]
            position[k] += h * velocity[k]
        cable_directions(exits, position, directions)
        for i in range(m):
            if taut[i] != 0.0:
                angle[i] = (directions[i, 3] - offsets[i]) / radius
                speed[i] = -(directions[i, 0] * velocity[0] + directions[i, 1] * velocity[1]
                             + directions[i, 2] * velocity[2]) / radius
            else:
                speed[i] += h * joint_acceleration[i]
                angle[i] += h * speed[i]


HELPERS = (cable_directions, taut_sums, direct_dynamics, catch_slack, solve_positive_definite3)


PYTHON = python_kernel(cable_directions, direct_dynamics, rigid_substeps)


def signatures(types) -> dict:
    # C-contiguous float64 arrays only, those only read also read-only ones
    row, rows = types.float64[::1], types.float64[:, ::1]
    given, given_rows = types.Array(types.float64, 1, 'C', readonly=True), types.Array(types.float64, 2, 'C',
                                                                                         readonly=True)
    return {cable_directions: types.void(given_rows, given, rows),
            direct_dynamics: types.void(given, given_rows, *(given,) * 5, *(row,) * 4),
            rigid_substeps: types.void(types.intp, types.float64, given, given_rows, *(given,) * 4, *(row,) * 6,
                                       rows)}


# kernel(name='compiled'): this module's functions as the kernel called `name` runs them
kernel = chooser(__name__, PYTHON)
