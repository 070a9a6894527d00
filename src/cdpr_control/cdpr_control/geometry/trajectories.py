"""Cartesian reference trajectories that start and end at rest.

Every trajectory gives position (m), velocity (m/s) and acceleration (m/s²) at time t
(s) from its start; before 0 and after `duration_s` it rests at its ends. t is a number
(each figure a 3-vector) or an array of n times (each figure n × 3), which is how a
reference is tabulated.
"""
from __future__ import annotations

from abc import ABC, abstractmethod

import numpy as np

# Peak of the quintic rest-to-rest profile's speed, in units of (distance / duration).
QUINTIC_PEAK_SPEED_RATIO = 1.875


def quintic_profile(t, duration_s: float):
    """s, ṡ, s̈ of s(τ) = 10τ³ − 15τ⁴ + 6τ⁵, τ = t / T clipped to [0, 1]; of each element
    for an array t."""
    tau = _fraction(t, duration_s)
    tau2 = tau * tau
    s = tau2 * tau * (10.0 - 15.0 * tau + 6.0 * tau2)
    s_dot = 30.0 * tau2 * (1.0 - tau) ** 2 / duration_s
    s_ddot = 60.0 * tau * (1.0 - tau) * (1.0 - 2.0 * tau) / duration_s ** 2
    return s, s_dot, s_ddot


def quintic_time_at_fraction(fraction: float, duration_s: float) -> float:
    """Time (s) at which the quintic profile of duration T reaches s = fraction."""
    if not 0.0 <= fraction <= 1.0:
        raise ValueError(f'fraction must be within [0, 1], got {fraction}')
    low, high = 0.0, duration_s
    for _ in range(60):
        middle = 0.5 * (low + high)
        if quintic_profile(middle, duration_s)[0] < fraction:
            low = middle
        else:
            high = middle
    return 0.5 * (low + high)


def _fraction(t, duration_s: float):
    """t / T clipped to [0, 1], elementwise for an array t."""
    if isinstance(t, np.ndarray):
        return np.clip(t / duration_s, 0.0, 1.0)
    # numpy's clip costs microseconds on a number: the recovery's tension phase asks every tick
    return min(max(t / duration_s, 0.0), 1.0)


def _column(value):
    """A number, or n numbers as an n × 1 column, to scale 3-vectors row by row."""
    return np.asarray(value)[..., None]


class Trajectory(ABC):

    duration_s: float

    @abstractmethod
    def sample(self, t):
        """(p, ṗ, p̈) at time t (s)."""

    @abstractmethod
    def reversed(self) -> 'Trajectory':
        """The same path run from its end back to its start."""

    @property
    def start(self) -> np.ndarray:
        return self.sample(0.0)[0]

    @property
    def end(self) -> np.ndarray:
        return self.sample(self.duration_s)[0]


class StraightLine(Trajectory):
    """A straight segment with a quintic (rest-to-rest) time law."""

    def __init__(self, start_m, goal_m, duration_s: float):
        if duration_s <= 0.0:
            raise ValueError(f'duration must be positive, got {duration_s}')
        self.start_m = np.array(start_m, dtype=float)
        self.goal_m = np.array(goal_m, dtype=float)
        self.duration_s = float(duration_s)

    @classmethod
    def with_peak_speed(cls, start_m, goal_m, peak_speed_m_s: float) -> 'StraightLine':
        length = float(np.linalg.norm(np.subtract(goal_m, start_m)))
        if length == 0.0:
            raise ValueError('start and goal coincide')
        return cls(start_m, goal_m, QUINTIC_PEAK_SPEED_RATIO * length / peak_speed_m_s)

    def sample(self, t):
        s, s_dot, s_ddot = quintic_profile(t, self.duration_s)
        delta = self.goal_m - self.start_m
        return (self.start_m + _column(s) * delta, _column(s_dot) * delta,
                _column(s_ddot) * delta)

    def reversed(self) -> 'StraightLine':
        return StraightLine(self.goal_m, self.start_m, self.duration_s)


