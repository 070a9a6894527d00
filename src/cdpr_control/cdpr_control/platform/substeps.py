"""A platform's equations of motion, one control period in sub-steps, and the steered
approach's rows (cdpr_control.platform.steered_approach): one source, run by CPython or compiled
by numba (docs/platform.md, "Speed").

The equations are those of platform.dynamics' docstring (Newton–Euler at the platform frame's
origin, the motors J θ̈ = −b θ̇ + c + ρ τ) and of pose_kinematics' (l_i = A_i − p − R b_i,
W's column [u_i ; r_i × u_i]); here they are written on floats and small arrays, element
by element, the form numba compiles to a few µs a call where numpy's per-call cost
on 6 × 8 arrays made them 9 to 40 times slower. CPython runs the same functions as they are (the
`python` kernel: slow, for a machine without numba and to check the compiled one
against); both do the same operations in the same order.

Arrays in, arrays updated in place, nothing else: `constants` is `constants_of(robot, …)`,
the geometry is the exit points A (m × 3), attachment points b (m × 3, platform frame)
and length offsets l_0 (m); a pose is (px, py, pz, qw, qx, qy, qz), a twist (v, ω) six
floats, world frame; a mask holds 1.0 for yes and 0.0 for no.
"""
from __future__ import annotations

from math import atan2, cos, sin, sqrt, tanh

import numpy as np

from cdpr_control.kernels import chooser, python_kernel

from cdpr_control.geometry.rotation import SMALL_ANGLE_RAD

# the slots of `constants`
MASS, CENTRE, INERTIA, GRAVITY = 0, 1, 4, 13
MOTOR_INERTIA, VISCOUS, RADIUS, SMOOTHING, STIFFNESS, DAMPING, RETAUT = range(16, 23)
CONSTANT_COUNT = 23
# A cable at its length whose end draws away from its exit point faster than its motor
# pays out by more than this (m/s) is caught: an inelastic jerk (catch_slack). A taut
# cable's rate is rounding (its motor is put on its constraint every sub-step).
CATCH_RATE_M_S = 1e-9
# the rows of the elastic model's `motors`, a column per motor
MOTOR_ROW_INERTIA, MOTOR_ROW_VISCOUS, MOTOR_ROW_COULOMB = range(3)
# Forward kinematics' Levenberg–Marquardt damping where W Wᵀ is singular, a share of its
# largest diagonal entry.
LEVENBERG_DAMPING = 1e-6
# Forward kinematics halves a Gauss–Newton step that would raise the lengths' squared
# misfit, at most this many times: on lengths no pose meets (stretched elastic cables)
# along a direction W barely holds, full steps jumped between two poses 0.8 mm apart for
# ever (a drawn crossed 7-cable platform, W's least singular value 1.6e-3).
FK_STEP_HALVINGS = 30
# The nearest wrench's tie-break between tensions that pull the same wrench (the free
# directions of more cables than degrees of freedom): this share of the problem's scale
# times |τ|² is added, so the lowest such tensions are taken, as the bounded minimum norm
# does.
TIE_BREAK_SHARE = 1e-12
# A held cable is let go of only where the objective's slope away from its bound exceeds
# this share of the problem's scale: a slope of rounding size would be let go of and held
# again for ever.
SLOPE_TOLERANCE_SHARE = 1e-10
# An active-set search over m cables ends within a few times m steps; this many is a bug.
ACTIVE_SET_STEPS_PER_CABLE = 8
# the slots of a steered approach's row: pose (p, q), twist (v, ω), twist rate (a, α)
ROW_POSE, ROW_TWIST, ROW_RATE, ROW_WIDTH = 0, 7, 13, 19


def constants_of(robot, coulomb_velocity_rad_s: float = 1.0, axial_stiffness_n: float = 0.0,
                 damping_n_s_m: float = 0.0, retaut_tolerance_m: float = 0.0) -> np.ndarray:
    """The numbers a kernel needs of a platform robot: mass m (kg), centre of mass c (m),
    inertia I_c (platform frame), gravity g (m/s²), the motors' J, b (the rigid model's,
    one for all: the elastic model takes each motor's in its `motors`) and ρ, and for the
    elastic cables the Coulomb friction's smoothing speed (rad/s), EA (N) and damping
    (N·s/m); for the rigid ones the re-tautening tolerance (m)."""
    platform, motor = robot.body, robot.motor
    constants = np.empty(CONSTANT_COUNT)
    constants[MASS] = robot.mass_kg
    constants[CENTRE:CENTRE + 3] = platform.centre_of_mass_m
    constants[INERTIA:INERTIA + 9] = platform.inertia_kg_m2.ravel()
    constants[GRAVITY:GRAVITY + 3] = robot.gravity_m_s2
    constants[MOTOR_INERTIA:RETAUT + 1] = (motor.inertia_kg_m2, motor.viscous_friction_nm_s_rad,
                                           motor.drum_radius_m, coulomb_velocity_rad_s, axial_stiffness_n,
                                           damping_n_s_m, retaut_tolerance_m)
    return constants


