"""The digital twin: a healthy rigid model driven by its own copy of the controller."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from cdpr_control.controller import JointController, JointReference, PdGains
from cdpr_control.robot import Robot

from .rigid_model import RigidCableRobot


@dataclass
class TwinOutput:
    """The twin at one tick: θ (rad), θ̇ (rad/s), its torque c_DT (N·m), pose p (m)."""

    angle_rad: np.ndarray
    angular_velocity_rad_s: np.ndarray
    torque_nm: np.ndarray
    position_m: np.ndarray


class DigitalTwin:
    """Fed the same reference as the robot; never sees the robot's measurements."""

    def __init__(self, robot: Robot, gains: PdGains, start_position_m, substeps: int):
        self.model = RigidCableRobot(robot, start_position_m, substeps)
        self.controller = JointController(robot, gains)

    def step(self, reference: JointReference, period_s: float) -> TwinOutput:
        """The twin's state and torque at this tick; then it advances one period."""
        model = self.model
        # No copies needed: the model's step replaces its state arrays, never writes into them.
        angle, speed, position = model.angle_rad, model.angular_velocity_rad_s, model.position_m
        torque = self.controller.command(angle, speed, reference)
        model.step(torque, period_s)
        return TwinOutput(angle, speed, torque, position)
