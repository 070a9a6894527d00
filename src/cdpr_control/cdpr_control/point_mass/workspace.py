"""Residual static-equilibrium workspace (SEW) cross-sections and safe points."""
from __future__ import annotations

import numpy as np

from cdpr_control.model.dynamics import inverse_dynamics
from cdpr_control.model.robot import Robot
from cdpr_control.model.searches import found_once, section_grid
from cdpr_control.tension_distribution import make_tension_distribution

# Held safe points already found (a grid of the workspace box's section where the paper's
# SP is not held: ~0.1 s, more than a tick), or why there is none (model.searches)
_found: dict[tuple, 'np.ndarray | str'] = {}
# Points a side of the coarse grid a height is first looked at on (held_safe_point)
COARSE_SIDE = 17


def sew_cross_section(robot: Robot, attached, height_m: float) -> np.ndarray:
    """Border (k × 2, counter-clockwise) of the SEW of the `attached` cables at z = height.

    A point mass hangs in equilibrium at p iff the upward vertical through p meets the
    convex hull of the exit points above p. The cross-section is therefore the x-y
    projection of that hull cut by the half-space z > height: the hull of the exit
    points above the plane and of the points where segments between exit points on
    either side cross it. Exit points at one height give the hull of their projections.
    """
    points = robot.exit_points_m[attached]
    above = points[points[:, 2] > height_m]
    below = points[points[:, 2] <= height_m]
    crossings = []
    for top in above:
        for bottom in below:
            s = (top[2] - height_m) / (top[2] - bottom[2])
            crossings.append(top + s * (bottom - top))
    candidates = np.vstack([above] + ([np.array(crossings)] if crossings else []))[:, :2]
    return convex_hull(candidates)


def convex_hull(points: np.ndarray) -> np.ndarray:
    """Vertices of the 2-D convex hull, counter-clockwise (Andrew's monotone chain)."""
    ordered = sorted(set(map(tuple, np.round(points, 12))))
    if len(ordered) < 3:
        return np.array(ordered)

    def chain(sequence):
        hull = []
        for point in sequence:
            while len(hull) >= 2 and _cross(hull[-2], hull[-1], point) <= 0.0:
                hull.pop()
            hull.append(point)
        return hull

    lower = chain(ordered)
    upper = chain(reversed(ordered))
    return np.array(lower[:-1] + upper[:-1])


def _cross(o, a, b) -> float:
    return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])


def polygon_centroid(polygon: np.ndarray) -> np.ndarray:
    """Area barycentre of a simple polygon (k × 2) by the shoelace formula."""
    if len(polygon) < 3:
        raise ValueError('the SEW cross-section has no area')
    x, y = polygon[:, 0], polygon[:, 1]
    x_next, y_next = np.roll(x, -1), np.roll(y, -1)
    cross = x * y_next - x_next * y
    area = cross.sum() / 2.0
    if abs(area) < 1e-12:
        raise ValueError('the SEW cross-section has no area')
    return np.array([((x + x_next) * cross).sum(), ((y + y_next) * cross).sum()]) / (6.0 * area)


def safe_point(robot: Robot, attached, height_m: float) -> np.ndarray:
    """SP: barycentre of the residual SEW cross-section at `height_m` (paper §3.2)."""
    centre = polygon_centroid(sew_cross_section(robot, attached, height_m))
    return np.array([centre[0], centre[1], height_m])


def holding_tensions_each(robot: Robot, positions_m, attached) -> np.ndarray:
    """Tensions (n × cables, N, 0 for a detached cable) of the `attached` cables within
    [tension_min_n, tension_max_n] that hold the end-effector at rest at each of the
    positions (n × 3, m), the minimum-norm ones; NaN for the attached cables of a row
    where there are none (the inverse dynamics at rest, as the platform's statics)."""
    positions_m = np.atleast_2d(np.asarray(positions_m, dtype=float))
    still = np.zeros(positions_m.shape)
    distribution = make_tension_distribution('bounded_minimum_norm', robot.tension_min_n, robot.tension_max_n)
    return inverse_dynamics(robot, distribution, positions_m, still, still, attached=np.asarray(attached, dtype=bool),
                            nan_where_infeasible=True).tension_n