def geometry_of(robot) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The exit points A (m × 3), attachment points b (m × 3) and length offsets l_0 (m) of
    a platform robot, as the compiled kernels take arrays: writable copies."""
    return (np.array(robot.exit_points_m, dtype=float), np.array(robot.body.attachment_points_m, dtype=float),
            np.array(robot.cable_length_offset_m, dtype=float))


def rotation_of(pose, rotation) -> None:
    """R (3 × 3, into `rotation`) of the pose's unit quaternion."""
    w, x, y, z = pose[3], pose[4], pose[5], pose[6]
    rotation[0, 0], rotation[0, 1], rotation[0, 2] = 1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)
    rotation[1, 0], rotation[1, 1], rotation[1, 2] = 2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)
    rotation[2, 0], rotation[2, 1], rotation[2, 2] = 2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)


def cables_at(pose, rotation, exits, attachments, wrench_columns, lengths, arms) -> None:
    """At the pose (its R in `rotation`): W's columns as rows (m × 6: u_i, r_i × u_i), the
    lengths d (m) and the attachment points r_i = R b_i relative to p (m × 3)."""
    for i in range(exits.shape[0]):
        bx, by, bz = attachments[i, 0], attachments[i, 1], attachments[i, 2]
        rx = rotation[0, 0] * bx + rotation[0, 1] * by + rotation[0, 2] * bz
        ry = rotation[1, 0] * bx + rotation[1, 1] * by + rotation[1, 2] * bz
        rz = rotation[2, 0] * bx + rotation[2, 1] * by + rotation[2, 2] * bz
        lx, ly, lz = exits[i, 0] - pose[0] - rx, exits[i, 1] - pose[1] - ry, exits[i, 2] - pose[2] - rz
        d = sqrt(lx * lx + ly * ly + lz * lz)
        ux, uy, uz = lx / d, ly / d, lz / d
        wrench_columns[i, 0], wrench_columns[i, 1], wrench_columns[i, 2] = ux, uy, uz
        wrench_columns[i, 3], wrench_columns[i, 4], wrench_columns[i, 5] = (ry * uz - rz * uy, rz * ux - rx * uz,
                                                                            rx * uy - ry * ux)
        lengths[i] = d
        arms[i, 0], arms[i, 1], arms[i, 2] = rx, ry, rz


def length_rate(wrench_columns, i, twist) -> float:
    """ḋ_i = −w_iᵀ (v, ω) (m/s)."""
    total = 0.0
    for k in range(6):
        total += wrench_columns[i, k] * twist[k]
    return -total


def rigid_body(constants, rotation, twist, mass_matrix, free_wrench) -> None:
    """The platform's M (6 × 6, into `mass_matrix`) and w_g − h (6, into `free_wrench`) at
    its rotation R and twist: platform.dynamics' docstring."""
    mass = constants[MASS]
    cx, cy, cz = constants[CENTRE], constants[CENTRE + 1], constants[CENTRE + 2]
    # c_w = R c, I_w = R I_c Rᵀ
    ox = rotation[0, 0] * cx + rotation[0, 1] * cy + rotation[0, 2] * cz
    oy = rotation[1, 0] * cx + rotation[1, 1] * cy + rotation[1, 2] * cz
    oz = rotation[2, 0] * cx + rotation[2, 1] * cy + rotation[2, 2] * cz
    offset = np.empty(3)
    offset[0], offset[1], offset[2] = ox, oy, oz
    inertia = np.empty((3, 3))
    for a in range(3):
        for b in range(3):
            total = 0.0
            for k in range(3):
                for n in range(3):
                    total += rotation[a, k] * constants[INERTIA + 3 * k + n] * rotation[b, n]
            inertia[a, b] = total
    # M = [[m I, −m [c]×], [m [c]×, I_w − m [c]×²]], −[c]×² = |c|² I − c cᵀ
    squared = ox * ox + oy * oy + oz * oz
    for a in range(3):
        for b in range(3):
            mass_matrix[a, b] = mass if a == b else 0.0
            mass_matrix[3 + a, 3 + b] = inertia[a, b] + mass * ((squared if a == b else 0.0) - offset[a] * offset[b])
    mass_matrix[0, 3], mass_matrix[0, 4], mass_matrix[0, 5] = 0.0, mass * oz, -mass * oy
    mass_matrix[1, 3], mass_matrix[1, 4], mass_matrix[1, 5] = -mass * oz, 0.0, mass * ox
    mass_matrix[2, 3], mass_matrix[2, 4], mass_matrix[2, 5] = mass * oy, -mass * ox, 0.0
    for a in range(3):
        for b in range(3):
            mass_matrix[3 + a, b] = mass_matrix[b, 3 + a]
    wx, wy, wz = twist[3], twist[4], twist[5]
    # e = ω × (ω × c_w), j = I_w ω
    sx, sy, sz = wy * oz - wz * oy, wz * ox - wx * oz, wx * oy - wy * ox
    ex, ey, ez = wy * sz - wz * sy, wz * sx - wx * sz, wx * sy - wy * sx
    jx = inertia[0, 0] * wx + inertia[0, 1] * wy + inertia[0, 2] * wz
    jy = inertia[1, 0] * wx + inertia[1, 1] * wy + inertia[1, 2] * wz
    jz = inertia[2, 0] * wx + inertia[2, 1] * wy + inertia[2, 2] * wz
    # w_g − h = [m g − m e ; c_w × m g − ω × j − m c_w × e]
    gx, gy, gz = mass * constants[GRAVITY], mass * constants[GRAVITY + 1], mass * constants[GRAVITY + 2]
    free_wrench[0], free_wrench[1], free_wrench[2] = gx - mass * ex, gy - mass * ey, gz - mass * ez
    free_wrench[3] = (oy * gz - oz * gy) - (wy * jz - wz * jy) - mass * (oy * ez - oz * ey)
    free_wrench[4] = (oz * gx - ox * gz) - (wz * jx - wx * jz) - mass * (oz * ex - ox * ez)
    free_wrench[5] = (ox * gy - oy * gx) - (wx * jy - wy * jx) - mass * (ox * ey - oy * ex)


