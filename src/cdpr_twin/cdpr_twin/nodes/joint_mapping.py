"""The decisions of the ros2_control bridge, without ROS: which of the robot's joints is
which motor, on which tick a robot sample lies, when the robot's data are stale, and
what to send the effort controller when the graph's controller falls silent.

A ros2_control robot names its joints as its URDF does and lists them in any order
(joint_state_broadcaster) or in its controller's order (JointGroupEffortController);
the graph speaks of motor_1 … motor_m in the order of robot.exit_points_m
(docs/design.md §3). A JointGroupEffortController cannot brake: it applies the last
command it got until the next one, for ever. So when the commands stop, the bridge
lets it hold the last command `plant.command_timeout_cycles` periods, as a drive would,
and then sends the static holding torque of the end-effector's pose, measured anew
each period (Body.holding_torques_nm; a platform's pose, position and
orientation, by its forward kinematics) — never zero torque on a suspended load.
"""
from __future__ import annotations

from math import isfinite

import numpy as np

from cdpr_control.model.body import KinematicsError
from cdpr_control.model.robot import Robot

from cdpr_twin.nodes.watchdog import BRAKING, CommandWatchdog


class JointMismatch(ValueError):
    """A robot sample that does not give what the graph needs (missing joints, sizes,
    non-finite values, a stamp not after the last tick)."""


def _distinct(names, parameter: str) -> list[str]:
    names = [str(name) for name in names]
    doubles = sorted({name for name in names if names.count(name) > 1})
    if doubles or not all(names):
        raise ValueError(f'parameter {parameter}: joint names must be distinct and not empty, '
                         f'got {names}')
    return names


class JointMapping:
    """Motors motor_1 … motor_m ⇄ the robot's joints, by name.

    `robot_joints[i]` is the robot's name of motor i + 1; `controller_joints` is the
    effort controller's joint order, the same joints in its own order: a command must
    give every joint it drives a value, and every motor must be driven.
    """

    def __init__(self, motor_names: list[str], robot_joints, controller_joints):
        self.motor_names = list(motor_names)
        self.robot_joints = _distinct(robot_joints, 'robot_joints')
        controller_joints = _distinct(controller_joints, 'controller_joints')
        if len(self.robot_joints) != len(self.motor_names):
            raise ValueError(f'parameter robot_joints: {len(self.motor_names)} names expected '
                             f'(one per motor, in the order {self.motor_names}), got {self.robot_joints}')
        if sorted(controller_joints) != sorted(self.robot_joints):
            raise ValueError(f'parameter controller_joints: the effort controller must drive '
                             f'exactly the joints {self.robot_joints}, got {controller_joints}')
        self.controller_joints = controller_joints
        motor_of = {joint: motor for motor, joint in enumerate(self.robot_joints)}
        # controller index j commands motor controller_motor[j]
        self.controller_motor = np.array([motor_of[joint] for joint in controller_joints])

    def motor_order(self, names, fields: dict[str, list]) -> dict[str, np.ndarray]:
        """The `fields` (name → values, one per entry of `names`, as a JointState has
        them) of our joints, in motor order; other joints are ignored. JointMismatch
        when one of ours is missing or a value of ours is not finite."""
        names = list(names)
        index = {name: i for i, name in enumerate(names)}
        missing = [joint for joint in self.robot_joints if joint not in index]
        if missing:
            raise JointMismatch(f'joints {missing} missing (it has {names})')
        if len(index) != len(names):
            raise JointMismatch(f'a joint named twice in {names}')
        rows = [index[joint] for joint in self.robot_joints]
        ordered = {}
        for field, values in fields.items():
            if len(values) != len(names):
                raise JointMismatch(f'{field} has {len(values)} values for {len(names)} joints')
            picked = [values[row] for row in rows]
            if not all(map(isfinite, picked)):
                raise JointMismatch(f'{field} of {self.robot_joints} holds a non-finite value')
            ordered[field] = np.asarray(picked, dtype=float)
        return ordered

    def controller_order(self, values) -> list[float]:
        """Per-motor `values` in the effort controller's joint order."""
        return np.asarray(values, dtype=float)[self.controller_motor].tolist()


