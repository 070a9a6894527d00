"""The end-effector's pose from the motors through a recovery, with one fallback where
forward kinematics does not converge (issue 52; docs/detection-and-recovery.md).

A platform's forward kinematics is Gauss–Newton from a start pose (home by default), in
a bounded number of steps: from home, the lengths of a platform turned far from it, on
the cables left after a break, may not converge in them. A recovery that ended on that
(FAULT) gave up a robot whose cables still hold it. `PoseTracker.pose` tries, in order:

1. the body's forward kinematics from the last pose it found (home before any), or the
   pose a plan the drives track has put the end-effector at since (`expect`), in the
   body's own step count;
2. where that does not converge, `fallback_iterations` steps from each of the better
   starts it knows: the last pose found, the `hint` the caller gives (the reference pose
   of the naming tick), home;
3. where none converges either, the last pose found, as it is: the recovery goes on
   from there, and `fallbacks` counts the ticks it did (the recovery says so in its notes).

Only where no pose was ever found (the first call fails every start) is KinematicsError
raised. Either body's forward kinematics is called through Body.pose_of_angles; a point
mass's is closed form and never needs more than the first try.
"""
from __future__ import annotations

import numpy as np

from cdpr_control.model.body import KinematicsError


class PoseTracker:
    """Forward kinematics of a recovery's `cables` (boolean mask) on `robot`, falling back
    as the module docstring says; `fallbacks` counts the calls answered by a retry
    (`retried`) or by the last pose (`held`)."""

    def __init__(self, robot, cables, fallback_iterations: int):
        self.robot = robot
        self.cables = np.asarray(cables, dtype=bool).copy()
        self.fallback_iterations = int(fallback_iterations)
        self.last = None
        self.retried = 0
        self.held = 0
        # the first failure's reason, for the recovery's note
        self.first_error = ''

    @property
    def fallbacks(self) -> int:
        return self.retried + self.held

    def pose(self, angles_rad, hint=None):
        """(position m, orientation) of the motor angles (module docstring); `hint` a pose
        (position, orientation) to start a retry from."""
        body, angles = self.robot.body, np.asarray(angles_rad, dtype=float)
        try:
            found = body.pose_of_angles(self.robot, angles, self.cables, start=self.last)
        except KinematicsError as err:
            self.first_error = self.first_error or str(err)
            found = self.retry(angles, hint)
        self.last = found
        return found

    def expect(self, position_m, orientation) -> None:
        """The pose (position m, orientation) a plan the drives track has put the
        end-effector at: the next call's start. From a pose long past (the naming's, a
        steered approach later), Gauss–Newton can find another pose of the six cables'
        lengths: a platform at its safe pose was read 0.1 m and 65° from it."""
        self.last = (np.array(position_m, dtype=float), np.array(orientation, dtype=float))

    def retry(self, angles: np.ndarray, hint):
        """More steps from each better start; else the last pose found."""
        body = self.robot.body
        # home (None) last
        for start in [start for start in (self.last, hint) if start is not None] + [None]:
            try:
                found = body.pose_of_angles(self.robot, angles, self.cables, start=start,
                                            iterations=self.fallback_iterations)
            except KinematicsError:
                continue
            self.retried += 1
            return found
        if self.last is None:
            raise KinematicsError(f'{self.first_error}; nor in {self.fallback_iterations} steps from the '
                                  f'reference pose or home, and no pose was found before')
        self.held += 1
        return self.last

    def note(self) -> str:
        """What the fallback did, for a recovery's notes ('' where it never acted)."""
        if not self.fallbacks:
            return ''
        return (f'forward kinematics fell back on {self.fallbacks} tick(s) ({self.first_error}): '
                f'{self.retried} converged in {self.fallback_iterations} steps from a better start, '
                f'{self.held} took the last pose found')
