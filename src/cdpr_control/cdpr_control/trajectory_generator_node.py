"""trajectory_generator: /cdpr/reference (θ_d, θ̇_d, c_ID) and /cdpr/reference/pose.

Time comes from the stamps of /cdpr/joint_states (sim time in lockstep, the robot's
clock in realtime); each reference is published `reference_lead_cycles` ahead, so the
controller and the twin never wait for it. A goal on /cdpr/goal is reached by a
straight quintic move that starts when the current motion has come to rest.

Planning a move takes ~0.1 s here (tens of periods). In lockstep nothing moves
meanwhile, so it is planned at once. In realtime it is planned
`realtime_planning_rows_per_tick` rows per tick and adopted when complete, so the
references keep flowing: a generator that stops for longer than the lead leaves the
controller on a stale reference and the twin a tick behind the robot for every
reference it skips, which the FDI reads as a failure. (A worker thread does not help:
it holds the GIL for tens of ms at a time.)
"""
from __future__ import annotations

from collections import deque

import numpy as np
from geometry_msgs.msg import PointStamped
from sensor_msgs.msg import JointState

from cdpr_msgs_py import contract, qos
from cdpr_msgs_py.conversions import (InvalidMessage, joint_state, point_from_message,
                                      point_stamped, stamp_to_ns)
from cdpr_msgs_py.runtime import CdprNode, run
from cdpr_msgs_py.stamps import seconds_to_ns

from .motions import motion_from_settled, settled_motion
from .reference import IncrementalTabulation, ReferenceTable, tabulate_reference
from .settings import node_settings
from .tension_distribution import InfeasibleTensionError, configured_tension_distribution
from .trajectories import Hold, Sequence, StraightLine


class TrajectoryGeneratorNode(CdprNode):

    def __init__(self):
        super().__init__('trajectory_generator')
        settings = node_settings(self)
        self.robot = settings.robot
        control = settings.section('control')
        self.period_s = control.number('period_s', positive=True)
        self.configure(settings, self.period_s)
        self.period_ns = seconds_to_ns(self.period_s)
        self.lead = control.integer('reference_lead_cycles', minimum=1)
        self.distribution = configured_tension_distribution(control, self.robot)
        # started alone, without a settled motion: the named one of a motions file (a path)
        motion = (settings.section('motion') if settings.has('motion') else settled_motion(
            self.parameter('motions_file', ''), self.parameter('motion', 'circle'),
            self.parameter('reverse', False)))
        self.goal_speed_m_s = motion.number('goal_peak_speed_m_s', positive=True)
        self.segments: list[tuple[int, ReferenceTable]] = [
            (0, tabulate_reference(self.robot, self.distribution, motion_from_settled(motion).trajectory,
                                   self.period_s))]
        self.names = contract.joint_names(self.robot.cable_count)
        self.origin_ns: int | None = None
        self.next_index = 0
        self.goals: deque[np.ndarray] = deque()   # accepted, waiting to be planned, in order
        self.planning: tuple[np.ndarray, IncrementalTabulation] | None = None
        self.rows_per_tick = control.integer('realtime_planning_rows_per_tick', minimum=1)
        self.reference = self.create_stream_publisher(JointState, contract.REFERENCE)
        self.pose = self.create_stream_publisher(PointStamped, contract.REFERENCE_POSE)
        self.create_subscription(PointStamped, contract.GOAL, self.on_goal, qos.STREAM)
        self.start_when_matched(lambda: self.create_subscription(
            JointState, contract.JOINT_STATES, self.on_state, qos.STREAM))

    def sample(self, index: int):
        start, table = next((s, t) for s, t in reversed(self.segments) if s <= index)
        return table, min(index - start, len(table) - 1)

    def on_state(self, message: JointState) -> None:
        stamp = stamp_to_ns(message.header.stamp)
        if self.origin_ns is None:
            self.origin_ns = stamp
        tick = (stamp - self.origin_ns) // self.period_ns
        self.plan_goals()
        # After a jump in time the references of the ticks jumped over are of no use.
        self.next_index = max(self.next_index, tick)
        while self.next_index <= tick + self.lead:
            self.publish(self.next_index)
            self.next_index += 1

    def publish(self, index: int) -> None:
        table, row = self.sample(index)
        stamp = self.origin_ns + index * self.period_ns
        self.reference.publish(joint_state(
            self.names, stamp, table.angle_rad[row], table.angular_velocity_rad_s[row],
            table.feedforward_nm[row]))
        self.pose.publish(point_stamped(stamp, table.position_m[row]))
        self.diagnostics.count('references')

    def on_goal(self, message: PointStamped) -> None:
        try:
            goal = point_from_message(message)
        except InvalidMessage as err:
            self.diagnostics.reject(contract.GOAL, str(err))
            return
        if np.any(goal < self.robot.workspace_min_m) or np.any(goal > self.robot.workspace_max_m):
            self.diagnostics.reject(contract.GOAL, f'goal {goal} outside the workspace')
            return
        self.goals.append(goal)
        self.plan_goals()

    def plan_goals(self) -> None:
        """Go on planning: the waiting goals in order, each from where the last planned move
        ends; a whole move at once in lockstep, `rows_per_tick` rows per call in realtime."""
        while True:
            if self.planning is not None:
                goal, tabulation = self.planning
                try:
                    done = tabulation.advance(tabulation.count if self.clock_mode == 'lockstep'
                                              else self.rows_per_tick)
                except InfeasibleTensionError as err:
                    self.diagnostics.reject(contract.GOAL, f'goal {goal} cannot be reached: {err}')
                    done, tabulation = True, None
                if not done:
                    return
                self.planning = None
                if tabulation is not None:
                    self.adopt(goal, tabulation.table())
            if not self.goals:
                return
            goal = self.goals.popleft()
            here = self.segments[-1][1].position_m[-1]
            if not np.allclose(goal, here):
                trajectory = Sequence([StraightLine.with_peak_speed(here, goal, self.goal_speed_m_s),
                                       Hold(goal, self.period_s)])
                self.planning = (goal, IncrementalTabulation(self.robot, self.distribution,
                                                             trajectory, self.period_s))

    def adopt(self, goal: np.ndarray, table: ReferenceTable) -> None:
        """The planned move starts when the last segment ends, and never in the past."""
        start, last = self.segments[-1]
        begin = max(start + len(last), self.next_index)
        self.segments.append((begin, table))
        # Segments wholly published are done with: a long run of goals must not pile up.
        self.segments = [segment for segment in self.segments[:-1]
                         if segment[0] + len(segment[1]) > self.next_index] + self.segments[-1:]
        self.get_logger().info(f'goal {goal} planned: {len(table) * self.period_s:.2f} s '
                               f'from tick {begin}')


def main(args=None):
    return run(TrajectoryGeneratorNode, args)


if __name__ == '__main__':
    main()
