"""Detection on recorded data: the digital twin and the supervisor replayed tick by tick.

What a drive recorded (θ, θ̇, the torque it applied), what the controller commanded and
the reference are all the method needs; the twin is re-run from the reference, so a
bag from any robot whose driver honours the topic contract can be checked offline.
Detection only: the replay stops at the first verdict and commands nothing.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from cdpr_control.control.controller import JointReference, PdGains
from cdpr_control.model.friction import FrictionModel
from cdpr_control.model.robot import Robot
from cdpr_control.tension_distribution import TensionDistribution
from cdpr_twin.models.twin import DigitalTwin

from ..settings.config import FdiConfig, RecoveryConfig
from .monitor import Monitor
from .supervisor import Supervisor


@dataclass
class RecordedTick:
    """One control tick as recorded: the drive's state, the command and the reference."""

    angle_rad: np.ndarray
    angular_velocity_rad_s: np.ndarray
    applied_torque_nm: np.ndarray
    command_nm: np.ndarray
    reference: JointReference


@dataclass
class OfflineVerdict:
    ticks: int
    alarm_tick: int | None
    identified_tick: int | None
    identified_cables: list[int]


def replay(ticks: list[RecordedTick], robot: Robot, gains: PdGains, twin_substeps: int,
           twin_friction: FrictionModel | None, fdi: FdiConfig, recovery: RecoveryConfig,
           distribution: TensionDistribution, period_s: float) -> OfflineVerdict:
    """Run the twin (with the Coulomb friction it models, if any) and the supervisor over
    the recorded ticks until a cable is named."""
    start, orientation = robot.body.pose_of_angles(robot, ticks[0].reference.angle_rad)
    twin = DigitalTwin(robot, gains, start, twin_substeps, orientation, twin_friction)
    supervisor = Supervisor(robot, fdi, recovery, distribution, period_s)
    monitor = Monitor(twin, supervisor, period_s)
    for k, tick in enumerate(ticks):
        _, verdict = monitor.step(k, tick.angle_rad, tick.angular_velocity_rad_s,
                                  tick.applied_torque_nm, tick.command_nm, tick.reference)
        if verdict.broken_cables:
            return OfflineVerdict(k + 1, supervisor.alarm_tick, k, verdict.broken_cables)
    return OfflineVerdict(len(ticks), supervisor.alarm_tick, None, [])
