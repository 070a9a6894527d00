"""supervisor: failure detection, identification and recovery setpoints (paper §3).

Per tick k it pairs /cdpr/joint_states, /cdpr/effort_command, /cdpr/twin/joint_states and
/cdpr/reference by stamp, runs the Supervisor core, and publishes, in this order: the
recovery setpoint for the tick its verdict is due (k + contract.VERDICT_DELAY_TICKS; in a
tabulated move, also those of the ticks up to `reference_lead_cycles` after the
controller's, once each: a realtime controller running ahead of this node finds its own
tick's), /cdpr/fdi/broken_cable and /cdpr/mode when they change (latched), then
/cdpr/fdi/residual of the tick — which tells, in lockstep, which tick the unstamped
verdict judged: the controller answers state k + 2 only after it, and applies the verdict
from that tick on, as the in-process engine does. It reads the commands of the graph's controller only
(parameter `command_writer`), those the plant obeys: another writer's raise no alarm.
"""
from __future__ import annotations

import json
import time

from rclpy.duration import Duration
from sensor_msgs.msg import JointState
from std_msgs.msg import Int32, String

from cdpr_control.control.controller import JointReference
from cdpr_control.setup.settings import node_settings
from cdpr_control.tension_distribution import configured_tension_distribution
from cdpr_msgs_py import contract, qos
from cdpr_msgs_py.contract import NOMINAL
from cdpr_msgs_py.conversions import joint_state_bytes
from cdpr_msgs_py.health import unjudged_problem, verdict_problems
from cdpr_msgs_py.runtime.diagnostics import LOG_THROTTLE_S
from cdpr_msgs_py.runtime.node import CdprNode
from cdpr_msgs_py.runtime.spin import run

from ..settings.config import settled_fdi
from ..recovery_planning.planning import PlanAtOnce, PlanInBackground
from ..supervision.supervisor import Supervisor

INPUTS = ('state', 'command', 'twin', 'reference')
ACK_TIMEOUT = Duration(seconds=1.0)
BUFFER_LENGTH = 512
# A recovery's reference is due this many ticks after the plant's current one: the drives
# want the next tick's, and it takes up to a tick to reach them.
DUE_AHEAD_TICKS = 2


