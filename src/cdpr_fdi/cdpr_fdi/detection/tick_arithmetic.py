"""What the supervisor computes on every tick, motor by motor: one source, run by CPython
or compiled by numba (cdpr_control.kernels).

On a handful of motors each of these took 5–12 µs as numpy expressions, nearly all of
it numpy's per-call cost, together half of the supervisor's tick; compiled, a call takes
under 1 µs (docs/performance.md). The formulas are residual.py's, tension_collapse.py's
and the supervisor's reference tension and motor watch; their docstrings say why.

Arrays in, arrays written: `motor` is `motor_constants(robot.motor, friction)`; the
per-motor arrays hold one entry per motor.
"""
from __future__ import annotations

from functools import cache
from math import tanh

import numpy as np

from cdpr_control.model.friction import FrictionModel
from cdpr_control.kernels import chooser, python_kernel
from cdpr_control.model.robot import Motor

# the slots of `motor`
INERTIA, VISCOUS, RADIUS, COULOMB, SMOOTHING = range(5)


@cache
def motor_constants(motor: Motor, friction: FrictionModel) -> np.ndarray:
    """J (kg·m²), b (N·m·s/rad), ρ (m), and the Coulomb friction f_c (N·m) with its
    smoothing speed (rad/s) as the control stack models them (read-only: made once)."""
    constants = np.array([motor.inertia_kg_m2, motor.viscous_friction_nm_s_rad, motor.drum_radius_m,
                          friction.coulomb_nm, friction.smoothing_rad_s])
    constants.flags.writeable = False
    return constants


def sensorless_tensions(motor, applied_torque_nm, speed_before_rad_s, speed_after_rad_s, period_s,
                        tension_n, low_n, high_n) -> None:
    """τ̂ = (J θ̈ + b θ̇ + f_c(θ̇) − c) / ρ (N) over a period in which the applied torque c
    took a motor between two speeds, friction at the speed it started with (into
    `tension_n`), and the lowest and highest τ̂ the friction between the two speeds
    allows (into `low_n`, `high_n`); the period `period_s` long (s)."""
    inertia, viscous, radius = motor[INERTIA], motor[VISCOUS], motor[RADIUS]
    coulomb, smoothing = motor[COULOMB], motor[SMOOTHING]
    for i in range(applied_torque_nm.shape[0]):
        before, after = speed_before_rad_s[i], speed_after_rad_s[i]
        friction_before = coulomb * tanh(before / smoothing)
        at_start = (inertia * ((after - before) / period_s) + viscous * before + friction_before
                    - applied_torque_nm[i]) / radius
        other_end = at_start + (coulomb * tanh(after / smoothing) - friction_before) / radius
        tension_n[i] = at_start
        low_n[i], high_n[i] = min(at_start, other_end), max(at_start, other_end)


def reference_tensions(motor, period_s, angular_velocity_rad_s, previous_angular_velocity_rad_s,
                       feedforward_nm, tension_n) -> None:
    """τ_d = (J θ̈_d + b θ̇_d − c_ID) / ρ (N, into `tension_n`): the tensions a reference
    asks for, θ̈_d from the previous reference's speeds."""
    inertia, viscous, radius = motor[INERTIA], motor[VISCOUS], motor[RADIUS]
    for i in range(angular_velocity_rad_s.shape[0]):
        acceleration = (angular_velocity_rad_s[i] - previous_angular_velocity_rad_s[i]) / period_s
        tension_n[i] = (inertia * acceleration + viscous * angular_velocity_rad_s[i] - feedforward_nm[i]) / radius


