"""plant_simulator: the stand-in for the hardware, publishing what a real drive reports.

lockstep: publishes the state of tick k (and /clock), steps only when the command
stamped with tick k has arrived; bit-for-bit repeatable. realtime: steps on the wall
clock, a period at a time from its first tick (CdprNode.due_s: no drift), with zero-order
hold of the last command, as hardware does. Exits with
code 0 after the settled run's `run.last_tick` (the run is complete; sooner, as
cdpr_twin.nodes.run_length says, once a recovery is over). The run's start, failures and
length are values the launcher settled (cdpr_control.setup.settings): the plant knows no motion.
Obeys the commands of the graph's controller only (parameter `command_writer`), as a
hardware bridge must. A cable breaks on `inject_failure` only where the plant was
started with `failure_injection` on, and only from the node `injection_writer` names:
otherwise any terminal on the network could break a running robot's cable. A run's own
failures are settled values (`run.failure_times_s`), which need no topic. With
`wait_for_recorder` (set whenever the graph records) a lockstep run stays within
`recorder_lead_s` of the recorder's newest tick, and the end of a run in either mode
waits, at most a drain, until the recorder has the last state.
"""
from __future__ import annotations

import json
import math
import time

from geometry_msgs.msg import PointStamped, PoseStamped
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from std_msgs.msg import Header, Int32, String

from cdpr_control.setup.settings import node_settings
from cdpr_msgs_py import contract, qos
from cdpr_msgs_py.conversions import joint_state_bytes, ns_to_stamp, pose_stamped
from cdpr_msgs_py.health import loop_problem
from cdpr_msgs_py.runtime.node import CdprNode
from cdpr_msgs_py.runtime.spin import run
from cdpr_msgs_py.stamps import stamp_to_ns

from cdpr_twin.models.plant import PlantConfig, PlantSimulator, settled_pushes
from cdpr_twin.nodes.recorder_pacing import RecorderPacing
from cdpr_twin.models.run_figures import RunFigures
from cdpr_twin.nodes.run_length import RunLength
from cdpr_twin.nodes.watchdog import BRAKING, CommandWatchdog
from cdpr_twin.nodes.tick_timing import TickTiming


# How far ahead of the recorder a lockstep run may be (s of ticks): well within the
# writers' history, and what a recorder catches up on within a node's drain at the end.
RECORDER_LEAD_S = 0.5


