"""Where a platform goes after a cable breaks: its safe pose (docs/design.md §5, "A
platform's safe pose").

The paper's safe point for a point mass is the barycentre of the residual static
equilibrium workspace's cross-section at the safe height. A platform's residual workspace
depends on its orientation as well as on its position, so the criterion is taken at each
of a few candidate orientations — the home orientation, and the home orientation turned
by each of `turns_deg` both ways about the world's x, y and z axes — and the candidate
that holds best is kept:

1. at orientation q, the cross-section at the safe height of the residual wrench-feasible
   workspace — the positions where the remaining cables hold the platform at rest with
   every tension within [τ_min, τ_max] — is sampled on a grid of the workspace box
   `spacing_m` apart, and its barycentre b(q) is the mean of the points inside it;
2. the tension margin of a pose is the least distance of the remaining cables' holding
   tensions (the bounded minimum-norm ones the plant and the recovery hold it with) to
   either bound: how far the pose is from the workspace's border, in newtons;
3. the safe pose is (b(q*), q*), q* the candidate whose barycentre has the largest
   margin; a barycentre outside its own section (a section that is not convex) does not
   count.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from cdpr_control.platform.statics import static_tensions_each
from cdpr_control.model.robot import Robot
from cdpr_control.model.searches import found_once, section_grid
from cdpr_control.geometry.rotation import from_axis_angle, normalised, product

AXES = np.eye(3)
# Safe poses already found (~0.2 s each on the shipped platform), or why there is none
# (model.searches): a supervisor finds every single break's when it starts
# (cdpr_fdi.recovery_planning.recovery.find_safe_targets), a run's length and the naming ask again.
_found: dict[tuple, 'SafePose | str'] = {}


@dataclass(frozen=True)
class SafePose:
    """A safe pose: position (m), orientation (unit quaternion), its tension margin (N),
    and the points (n × 2, m) of the cross-section sampled at its orientation."""

    position_m: np.ndarray
    orientation: np.ndarray
    tension_margin_n: float
    section_m: np.ndarray


def tension_margin_n(robot: Robot, position_m, orientation, attached) -> float:
    """The least distance (N) of the `attached` cables' holding tensions to τ_min or τ_max
    at the pose; −inf where no tensions within the bounds hold the platform there."""
    return float(tension_margins_n(robot, np.atleast_2d(position_m), orientation, attached)[0])


def tension_margins_n(robot: Robot, positions_m, orientation, attached) -> np.ndarray:
    """`tension_margin_n` at each of the positions (n × 3, m) at one orientation."""
    tension = static_tensions_each(robot, np.asarray(positions_m, dtype=float), orientation, attached)[:, attached]
    margins = np.minimum(np.min(tension - robot.tension_min_n, axis=1), np.min(robot.tension_max_n - tension, axis=1))
    # where the distribution puts a cable on a bound, rounding leaves it ~1e-16 N either
    # side: such a pose is held, with no margin (not left out of the workspace by the sign)
    return np.where(np.isnan(margins), -np.inf, np.maximum(margins, 0.0))


def candidate_orientations(home_orientation, turns_deg) -> list[np.ndarray]:
    """The home orientation, then it turned by each of `turns_deg` (deg) both ways about
    the world's x, y and z axes."""
    candidates = [normalised(home_orientation)]
    for turn in turns_deg:
        for axis in AXES:
            for sign in (1.0, -1.0):
                candidates.append(normalised(product(from_axis_angle(axis, sign * np.radians(turn)),
                                                     home_orientation)))
    return candidates


def residual_section(robot: Robot, attached, orientation, height_m: float, spacing_m: float) -> np.ndarray:
    """The points (n × 2, m) of a grid `spacing_m` apart over the workspace box's x-y extent
    where the `attached` cables hold the platform at `orientation` and `height_m`."""
    positions = section_grid(robot, height_m, spacing_m)
    return positions[tension_margins_n(robot, positions, orientation, attached) >= 0.0, :2]


def safe_pose(robot: Robot, attached, height_m: float, turns_deg, spacing_m: float) -> SafePose:
    """The safe pose of the module docstring for the `attached` cables (boolean mask) at
    `height_m`; ValueError when no candidate orientation has a residual workspace there.
    Found once per robot, cables and settings (model.searches)."""
    attached = np.asarray(attached, dtype=bool)
    return found_once(_found, robot, (attached.tobytes(), float(height_m), tuple(map(float, turns_deg)),
                                      float(spacing_m)),
                      lambda: _search(robot, attached, height_m, turns_deg, spacing_m))


def _search(robot: Robot, attached: np.ndarray, height_m: float, turns_deg, spacing_m: float) -> 'SafePose | str':
    """`safe_pose`'s search, or why it found none."""
    best = None
    for orientation in candidate_orientations(robot.body.home_orientation, turns_deg):
        section = residual_section(robot, attached, orientation, height_m, spacing_m)
        if not len(section):
            continue
        position = np.append(section.mean(axis=0), height_m)
        margin = tension_margin_n(robot, position, orientation, attached)
        if margin >= 0.0 and (best is None or margin > best.tension_margin_n):
            best = SafePose(position, orientation, margin, section)
    if best is None:
        return (f'the remaining cables hold the platform nowhere at z = {height_m} m at any of '
                f'the {1 + 6 * len(turns_deg)} orientations tried')
    return best
