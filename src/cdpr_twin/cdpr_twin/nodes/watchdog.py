"""What a drive does when the commands stop: hold the last one briefly, then brake.

Never zero torque on a suspended load: that drops it. Holding the last command for a
few periods rides out a late message; after that the command is stale and the drums
are locked, which keeps every cable at its length. A fresh command releases the brake.
"""
from __future__ import annotations

OK = 'ok'
HOLDING = 'holding'
BRAKING = 'braking'


class CommandWatchdog:

    def __init__(self, hold_cycles: int):
        if hold_cycles < 1:
            raise ValueError(f'hold_cycles must be at least 1, got {hold_cycles}')
        self.hold_cycles = hold_cycles
        self.silent_cycles = 0
        self.state = OK

    def command_arrived(self) -> None:
        self.silent_cycles = 0
        self.state = OK

    def tick(self) -> str:
        """One control period passed; the state for it."""
        self.silent_cycles += 1
        if self.silent_cycles > self.hold_cycles:
            self.state = BRAKING
        elif self.silent_cycles > 1:
            self.state = HOLDING
        return self.state
