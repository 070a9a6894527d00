"""trajectory_generator: /cdpr/reference (θ_d, θ̇_d, c_ID), every tick, and
/cdpr/reference/pose, on the view ticks.

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

from geometry_msgs.msg import PointStamped, PoseStamped
from sensor_msgs.msg import JointState

from cdpr_msgs_py import contract, qos
from cdpr_msgs_py.conversions import InvalidMessage, joint_state_bytes, point_from_message, pose_stamped, stamp_of
from cdpr_msgs_py.runtime.node import CdprNode
from cdpr_msgs_py.runtime.spin import run

from cdpr_control.geometry.motions import settled_motion
from cdpr_control.control.reference_schedule import GoalRejected, ReferenceSchedule
from cdpr_control.model.reference_table import tabulate_reference
from cdpr_control.setup.settings import node_settings
from cdpr_control.tension_distribution import configured_tension_distribution


class TrajectoryGeneratorNode(CdprNode):

    def __init__(self):
        super().__init__(contract.TRAJECTORY_GENERATOR)
        settings = node_settings(self, contract.TRAJECTORY_GENERATOR)
        self.robot, self.period_s, self.period_ns = settings.robot, settings.period_s, settings.period_ns
        control = settings.section('control')
        self.lead = control.integer('reference_lead_cycles', minimum=1)
        self.distribution = configured_tension_distribution(control, self.robot)
        # started alone, without a settled motion: the named one of a motions file (a path)
        motion = (settings.section('motion') if settings.has('motion') else settled_motion(
            self.parameter('motions_file', '', 'started without a settled motion: a motions YAML'),
            self.parameter('motion', 'circle', 'started without a settled motion: its name there'),
            self.parameter('reverse', False, 'started without a settled motion: run it backward')))
        self.goal_speed_m_s = motion.number('goal_peak_speed_m_s', positive=True)
        self.schedule = ReferenceSchedule(
            self.robot, self.distribution, self.period_s, self.goal_speed_m_s,
            tabulate_reference(self.robot, self.distribution, self.robot.body.motion(motion).pose_trajectory,
                               self.period_s))
        self.names = contract.joint_names(self.robot.cable_count)
        self.origin_ns: int | None = None
        self.rows_per_tick = control.integer('realtime_planning_rows_per_tick', minimum=1)
        self.reference = self.create_stream_publisher(JointState, contract.REFERENCE)
        self.pose = self.create_stream_publisher(PoseStamped, contract.REFERENCE_POSE)
        self.create_subscription(PointStamped, contract.GOAL, self.on_goal, qos.STREAM)
        self.start_when_matched(lambda: self.create_subscription(
            JointState, contract.JOINT_STATES, self.on_state, qos.STREAM))
        settings.declare(self)

    def on_state(self, message: JointState) -> None:
        stamp = stamp_of(message)
        if self.origin_ns is None:
            self.origin_ns = stamp
        tick = (stamp - self.origin_ns) // self.period_ns
        self.plan_goals()
        for index in self.schedule.due(tick, self.lead):
            self.publish(index)

    def publish(self, index: int) -> None:
        table, row = self.schedule.sample(index)
        stamp = self.origin_ns + index * self.period_ns
        self.reference.publish(joint_state_bytes(
            self.names, stamp, table.angle_rad[row], table.angular_velocity_rad_s[row],
            table.feedforward_nm[row]))
        if self.view_ticks.at(stamp):
            # a view topic: for the recorder and viewers only (contract.Topic.on_demand)
            self.pose.publish_if_subscribed(lambda: pose_stamped(
                stamp, table.position_m[row], table.orientation_at(row)))
        self.diagnostics.count('references')

    def on_goal(self, message: PointStamped) -> None:
        try:
            self.schedule.add_goal(point_from_message(message))
        except (InvalidMessage, GoalRejected) as err:
            self.diagnostics.reject(contract.GOAL, str(err))
            return
        self.plan_goals()

    def plan_goals(self) -> None:
        """A whole move at once in lockstep, where nothing moves meanwhile;
        `rows_per_tick` rows per call in realtime."""
        for settled in self.schedule.plan(None if self.clock_mode == 'lockstep' else self.rows_per_tick):
            if isinstance(settled, GoalRejected):
                self.diagnostics.reject(contract.GOAL, str(settled))
            else:
                self.get_logger().info(f'goal {settled.goal_m} planned: {settled.duration_s:.2f} s '
                                       f'from tick {settled.start_tick}')


def main(args=None):
    return run(TrajectoryGeneratorNode, args)


if __name__ == '__main__':
    main()