def solve_symmetric(matrix, rhs, solution) -> bool:
    """`solution` of matrix · x = rhs, `matrix` 6 × 6 symmetric positive definite (M,
    M + (J/ρ²) W Wᵀ, W Wᵀ): by Cholesky, `matrix` overwritten with its factor. False, and
    no solution, when a pivot is not positive: the matrix is singular (to 1e-12 of its
    diagonal) or not positive definite."""
    n = rhs.shape[0]
    for j in range(n):
        total = matrix[j, j]
        for k in range(j):
            total -= matrix[j, k] * matrix[j, k]
        if not total > 1e-12 * matrix[j, j]:
            return False
        matrix[j, j] = sqrt(total)
        for i in range(j + 1, n):
            total = matrix[i, j]
            for k in range(j):
                total -= matrix[i, k] * matrix[j, k]
            matrix[i, j] = total / matrix[j, j]
    for i in range(n):
        total = rhs[i]
        for k in range(i):
            total -= matrix[i, k] * solution[k]
        solution[i] = total / matrix[i, i]
    for i in range(n - 1, -1, -1):
        total = solution[i]
        for k in range(i + 1, n):
            total -= matrix[k, i] * solution[k]
        solution[i] = total / matrix[i, i]
    return True


def velocity_product(units, lengths, arms, twist, kappa) -> None:
    """κ (m/s², into `kappa`) of pose_kinematics.velocity_product; `units` the cables'
    unit vectors in its first three columns (W's columns as rows do)."""
    vx, vy, vz, wx, wy, wz = twist[0], twist[1], twist[2], twist[3], twist[4], twist[5]
    for i in range(lengths.shape[0]):
        rx, ry, rz = arms[i, 0], arms[i, 1], arms[i, 2]
        ux, uy, uz = units[i, 0], units[i, 1], units[i, 2]
        swept_x, swept_y, swept_z = wy * rz - wz * ry, wz * rx - wx * rz, wx * ry - wy * rx
        sx, sy, sz = swept_x + vx, swept_y + vy, swept_z + vz
        along = ux * sx + uy * sy + uz * sz
        inward = (ux * (wy * swept_z - wz * swept_y) + uy * (wz * swept_x - wx * swept_z)
                  + uz * (wx * swept_y - wy * swept_x))
        kappa[i] = (sx * sx + sy * sy + sz * sz - along * along) / lengths[i] - inward


def taut_system(mass_matrix, base, columns, mask, coupling, weights, scale, system, rhs) -> bool:
    """M + coupling Σ w_i w_iᵀ (into `system`) and base + Σ w_i (scale · weights_i) (into
    `rhs`) over the cables of `mask`, W's columns as rows `columns`; whether any is in it."""
    for a in range(6):
        rhs[a] = base[a]
        for b in range(6):
            system[a, b] = mass_matrix[a, b]
    any_taut = False
    for i in range(columns.shape[0]):
        if mask[i] != 0.0:
            any_taut = True
            weight = scale * weights[i]
            for a in range(6):
                rhs[a] += columns[i, a] * weight
                for b in range(6):
                    system[a, b] += coupling * columns[i, a] * columns[i, b]
    return any_taut


def direct_dynamics(constants, exits, attachments, pose, twist, torque, joint_velocity, candidates, external_wrench,
                    acceleration, joint_acceleration, tension, taut) -> None:
    """(a, α) (into `acceleration`), θ̈, the tensions and which cables are taut, under
    motor torques c with rigid cables: platform.dynamics.direct_dynamics. The `candidates`
    that stay taut pull; one whose tension comes out negative goes slack and the rest are
    solved again, the most negative first; a slack motor spins freely."""
    m = exits.shape[0]
    inertia, viscous, radius = constants[MOTOR_INERTIA], constants[VISCOUS], constants[RADIUS]
    coupling = inertia / (radius * radius)
    rotation = np.empty((3, 3))
    rotation_of(pose, rotation)
    columns, lengths, arms = np.empty((m, 6)), np.empty(m), np.empty((m, 3))
    cables_at(pose, rotation, exits, attachments, columns, lengths, arms)
    kappa, pull = np.empty(m), np.empty(m)
    velocity_product(columns, lengths, arms, twist, kappa)
    mass_matrix, free = np.empty((6, 6)), np.empty(6)
    rigid_body(constants, rotation, twist, mass_matrix, free)
    for k in range(6):
        free[k] += external_wrench[k]
    # a taut cable's tension as the motor's equation gives it, before the platform's part
    for i in range(m):
        pull[i] = coupling * kappa[i] + (viscous / radius) * joint_velocity[i] - torque[i] / radius
        taut[i] = candidates[i]
    system, rhs = np.empty((6, 6)), np.empty(6)
    while True:
        any_taut = taut_system(mass_matrix, free, columns, taut, coupling, pull, 1.0, system, rhs)
        solve_symmetric(system, rhs, acceleration)
        most_negative, worst = 0.0, -1
        for i in range(m):
            tension[i] = 0.0
            if taut[i] != 0.0:
                along = 0.0
                for a in range(6):
                    along += columns[i, a] * acceleration[a]
                tension[i] = pull[i] - coupling * along
                if tension[i] < most_negative:
                    most_negative, worst = tension[i], i
        if not any_taut or worst < 0:
            break
        taut[worst] = 0.0
    for i in range(m):
        if taut[i] != 0.0:
            along = 0.0
            for a in range(6):
                along += columns[i, a] * acceleration[a]
            joint_acceleration[i] = (kappa[i] - along) / radius
        else:
            joint_acceleration[i] = (-viscous * joint_velocity[i] + torque[i]) / inertia
            tension[i] = 0.0


