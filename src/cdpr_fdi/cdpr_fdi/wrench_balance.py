"""Is a free motor a broken cable, or a pushed end-effector? Newton's law decides.

A push (a hand, a brief contact with an obstacle) can slacken a cable as surely as a
break: its motor turns freely, its sensorless tension is zero, and identification (eq. 21)
alone would name it. What differs is the end-effector's balance. With the cables that
look free left out of placing it, the end-effector's motion and the cables' sensorless
tensions τ̂_j along their directions u_j, all read off the motors, leave

    F = m p̈ − Σ_j τ̂_j u_j − m g,

the force nothing on the robot explains: about zero when the free cables are broken, the
push itself when something outside pulls. p comes from the motor angles of the taut
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

from cdpr_control.kinematics import cable_vectors, forward_kinematics
from cdpr_control.robot import Robot

# The fewest taut cables that fix the end-effector's position (a point mass in space).
POSITION_CABLES = 3


class WrenchBalance:
    """The unexplained force on the end-effector over the last `window` periods (N)."""

    def __init__(self, robot: Robot, period_s: float, window: int):
        self.robot = robot
        self.period_s = period_s
        self.window = window
        # per tick: motor angles (rad), speeds (rad/s), sensorless tensions over the period
        # that ended there (N)
        self.ticks: deque[tuple[np.ndarray, np.ndarray, np.ndarray]] = deque(maxlen=window + 1)

    def record(self, tick: int, angle_rad: np.ndarray, angular_velocity_rad_s: np.ndarray,
               tension_n: np.ndarray) -> None:
        self.ticks.append((tick, np.asarray(angle_rad, float),
                           np.asarray(angular_velocity_rad_s, float), np.asarray(tension_n, float)))

    def unexplained_force_n(self, free_since: dict[int, int]) -> np.ndarray | None:
        """F (N) with the cables of `free_since` (0-based cable → the first tick its motor
        looked free) pulling nothing from then on, and as their motors said before (a
        cable that broke within the window pulled until it broke; once free, its motor's
        estimate is noise: an unloaded drum under a lagging drive), the others placing and
        moving the end-effector and pulling as their motors say. None until `window`
        periods are recorded, or when fewer than three cables are taut (they do not place
        the end-effector)."""
        taut = self.robot.cable_mask(list(free_since))
        if len(self.ticks) <= self.window or np.count_nonzero(taut) < POSITION_CABLES:
            return None
        (_, angle_then, speed_then, _), (_, angle_now, speed_now, _) = self.ticks[0], self.ticks[-1]
        velocity_then, _ = self.velocity_m_s(angle_then, speed_then, taut)
        velocity_now, position = self.velocity_m_s(angle_now, speed_now, taut)
        acceleration = (velocity_now - velocity_then) / (self.window * self.period_s)
        tensions = np.array([tension for _, _, _, tension in list(self.ticks)[1:]])
        ticks = np.array([tick for tick, _, _, _ in list(self.ticks)[1:]])
        for cable, since in free_since.items():
            tensions[ticks >= since, cable] = 0.0
        directions, _ = cable_vectors(self.robot.exit_points_m, position)
        robot = self.robot
        return robot.mass_kg * (acceleration - robot.gravity_m_s2) - directions.T @ tensions.mean(axis=0)

    def velocity_m_s(self, angle_rad: np.ndarray, angular_velocity_rad_s: np.ndarray,
                     taut: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """ṗ (m/s) from the taut cables' speeds, and p (m) from their angles."""
        position = forward_kinematics(self.robot, angle_rad, taut)
        directions, _ = cable_vectors(self.robot.exit_points_m[taut], position)
        length_rate = self.robot.motor.drum_radius_m * angular_velocity_rad_s[taut]
        velocity, *_ = np.linalg.lstsq(directions, -length_rate, rcond=None)
        return velocity, position


def overstretch_m(robot: Robot, angle_rad: np.ndarray, taut: np.ndarray) -> np.ndarray:
    """Per cable, the distance from its exit point to the end-effector (placed by the
    `taut` cables' motor angles) less the length its motor has paid out, l_i0 + ρ θ_i (m):
    at most the elastic stretch for an attached cable, negative for a slack one."""
    position = forward_kinematics(robot, np.asarray(angle_rad, float), taut)
    _, distance = cable_vectors(robot.exit_points_m, position)
    return distance - (robot.cable_length_offset_m + robot.motor.drum_radius_m * np.asarray(angle_rad, float))