def collapse_window(recent, total, slot, low_n, high_n, reference_n, band_n, reference_min_n,
                    largest_n, collapsed) -> int:
    """A period's τ̂ bounds and reference tension into a window of periods (rows 0–2 of
    `recent[slot]`, the oldest, replaced; `total` their sum over the window, kept); then
    per motor (into `collapsed`, 1.0 or 0.0) whether the window's averages put τ̂ within
    `band_n` of zero while the reference asked for at least `reference_min_n`, and the
    largest such average reference at any level into `largest_n[0]` (kept: the most seen).
    Returns how many did."""
    window = recent.shape[0]
    count = 0
    for i in range(low_n.shape[0]):
        total[0, i] += low_n[i]
        total[1, i] += high_n[i]
        total[2, i] += reference_n[i]
        for row in range(3):
            total[row, i] -= recent[slot, row, i]
        recent[slot, 0, i], recent[slot, 1, i], recent[slot, 2, i] = low_n[i], high_n[i], reference_n[i]
        low, high, reference = total[0, i] / window, total[1, i] / window, total[2, i] / window
        distance = max(max(low, -high), 0.0)
        free = distance < band_n
        if free and reference > largest_n[0]:
            largest_n[0] = reference
        collapsed[i] = 1.0 if free and reference >= reference_min_n else 0.0
        count += collapsed[i] != 0.0
    return count


def watch_unloaded(residual_nm, delta_nm, tick, unloaded, unloaded_since, last_unloaded) -> None:
    """Per motor, whether its residual is above δ (`delta_nm`) on `tick` (into `unloaded`,
    1.0 or 0.0), the first tick of its run above δ (into `unloaded_since`, -1 where not
    above now) and the last tick it was above δ (into `last_unloaded`, kept where not)."""
    for i in range(residual_nm.shape[0]):
        if residual_nm[i] > delta_nm:
            unloaded[i] = 1.0
            if unloaded_since[i] < 0:
                unloaded_since[i] = tick
            last_unloaded[i] = tick
        else:
            unloaded[i] = 0.0
            unloaded_since[i] = -1


def watch_freed(low_n, radius_m, delta_nm, delta_n, tick, recent_low_n, unloaded_since, dropped_since,
                freed_since) -> None:
    """Per motor, from its τ̂ lower bound of `tick` (`low_n`, N): whether it looks free
    (ρ τ̂ under δ), the tick it dropped to that, down by δ/ρ (`delta_n`) or more from the
    larger of the two periods before (rows of `recent_low_n`, shifted on by this one), while
    it has looked free since (into `dropped_since`, -1 where not so), and the first tick it
    looked free with its residual's run above δ (`unloaded_since`) or on the period it
    dropped, until it does neither (into `freed_since`, -1 where not so)."""
    for i in range(low_n.shape[0]):
        free = low_n[i] * radius_m < delta_nm
        dropped = max(recent_low_n[0, i], recent_low_n[1, i]) - low_n[i] >= delta_n
        if not free:
            dropped_since[i] = -1
        elif dropped_since[i] < 0 and dropped:
            dropped_since[i] = tick
        recent_low_n[0, i] = recent_low_n[1, i]
        recent_low_n[1, i] = low_n[i]
        lost = unloaded_since[i] >= 0
        if freed_since[i] < 0 and free and (lost or dropped_since[i] == tick):
            freed_since[i] = tick
        elif not free and not lost:
            freed_since[i] = -1


# what the compiled functions call: nothing but themselves
HELPERS = ()
PYTHON = python_kernel(sensorless_tensions, reference_tensions, collapse_window, watch_unloaded, watch_freed)


def signatures(types) -> dict:
    # C-contiguous float64 arrays only, those only read also read-only ones (from messages)
    row, rows, floats = types.float64[::1], types.float64[:, ::1], types.float64
    ticks, tick = types.int64[::1], types.int64
    given = types.Array(types.float64, 1, 'C', readonly=True)
    return {sensorless_tensions: types.void(*(given,) * 4, floats, row, row, row),
            reference_tensions: types.void(given, floats, given, given, given, row),
            collapse_window: types.intp(types.float64[:, :, ::1], rows, types.intp, given, given, given, floats,
                                        floats, row, row),
            watch_unloaded: types.void(given, floats, tick, row, ticks, ticks),
            watch_freed: types.void(given, floats, floats, floats, tick, rows, ticks, ticks, ticks)}


# kernel(name='compiled'): this module's functions as the kernel called `name` runs them
kernel = chooser(__name__, PYTHON)