def motion_rows(constants, exits, attachments, poses, twists, accelerations, wrench_columns, lengths, wrenches,
                joint_velocity, joint_acceleration) -> None:
    """For each row k of a motion — pose, twist (v, ω) and its rate (a, α) — W's columns as
    rows (into `wrench_columns[k]`, m × 6), the lengths d (m), the wrench the cables must
    apply, M (a, α) − (w_g − h) (N, N·m), and the joint motion θ̇ = ḋ / ρ (rad/s) and
    θ̈ = (−Wᵀ (a, α) + κ) / ρ (rad/s²): the inverse dynamics of model.dynamics but for the
    tension distribution, a whole tabulated motion per call."""
    m = exits.shape[0]
    radius = constants[RADIUS]
    rotation, arms, kappa = np.empty((3, 3)), np.empty((m, 3)), np.empty(m)
    mass_matrix, free = np.empty((6, 6)), np.empty(6)
    for k in range(poses.shape[0]):
        rotation_of(poses[k], rotation)
        cables_at(poses[k], rotation, exits, attachments, wrench_columns[k], lengths[k], arms)
        rigid_body(constants, rotation, twists[k], mass_matrix, free)
        for a in range(6):
            total = 0.0
            for b in range(6):
                total += mass_matrix[a, b] * accelerations[k, b]
            wrenches[k, a] = total - free[a]
        velocity_product(wrench_columns[k], lengths[k], arms, twists[k], kappa)
        for i in range(m):
            joint_velocity[k, i] = length_rate(wrench_columns[k], i, twists[k]) / radius
            along = 0.0
            for b in range(6):
                along += wrench_columns[k, i, b] * accelerations[k, b]
            joint_acceleration[k, i] = (kappa[i] - along) / radius


def unit_product(w1, x1, y1, z1, w2, x2, y2, z2):
    """The unit quaternion (w, x, y, z), w ≥ 0, of the product of (w1, x1, y1, z1) and
    (w2, x2, y2, z2): rotating by the second, then by the first."""
    w = w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2
    qx = w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2
    qy = w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2
    qz = w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2
    norm = sqrt(w * w + qx * qx + qy * qy + qz * qz)
    if w < 0.0:
        norm = -norm
    return w / norm, qx / norm, qy / norm, qz / norm


def turn(pose, x, y, z) -> None:
    """The pose's orientation turned by the rotation vector (x, y, z) (rad, world frame),
    kept a unit quaternion with w ≥ 0."""
    angle = sqrt(x * x + y * y + z * z)
    half_sinc = 0.5 - angle * angle / 48.0 if angle < SMALL_ANGLE_RAD else sin(0.5 * angle) / angle
    pose[3], pose[4], pose[5], pose[6] = unit_product(cos(0.5 * angle), half_sinc * x, half_sinc * y,
                                                      half_sinc * z, pose[3], pose[4], pose[5], pose[6])


def move(pose, twist, acceleration, h) -> None:
    """Semi-implicit Euler over `h` s: the twist by the accelerations, then the pose with
    the new twist, the orientation turned by the rotation vector h ω."""
    for k in range(6):
        twist[k] += h * acceleration[k]
    for k in range(3):
        pose[k] += h * twist[k]
    turn(pose, h * twist[3], h * twist[4], h * twist[5])


