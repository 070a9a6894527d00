"""The example strategy of docs/recovery-strategies.md, recovery.strategy `line`: a point
mass (3 DOF) taken from where it is named straight to SP under position control, in one
quintic that starts with its velocity and ends at rest there; then SAFE_HOLD.

It is the paper's phase 2 without its phase 1 and without re-planning. Where the
remaining cables cannot pull the end-effector along that line with every tension within
[τ_min + the planning margin, τ_max] — named outside their residual workspace, or moving
faster than the line's time lets them brake — there is no plan, and the recovery does not
start: RecoveryInfeasible, the supervisor holds the drums (FAULT). The paper's strategy
recovers those cases too.
"""
from __future__ import annotations

import numpy as np

from cdpr_control.model.reference_table import tabulate_reference
from cdpr_control.tension_distribution import InfeasibleTensionError, make_tension_distribution
from cdpr_control.geometry.pose_trajectories import PoseTrajectory
from cdpr_control.geometry.trajectories import HermiteQuintic, Hold, Sequence
from cdpr_msgs_py.contract import RECOVERY_MOVE, SAFE_HOLD

from ..recovery_planning.recovery import RecoveryInfeasible, safe_point_for
from ..detection.wrench_balance import placement
from .base import Naming, RecoveryStrategy, TabulatedMove


class LineMove(TabulatedMove):
    """The line, tabulated per tick from the naming tick on (row 0 its state)."""

    def __init__(self, naming: Naming, table, safe_point_m: np.ndarray, tracker):
        super().__init__()
        start_tick = naming.tick
        self.robot, self.config, self.period_s = naming.robot, naming.config, naming.period_s
        self.attached, self.tracker = naming.attached.copy(), tracker
        self.safe_point_m = safe_point_m
        self.move = (start_tick, table)
        self.mode = RECOVERY_MOVE
        self.phase_ticks = {RECOVERY_MOVE: start_tick}

    def tabulated(self) -> tuple[int, object]:
        return self.move

    def setpoint(self, tick: int, angle_rad, angular_velocity_rad_s):
        """(mode, None, the line's joint reference) for tick + VERDICT_DELAY_TICKS; nothing
        in SAFE_HOLD (the controller holds the last)."""
        if self.mode == SAFE_HOLD:
            return self.mode, None, None
        reference = self.move_setpoint(tick)
        return self.mode, None, reference


class Line(RecoveryStrategy):
    """A point mass moved in a straight line to SP (module docstring)."""

    name = 'line'
    degrees_of_freedom = 3
    description = 'moved in a straight line to SP under position control, where the cables left can pull it there'

    def start(self, naming: Naming) -> LineMove:
        robot, config, attached = naming.robot, naming.config, naming.attached
        tracker, pose = naming.named_pose()
        position, _, velocity, _ = placement(robot, naming.angle_rad, naming.angular_velocity_rad_s, attached, pose)
        safe = safe_point_for(robot, config, attached)
        # as long as the paper's move to SP would take from rest, and at least as long as
        # its brake from this speed
        duration_s = max(config.move_s(float(np.linalg.norm(safe - position))),
                         config.brake_s(float(np.linalg.norm(velocity))))
        path = Sequence([HermiteQuintic(position, velocity, safe, np.zeros(3), duration_s),
                         Hold(safe, naming.period_s)])
        # planned above τ_min by what the drives' tracking takes off a planned tension
        distribution = make_tension_distribution(
            naming.distribution.name, naming.distribution.tension_min_n + config.plan_tension_margin_n,
            naming.distribution.tension_max_n)
        try:
            table = tabulate_reference(robot, distribution, PoseTrajectory(path), naming.period_s, attached=attached)
        except InfeasibleTensionError as err:
            raise RecoveryInfeasible(f'no straight line to SP keeps the tensions within their bounds: {err}') from None
        return LineMove(naming, table, safe, tracker)