class TickStamps:
    """The robot's sample times on the graph's tick grid: tick k at k × period (ns),
    counted from the first sample, as every per-tick message of the graph is stamped."""

    def __init__(self, period_ns: int):
        self.period_ns = period_ns
        self.first_ns: int | None = None
        self.last_tick: int | None = None

    def stamp_ns(self, sample_ns: int) -> int:
        """The tick stamp of a sample taken at `sample_ns`; JointMismatch when it is not
        a tick after the last one (a robot publishing faster than 1/period, or a clock
        that went back)."""
        if self.first_ns is None:
            self.first_ns = sample_ns
        tick = round((sample_ns - self.first_ns) / self.period_ns)
        if self.last_tick is not None and tick <= self.last_tick:
            raise JointMismatch(f'sampled at tick {tick}, not after tick {self.last_tick} '
                                f'(samples must come one period apart)')
        self.last_tick = tick
        return tick * self.period_ns


class StaleWatch:
    """Whether a stream has been silent for more than `stale_cycles` periods (s)."""

    def __init__(self, stale_cycles: int, period_s: float, started_s: float):
        self.limit_s = stale_cycles * period_s
        self.last_s = started_s

    def arrived(self, now_s: float) -> None:
        self.last_s = now_s

    def silent_s(self, now_s: float) -> float:
        return now_s - self.last_s

    def stale(self, now_s: float) -> bool:
        return self.silent_s(now_s) > self.limit_s


class EffortBridge:
    """What the bridge sends the effort controller: the graph's commands, clamped to the
    motors' limit; and while the graph's controller is silent (before its first command,
    or for more than `hold_cycles` periods) the static holding torque of the measured pose
    with the cables the supervisor has declared broken."""

    def __init__(self, robot: Robot, hold_cycles: int):
        self.robot = robot
        self.watchdog = CommandWatchdog(hold_cycles)
        self.commanded = False
        self.broken: list[int] = []
        self.holding = False
        self.last_sent_nm: np.ndarray | None = None

    def command_nm(self, effort_nm) -> np.ndarray:
        """A command of the graph's controller, as the motors can apply it (N·m)."""
        self.watchdog.command_arrived()
        self.commanded = True
        self.holding = False
        return self._sent(effort_nm)

    def _sent(self, torque_nm) -> np.ndarray:
        """`torque_nm` clamped to the motors' limit, remembered as the last sent."""
        limit = self.robot.motor.torque_limit_nm
        self.last_sent_nm = np.asarray(torque_nm, dtype=float).clip(-limit, limit)
        return self.last_sent_nm

    def cable_broken(self, cable: int) -> None:
        """The supervisor's verdict: 0-based `cable` is broken (it holds nothing)."""
        if not 0 <= cable < self.robot.cable_count:
            raise ValueError(f'cable {cable + 1} outside 1..{self.robot.cable_count}')
        if cable not in self.broken:
            self.broken.append(cable)

    def tick(self, angle_rad) -> np.ndarray | None:
        """One period passed; the torques (N·m) to send now, or None: the effort
        controller goes on applying the last command it got. `angle_rad`: the latest
        measured motor angles, None before the robot's first sample."""
        silent = self.watchdog.tick() == BRAKING or not self.commanded
        self.holding = silent and angle_rad is not None
        if not self.holding:
            return None
        attached = self.robot.cable_mask(self.broken)
        try:
            position, orientation = self.robot.body.pose_of_angles(self.robot, angle_rad, attached)
        except KinematicsError:
            # too few cables for a pose (3 for a point mass, 6 for a platform): none to
            # hold, the last torques sent stay
            self.holding = self.last_sent_nm is not None
            return self.last_sent_nm
        return self._sent(self.robot.body.holding_torques_nm(self.robot, position, orientation, attached))