def forward_kinematics(exits, attachments, lengths, used, pose, iterations, tolerance, step_tolerance) -> int:
    """Gauss–Newton from `pose` (updated in place) to the pose whose cable lengths d are
    `lengths` (m) on the `used` cables (pose_kinematics.forward_kinematics): each step
    solves the normal equations W Wᵀ δ = W (d − l) for δ = (δp, δφ), damped where W Wᵀ is
    singular. The steps taken when every length is met to `tolerance` or the step is
    below `step_tolerance`; −1 when `iterations` steps did not do it, −2 when not even the
    damped equations could be solved (lengths that are not numbers). A step that would
    raise the squared misfit Σ (d − l)² is halved until it does not (FK_STEP_HALVINGS);
    where none of them lowers it, the pose is the least-squares one to round-off, and
    the steps taken are returned."""
    m = exits.shape[0]
    rotation, columns, d, arms = np.empty((3, 3)), np.empty((m, 6)), np.empty(m), np.empty((m, 3))
    normal, system, rhs, step = np.empty((6, 6)), np.empty((6, 6)), np.empty(6), np.empty(6)
    trial = np.empty(7)
    # the geometry at the pose; after a step, the accepted trial's is the pose's
    rotation_of(pose, rotation)
    cables_at(pose, rotation, exits, attachments, columns, d, arms)
    for taken in range(iterations):
        worst = 0.0
        misfit = 0.0
        for a in range(6):
            rhs[a] = 0.0
            for b in range(6):
                normal[a, b] = 0.0
        for i in range(m):
            if used[i] != 0.0:
                residual = d[i] - lengths[i]
                worst = max(worst, abs(residual))
                misfit += residual * residual
                for a in range(6):
                    rhs[a] += columns[i, a] * residual
                    for b in range(6):
                        normal[a, b] += columns[i, a] * columns[i, b]
        if worst < tolerance:
            return taken
        for a in range(6):
            for b in range(6):
                system[a, b] = normal[a, b]
        if not solve_symmetric(system, rhs, step):
            # W Wᵀ singular here (six cables through a degenerate pose on the way): a
            # Levenberg–Marquardt step, damped by LEVENBERG_DAMPING of its largest entry
            largest = 0.0
            for a in range(6):
                largest = max(largest, normal[a, a])
            for a in range(6):
                for b in range(6):
                    system[a, b] = normal[a, b]
                system[a, a] += LEVENBERG_DAMPING * largest
            if not solve_symmetric(system, rhs, step):
                return -2
        scale, lowered = 1.0, False
        for _ in range(FK_STEP_HALVINGS):
            for k in range(7):
                trial[k] = pose[k]
            for k in range(3):
                trial[k] += scale * step[k]
            turn(trial, scale * step[3], scale * step[4], scale * step[5])
            rotation_of(trial, rotation)
            cables_at(trial, rotation, exits, attachments, columns, d, arms)
            raised = 0.0
            for i in range(m):
                if used[i] != 0.0:
                    residual = d[i] - lengths[i]
                    raised += residual * residual
            if raised <= misfit:
                lowered = True
                break
            scale *= 0.5
        if not lowered:
            return taken
        largest = 0.0
        for a in range(6):
            largest = max(largest, abs(scale * step[a]))
        for k in range(7):
            pose[k] = trial[k]
        if largest < step_tolerance:
            return taken + 1
    return -1


def rotation_towards(target, pose, phi) -> None:
    """φ (rad, world frame, into `phi`) that turns the pose's orientation into the unit
    quaternion `target`, |φ| in [0, π]: rotation.difference."""
    w, qx, qy, qz = unit_product(target[0], target[1], target[2], target[3], pose[3], -pose[4], -pose[5], -pose[6])
    sine = sqrt(qx * qx + qy * qy + qz * qz)
    scale = 2.0 if sine < SMALL_ANGLE_RAD else 2.0 * atan2(sine, w) / sine
    phi[0], phi[1], phi[2] = scale * qx, scale * qy, scale * qz


def nearest_wrench(columns, wrench, weights, tension_min_n, tension_max_n, tension) -> int:
    """τ (N, into `tension`) in [tension_min_n, tension_max_n] minimising |D (W τ − w)|²,
    D = diag(`weights`), W's columns the rows of `columns` (n × 6): the wrench `wrench`
    exactly where tensions within the bounds pull it, else the nearest in that norm (the
    weights say how much a moment's N·m counts against a force's N). The convex quadratic
    program is solved exactly by a primal active-set search (against scipy's bounded least
    squares in tests/test_tension_distribution.py): the steps it took; −1 where it did not
    end (a bug), −2 where a free set's system was singular."""
    n = columns.shape[0]
    hessian, gradient = np.empty((n, n)), np.empty(n)
    for i in range(n):
        total = 0.0
        for a in range(6):
            total += columns[i, a] * weights[a] * weights[a] * wrench[a]
        gradient[i] = total
        for j in range(n):
            total = 0.0
            for a in range(6):
                total += columns[i, a] * weights[a] * weights[a] * columns[j, a]
            hessian[i, j] = total
    trace = 0.0
    for i in range(n):
        trace += hessian[i, i]
    largest_entry, largest_gradient = 0.0, 0.0
    for i in range(n):
        hessian[i, i] += TIE_BREAK_SHARE * trace
        largest_gradient = max(largest_gradient, abs(gradient[i]))
        for j in range(n):
            largest_entry = max(largest_entry, abs(hessian[i, j]))
    slope_tolerance = SLOPE_TOLERANCE_SHARE * (largest_entry * tension_max_n + largest_gradient)
    held, free_index = np.zeros(n), np.empty(n, dtype=np.intp)
    target, step, reach = np.empty(n), np.empty(n), np.empty(n)
    for i in range(n):
        tension[i] = 0.5 * (tension_min_n + tension_max_n)
    for taken in range(ACTIVE_SET_STEPS_PER_CABLE * n):
        free = 0
        for i in range(n):
            target[i] = tension[i]
            if held[i] == 0.0:
                free_index[free] = i
                free += 1
        if free > 0:
            system, rhs, solution = np.empty((free, free)), np.empty(free), np.empty(free)
            for f in range(free):
                i = free_index[f]
                total = gradient[i]
                for j in range(n):
                    if held[j] != 0.0:
                        total -= hessian[i, j] * tension[j]
                rhs[f] = total
                for g in range(free):
                    system[f, g] = hessian[i, free_index[g]]
            if not solve_symmetric(system, rhs, solution):
                return -2
            for f in range(free):
                target[free_index[f]] = solution[f]
        # the longest share of the step that stays within the bounds
        share = 1.0
        for i in range(n):
            step[i] = target[i] - tension[i]
            if step[i] < 0.0:
                reach[i] = (tension_min_n - tension[i]) / step[i]
            elif step[i] > 0.0:
                reach[i] = (tension_max_n - tension[i]) / step[i]
            else:
                reach[i] = np.inf
            if held[i] == 0.0:
                share = min(share, reach[i])
        for i in range(n):
            tension[i] += share * step[i]
        if share < 1.0:
            for i in range(n):
                if held[i] == 0.0 and reach[i] <= share:
                    tension[i] = tension_min_n if step[i] < 0.0 else tension_max_n
                    held[i] = 1.0
            continue
        # a held cable whose bound the objective would rather leave is let go of, the
        # steepest first
        leaving, steepest = -1, 0.0
        for i in range(n):
            if held[i] != 0.0:
                slope = -gradient[i]
                for j in range(n):
                    slope += hessian[i, j] * tension[j]
                if ((tension[i] <= tension_min_n and slope < -slope_tolerance)
                        or (tension[i] >= tension_max_n and slope > slope_tolerance)) and abs(slope) > steepest:
                    leaving, steepest = i, abs(slope)
        if leaving < 0:
            return taken
        held[leaving] = 0.0
    return -1


