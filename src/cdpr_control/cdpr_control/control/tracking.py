"""The controller's law while it tracks a joint reference, motor by motor: one source, run
by CPython or compiled by numba (kernels.py).

c = c_ID + K_p (θ_d − θ) + K_d (θ̇_d − θ̇), within ±c_max, 0 on a broken cable's motor
(controller.JointController says why). Every tick runs it twice in-process (the
robot's controller and the twin's); as numpy expressions on a handful of motors it took
~5 µs, nearly all of it numpy's per-call cost; compiled, ~1 µs.
"""
from __future__ import annotations

from cdpr_control.kernels import chooser, python_kernel


def tracking_torques(stiffness_nm_rad, damping_nm_s_rad, limit_nm, angle_rad, reference_angle_rad,
                     angular_velocity_rad_s, reference_angular_velocity_rad_s, feedforward_nm, broken,
                     torque_nm) -> None:
    """c (N·m, into `torque_nm`); `broken` holds 1.0 for a broken cable's motor, else 0.0."""
    for i in range(torque_nm.shape[0]):
        torque = feedforward_nm[i] + (stiffness_nm_rad * (reference_angle_rad[i] - angle_rad[i])
                                      + damping_nm_s_rad * (reference_angular_velocity_rad_s[i]
                                                            - angular_velocity_rad_s[i]))
        torque_nm[i] = 0.0 if broken[i] != 0.0 else min(max(torque, -limit_nm), limit_nm)


# what the compiled functions call: nothing but themselves
HELPERS = ()
PYTHON = python_kernel(tracking_torques)


def signatures(types) -> dict:
    # C-contiguous float64 arrays only, those only read also read-only ones (from messages)
    row, floats = types.float64[::1], types.float64
    given = types.Array(types.float64, 1, 'C', readonly=True)
    return {tracking_torques: types.void(floats, floats, floats, *(given,) * 6, row)}


# kernel(name='compiled'): this module's functions as the kernel called `name` runs them
kernel = chooser(__name__, PYTHON)