class SupervisorNode(CdprNode):

    def __init__(self):
        super().__init__(contract.SUPERVISOR)
        settings = node_settings(self, contract.SUPERVISOR)
        self.robot, self.period_s, self.period_ns = settings.robot, settings.period_s, settings.period_ns
        control = settings.section('control')
        self.stale_ns = control.integer('stale_cycles', minimum=1) * self.period_ns
        # a recovery's move goes out as far ahead as the trajectory's references do
        self.lead = control.integer('reference_lead_cycles', minimum=1)
        self.reference_sent_ns = -1
        self.origin_wall_ns = 0    # when the first tick was judged (monotonic ns)
        fdi, recovery = settled_fdi(settings, self.robot)
        distribution = configured_tension_distribution(control, self.robot)
        # realtime, a platform's recovery is planned beside the loop, not in the tick (planning.py)
        self.supervisor = Supervisor(self.robot, fdi, recovery, distribution, self.period_s,
                                     PlanInBackground() if self.clock_mode == 'realtime' else PlanAtOnce())
        self.names = contract.joint_names(self.robot.cable_count)
        self.inputs: dict[str, dict[int, object]] = {name: {} for name in INPUTS}
        self.origin_ns: int | None = None
        self.last_tick_ns: int | None = None
        self.published_broken: list[int] = []
        # Realtime: how far judging trails the newest state (ns), which adds to the reaction.
        self.max_lag_ns = 0
        self.verdict_lag_ns: int | None = None
        self.published_mode = NOMINAL
        self.unidentified_alarms = 0
        self.disturbances = 0
        self.residual = self.create_stream_publisher(JointState, contract.FDI_RESIDUAL)
        self.broken_cable = self.create_publisher(Int32, contract.FDI_BROKEN_CABLE, qos.LATCHED)
        self.mode = self.create_publisher(String, contract.MODE, qos.LATCHED)
        self.tensions = self.create_stream_publisher(JointState, contract.RECOVERY_TENSIONS)
        self.recovery_reference = self.create_stream_publisher(JointState, contract.RECOVERY_REFERENCE)
        self.create_sole_writer_subscription(JointState, contract.EFFORT_COMMAND, self.on_command,
                                             qos.STREAM, self.parameter(
                                                 'command_writer', 'controller',
                                                 'the node whose effort_command the motors obey, '
                                                 'the only one judged'))
        self.create_subscription(JointState, contract.TWIN_JOINT_STATES, self.on_twin, qos.STREAM)
        self.create_subscription(JointState, contract.REFERENCE, self.on_reference, qos.STREAM)
        self.start_when_matched(lambda: self.create_subscription(
            JointState, contract.JOINT_STATES, self.on_state, qos.STREAM))
        self.broken_cable.publish(Int32(data=0))
        self.mode.publish(String(data=NOMINAL))
        settings.declare(self)

    def on_state(self, message: JointState) -> None:
        self.store('state', self.joints_or_reject(message, contract.JOINT_STATES))

    def on_command(self, message: JointState) -> None:
        self.store('command', self.joints_or_reject(message, contract.EFFORT_COMMAND, ('effort',)))

    def on_twin(self, message: JointState) -> None:
        self.store('twin', self.joints_or_reject(message, contract.TWIN_JOINT_STATES))

    def on_reference(self, message: JointState) -> None:
        self.store('reference', self.joints_or_reject(message, contract.REFERENCE))

    def store(self, name: str, joints) -> None:
        if joints is None or (self.last_tick_ns is not None and joints.stamp_ns <= self.last_tick_ns):
            return
        buffer = self.inputs[name]
        buffer[joints.stamp_ns] = joints
        if len(buffer) > BUFFER_LENGTH:
            # an input that stopped (a dead twin) must not make the others pile up
            del buffer[min(buffer)]
            if name == 'state':
                self.diagnostics.count('skipped ticks')
        self.judge_ready_ticks()

    def judge_ready_ticks(self) -> None:
        """Judge every tick whose four inputs have arrived, oldest first."""
        ready = sorted(set.intersection(*(set(self.inputs[name]) for name in INPUTS)))
        for stamp in ready:
            self.judge(stamp, *(self.inputs[name].pop(stamp) for name in INPUTS))
            for name, buffer in self.inputs.items():
                for old in [s for s in buffer if s <= stamp]:
                    del buffer[old]
                    if name == 'state':
                        # a tick whose inputs never all came: it goes unjudged
                        self.diagnostics.count('skipped ticks')

    def judge(self, stamp: int, state, command, twin, reference) -> None:
        if self.origin_ns is None:
            self.origin_ns, self.origin_wall_ns = stamp, time.monotonic_ns()
        self.last_tick_ns = stamp
        lag = max(self.inputs['state'], default=stamp) - stamp
        self.max_lag_ns = max(self.max_lag_ns, lag)
        tick = (stamp - self.origin_ns) // self.period_ns
        unjudged = self.supervisor.unjudged_ticks
        verdict = self.supervisor.update(
            tick, state.position, state.velocity, state.effort, command.effort, twin.effort,
            twin.velocity, JointReference(reference.position, reference.velocity, reference.effort))
        # the verdict's setpoints are for the tick it is due
        following = stamp + contract.VERDICT_DELAY_TICKS * self.period_ns
        if verdict.tension_setpoint_n is not None:
            self.tensions.publish(joint_state_bytes(self.names, following, effort=verdict.tension_setpoint_n))
        if verdict.reference is not None:
            # ahead of the controller's tick, not of the one judged, which may trail it: in
            # realtime the plant's clock's, beyond the states this node has had (a stall
            # at the naming leaves them queued)
            behind = (max(lag, self.origin_ns + time.monotonic_ns() - self.origin_wall_ns - stamp)
                      if self.clock_mode == 'realtime' else lag)
            behind_ticks = behind // self.period_ns
            ahead = [(self.origin_ns + later * self.period_ns, reference) for later, reference
                     in self.supervisor.planned_references(tick, self.lead + behind_ticks,
                                                           tick + behind_ticks + DUE_AHEAD_TICKS)]
            for at_ns, reference in [(following, verdict.reference)] + ahead:
                if at_ns > self.reference_sent_ns:
                    self.recovery_reference.publish(joint_state_bytes(
                        self.names, at_ns, reference.angle_rad, reference.angular_velocity_rad_s,
                        reference.feedforward_nm))
                    self.reference_sent_ns = at_ns
        # Lockstep: a verdict change is acknowledged by every reader before the residual
        # goes out, so the controller handles it before the residual that releases its next
        # tick (separate topics keep no order between them). Realtime: nothing waits on the
        # residual, and waiting (~6 ms per topic here) would start the recovery ticks late;
        # only a further broken cable waits for the one before, which it would otherwise
        # overwrite in the depth-1 latched history before every reader had it.
        lockstep = self.clock_mode == 'lockstep'
        if verdict.broken_cables and self.verdict_lag_ns is None:
            self.verdict_lag_ns = lag
        for cable in verdict.broken_cables:
            if cable not in self.published_broken:
                if self.published_broken and not lockstep:
                    self.broken_cable.wait_for_all_acked(ACK_TIMEOUT)
                self.broken_cable.publish(Int32(data=cable))
                self.published_broken.append(cable)
                if lockstep:
                    self.broken_cable.wait_for_all_acked(ACK_TIMEOUT)
        if verdict.mode != self.published_mode:
            self.mode.publish(String(data=verdict.mode))
            if lockstep:
                self.mode.wait_for_all_acked(ACK_TIMEOUT)
            self.published_mode = verdict.mode
        self.residual.publish(joint_state_bytes(self.names, stamp, effort=verdict.residual_nm))
        self.diagnostics.count('ticks')
        if self.supervisor.unjudged_ticks > unjudged:
            self.diagnostics.count('unjudged ticks')
        for event in verdict.events:
            self.get_logger().warning(event)
        if self.supervisor.unidentified_alarms > self.unidentified_alarms:
            self.unidentified_alarms = self.supervisor.unidentified_alarms
            text = f'an alarm ended without a free motor ({self.unidentified_alarms} in all)'
            self.diagnostics.warn('unidentified alarm', text)
            self.get_logger().warning(text, throttle_duration_sec=LOG_THROTTLE_S)
        if self.supervisor.disturbances > self.disturbances:
            self.disturbances = self.supervisor.disturbances
            self.diagnostics.warn('disturbance', f'a push or contact on the end-effector, not a '
                                                 f'failure: no cable named ({self.disturbances} in all)')
        if verdict.events:
            self.diagnostics.publish()

    def idle(self) -> None:
        super().idle()
        states = self.inputs['state']
        if self.clock_mode == 'realtime' and states:
            # States keep coming but ticks cannot be judged: the twin or the commands are
            # missing. Say so; judging nothing raises no alarm.
            judged = min(states) if self.last_tick_ns is None else max(self.last_tick_ns, min(states))
            behind = max(states) - judged
            missing = [name for name in ('twin', 'command') if not self.inputs[name]]
            self.diagnostics.error = (f'FDI unavailable: no {" or ".join(missing) or "matching input"} '
                                      f'for {behind / 1e6:.0f} ms' if behind > self.stale_ns else '')

    def current_problems(self) -> tuple[list[str], list[str]]:
        # skipped ticks never reached the core: they count as ticks, unjudged
        window = self.diagnostics.window
        skipped = window['skipped ticks']
        blind = unjudged_problem(self.diagnostics.health.limits, window['ticks'] + skipped,
                                 window['unjudged ticks'] + skipped)
        error, warning = verdict_problems(self.supervisor.mode, self.published_broken,
                                          self.supervisor.fault_reason)
        return [error], [warning, blind]

    def current_facts(self) -> dict[str, str]:
        """The supervisor's summary as /diagnostics key-values (JSON texts)."""
        facts = super().current_facts()
        facts.update({f'fdi {key}': json.dumps(value) for key, value in self.supervisor.summary().items()})
        facts['judging lag max ms'] = f'{self.max_lag_ns / 1e6:.1f}'
        if self.verdict_lag_ns is not None:
            facts['judging lag at the verdict ms'] = f'{self.verdict_lag_ns / 1e6:.1f}'
        return facts


def main(args=None):
    return run(SupervisorNode, args)


if __name__ == '__main__':
    main()