class PlantSimulatorNode(CdprNode):

    def __init__(self):
        super().__init__(contract.PLANT_SIMULATOR)
        settings = node_settings(self, contract.PLANT_SIMULATOR)
        self.robot, self.period_s, self.period_ns = settings.robot, settings.period_s, settings.period_ns
        plant_section = settings.section('plant')
        # Started alone, without a settled run: from the robot's home, until stopped.
        run = settings.section('run', {})
        failures = zip(run.raw('failure_times_s', []), run.raw('failure_cable_indices', []))
        self.plant = PlantSimulator(self.robot, PlantConfig.from_section(plant_section, self.robot.cable_count),
                                    run.vector('start_position_m', 3, self.robot.home_position_m.tolist()),
                                    failures, settled_pushes(run),
                                    self.robot.body.orientation_from(run, 'start_orientation'))
        # The figures of the end-effector from every tick (run_figures), against the settled
        # motion's reference poses (none when started alone without one).
        self.figures = RunFigures(self.robot.cable_count, self.period_s, self.robot.body.has_orientation,
                                  tension_min_n=self.robot.tension_min_n)
        self.reference_poses = (self.robot.body.reference_poses(self.robot, settings.section('motion'), self.period_s)
                                if settings.has('motion') else None)
        self.run_length = RunLength(
            run.integer('last_tick', minimum=0) if run.has('last_tick') else math.inf,
            run.integer('hold_after_ticks', minimum=0) if run.has('hold_after_ticks') else None)
        self.resend_s = self.parameter(
            'command_timeout_s', 0.5, 'lockstep: a state not answered for this long (s) is sent again',
            value_range=(0.0, None))
        self.start_delay_s = self.parameter(
            'start_delay_s', 0.5, 'the first tick waits this long (s) once every node listens',
            value_range=(0.0, None))
        self.ready_since = None
        self.names = contract.joint_names(self.robot.cable_count)
        self.tick = 0
        self.timing = TickTiming(self.period_s, deadlines=self.clock_mode == 'realtime')
        self.started = False
        self.sent_at = 0.0
        # Until the first command arrives, hold the load.
        self.command = self.plant.holding_torque_nm()
        self.state = self.create_stream_publisher(JointState, contract.JOINT_STATES)
        self.truth_pose = self.create_stream_publisher(PoseStamped, contract.GROUND_TRUTH_POSE)
        self.truth_tensions = self.create_stream_publisher(JointState, contract.GROUND_TRUTH_TENSIONS)
        self.clock = self.create_stream_publisher(Clock, contract.CLOCK)
        # A mode carries no stamp, and may come before or after the command of the tick it
        # judged: in lockstep the supervisor's residual of that tick, which follows the
        # mode, says which tick it was (so that a run ends at the same tick as in the
        # engine); in realtime the mode applies from the plant's next tick.
        self.learnt_mode: str | None = None
        # The same for the first naming of a broken cable, the run's detection (its figures).
        self.learnt_naming = False
        self.create_subscription(String, contract.MODE, self.on_mode, qos.LATCHED)
        self.create_subscription(Int32, contract.FDI_BROKEN_CABLE, self.on_broken_cable, qos.LATCHED)
        self.create_subscription(PointStamped, contract.GOAL, self.on_goal, qos.STREAM)
        if self.clock_mode == 'lockstep':
            self.create_subscription(JointState, contract.FDI_RESIDUAL, self.on_residual, qos.STREAM)
        self.create_sole_writer_subscription(JointState, contract.EFFORT_COMMAND, self.on_command,
                                             qos.STREAM, self.parameter(
                                                 'command_writer', 'controller',
                                                 'the only node whose effort_command the motors obey'))
        if self.parameter('failure_injection', False,
                          'obey inject_failure (cable k breaks now); off, every message on it is rejected'):
            self.create_sole_writer_subscription(
                Int32, contract.INJECT_FAILURE, self.on_inject, qos.STREAM,
                self.parameter('injection_writer', 'failure_injector',
                               'the only node whose inject_failure is obeyed'), required=False)
        else:
            self.create_subscription(Int32, contract.INJECT_FAILURE, self.refuse_injection, qos.STREAM)
        # With a recorder in the graph: in lockstep no further ahead of it than its lead,
        # and in either mode the run's end waits until it has the last state, so that its
        # bag gets every tick (recorder_pacing).
        wait_for_recorder = self.parameter(
            'wait_for_recorder', False,
            f'lockstep: run no further ahead of the graph\'s {contract.BAG_RECORDER} than '
            'recorder_lead_s; either mode: the end waits (at most a drain) until it has the last state')
        lead_s = self.parameter('recorder_lead_s', RECORDER_LEAD_S,
                                'lockstep, waiting for the recorder: how far ahead of it the run may be '
                                '(s of ticks; less than the writers\' streams.history_s)',
                                value_range=(0.0, None))
        self.recorder = None
        if wait_for_recorder:
            self.recorder = RecorderPacing(max(1, round(lead_s / self.period_s)))
            self.create_sole_writer_subscription(Header, contract.RECORDER_PROGRESS, self.on_recorder_progress,
                                                 qos.LATCHED, contract.BAG_RECORDER)
        # A state held until the recorder catches up.
        self.held = False
        self.published_tick = -1
        # realtime: the plant's own clock, periods from its first tick (monotonic s)
        self.clock_start_s = 0.0
        self.periods = 0
        self.watchdog = CommandWatchdog(plant_section.integer('command_timeout_cycles', minimum=1))
        settings.declare(self)

    def stamp_ns(self) -> int:
        return self.tick * self.period_ns

    def publish_state(self) -> None:
        stamp = self.stamp_ns()
        angle, speed = self.plant.measure()
        self.last_state = joint_state_bytes(self.names, stamp, angle, speed, self.command)
        self.timing.state_published(stamp)
        self.state.publish(self.last_state)
        # The state first: the controller answers while the rest is done. The truth goes
        # out on the view ticks, to readers only (contract.Topic.on_demand); its figures
        # come from every tick.
        if self.view_ticks.at(stamp):
            if self.clock_mode == 'lockstep':
                self.clock.publish_if_subscribed(lambda: Clock(clock=ns_to_stamp(stamp)))
            self.truth_pose.publish_if_subscribed(lambda: pose_stamped(stamp, self.plant.position_m,
                                                                       self.plant.orientation))
            self.truth_tensions.publish_if_subscribed(
                lambda: joint_state_bytes(self.names, stamp, velocity=self.plant.angular_velocity_rad_s,
                                          effort=self.plant.tension_n))
        self.add_figures()
        self.published_tick = self.tick
        self.sent_at = time.monotonic()
        self.diagnostics.count('states')

    def add_figures(self) -> None:
        """This tick's truth into the run's figures, with the settled motion's reference pose
        of the tick (held at its end) where there is one."""
        reference = orientation = None
        if self.reference_poses is not None:
            positions, orientations = self.reference_poses
            row = min(self.tick, len(positions) - 1)
            reference = positions[row]
            orientation = None if orientations is None else orientations[row]
        self.figures.add(self.tick, self.plant.position_m, self.plant.orientation, self.plant.tension_n,
                         reference, orientation)

    def resend_state(self) -> None:
        """The same measurement again: a second draw of noise would break repeatability."""
        self.state.publish(self.last_state)
        self.sent_at = time.monotonic()
        self.diagnostics.count('resent states')

    def current_facts(self) -> dict[str, str]:
        # Timing figures only when diagnostics go out: percentiles cost more than a tick.
        # The instants cables really parted (1-based), for the run's metrics: the field
        # plant's electromagnet parts its cable after the failure it was told. And the
        # figures of the end-effector from every tick, where the run ended among them,
        # whatever a recorder kept.
        run = {contract.BROKEN_AT_KEY: json.dumps({str(cable + 1): at for cable, at
                                                  in self.plant.broken_at_s.items()}),
               contract.RUN_FIGURES_KEY: json.dumps(self.figures.summary())}
        return {**super().current_facts(), **self.timing.facts(), **run}

    def current_problems(self) -> tuple[list[str], list[str]]:
        window = self.timing.take_window()
        if self.clock_mode != 'realtime':
            return [], []   # lockstep runs as fast as the graph can: it has no period to keep
        return [loop_problem(self.diagnostics.health.limits, self.period_s, *window)], []

    def idle(self) -> None:
        super().idle()
        if not self.started:
            # Every node listens (`matches`, from the launcher) and the controller whose
            # commands it obeys is known (standalone: that alone).
            if self.ready_since is None and self.matched():
                self.ready_since = time.monotonic()
            # A short grace period: the nodes' last subscriptions settle.
            if self.ready_since is not None and time.monotonic() - self.ready_since >= self.start_delay_s:
                self.started = True
                self.get_logger().info(f'starting, {self.clock_mode}, {self.run_length.last_tick} ticks at most')
                self.publish_state()
                if self.clock_mode == 'realtime':
                    self.clock_start_s = time.monotonic()
                    self.periods = 1
                    self.due_s = self.clock_start_s + self.period_s
        elif self.clock_mode == 'lockstep' and not self.held and time.monotonic() - self.sent_at > self.resend_s:
            self.resend_state()

    def on_command(self, message: JointState) -> None:
        joints = self.joints_or_reject(message, contract.EFFORT_COMMAND, ('effort',))
        if joints is None:
            return
        self.timing.command_received(joints.stamp_ns)
        joints.effort = self.plant.applied_torque_nm(joints.effort)
        if self.clock_mode == 'realtime':
            self.command = joints.effort
            self.watchdog.command_arrived()
            return
        if joints.stamp_ns != self.stamp_ns() or not self.started:
            return
        self.command = joints.effort
        self.advance()
        if self.finished:
            return
        if self.recorder is not None and not self.recorder.may_publish(self.tick):
            self.held = True
            self.diagnostics.count('states held for the recorder')
            return
        self.publish_state()

    def on_recorder_progress(self, message: Header) -> None:
        self.recorder.recorded(stamp_to_ns(message.stamp) // self.period_ns)
        if self.held and self.recorder.may_publish(self.tick):
            self.held = False
            self.publish_state()

    def keeps_draining(self) -> bool:
        """Waiting for the recorder, the run's end waits until it has the last state."""
        return self.recorder is not None and not self.recorder.has_recorded(self.published_tick)

    def advance(self) -> None:
        self.plant.step(self.command, self.period_s)
        self.figures.take_breaks(self.plant.broken_at_s)
        self.tick += 1
        if self.tick > self.run_length.last_tick:
            self.finished = True
            # the run is over: no more steps (nor watchdog braking) while the node drains
            self.due_s = None
            # The run's figures now, while the node still spins to deliver them.
            self.diagnostics.publish()

    def on_due(self) -> None:
        """Realtime, a period has ended on the plant's clock: its step, and the next
        period's end, on the clock from the first tick (a drive's cycle does not drift
        with the loop's latencies); periods slept through are missed, as a drive's are."""
        self.realtime_step()
        if self.finished:
            return
        now = time.monotonic()
        self.periods = max(self.periods + 1, int((now - self.clock_start_s) / self.period_s) + 1)
        self.due_s = self.clock_start_s + self.periods * self.period_s

    def realtime_step(self) -> None:
        """The period that just ended ran under the latest command (sample and hold: the
        answer to its state if it came in time, else an older one); then the next state.

        Stepping before publishing, not after, keeps an answer that arrives within the
        period from waiting a whole extra period, which the twin does not wait.
        """
        state = self.watchdog.tick()
        braking = state == BRAKING
        if braking != self.plant.drums_locked:
            self.plant.lock_drums(braking)
            message = (f'no command for {self.watchdog.silent_cycles} cycles: drums braked'
                       if braking else 'commands are back: brake released')
            self.get_logger().warning(message)
            self.diagnostics.facts['command watchdog'] = message
            self.diagnostics.error = message if braking else ''
            self.diagnostics.publish()
        if braking:
            self.diagnostics.count('braked ticks')
        self.advance()
        if not self.finished:
            self.publish_state()

    def on_mode(self, message: String) -> None:
        if self.clock_mode == 'lockstep':
            self.learnt_mode = message.data
        else:
            self.run_length.mode(message.data, self.tick + 1)

    def on_broken_cable(self, message: Int32) -> None:
        if not message.data or self.learnt_naming:
            return
        if self.clock_mode == 'lockstep':
            self.learnt_naming = True
        else:
            # realtime: the verdict judged a tick of the last few (the supervisor trails)
            self.figures.detection_at(self.published_tick)

    def on_goal(self, _message: PointStamped) -> None:
        self.figures.goal_at(self.published_tick)

    def on_residual(self, message: JointState) -> None:
        if self.learnt_mode is None and not self.learnt_naming:
            return
        joints = self.joints_or_reject(message, contract.FDI_RESIDUAL, ('effort',))
        if joints is None:
            return
        judged = joints.stamp_ns // self.period_ns
        if self.learnt_naming:
            self.figures.detection_at(judged)
            self.learnt_naming = False
        if self.learnt_mode is not None:
            # the verdict on tick k steers the loop from tick k + VERDICT_DELAY_TICKS
            self.run_length.mode(self.learnt_mode, judged + contract.VERDICT_DELAY_TICKS)
            self.learnt_mode = None

    def refuse_injection(self, message: Int32) -> None:
        self.diagnostics.reject(contract.INJECT_FAILURE, f'cable {message.data}: failure injection is off '
                                f'(parameter failure_injection)')

    def on_inject(self, message: Int32) -> None:
        if not 1 <= message.data <= self.robot.cable_count:
            self.diagnostics.reject(contract.INJECT_FAILURE, f'cable {message.data} out of range')
            return
        self.get_logger().warning(f'cable {message.data} breaks now (injected)')
        self.plant.inject_failure(message.data - 1)


def main(args=None):
    return run(PlantSimulatorNode, args)


if __name__ == '__main__':
    main()