def steered_rows(constants, exits, attachments, attached, origin, aim, target, gains, bounds, h, first_row,
                 pose, twist, rows) -> int:
    """Rows `first_row`, `first_row` + 1, … of a steered approach (cdpr_control.
    steered_approach) into `rows` (k × ROW_WIDTH: the pose, the twist and the twist rate
    (a, α) the tensions give there), the state (`pose`, `twist`) moved one period `h` on
    after each. `origin` is the approach's first pose, `aim` the shares c of the turn
    from its orientation to the target's at evenly spaced shares of the way
    (steered_approach.aim_schedule), `target` the target pose, `gains`
    (ω_p, ω_q in rad/s, the moment's weight, the ease-in in s), `bounds` the tensions'
    (N). 0, or nearest_wrench's failure."""
    m = exits.shape[0]
    count = 0
    for i in range(m):
        if attached[i] != 0.0:
            count += 1
    rotation, columns, lengths, arms = np.empty((3, 3)), np.empty((m, 6)), np.empty(m), np.empty((m, 3))
    pulling, tension = np.empty((count, 6)), np.empty(count)
    mass_matrix, system, free = np.empty((6, 6)), np.empty((6, 6)), np.empty(6)
    phi, pull, wrench, rhs, acceleration, weights = (np.empty(3), np.empty(6), np.empty(6), np.empty(6),
                                                     np.empty(6), np.empty(6))
    position_gain, orientation_gain, ease_in_s = gains[0], gains[1], gains[3]
    for a in range(6):
        weights[a] = 1.0 if a < 3 else gains[2]
    # the turn φ_0 from the origin's orientation to the target's, and the origin's distance
    turn_to_target, aimed = np.empty(3), np.empty(7)
    rotation_towards(target[3:], origin, turn_to_target)
    distance_m = sqrt((target[0] - origin[0]) ** 2 + (target[1] - origin[1]) ** 2 + (target[2] - origin[2]) ** 2)
    for k in range(rows.shape[0]):
        rotation_of(pose, rotation)
        cables_at(pose, rotation, exits, attachments, columns, lengths, arms)
        rigid_body(constants, rotation, twist, mass_matrix, free)
        # the pull eased in (smoothstep) from none at the first row
        share = 1.0 if ease_in_s <= 0.0 else min(1.0, (first_row + k) * h / ease_in_s)
        share = share * share * (3.0 - 2.0 * share)
        # the orientation aimed at, on the turn from the origin's to the target's, by the
        # share of the origin's distance covered: the orientations the cables left hold
        # the platform at shift with its position (steered_approach's docstring)
        progress = 1.0
        if distance_m > 0.0:
            left = sqrt((target[0] - pose[0]) ** 2 + (target[1] - pose[1]) ** 2 + (target[2] - pose[2]) ** 2)
            progress = min(1.0, max(0.0, 1.0 - left / distance_m))
        place = progress * (aim.shape[0] - 1)
        below = min(int(place), aim.shape[0] - 2)
        turned = aim[below] + (place - below) * (aim[below + 1] - aim[below])
        for a in range(7):
            aimed[a] = origin[a]
        turn(aimed, turned * turn_to_target[0], turned * turn_to_target[1], turned * turn_to_target[2])
        rotation_towards(aimed[3:], pose, phi)
        for a in range(3):
            pull[a] = share * (position_gain * position_gain * (target[a] - pose[a]) - 2.0 * position_gain * twist[a])
            pull[3 + a] = share * (orientation_gain * orientation_gain * phi[a]
                                   - 2.0 * orientation_gain * twist[3 + a])
        for a in range(6):
            total = 0.0
            for b in range(6):
                total += mass_matrix[a, b] * pull[b]
            wrench[a] = total - free[a]
        used = 0
        for i in range(m):
            if attached[i] != 0.0:
                for a in range(6):
                    pulling[used, a] = columns[i, a]
                used += 1
        status = nearest_wrench(pulling, wrench, weights, bounds[0], bounds[1], tension)
        if status < 0:
            return status
        # M (a, α) = W τ + w_g − h
        for a in range(6):
            total = free[a]
            for i in range(count):
                total += pulling[i, a] * tension[i]
            rhs[a] = total
            for b in range(6):
                system[a, b] = mass_matrix[a, b]
        solve_symmetric(system, rhs, acceleration)
        for a in range(7):
            rows[k, ROW_POSE + a] = pose[a]
        for a in range(6):
            rows[k, ROW_TWIST + a] = twist[a]
            rows[k, ROW_RATE + a] = acceleration[a]
        move(pose, twist, acceleration, h)
    return 0


