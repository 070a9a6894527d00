"""How long a simulated run lasts: its scheduled length, or until the recovery is over.

A run is scheduled for the motion and, after a failure, for the longest recovery it may
need (every re-plan included: Scenario.recovery_budget_s). Most recoveries end sooner; a
run then ends `hold_cycles` after the supervisor's mode says the recovery is over (SAFE_HOLD
at the safe point, or FAULT), long enough to show the end-effector stays there. Both
engines take the same rule: the in-process loop and the plant simulator of the graph,
which learns the mode on /cdpr/mode.
"""
from __future__ import annotations

from cdpr_msgs_py.contract import FAULT, SAFE_HOLD

RECOVERY_OVER = (SAFE_HOLD, FAULT)


class RunLength:
    """The last tick of a run (0-based, inclusive)."""

    def __init__(self, scheduled_last_tick: int, hold_cycles: int | None):
        """`hold_cycles`: ticks to run on once the recovery is over; None: never end early."""
        if hold_cycles is not None and hold_cycles < 0:
            raise ValueError(f'hold_cycles must not be negative, got {hold_cycles}')
        self.last_tick = scheduled_last_tick
        self.hold_cycles = hold_cycles

    def mode(self, mode: str, tick: int) -> None:
        """The supervisor's mode, as learnt at `tick` (before the plant steps from it)."""
        if self.hold_cycles is not None and mode in RECOVERY_OVER:
            self.last_tick = min(self.last_tick, tick + self.hold_cycles)
