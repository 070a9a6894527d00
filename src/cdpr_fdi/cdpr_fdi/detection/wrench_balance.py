"""Is a free motor a broken cable, or a pushed end-effector? Newton's law decides.

A push (a hand, a brief contact with an obstacle) can slacken a cable as surely as a
break: its motor turns freely, its sensorless tension is zero, and identification (eq. 21)
alone would name it. What differs is the end-effector's balance. With the cables that
look free left out of placing it, the end-effector's motion and the cables' sensorless
tensions τ̂_j along their directions u_j, all read off the motors, leave

    F = m p̈ − Σ_j τ̂_j u_j − m g,

the force nothing on the robot explains: about zero when the free cables are broken, the
push itself when something outside pulls. A platform's is the force part of the wrench
M (a, α) − (w_g − h) − Σ_j τ̂_j w_j (cdpr_control.platform.dynamics), its pose and twist
read off the taut cables' motors the same way. p comes from the motor angles of the taut
cables (forward kinematics), ṗ from their resolver speeds (ρ θ̇_j = −u_jᵀ ṗ, as sharp as
the speeds, where differentiating positions would amplify their quantisation), p̈ from two
speeds `window` periods apart, and τ̂ is averaged over the same periods, so both sides
describe one stretch of time: a free cable pulled as its motor said until it looked free,
nothing since.

A balance that holds does not prove a break, though: after a push the end-effector
swings, and a cable can go slack with nothing pushing. What does prove one is a cable
spanning more than its length: an attached cable is never longer than the motor has
paid out (beyond its elastic stretch), while a broken one's end-effector falls away from
its exit point as its motor, unloaded, winds in (`overstretch_m`).
"""
from __future__ import annotations

from collections import deque

import numpy as np

from cdpr_control.model.robot import Robot

# The twist the taut cables' speeds give has no part along a direction whose singular
# value of their structure matrix is under this share of the largest: their speeds do not
# see it (a drawn suspended platform's six cables left, at home orientation, had one of
# 4e-9 against 1.75, and its speeds' noise made a twist of 3 km/s and 8e4 rad/s).
TWIST_RCOND = 1e-3


class WrenchBalance:
    """The unexplained force on the end-effector over the last `window` periods (N)."""

    def __init__(self, robot: Robot, period_s: float, window: int):
        self.robot = robot
        self.period_s = period_s
        self.window = window
        # per tick: motor angles (rad), speeds (rad/s), sensorless tensions over the period
        # that ended there (N), and its placements found so far (taut cables → placement):
        # a tick placed as "now" is placed again as "then" `window` ticks later
        self.ticks: deque[tuple[int, np.ndarray, np.ndarray, np.ndarray, dict]] = deque(maxlen=window + 1)

    def record(self, tick: int, angle_rad: np.ndarray, angular_velocity_rad_s: np.ndarray,
               tension_n: np.ndarray) -> None:
        self.ticks.append((tick, np.asarray(angle_rad, float),
                           np.asarray(angular_velocity_rad_s, float), np.asarray(tension_n, float), {}))

    def _placed(self, recorded, taut: np.ndarray):
        """`placement` of a recorded tick by the `taut` cables, found once."""
        _, angle, speed, _, placements = recorded
        key = taut.tobytes()
        if key not in placements:
            placements[key] = placement(self.robot, angle, speed, taut)
        return placements[key]

    def unexplained_force_n(self, free_since: dict[int, int]) -> np.ndarray | None:
        """F (N) with the cables of `free_since` (0-based cable → the first tick its motor
        looked free) pulling nothing from then on, and as their motors said before (a
        cable that broke within the window pulled until it broke; once free, its motor's
        estimate is noise: an unloaded drum under a lagging drive), the others placing and
        moving the end-effector and pulling as their motors say. None until `window`
        periods are recorded, or when fewer cables are taut than the end-effector has
        degrees of freedom (they do not place it). A platform's is the force part of
        M (a, α) − (w_g − h) − W τ̂: a push has a force wherever it acts."""
        robot = self.robot
        taut = robot.cable_mask(list(free_since))
        if len(self.ticks) <= self.window or np.count_nonzero(taut) < robot.degrees_of_freedom:
            return None
        twist_then = self._placed(self.ticks[0], taut)[2]
        _, orientation, twist_now, structure = self._placed(self.ticks[-1], taut)
        acceleration = (twist_now - twist_then) / (self.window * self.period_s)
        window = list(self.ticks)[1:]
        tensions = np.array([tension for _, _, _, tension, _ in window])
        ticks = np.array([tick for tick, *_ in window])
        for cable, since in free_since.items():
            tensions[ticks >= since, cable] = 0.0
        return robot.body.unbalanced_force_n(robot, orientation, twist_now, acceleration,
                                             structure @ tensions.mean(axis=0))


def placement(robot: Robot, angle_rad, angular_velocity_rad_s, taut: np.ndarray, pose=None):
    """The end-effector as the `taut` cables place and move it: (position m, orientation
    or None for a point mass, twist — ṗ (m/s), or a platform's (v, ω) — and the wrench
    matrix at the pose). The pose by forward kinematics of their angles (`pose` where the
    caller found it: a recovery's, model.pose_tracking), the twist from
    their speeds, ρ θ̇_j = −w_jᵀ twist, in the least-squares sense (as sharp as the speeds,
    where differentiating poses would amplify their quantisation), none along a direction
    they barely see (TWIST_RCOND)."""
    position, orientation = (robot.body.pose_of_angles(robot, np.asarray(angle_rad, float), taut)
                             if pose is None else pose)
    structure = robot.body.structure_matrix(robot, position, orientation)
    twist, *_ = np.linalg.lstsq(structure[:, taut].T,
                                -robot.motor.drum_radius_m * np.asarray(angular_velocity_rad_s, float)[taut],
                                rcond=TWIST_RCOND)
    return position, orientation, twist, structure


def overstretch_m(robot: Robot, angle_rad: np.ndarray, taut: np.ndarray) -> np.ndarray:
    """Per cable, the distance from its exit point to its end on the end-effector (placed
    by the `taut` cables' motor angles) less the length its motor has paid out,
    l_i0 + ρ θ_i (m): at most the elastic stretch for an attached cable, negative for a
    slack one."""
    angle = np.asarray(angle_rad, float)
    distance = np.linalg.norm(robot.exit_points_m - robot.cable_ends_m(
        *robot.body.pose_of_angles(robot, angle, taut)), axis=1)
    return distance - (robot.cable_length_offset_m + robot.motor.drum_radius_m * angle)