def catch_slack(constants, rotation, columns, twist, speed, candidates, caught) -> None:
    """Where a `candidates` cable's end draws away from its exit point faster than its
    motor pays out (ḋ_i = −w_iᵀ (v, ω) > ρ θ̇_i: a slack cable pulled straight by the
    platform's swing), the inelastic jerk that ends it, in place: the twist ξ and the
    `caught` cables' θ̇ (a mask, written) projected onto their constraint ρ θ̇_i = ḋ_i in
    the kinetic energy's metric, (M + (J/ρ²) Σ w_i w_iᵀ) ξ⁺ = M ξ − (J/ρ) Σ w_i θ̇_i, at
    the rotation R and W's columns as rows `columns` of the pose. A cable whose jerk
    J (θ̇_i⁺ − θ̇_i) / ρ would push lets go, the most negative first. As the point mass's
    (point_mass.substeps.catch_slack); nothing changes where no cable is drawn so."""
    m = columns.shape[0]
    inertia, radius = constants[MOTOR_INERTIA], constants[RADIUS]
    coupling = inertia / (radius * radius)
    drawn = False
    for i in range(m):
        caught[i] = 0.0
        if candidates[i] != 0.0:
            rate = length_rate(columns, i, twist) - radius * speed[i]
            if rate > -CATCH_RATE_M_S:
                caught[i] = 1.0
                drawn = drawn or rate > CATCH_RATE_M_S
    if not drawn:
        return
    mass_matrix, free = np.empty((6, 6)), np.empty(6)
    rigid_body(constants, rotation, twist, mass_matrix, free)
    # the twist's momentum M ξ, the right-hand side before the caught motors' part
    momentum = np.empty(6)
    for a in range(6):
        total = 0.0
        for b in range(6):
            total += mass_matrix[a, b] * twist[b]
        momentum[a] = total
    system, rhs, caught_twist = np.empty((6, 6)), np.empty(6), np.empty(6)
    while True:
        taut_system(mass_matrix, momentum, columns, caught, coupling, speed, -(inertia / radius), system, rhs)
        solve_symmetric(system, rhs, caught_twist)
        most_negative, pushing = 0.0, -1
        for i in range(m):
            if caught[i] != 0.0:
                jerk = inertia * (length_rate(columns, i, caught_twist) / radius - speed[i]) / radius
                if jerk < most_negative:
                    most_negative, pushing = jerk, i
        if pushing < 0:
            break
        caught[pushing] = 0.0
    for k in range(6):
        twist[k] = caught_twist[k]
    for i in range(m):
        if caught[i] != 0.0:
            speed[i] = length_rate(columns, i, twist) / radius


def rigid_substeps(substeps, h, constants, exits, attachments, offsets, attached, torque, external_wrench,
                   pose, twist, angle, speed, tension, taut) -> None:
    """`substeps` sub-steps of `h` s of the rigid model (cdpr_twin.models.rigid_model), the
    state updated in place: each solves the direct dynamics with the attached cables not
    paid out beyond their straight-line length, moves, and puts the taut motors back on
    the kinematic constraint l = d, θ̇ = ḋ / ρ; those drawn straight are caught first
    (catch_slack)."""
    m = exits.shape[0]
    radius, tolerance = constants[RADIUS], constants[RETAUT]
    rotation = np.empty((3, 3))
    columns, lengths, arms = np.empty((m, 6)), np.empty(m), np.empty((m, 3))
    candidates, joint_acceleration, acceleration = np.empty(m), np.empty(m), np.empty(6)
    rotation_of(pose, rotation)
    cables_at(pose, rotation, exits, attachments, columns, lengths, arms)
    for _ in range(substeps):
        for i in range(m):
            candidates[i] = 1.0 if attached[i] != 0.0 and offsets[i] + radius * angle[i] <= lengths[i] + tolerance \
                else 0.0
        catch_slack(constants, rotation, columns, twist, speed, candidates, taut)
        direct_dynamics(constants, exits, attachments, pose, twist, torque, speed, candidates, external_wrench,
                        acceleration, joint_acceleration, tension, taut)
        move(pose, twist, acceleration, h)
        for i in range(m):
            speed[i] += h * joint_acceleration[i]
            angle[i] += h * speed[i]
        rotation_of(pose, rotation)
        cables_at(pose, rotation, exits, attachments, columns, lengths, arms)
        for i in range(m):
            if taut[i] != 0.0:
                angle[i] = (lengths[i] - offsets[i]) / radius
                speed[i] = length_rate(columns, i, twist) / radius


