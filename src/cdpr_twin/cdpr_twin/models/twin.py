"""The digital twin: a healthy rigid model driven by its own copy of the controller."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from cdpr_control.control import tracking
from cdpr_control.control.controller import JointController, JointReference, PdGains
from cdpr_control.model.friction import FrictionModel
from cdpr_control.model.robot import Robot

from cdpr_twin.models.rigid_model import RigidModel


@dataclass
class TwinOutput:
    """The twin at one tick: θ (rad), θ̇ (rad/s), its torque c_DT (N·m), position p (m)
    and orientation (unit quaternion; the identity for a point mass)."""

    angle_rad: np.ndarray
    angular_velocity_rad_s: np.ndarray
    torque_nm: np.ndarray
    position_m: np.ndarray
    orientation: np.ndarray


class DigitalTwin:
    """Fed the same reference as the robot; never sees the robot's measurements. Its
    model is the rigid one, a platform's starting at `start_orientation` (its home
    orientation when None). With `friction` its motors feel that Coulomb friction, taken
    at the speed each period starts with (as the rigid model's one sub-step takes the
    viscous friction)."""

    def __init__(self, robot: Robot, gains: PdGains, start_position_m, substeps: int, start_orientation=None,
                 friction: FrictionModel | None = None):
        self.model = RigidModel(robot, start_position_m, start_orientation, substeps)
        self.controller = JointController(robot, gains)
        self.friction = friction

    @staticmethod
    def load_kernels(robot: Robot) -> None:
        """The compiled functions a twin of `robot` steps with, loaded now (~1 ms built
        ahead of time, ~0.5 s with numba's import where they were not): a node builds its
        twin at the first reference, which must not wait for them."""
        robot.body.load_kernels()
        tracking.kernel().load_all()

    def step(self, reference: JointReference, period_s: float) -> TwinOutput:
        """The twin's state and torque at this tick; then it advances one period."""
        model = self.model
        # No copies needed: the model's step replaces its state arrays, never writes into them.
        angle, speed, position = model.angle_rad, model.angular_velocity_rad_s, model.position_m
        torque = self.controller.command(angle, speed, reference)
        orientation = model.orientation
        model.step(torque if self.friction is None else torque - self.friction.torque_nm(speed), period_s)
        return TwinOutput(angle, speed, torque, position, orientation)