def held_safe_point(robot: Robot, attached, height_m: float, spacing_m: float, lowest_m: float) -> np.ndarray:
    """SP (m) where the `attached` cables hold the end-effector within [tension_min_n,
    tension_max_n]: the paper's (`safe_point`) where they do there, else the barycentre
    of the residual wrench-feasible workspace's section at `height_m` — the mean of the
    points of a grid `spacing_m` apart over the workspace box's x-y extent where they do,
    as a platform's safe pose (docs/design.md §5). The paper's SEW asks only for tensions
    that are not negative: with a heavy end-effector under cables far from vertical its
    barycentre can need more than τ_max of a cable, and no move ends there. The bounds,
    not the plan's margin above τ_min: a light end-effector on many cables is held
    nowhere with it (the recovery lowers it where a pose needs, LoweredFloor). Where
    there is no such section at `height_m`, or its barycentre is not held (a section
    that is not convex), the same at the nearest height of the workspace box above
    `lowest_m` (the table), `spacing_m` apart, where there is (a drawn 5-cable robot's
    four cables held it where it broke but nowhere at 1.2 m): each height first looked at
    on a grid of COARSE_SIDE² points, the fine grid's ~0.2 ms a point being spent only
    where that one holds it somewhere. ValueError where there is none. Found once per
    robot, cables and settings (model.searches)."""
    attached = np.asarray(attached, dtype=bool)
    key = (attached.tobytes(), float(height_m), float(spacing_m), float(lowest_m))
    return found_once(_found, robot, key, lambda: _held_at_a_height(robot, attached, height_m, spacing_m,
                                                                      lowest_m)).copy()


def _held_at_a_height(robot: Robot, attached: np.ndarray, height_m: float, spacing_m: float,
                      lowest_m: float) -> 'np.ndarray | str':
    """`held_safe_point`'s search over the heights, or why it found none."""
    found = _held_safe_point(robot, attached, height_m, spacing_m)
    if not isinstance(found, str):
        return found
    heights = np.arange(robot.workspace_max_m[2], max(lowest_m, robot.workspace_min_m[2]), -spacing_m)
    heights = heights[(heights > lowest_m) & ~np.isclose(heights, height_m)]
    for other in heights[np.argsort(np.abs(heights - height_m), kind='stable')]:
        coarse = section_grid(robot, other, points_per_side=COARSE_SIDE)
        if np.isnan(holding_tensions_each(robot, coarse, attached)).any(axis=1).all():
            continue
        point = _held_safe_point(robot, attached, other, spacing_m)
        if not isinstance(point, str):
            return point
    return f'{found}; nor at any height of the workspace above {lowest_m:g} m'


def _held_safe_point(robot: Robot, attached: np.ndarray, height_m: float, spacing_m: float) -> 'np.ndarray | str':
    """`held_safe_point`'s search at `height_m`, or why it found none."""
    paper = safe_point(robot, attached, height_m)
    if not np.isnan(holding_tensions_each(robot, paper, attached)).any():
        return paper
    positions = section_grid(robot, height_m, spacing_m)
    held = ~np.isnan(holding_tensions_each(robot, positions, attached)).any(axis=1)
    bounds = f'[{robot.tension_min_n:g}, {robot.tension_max_n:g}] N'
    if not held.any():
        return f'the remaining cables hold the end-effector nowhere at z = {height_m} m within {bounds}'
    barycentre = positions[held].mean(axis=0)
    if np.isnan(holding_tensions_each(robot, barycentre, attached)).any():
        return (f'the barycentre {np.round(barycentre, 4).tolist()} m of where the remaining cables hold the '
                f'end-effector at z = {height_m} m within {bounds} is not held itself')
    return barycentre


def contains(polygon: np.ndarray, point_xy) -> bool:
    """True when `point_xy` lies inside or on the counter-clockwise convex `polygon`."""
    following = np.roll(polygon, -1, axis=0)
    return all(_cross(a, b, point_xy) >= -1e-9 for a, b in zip(polygon, following))
