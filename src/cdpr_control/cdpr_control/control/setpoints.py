"""What the controller tracks on each tick, in each mode: the loop's wiring, without ROS.

The trajectory's references, the recovery's joint references and its tension setpoints
arrive stamped (ns) for the tick they belong to; the supervisor's mode and broken cables
steer which of them the controller uses. A verdict steers from the tick it is due
(`verdict`: the judged tick + contract.VERDICT_DELAY_TICKS), whenever it arrives before
it. The controller node feeds it from topics, the in-process engine from the cores
directly: both take the same setpoint for the same tick.

Lockstep (`exact`): a tick is answered with the setpoint stamped exactly for it, and waits
for it. Realtime: with the latest one not after it, never waiting; a trajectory reference
older than `stale_ns` sends the robot to SAFE_HOLD.
"""
from __future__ import annotations

from collections import OrderedDict

import numpy as np

from cdpr_msgs_py.contract import NOMINAL, RECOVERY_MOVE, RECOVERY_TENSION, SAFE_HOLD

from cdpr_control.control.controller import JointController, JointReference

BUFFER_LENGTH = 256


class StampedBuffer(OrderedDict):
    """The last BUFFER_LENGTH values by stamp (ns)."""

    def put(self, stamp_ns: int, value) -> None:
        self[stamp_ns] = value
        while len(self) > BUFFER_LENGTH:
            self.popitem(last=False)

    def at(self, stamp_ns: int, exact: bool):
        """(stamp, value) of exactly this stamp, or (not exact) of the latest not after
        it; (None, None) when there is none."""
        if exact:
            return (stamp_ns, self[stamp_ns]) if stamp_ns in self else (None, None)
        earlier = [stamp for stamp in self if stamp <= stamp_ns]
        return (max(earlier), self[max(earlier)]) if earlier else (None, None)


class Setpoints:
    """The setpoint of each tick for `controller`, and the commands it gives."""

    def __init__(self, controller: JointController, exact: bool, stale_ns: int | None = None):
        """`stale_ns`: realtime, how old a trajectory reference may be (ns)."""
        self.controller = controller
        self.exact = exact
        self.stale_ns = stale_ns
        self.references = StampedBuffer()
        self.recovery_references = StampedBuffer()
        self.recovery_tensions = StampedBuffer()
        # Why the robot holds because an input went stale (realtime), once it does.
        self.safe_hold_reason = ''
        # verdicts not yet due: (due stamp ns, broken cables 1-based, mode or None)
        self.pending: list[tuple[int, list[int], str | None]] = []

    def put_reference(self, stamp_ns: int, reference: JointReference) -> None:
        self.references.put(stamp_ns, reference)

    def put_recovery_reference(self, stamp_ns: int, reference: JointReference) -> None:
        self.recovery_references.put(stamp_ns, reference)

    def put_recovery_tensions(self, stamp_ns: int, tensions_n: np.ndarray) -> None:
        self.recovery_tensions.put(stamp_ns, tensions_n)

    def cable_broken(self, cable: int) -> None:
        """The supervisor named the 1-based `cable`: its motor gets no torque from now on."""
        self.controller.set_broken([cable - 1])

    def set_mode(self, mode: str) -> None:
        """The supervisor's mode, from now on (ValueError for an unknown one)."""
        self.controller.set_mode(mode)

    def verdict(self, due_ns: int, broken_cables: list[int], mode: str | None) -> None:
        """A verdict (the broken cables, 1-based, and the mode, None: unchanged) that
        steers the ticks stamped `due_ns` and later (ValueError for an unknown mode, now)."""
        if mode is not None:
            self.controller.check_mode(mode)
        # what changes nothing is not kept (the in-process engine steers every tick): the
        # mode is news only against the one the verdicts pending already leave
        latest = next((pending for _, _, pending in reversed(self.pending) if pending is not None),
                      self.controller.mode)
        if broken_cables or (mode is not None and mode != latest):
            self.pending.append((due_ns, list(broken_cables), mode))

    def apply_due(self, stamp_ns: int) -> None:
        """The verdicts due by the tick stamped `stamp_ns`, in the order they came."""
        while self.pending and self.pending[0][0] <= stamp_ns:
            _, cables, mode = self.pending.pop(0)
            for cable in cables:
                self.cable_broken(cable)
            if mode is not None:
                self.set_mode(mode)

    def go_safe_hold(self, why: str) -> bool:
        """Realtime, an input went stale: hold where the last reference was, at rest. True
        when this changed the mode (only NOMINAL goes: a recovery keeps its own course)."""
        if self.controller.mode != NOMINAL:
            return False
        self.controller.set_mode(SAFE_HOLD)
        self.safe_hold_reason = why
        return True

    def select(self, stamp_ns: int) -> tuple[bool, JointReference | None]:
        """(ready, reference) for the tick stamped `stamp_ns` in the current mode; in
        RECOVERY_TENSION the controller takes the tick's tensions and the reference is
        None. Not ready: lockstep, and the tick's setpoint has not arrived."""
        mode = self.controller.mode
        if mode == RECOVERY_TENSION:
            _, tensions = self.recovery_tensions.at(stamp_ns, self.exact)
            if tensions is not None:
                self.controller.set_tension_setpoint(tensions)
            return tensions is not None or not self.exact, None
        if mode == RECOVERY_MOVE:
            _, reference = self.recovery_references.at(stamp_ns, self.exact)
            return reference is not None or not self.exact, reference
        stamp, reference = self.references.at(stamp_ns, self.exact)
        if (not self.exact and reference is not None and mode == NOMINAL
                and stamp_ns - stamp > self.stale_ns):
            self.go_safe_hold(f'reference stale by {(stamp_ns - stamp) / 1e6:.0f} ms')
        return reference is not None or mode != NOMINAL, reference

    def command(self, stamp_ns: int, angle_rad, angular_velocity_rad_s) -> np.ndarray | None:
        """The motor torques (N·m) for the state of the tick stamped `stamp_ns`; None
        while its setpoint has not arrived (lockstep)."""
        self.apply_due(stamp_ns)
        ready, reference = self.select(stamp_ns)
        if not ready:
            return None
        return self.controller.command(angle_rad, angular_velocity_rad_s, reference)