class Circle(Trajectory):
    """A horizontal arc whose angle follows a quintic law (smooth start and stop)."""

    def __init__(self, centre_m, radius_m: float, start_angle_rad: float, sweep_rad: float,
                 duration_s: float):
        if radius_m <= 0.0 or duration_s <= 0.0 or sweep_rad == 0.0:
            raise ValueError('radius, duration and sweep must be non-zero and positive')
        self.centre_m = np.array(centre_m, dtype=float)
        self.radius_m = float(radius_m)
        self.start_angle_rad = float(start_angle_rad)
        self.sweep_rad = float(sweep_rad)
        self.duration_s = float(duration_s)

    @classmethod
    def with_peak_speed(cls, centre_m, radius_m, start_angle_rad, sweep_rad,
                        peak_speed_m_s: float) -> 'Circle':
        arc = abs(sweep_rad) * radius_m
        return cls(centre_m, radius_m, start_angle_rad, sweep_rad,
                   QUINTIC_PEAK_SPEED_RATIO * arc / peak_speed_m_s)

    def sample(self, t):
        s, s_dot, s_ddot = quintic_profile(t, self.duration_s)
        angle = self.start_angle_rad + s * self.sweep_rad
        rate = s_dot * self.sweep_rad
        angular_acceleration = s_ddot * self.sweep_rad
        cos, sin = np.cos(angle), np.sin(angle)
        radial = np.stack([cos, sin, np.zeros_like(cos)], axis=-1)
        tangent = np.stack([-sin, cos, np.zeros_like(cos)], axis=-1)
        r = self.radius_m
        position = self.centre_m + r * radial
        velocity = r * _column(rate) * tangent
        acceleration = (r * _column(angular_acceleration) * tangent
                        - r * _column(rate ** 2) * radial)
        return position, velocity, acceleration

    def reversed(self) -> 'Circle':
        return Circle(self.centre_m, self.radius_m, self.start_angle_rad + self.sweep_rad,
                      -self.sweep_rad, self.duration_s)