def spring_tensions(constants, exits, attachments, offsets, attached, pose, twist, angle, speed, tension,
                    wrench) -> None:
    """The elastic cables' tensions at a state (into `tension`): EA / l · stretch +
    damping · stretch rate, never negative, 0 for a detached cable (l = l_0 + ρ θ, the
    stretch rate ḋ − ρ θ̇); and the wrench W τ they apply (into `wrench`)."""
    m = exits.shape[0]
    radius, stiffness, damping = constants[RADIUS], constants[STIFFNESS], constants[DAMPING]
    rotation = np.empty((3, 3))
    columns, lengths, arms = np.empty((m, 6)), np.empty(m), np.empty((m, 3))
    rotation_of(pose, rotation)
    cables_at(pose, rotation, exits, attachments, columns, lengths, arms)
    for k in range(6):
        wrench[k] = 0.0
    for i in range(m):
        length = offsets[i] + radius * angle[i]
        pull = ((stiffness / length) * (lengths[i] - length)
                + damping * (length_rate(columns, i, twist) - radius * speed[i]))
        tension[i] = pull if attached[i] != 0.0 and lengths[i] > length and pull > 0.0 else 0.0
        for k in range(6):
            wrench[k] += columns[i, k] * tension[i]


def elastic_substeps(substeps, h, constants, exits, attachments, offsets, motors, attached, torque,
                     external_wrench, drums_locked, pose, twist, angle, speed, tension) -> None:
    """`substeps` sub-steps of `h` s of the elastic model (cdpr_twin.models.elastic_platform), the
    state updated in place: the twist with the tensions of the sub-step's start, then the
    pose and the motors with the new speeds, then the tensions of the end. Motors carry
    viscous and Coulomb friction (smoothed by tanh), each its own (`motors`, a column per
    motor: J_i in kg·m², b_i in N·m·s/rad, f_c,i in N·m), as real drives differ; locked
    drums neither pay out nor wind."""
    m = exits.shape[0]
    radius, smoothing = constants[RADIUS], constants[SMOOTHING]
    rotation, mass_matrix = np.empty((3, 3)), np.empty((6, 6))
    wrench, free, acceleration = np.empty(6), np.empty(6), np.empty(6)
    spring_tensions(constants, exits, attachments, offsets, attached, pose, twist, angle, speed, tension, wrench)
    for _ in range(substeps):
        rotation_of(pose, rotation)
        rigid_body(constants, rotation, twist, mass_matrix, free)
        for k in range(6):
            free[k] += wrench[k] + external_wrench[k]
        solve_symmetric(mass_matrix, free, acceleration)
        move(pose, twist, acceleration, h)
        for i in range(m):
            if drums_locked:
                speed[i] = 0.0
            else:
                friction = (motors[MOTOR_ROW_VISCOUS, i] * speed[i]
                            + motors[MOTOR_ROW_COULOMB, i] * tanh(speed[i] / smoothing))
                speed[i] += h * (torque[i] - friction + radius * tension[i]) / motors[MOTOR_ROW_INERTIA, i]
                angle[i] += h * speed[i]
        spring_tensions(constants, exits, attachments, offsets, attached, pose, twist, angle, speed, tension,
                        wrench)


HELPERS = (rotation_of, cables_at, length_rate, rigid_body, solve_symmetric, velocity_product, taut_system,
           direct_dynamics, catch_slack, unit_product, turn, move, spring_tensions, rotation_towards, nearest_wrench)


PYTHON = python_kernel(forward_kinematics, velocity_product, rigid_body, direct_dynamics, motion_rows, rigid_substeps,
                       elastic_substeps, move, nearest_wrench, steered_rows)


def signatures(types) -> dict:
    # writable C-contiguous float64 arrays only
    row, rows, count, flag = types.float64[::1], types.float64[:, ::1], types.intp, types.boolean
    stack = types.float64[:, :, ::1]
    geometry = (row, rows, rows, row)    # constants, exits, attachments, offsets
    return {forward_kinematics: count(rows, rows, row, row, row, count, types.float64, types.float64),
            velocity_product: types.void(rows, row, rows, row, row),
            rigid_body: types.void(row, rows, row, rows, row),
            direct_dynamics: types.void(row, rows, rows, *(row,) * 10),
            motion_rows: types.void(row, rows, rows, rows, rows, rows, stack, rows, rows, rows, rows),
            rigid_substeps: types.void(count, types.float64, *geometry, *(row,) * 9),
            elastic_substeps: types.void(count, types.float64, *geometry, rows, row, row, row, flag, *(row,) * 5),
            move: types.void(row, row, row, types.float64),
            nearest_wrench: count(rows, row, row, types.float64, types.float64, row),
            steered_rows: count(row, rows, rows, row, row, row, row, row, row, types.float64, count, row, row, rows)}


# kernel(name='compiled'): this module's functions as the kernel called `name` runs them
kernel = chooser(__name__, PYTHON)
