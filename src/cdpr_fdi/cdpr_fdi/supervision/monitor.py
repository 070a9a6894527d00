"""The digital twin and the supervisor on one control tick, without ROS.

As the graph's digital_twin and supervisor nodes do it: the twin steps on the tick's
reference; the supervisor judges the tick from what the drive reported (θ, θ̇, the torque
it applied), the command and the twin's output. The in-process engine and the offline
replay of recorded ticks both step through here.
"""
from __future__ import annotations

import numpy as np

from cdpr_control.control.controller import JointReference
from cdpr_twin.models.twin import DigitalTwin, TwinOutput

from .supervisor import Supervisor, Verdict


class Monitor:
    """A twin, and a supervisor judging against it (None: the twin alone runs)."""

    def __init__(self, twin: DigitalTwin, supervisor: Supervisor | None, period_s: float):
        self.twin = twin
        self.supervisor = supervisor
        self.period_s = period_s

    def step(self, tick: int, angle_rad: np.ndarray, angular_velocity_rad_s: np.ndarray,
             applied_torque_nm: np.ndarray, command_nm: np.ndarray,
             reference: JointReference) -> tuple[TwinOutput, Verdict | None]:
        """The twin's output for the tick and the supervisor's verdict on it."""
        output = self.twin.step(reference, self.period_s)
        if self.supervisor is None:
            return output, None
        verdict = self.supervisor.update(tick, angle_rad, angular_velocity_rad_s, applied_torque_nm,
                                         command_nm, output.torque_nm,
                                         output.angular_velocity_rad_s, reference)
        return output, verdict
