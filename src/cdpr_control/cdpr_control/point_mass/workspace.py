"""Residual static-equilibrium workspace (SEW) cross-sections and safe points."""
from __future__ import annotations

import numpy as np

from cdpr_control.model.robot import Robot


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


def contains(polygon: np.ndarray, point_xy) -> bool:
    """True when `point_xy` lies inside or on the counter-clockwise convex `polygon`."""
    following = np.roll(polygon, -1, axis=0)
    return all(_cross(a, b, point_xy) >= -1e-9 for a, b in zip(polygon, following))
