"""The dual active-set search of bounded_minimum_norm: one source, run by CPython or
compiled by numba (cdpr_control.kernels).

Goldfarb and Idnani's method projects z_ref onto the polytope {z : a_i · z ≥ b_i}: it adds
the most violated constraint, steps in the primal and the dual until it holds, dropping
an active one whose multiplier would turn negative on the way. On a handful of cables
each step is a few dot products and the solve of the active constraints' small Gram
system; as numpy expressions nearly all of a step's ~80 µs was numpy's per-call cost
(the projections of a recovery planned on an 8-cable point mass took two thirds of its
run), compiled it takes about a µs.

Statuses of `project`: SETTLED, or why not, with the constraint it concerns in
`failed[0]` where it names one.
"""
from __future__ import annotations

import numpy as np

from cdpr_control.kernels import chooser, python_kernel

SETTLED, UNSETTLED, UNREACHABLE, SINGULAR = range(4)


def solve_small(system, rhs, m, solution) -> bool:
    """x (into `solution`'s first `m`) with A x = b, A the top-left m × m of `system` and
    b the first m of `rhs` (both overwritten), by Gaussian elimination with partial
    pivoting; False where A is singular."""
    for column in range(m):
        pivot, largest = column, abs(system[column, column])
        for row in range(column + 1, m):
            if abs(system[row, column]) > largest:
                pivot, largest = row, abs(system[row, column])
        if largest == 0.0:
            return False
        if pivot != column:
            for k in range(m):
                system[column, k], system[pivot, k] = system[pivot, k], system[column, k]
            rhs[column], rhs[pivot] = rhs[pivot], rhs[column]
        for row in range(column + 1, m):
            factor = system[row, column] / system[column, column]
            for k in range(column, m):
                system[row, k] -= factor * system[column, k]
            rhs[row] -= factor * rhs[column]
    for row in range(m - 1, -1, -1):
        total = rhs[row]
        for k in range(row + 1, m):
            total -= system[row, k] * solution[k]
        solution[row] = total / system[row, row]
    return True


def project(normals, bounds, z, bound_tolerance, direction_tolerance, max_steps, failed) -> int:
    """z (updated in place, from z_ref) moved to the nearest point with normals · z ≥ bounds
    (rows of `normals`, n × r), within `bound_tolerance`; the status, and in `failed[0]` the
    constraint that no step can bring in (UNREACHABLE)."""
    count, size = normals.shape[0], normals.shape[1]
    active = np.empty(count, dtype=np.intp)
    multipliers, dual = np.empty(count + 1), np.empty(count)
    primal, normal = np.empty(size), np.empty(size)
    gram, rhs = np.empty((count, count)), np.empty(count)
    held = 0
    for _ in range(max_steps):
        violated, least = 0, np.inf
        for i in range(count):
            slack = -bounds[i]
            for k in range(size):
                slack += normals[i, k] * z[k]
            if slack < least:
                violated, least = i, slack
        if least >= -bound_tolerance:
            return SETTLED
        # one Goldfarb–Idnani step: constraint `violated` made active, others dropped as needed
        for k in range(size):
            normal[k] = normals[violated, k]
        multipliers[held] = 0.0
        while True:
            if held:
                for a in range(held):
                    total = 0.0
                    for k in range(size):
                        total += normals[active[a], k] * normal[k]
                    rhs[a] = total
                    for b in range(held):
                        total = 0.0
                        for k in range(size):
                            total += normals[active[a], k] * normals[active[b], k]
                        gram[a, b] = total
                if not solve_small(gram, rhs, held, dual):
                    return SINGULAR
            for k in range(size):
                total = normal[k]
                for a in range(held):
                    total -= normals[active[a], k] * dual[a]
                primal[k] = total
            # the largest dual step keeping the active multipliers non-negative
            partial, dropped = np.inf, -1
            for a in range(held):
                if dual[a] > direction_tolerance:
                    ratio = multipliers[a] / dual[a]
                    if ratio < partial:
                        partial, dropped = ratio, a
            curvature, reach = 0.0, -bounds[violated]
            for k in range(size):
                curvature += primal[k] * primal[k]
                reach += normal[k] * z[k]
            full = -reach / curvature if curvature > direction_tolerance else np.inf
            step = min(full, partial)
            if not np.isfinite(step):
                failed[0] = violated
                return UNREACHABLE
            if np.isfinite(full):
                for k in range(size):
                    z[k] += step * primal[k]
            for a in range(held):
                multipliers[a] -= step * dual[a]
            multipliers[held] += step
            if full <= partial:
                active[held] = violated
                held += 1
                break
            # constraint `dropped` leaves; the new one's multiplier moves down with the rest
            for a in range(dropped, held - 1):
                active[a] = active[a + 1]
            for a in range(dropped, held):
                multipliers[a] = multipliers[a + 1]
            held -= 1
    return UNSETTLED


# what the compiled functions call: compiled with them
HELPERS = (solve_small,)
PYTHON = python_kernel(project)


def signatures(types) -> dict:
    rows, row, floats = types.float64[:, ::1], types.float64[::1], types.float64
    return {project: types.intp(rows, row, row, floats, floats, types.intp, types.intp[::1])}


# kernel(name='compiled'): this module's functions as the kernel called `name` runs them
kernel = chooser(__name__, PYTHON)
