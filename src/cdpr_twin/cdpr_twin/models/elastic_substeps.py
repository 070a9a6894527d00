"""The elastic plant's sub-steps: one source, run by CPython or compiled by numba.

`integrate` is written on indexable sequences and scalars only. CPython runs it on lists
of floats (on m ≈ 4 cables numpy's per-call overhead would be most of the cost); numba,
when installed, compiles it for float64 arrays: a period of 8 sub-steps then takes ~12
instead of ~65 µs (2-core EPYC), built ahead of time by `make setup`
(cdpr_control.kernels). Both do the same floating-point operations in the same order
(tests/test_elastic_substeps.py compares them).
"""
from __future__ import annotations

from math import exp, sqrt, tanh

import numpy as np

from cdpr_control.kernels import chooser, python_kernel


def integrate(substeps, h, constants, cables, inputs, motors, state):
    """`substeps` semi-implicit Euler sub-steps of `h` s; returns the new state.

    `constants`: drum radius ρ (m), the Coulomb friction's smoothing speed ω_c (rad/s),
    the breakaway excess (N·m) and its Stribeck speed (rad/s), the gains of the drive's
    torque loop and speed estimate over a sub-step, the cables' EA (N) and damping
    (N·s/m), the end-effector's mass (kg), the accelerations of gravity plus the external
    force (m/s²), whether the drums are locked. Rows per cable: `cables` its exit point
    A_i and length offset l_i0 (m), and its motor's inertia J_i (kg·m²), viscous friction
    b_i (N·m·s/rad) and Coulomb friction f_c,i (N·m), each motor its own as real drives
    are; `inputs` the commanded torque (N·m), 1 if attached else 0, the mass hanging on
    its drum (kg), the pulleys' length change (m); `motors` θ (rad), θ̇ (rad/s), τ (N),
    the drive's speed estimate (rad/s) and applied torque (N·m), updated in place.
    `state` and the result: p (m), ṗ (m/s) and the net cable force Σ τ_i u_i (N), nine
    floats. Rows, not one argument each: a compiled call pays per argument.

    A sub-step moves the state with the tensions of its start, then evaluates the
    tensions of its end, which the next sub-step starts from. With h = 0 the state stays
    as it is and only its tensions are evaluated.
    """
    (radius, smoothing, breakaway, stribeck, torque_gain, speed_gain, stiffness, damping,
     mass, gx, gy, gz, drums_locked) = constants
    exit_x, exit_y, exit_z, offset = cables[0], cables[1], cables[2], cables[3]
    inertia, viscous, coulomb = cables[4], cables[5], cables[6]
    torque, attached, hanging, pulley = inputs[0], inputs[1], inputs[2], inputs[3]
    angle, speed, tension, estimate, applied = motors[0], motors[1], motors[2], motors[3], motors[4]
    px, py, pz, vx, vy, vz, fx, fy, fz = state
    for _ in range(substeps):
        vx, vy, vz = (vx + h * (fx / mass + gx), vy + h * (fy / mass + gy),
                      vz + h * (fz / mass + gz))
        px, py, pz = px + h * vx, py + h * vy, pz + h * vz
        fx = fy = fz = 0.0
        for i in range(len(angle)):
            c_applied = applied[i] + torque_gain * (torque[i] - applied[i])
            w, theta = speed[i], angle[i]
            if drums_locked:
                w = 0.0
            else:
                # Motor: J θ̈ = c − (b θ̇ + f_c tanh(θ̇ / ω_c)) + ρ τ, with f_c raised by
                # the breakaway excess near standstill, and a broken cable's hanging
                # mass m_h on the drum: (J + m_h ρ²) θ̈ = … + ρ m_h g.
                friction = coulomb[i]
                if breakaway:
                    ratio = w / stribeck
                    friction += breakaway * exp(-ratio * ratio)
                w += h * ((c_applied - (viscous[i] * w + friction * tanh(w / smoothing))
                           + radius * (tension[i] - hanging[i] * gz))
                          / (inertia[i] + hanging[i] * radius * radius))
                theta += h * w
            estimate[i] += speed_gain * (w - estimate[i])
            speed[i], angle[i], applied[i] = w, theta, c_applied
            # Cable: stiffness EA / l on the stretch beyond its unstretched length
            # l = l_0 + ρ θ, damping on the stretch rate; it pulls, never pushes.
            # Over a pulley the path to the end-effector is longer by its wrap's change.
            rx, ry, rz = exit_x[i] - px, exit_y[i] - py, exit_z[i] - pz
            d = sqrt(rx * rx + ry * ry + rz * rz)
            length = offset[i] + radius * theta
            stretch = d + pulley[i] - length
            pull = 0.0
            if stretch > 0.0 and attached[i] != 0.0:
                ux, uy, uz = rx / d, ry / d, rz / d
                stretch_rate = -(ux * vx + uy * vy + uz * vz) - radius * w
                pull = (stiffness / length) * stretch + damping * stretch_rate
                if pull > 0.0:
                    fx += pull * ux
                    fy += pull * uy
                    fz += pull * uz
                else:
                    pull = 0.0
            tension[i] = pull
    return px, py, pz, vx, vy, vz, fx, fy, fz


# what the compiled function calls: nothing but itself
HELPERS = ()
# `view` turns a 2-D float array into what `integrate` takes: lists for CPython, which it
# then writes into; the array itself for numba.
PYTHON = python_kernel(integrate, view=np.ndarray.tolist)


def signatures(types) -> dict:
    floats, rows = types.float64, types.float64[:, :]
    state = types.UniTuple(floats, 9)
    return {integrate: state(types.intp, floats, types.Tuple((floats,) * 12 + (types.boolean,)), rows, rows,
                             rows, state)}


# kernel(name='compiled'): this module's functions as the kernel called `name` runs them
kernel = chooser(__name__, PYTHON, view=lambda array: array)