class HermiteQuintic(Trajectory):
    """A quintic from p_0 with velocity v_0 and acceleration a_0 to p_1 with velocity v_1
    and acceleration a_1 (both accelerations zero unless given):
    p = p_0 + (p_1 − p_0) s(τ) + T (v_0 w(τ) − v_1 w(1 − τ)) + T² (a_0 z(τ) + a_1 z(1 − τ)),
    w(τ) = τ − 6τ³ + 8τ⁴ − 3τ⁵ (w, w'' vanish at both ends, w'(0) = 1, w'(1) = 0),
    z(τ) = τ² (1 − τ)³ / 2 (z, z' vanish at both ends, z''(0) = 1, z''(1) = 0).

    It takes over a motion already under way without a jump in velocity, or — given the
    acceleration the end-effector has — in the force its cables must apply.
    """

    def __init__(self, start_m, start_velocity_m_s, goal_m, goal_velocity_m_s, duration_s: float,
                 start_acceleration_m_s2=(0.0, 0.0, 0.0), goal_acceleration_m_s2=(0.0, 0.0, 0.0)):
        if duration_s <= 0.0:
            raise ValueError(f'duration must be positive, got {duration_s}')
        self.start_m = np.array(start_m, dtype=float)
        self.start_velocity_m_s = np.array(start_velocity_m_s, dtype=float)
        self.goal_m = np.array(goal_m, dtype=float)
        self.goal_velocity_m_s = np.array(goal_velocity_m_s, dtype=float)
        self.duration_s = float(duration_s)
        self.start_acceleration_m_s2 = np.array(start_acceleration_m_s2, dtype=float)
        self.goal_acceleration_m_s2 = np.array(goal_acceleration_m_s2, dtype=float)

    @staticmethod
    def _velocity_blend(tau: float):
        """w, dw/dτ, d²w/dτ² at τ."""
        tau2 = tau * tau
        return (tau - 6.0 * tau2 * tau + 8.0 * tau2 * tau2 - 3.0 * tau2 * tau2 * tau,
                1.0 - 18.0 * tau2 + 32.0 * tau2 * tau - 15.0 * tau2 * tau2,
                -36.0 * tau + 96.0 * tau2 - 60.0 * tau2 * tau)

    @staticmethod
    def _acceleration_blend(tau):
        """z, dz/dτ, d²z/dτ² at τ."""
        rest = 1.0 - tau
        return (0.5 * tau * tau * rest ** 3,
                tau * rest ** 3 - 1.5 * tau * tau * rest * rest,
                rest ** 3 - 6.0 * tau * rest * rest + 3.0 * tau * tau * rest)

    def sample(self, t):
        duration = self.duration_s
        tau = _fraction(t, duration)
        s, s_dot, s_ddot = (_column(value) for value in quintic_profile(t, duration))
        w, w_d, w_dd = (_column(value) for value in self._velocity_blend(tau))
        v, v_d, v_dd = (_column(value) for value in self._velocity_blend(1.0 - tau))
        z, z_d, z_dd = (_column(value) for value in self._acceleration_blend(tau))
        y, y_d, y_dd = (_column(value) for value in self._acceleration_blend(1.0 - tau))
        delta = self.goal_m - self.start_m
        v0, v1 = self.start_velocity_m_s, self.goal_velocity_m_s
        a0, a1 = self.start_acceleration_m_s2, self.goal_acceleration_m_s2
        position = (self.start_m + s * delta + duration * (v0 * w - v1 * v)
                    + duration * duration * (a0 * z + a1 * y))
        velocity = s_dot * delta + v0 * w_d + v1 * v_d + duration * (a0 * z_d - a1 * y_d)
        acceleration = s_ddot * delta + (v0 * w_dd - v1 * v_dd) / duration + a0 * z_dd + a1 * y_dd
        return position, velocity, acceleration

    def reversed(self) -> 'HermiteQuintic':
        return HermiteQuintic(self.goal_m, -self.goal_velocity_m_s, self.start_m,
                              -self.start_velocity_m_s, self.duration_s,
                              self.goal_acceleration_m_s2, self.start_acceleration_m_s2)


class Hold(Trajectory):
    """Rest at one point."""

    def __init__(self, position_m, duration_s: float):
        self.position_m = np.array(position_m, dtype=float)
        self.duration_s = float(duration_s)

    def sample(self, t):
        rows = np.shape(t) + (3,)
        return np.broadcast_to(self.position_m, rows).copy(), np.zeros(rows), np.zeros(rows)

    def reversed(self) -> 'Hold':
        return Hold(self.position_m, self.duration_s)


class Sequence(Trajectory):
    """Segments one after the other; each must start where the previous one ends."""

    def __init__(self, segments):
        self.segments = list(segments)
        if not self.segments:
            raise ValueError('a sequence needs at least one segment')
        for before, after in zip(self.segments, self.segments[1:]):
            if not np.allclose(before.end, after.start, atol=1e-9):
                raise ValueError(f'segment starts at {after.start}, previous ends at {before.end}')
        self.starts_s = np.cumsum([0.0] + [s.duration_s for s in self.segments[:-1]])
        self.duration_s = float(sum(s.duration_s for s in self.segments))

    def sample(self, t):
        index = np.clip(np.searchsorted(self.starts_s, t, side='right') - 1, 0,
                        len(self.segments) - 1)
        if not isinstance(t, np.ndarray):
            return self.segments[index].sample(t - self.starts_s[index])
        figures = tuple(np.empty(t.shape + (3,)) for _ in range(3))
        for number, segment in enumerate(self.segments):
            rows = index == number
            if rows.any():
                for figure, part in zip(figures, segment.sample(t[rows] - self.starts_s[number])):
                    figure[rows] = part
        return figures

    def reversed(self) -> 'Sequence':
        return Sequence([s.reversed() for s in reversed(self.segments)])

    def segment_start_s(self, index: int) -> float:
        return float(self.starts_s[index])
