"""The supervisor's core: residual, detection, identification and recovery, per tick.

Tick k brings the measured θ_k, θ̇_k and the torque applied over the previous period
(what the drive reports), the controller's answer c_k, the twin's c_DT,k and θ̇_DT,k, and
the reference of tick k. The verdict of tick k (broken cables, mode, setpoints) is what
the controller uses from tick k + contract.VERDICT_DELAY_TICKS on, the setpoints those
of that tick.
"""
from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field

import numpy as np

from cdpr_control.control.controller import JointReference
from cdpr_control.point_mass.kinematics import KinematicsError
from cdpr_control.model.robot import Robot
from cdpr_control.tension_distribution import TensionDistribution
from cdpr_msgs_py.contract import FAULT, NOMINAL, VERDICT_DELAY_TICKS

from ..detection import tick_arithmetic
from ..detection.identification import identify_broken_cables
from ..detection.tension_collapse import TensionCollapse
from ..detection.wrench_balance import WrenchBalance, overstretch_m
from ..detectors import make_detector
from ..recovery_planning.recovery import RecoveryInfeasible, check_recoverable
from ..recovery_strategies import STRATEGIES, Naming, StartedRecovery
from ..settings.config import FdiConfig, RecoveryConfig


def loss_onset(onset: int, freed: int, alarm: int) -> int:
    """The tick a watched motor lost its cable's pull (-1: not lost), from the first tick of
    its residual's run above δ seen while watched (`onset`, -1: none), the tick it was
    freed (`freed`, -1: not) and the alarm's tick: the freed tick where its residual never
    rose, or rose before the alarm (a model's mismatch tells no order), the earlier of
    the two where it rose after (it may have looked free first)."""
    if onset < 0:
        return freed
    if onset < alarm:
        return max(onset, freed)
    return onset if freed < 0 else min(onset, freed)


class AlarmEvidence:
    """The sensorless tensions' lower bounds (N) and residuals (N·m) of an alarm's ticks,
    the last `window` of them, averaged.

    A motor is judged free on the average: the mean of per-tick τ̂ takes its acceleration
    from the speed change over the ticks averaged, so what a drive's delay and speed
    filter shift from one period to the next cancels (on the field plant a freed motor,
    swinging under its controller, reads ±10 N and a residual of either sign from one
    period to the next, ~0 N and a positive residual over four). The average starts at
    the alarm, which comes after the break: no tick of the intact cable enters it, and
    the alarm's first tick is judged on its own, as the paper does. It goes on through
    ticks without an alarm, and ends after `window` of them in a row: the freed motor's
    swinging command takes the residual back under the threshold for a tick or two. The
    supervisor judges every tick the evidence holds, alarm or not.
    """

    def __init__(self, window: int):
        self.window = window
        # per tick: τ̂'s lower bound (N), the residual (N·m)
        self.recent: deque[tuple[np.ndarray, np.ndarray]] = deque(maxlen=window)
        self.quiet_ticks = 0

    @property
    def ticks(self) -> int:
        return len(self.recent)

    def add(self, low_n: np.ndarray, residual_nm: np.ndarray, alarm: bool) -> None:
        """A tick's τ̂ lower bound and residual: from an alarm on, until `window` quiet
        ticks."""
        self.quiet_ticks = 0 if alarm else self.quiet_ticks + 1
        if not alarm and (not self.ticks or self.quiet_ticks >= self.window):
            self.clear()
            return
        self.recent.append((low_n, residual_nm))

    def clear(self) -> None:
        self.recent.clear()
        self.quiet_ticks = 0

    def tension_low_n(self) -> np.ndarray:
        return np.mean([low for low, _ in self.recent], axis=0)

    def residual_nm(self) -> np.ndarray:
        return np.mean([residual for _, residual in self.recent], axis=0)


@dataclass
class Verdict:
    """The supervisor's output of one tick; cables 1-based, setpoints for the tick it is
    due (tick + VERDICT_DELAY_TICKS)."""

    tick: int
    residual_nm: np.ndarray
    alarm: bool
    broken_cables: list[int]
    mode: str
    tension_setpoint_n: np.ndarray | None = None
    reference: JointReference | None = None
    events: list[str] = field(default_factory=list)


class Supervisor:

    def __init__(self, robot: Robot, fdi: FdiConfig, recovery: RecoveryConfig,
                 distribution: TensionDistribution, period_s: float, planner=None):
        """`planner` plans what a recovery plans beside the loop (planning.py: at once when
        None; a realtime node's on a thread of its own): a platform's brake and its move to
        the safe pose. The recovery strategy is recovery.strategy's (recovery_strategies/),
        prepared now: the naming tick has no time to load kernels or find safe poses."""
        self.robot = robot
        self.planner = planner
        self.fdi = fdi
        self.recovery_config = recovery
        self.distribution = distribution
        self.period_s = period_s
        self.detector = make_detector(fdi)
        self.mode = NOMINAL
        self.broken: list[int] = []
        self.alarm_tick: int | None = None
        self.identified_tick: int | None = None
        self.unidentified_alarms = 0
        self.strategy = STRATEGIES[recovery.strategy]
        self.recovery: StartedRecovery | None = None
        self.fault_reason = ''
        self.previous_speed: np.ndarray | None = None
        self.previous_reference: JointReference | None = None
        self.tension_bounds_n = (np.zeros(robot.cable_count), np.zeros(robot.cable_count))
        # the per-tick arithmetic (tick_arithmetic), and what it takes of the robot
        self.arithmetic = tick_arithmetic.kernel().load_all()
        self.motor_constants = tick_arithmetic.motor_constants(robot.motor, fdi.friction)
        self.evidence = AlarmEvidence(fdi.identification_window_cycles)
        self.collapse = TensionCollapse(fdi.collapse_window_cycles, fdi.collapse_band_n,
                                        fdi.collapse_reference_n)
        self.candidates: list[int] = []
        self.candidates_since = 0
        self.previous_command: np.ndarray | None = None
        self.previous_applied: np.ndarray | None = None
        self.late_commands = 0
        self.recent_late_ticks: deque[int] = deque()
        self.untrusted_until = -1
        self.unjudged_ticks = 0
        self.balance = WrenchBalance(robot, period_s, fdi.disturbance_window_cycles)
        # the tick an unexplained force on the end-effector was first seen (None: none now)
        self.disturbed_since: int | None = None
        self.last_disturbed_tick: int | None = None
        # the first tick of the free motors leaving too few cables to place the end-effector
        self.unplaced_since: int | None = None
        # the motors looking free on the last alarm tick: since which tick (0-based cable)
        self.free_since: dict[int, int] = {}
        # per motor, the first tick of its residual's run above δ, on every tick (alarm or
        # not; -1: not above now): the order in which motors lost their cables' pull
        self.unloaded_since = np.full(robot.cable_count, -1, dtype=np.int64)
        # per motor, whether its residual is above δ now (1.0 or 0.0)
        self.unloaded = np.zeros(robot.cable_count)
        # per motor, the last tick its residual was above δ (long before the run: none yet)
        self.last_unloaded = np.full(robot.cable_count, np.iinfo(np.int64).min // 2, dtype=np.int64)
        # per motor, whether its residual rose above δ in the alarm's episode: of the motors
        # that look free, those that lost their pull; one that merely carries less than
        # δ/ρ all along (a drawn 7-cable platform's cable at 1.4 N, δ/ρ 1.7 N) looked as
        # free before the break
        self.lost_in_episode = np.zeros(robot.cable_count, dtype=bool)
        # per motor, the first tick it looked free (its sensorless tension's lower bound
        # under δ/ρ, as identify_broken_cables judges) with its residual above δ or on
        # the period it dropped there, until it does neither (its pull back); -1: not so
        self.freed_since = np.full(robot.cable_count, -1, dtype=np.int64)
        # per motor, the tick it dropped to looking free, its τ̂ (lower bound) down by δ/ρ
        # or more from the larger of the two periods before, while it has looked free
        # since; -1: not so. A cable parting under a load its residual cannot show (ρ τ
        # under ε) still drops its motor's τ̂ from that load to about zero in a period or
        # two (a drawn 8-cable point mass's cable 3, 4.2 N to 0.8 N, its residual under δ
        # throughout); a cable that carries about δ/ρ and dips under it (a drawn suspended
        # platform's cable 1, 2.9 to 2.7 N under δ/ρ = 2.78 N) does not drop.
        self.dropped_since = np.full(robot.cable_count, -1, dtype=np.int64)
        self.delta_n = fdi.delta_nm / robot.motor.drum_radius_m   # δ/ρ (N)
        # τ̂'s lower bound (N) of the two periods before, per motor
        self.recent_low_n = np.full((2, robot.cable_count), -np.inf)
        # of the candidates watched now, the first such tick seen while watched: a freed
        # motor's residual swings back under δ now and then, and its run starts again
        self.candidate_onsets: dict[int, int] = {}
        # of a motor that lost its pull alone, weighed once disturbance_window_cycles on:
        # (cable, since) whose balance the cables left explained (no push)
        self.unloaded_alone: tuple[int, int] | None = None
        # free cables spanning more than their length: since which tick
        self.overstretched_since: dict[int, int] = {}
        self.disturbance_reported = False
        self.disturbances = 0
        self.strategy.prepare(robot, recovery)

    def update(self, tick: int, angle_rad, angular_velocity_rad_s, applied_torque_nm,
               command_nm, twin_torque_nm, twin_angular_velocity_rad_s,
               reference: JointReference) -> Verdict:
        residual = np.asarray(command_nm, float) - np.asarray(twin_torque_nm, float)
        unloaded = self.unloaded
        self.arithmetic.watch_unloaded(residual, self.fdi.delta_nm, tick, unloaded, self.unloaded_since,
                                       self.last_unloaded)
        applied = np.ascontiguousarray(applied_torque_nm, float)
        speed = np.ascontiguousarray(angular_velocity_rad_s, float)
        collapsed: list[int] = []
        if self.previous_speed is not None:
            tension, low, high = np.empty(speed.size), np.empty(speed.size), np.empty(speed.size)
            self.arithmetic.sensorless_tensions(self.motor_constants, self.felt_torque_nm(applied),
                                                self.previous_speed, speed, self.period_s, tension, low, high)
            self.tension_bounds_n = low, high
            # kept while the motor looks free or its residual stays above δ: a slack
            # cable's residual swings about δ period by period, its pull does not return
            self.arithmetic.watch_freed(low, self.robot.motor.drum_radius_m, self.fdi.delta_nm, self.delta_n, tick,
                                        self.recent_low_n, self.unloaded_since, self.dropped_since,
                                        self.freed_since)
            self.balance.record(tick, angle_rad, angular_velocity_rad_s, (low + high) / 2)
            if not self.broken:   # once a cable is named, nothing more is looked for
                self.weigh_unloaded_alone(tick, unloaded)
                collapsed = self.collapse.update(low, high, self.reference_tensions(reference))
        events: list[str] = []
        alarm = False
        # compared as lists: == on floats, ~7x cheaper than numpy's on a few motors
        if self.previous_command is not None and applied.tolist() != self.previous_command.tolist():
            # The drive applied something other than the last command (it came late, or
            # its watchdog acted). After a burst of that the robot differs from the twin by
            # timing, not by a failure: the residual is not evidence until that has died out.
            self.late_commands += 1
            self.recent_late_ticks.append(tick)
            while self.recent_late_ticks[0] <= tick - self.fdi.late_command_window_cycles:
                self.recent_late_ticks.popleft()
            if len(self.recent_late_ticks) >= self.fdi.late_command_burst:
                self.untrusted_until = tick + self.fdi.late_command_guard_cycles
        if not self.broken and tick <= self.untrusted_until:
            self.candidates = []
            self.evidence.clear()
            self.unjudged_ticks += 1
        elif not self.broken:
            residual_alarm = self.detector.update(residual,
                                                  np.asarray(twin_angular_velocity_rad_s, float))
            alarm = residual_alarm or bool(collapsed)
            if alarm and self.alarm_tick is None:
                self.alarm_tick = tick
            if self.previous_speed is not None:
                self.evidence.add(self.tension_bounds_n[0], residual, alarm)
            # An alarm's episode lasts as long as its evidence, lapses included: judged on
            # the lapsed ticks too, a freed motor whose average comes near zero while its
            # swing takes the residual under the threshold is named then, before a cable the
            # break unloads goes slack and leaves two motors free (a push's signature).
            episode = alarm or self.evidence.ticks > 0
            if episode and self.previous_speed is not None:
                found = self.losing(tick, identify_broken_cables(self.evidence.tension_low_n(),
                                                           self.evidence.residual_nm(),
                                                           self.robot.motor.drum_radius_m, self.fdi.delta_nm))
                # a collapsed cable is free whatever the sign of a residual too small to judge
                found += [cable for cable in collapsed if cable not in found]
                if (self.disturbed_since is None and not self.settling(tick)
                        and (first := self.freed_first(found)) is not None):
                    found = [first]
                if self.disturbed(tick, found, events) or self.settling(tick):
                    found = self.overstretched(tick, found, angle_rad)
                confirmed = self.confirm(tick, found, angle_rad)
                if confirmed:
                    events += self.on_identified(tick, confirmed, angle_rad, angular_velocity_rad_s, command_nm,
                                                 reference)
            elif not episode:
                self.disturbed_since = None
                self.free_since = {}
                self.lost_in_episode[:] = False
            if not episode and self.alarm_tick is not None:
                # counted, not an event: under load such alarms come by the hundred
                self.unidentified_alarms += 1
                self.alarm_tick = None
        tensions = setpoint = None
        if self.recovery is not None and self.mode != FAULT:
            previous_mode = self.mode
            try:
                # SAFE_HOLD only at the safe pose (StartedRecovery.step)
                self.mode, tensions, setpoint = self.recovery.step(tick, angle_rad, angular_velocity_rad_s)
            except (ValueError, RecoveryInfeasible, np.linalg.LinAlgError) as err:
                # no pose was ever found, the move to SP cannot be planned, or it ended
                # off the safe pose and re-planning did not help: hold
                self.mode, tensions, setpoint = FAULT, None, None
                self.fault_reason = f'recovery failed at tick {tick}: {err}'
            events += self.recovery.take_notes()
            if self.mode != previous_mode:
                events.append(f'{self.mode} from tick {tick + VERDICT_DELAY_TICKS}'
                              + (f': {self.fault_reason}' if self.mode == FAULT else ''))
        self.previous_speed = speed.copy()
        self.previous_command = np.array(command_nm, dtype=float)
        self.previous_applied = applied
        self.previous_reference = reference
        return Verdict(tick, residual, alarm, [c + 1 for c in self.broken], self.mode, tensions,
                       setpoint, events)

    def felt_torque_nm(self, applied: np.ndarray) -> np.ndarray:
        """The torque the motors felt over the period that `applied` was applied in (N·m):
        the one before for fdi.drive_delay_s, then `applied`."""
        share = min(self.fdi.drive_delay_s / self.period_s, 1.0)
        if share == 0.0 or self.previous_applied is None:
            return applied
        return (1.0 - share) * applied + share * self.previous_applied

    def disturbed(self, tick: int, found: list[int], events: list[str]) -> bool:
        """Whether, on an alarm, something outside pushes the end-effector: the cables
        taken taut (all but the `found` free ones) leave a force above
        fdi.disturbance_force_n unexplained (wrench_balance), or are too few to weigh the
        end-effector while a push is on or the end-effector swings from one (a push
        slackening two cables of four). Reported once an episode, when it has lasted the
        balance's window; within it, a failure's jolt can look alike, and nothing is named."""
        # a motor free on average over the evidence's ticks pulled nothing over them
        since = tick - self.evidence.ticks + 1
        self.free_since = {cable: self.free_since.get(cable, since) for cable in found}
        weighable, force = self.placed_by(self.robot.cable_mask(found)), None
        if weighable:
            try:
                force = self.balance.unexplained_force_n(self.free_since)
            except KinematicsError:
                weighable = False   # their lengths fit no pose: one taken taut is slack too
        if weighable:
            self.unplaced_since = None
        elif self.unplaced_since is None:
            self.unplaced_since = tick
        magnitude = None if force is None else float(np.linalg.norm(force))
        # Right after a failure a loaded cable can slacken too, for less than
        # identification_confirm_cycles (confirm() narrows them): too few to weigh is a
        # disturbance within one, after one, or for longer.
        if ((weighable and (magnitude is None or magnitude <= self.fdi.disturbance_force_n))
                or (not weighable and self.disturbed_since is None and not self.settling(tick)
                    and tick - self.unplaced_since + 1 < self.fdi.identification_confirm_cycles)):
            self.disturbed_since = None
            return False
        if self.disturbed_since is None:
            self.disturbed_since, self.disturbance_reported = tick, False
        if tick - self.disturbed_since < self.fdi.disturbance_window_cycles:
            return True   # a failure's passing jolt, or the start of a push: hold
        self.last_disturbed_tick = tick
        if not self.disturbance_reported:
            self.disturbance_reported = True
            self.disturbances += 1
            slack = f'motor(s) {", ".join(str(c + 1) for c in found)} free' if found else ''
            events.append(f'disturbance from tick {self.disturbed_since}: ' + (
                f'{magnitude:.1f} N on the end-effector that the cables do not explain, not a '
                f'failure' + (f' ({slack})' if slack else '') if weighable else
                f'{slack}, too few cables taut to weigh the end-effector'))
        return True

    def settling(self, tick: int) -> bool:
        """Within fdi.disturbance_settle_cycles of a disturbance: the end-effector may still
        swing from it, and a cable go slack with nothing pushing."""
        return (self.last_disturbed_tick is not None
                and tick - self.last_disturbed_tick <= self.fdi.disturbance_settle_cycles)

    def overstretched(self, tick: int, found: list[int], angle_rad) -> list[int]:
        """Of the free motors `found`, the cables proven broken (wrench_balance.overstretch_m
        above fdi.identification_stretch_m for disturbance_window_cycles; only the one
        freed first, where one did so), the others taken taut; all while those are too few
        to place the end-effector (confirm() then holds them for disturbance_hold_cycles).
        Called on the ticks a disturbance is judged."""
        stretch = self.stretch_where_placed(self.robot.cable_mask(found), angle_rad)
        if stretch is None:
            return found   # confirm() holds them
        # for disturbance_window_cycles on end: a slack cable snapping taut again can
        # overshoot for a period, a broken one only draws further away. Where one of them
        # freed well before the others (freed_first), only it: placed by the rest along a
        # direction they barely hold, a cable the break slackened can read millimetres long
        leader = self.freed_first(found)
        self.overstretched_since = {
            cable: self.overstretched_since.get(cable, tick) for cable in found
            if stretch[cable] > self.fdi.identification_stretch_m and leader in (None, cable)}
        return [cable for cable, since in self.overstretched_since.items()
                if tick - since + 1 >= self.fdi.disturbance_window_cycles]

    def stretch_where_placed(self, taut: np.ndarray, angle_rad) -> np.ndarray | None:
        """wrench_balance.overstretch_m with the `taut` cables placing the end-effector (m,
        per cable); None where they do not: too few, or their lengths fit no pose (one of
        them is slack too)."""
        if not self.placed_by(taut):
            return None
        try:
            return overstretch_m(self.robot, angle_rad, taut)
        except KinematicsError:
            return None

    def placed_by(self, taut: np.ndarray) -> bool:
        """Whether the cables of the mask `taut` place the end-effector (and weigh it): as
        many as its degrees of freedom."""
        return np.count_nonzero(taut) >= self.robot.degrees_of_freedom

    def confirm(self, tick: int, found: list[int], angle_rad) -> list[int]:
        """One free motor is named at once; several are watched, narrowed to those free on
        every tick since, and named when one is left or after identification_confirm_cycles:
        those whose cables span more than their length by fdi.identification_stretch_m
        where the others place the end-effector (wrench_balance.overstretch_m), else all.
        None is named while the motors free now leave too few cables to place the
        end-effector (a push's slack cables, disturbed()), unless they stay so for
        disturbance_hold_cycles: then the one that lost its pull first
        (unloaded_before_all), else all.

        Right after a failure a loaded motor can look free for a while (its cable
        unloaded); the broken cables' motors stay free. On a redundant robot an intact
        cable can stay slack as long as the end-effector hangs off its reference on the
        others (a platform's crossing partner of the broken cable): its end then lies
        nearer its exit point than its motor has paid out, where a broken cable's, its
        motor wound in, lies further.
        """
        if self.candidates:
            self.candidates = [cable for cable in self.candidates if cable in found]
        if not self.candidates:
            self.candidates, self.candidates_since, self.candidate_onsets = found, tick, {}
        for cable in self.candidates:
            if cable not in self.candidate_onsets and self.unloaded_since[cable] >= 0:
                self.candidate_onsets[cable] = int(self.unloaded_since[cable])
        watched = tick - self.candidates_since + 1
        placed = self.placed_by(self.robot.cable_mask(found))
        if (not placed and len(self.candidates) > 1 and watched >= self.fdi.identification_confirm_cycles
                and (first := self.unloaded_first()) is not None):
            return [first]
        if (not placed and len(self.candidates) > 1 and watched >= self.fdi.disturbance_hold_cycles
                and (first := self.unloaded_before_all()) is not None):
            return [first]
        if (self.candidates and (len(self.candidates) == 1
                                 or watched >= self.fdi.identification_confirm_cycles)
                and (placed or watched >= self.fdi.disturbance_hold_cycles)):
            stretch = (self.stretch_where_placed(self.robot.cable_mask(self.candidates), angle_rad)
                       if len(self.candidates) > 1 and placed else None)
            proven = [] if stretch is None else [cable for cable in self.candidates
                                                 if stretch[cable] > self.fdi.identification_stretch_m]
            freed = self.freed_first(self.candidates)
            return sorted(proven or self.leading(stretch) or ([freed] if freed is not None else self.candidates))
        return []

    def weigh_unloaded_alone(self, tick: int, unloaded: np.ndarray) -> None:
        """Where one motor alone has lost its cable's pull for disturbance_window_cycles,
        whether the cables left explain the end-effector's balance without it (a break),
        or leave a force above fdi.disturbance_force_n (a push): weighed once a run. A
        motor whose residual is above δ but that does not look free (freed_since) still
        pulls: the twin's mismatch (a drawn 4-cable point mass's cable 2 carried 2 N with
        its residual above δ for 1.9 s before another cable broke), not a loss."""
        if np.count_nonzero(unloaded) != 1:
            return
        cable = int(np.argmax(unloaded))
        since = int(self.unloaded_since[cable])
        if (tick - since != self.fdi.disturbance_window_cycles or self.freed_since[cable] < 0
                or not self.placed_by(self.robot.cable_mask([cable]))):
            return
        try:
            force = self.balance.unexplained_force_n({cable: since})
        except KinematicsError:
            return
        if force is not None and float(np.linalg.norm(force)) <= self.fdi.disturbance_force_n:
            self.unloaded_alone = (cable, since)

    def unloaded_first(self) -> int | None:
        """Of several candidates too few cables are left to place the end-effector beside,
        the one whose motor lost its cable's pull (residual above δ) at least
        identification_confirm_cycles before every other's and has not had it back since:
        a cable that parted, the end-effector then falling away from it and off the cables
        that it leaves slack (a light point mass on four cables, hanging from the two
        either side of the broken one) — where, while it alone had lost its pull, the
        others explained the end-effector's balance (weigh_unloaded_alone): a push that
        unloads one cable before another leaves its force unexplained. None where none
        went first so."""
        first = self.lost_first(self.candidates, self.unloaded_since[self.candidates],
                                self.fdi.identification_confirm_cycles)
        # and the balance weighed while it alone had lost its pull was a break's
        return first[0] if first is not None and self.unloaded_alone == first else None

    def unloaded_before_all(self) -> int | None:
        """Of several candidates too few cables are left to place the end-effector beside,
        still so after disturbance_hold_cycles, the one whose motor lost its cable's pull
        a tick or more before every other's: the break comes first, the cables its
        end-effector then falls off after (a platform the six cables left cannot hold at
        the pose of the break: one of them slack within 2–20 ms). None where two lost it
        on the same tick (two parted at once) or one never lost it while watched (its
        first tick then: candidate_onsets). Where one freed first (freed_first), that one:
        a residual can rise above δ a tick before the break's on the cable it is to
        slacken (a drawn 6 kg point mass on four cables, its diagonal). A residual whose run
        above δ began before the alarm, a model's mismatch where δ is small, tells no
        order: that motor's loss starts when it first looked free (freed_since; a drawn
        5-cable point mass: above δ for 3 s before the break, freed a period after the
        broken motor). A motor that looked free before its residual rose, or whose
        residual never rose while watched, lost its pull when it looked free: a cable
        parting under ε/ρ (a drawn 4-cable point mass's cable 4 at 3.9 N dropped two
        periods before its diagonal's motor, whose residual was above δ all along, looked
        free; its own residual rose 0.9 s later)."""
        freed = self.freed_first(self.candidates)
        if freed is not None:
            return freed
        watched = [self.candidate_onsets.get(cable, -1) for cable in self.candidates]
        alarm = self.alarm_tick if self.alarm_tick is not None else -1
        onsets = [loss_onset(onset, int(self.freed_since[cable]), alarm)
                  for cable, onset in zip(self.candidates, watched)]
        first = self.lost_first(self.candidates, onsets, 1)
        return None if first is None else first[0]

    def losing(self, tick: int, found: list[int]) -> list[int]:
        """Of the motors that look free, those whose residual rose above δ in the alarm's
        episode (lost_in_episode) or within identification_confirm_cycles before it, where
        any did: a motor that merely carries less than δ/ρ all along looked as free before
        the break. All of them where none did yet. Before it too: a lightly loaded cable's
        freed motor, swinging under its controller, takes its residual above δ every
        other period, and the alarm can fall on a period between (a drawn crossed 8-cable
        platform: cable 1 parted at 2.9 N, its residual 0.13 / 0.03 N·m by turns, δ 0.1;
        the alarm 7 periods later, on cable 5's residual, a model's mismatch above δ for
        3 s)."""
        self.lost_in_episode |= self.unloaded_since >= 0
        lost = (self.lost_in_episode | (tick - self.last_unloaded <= self.fdi.identification_confirm_cycles)
                | (self.dropped_since >= 0))
        if not lost.any():
            return found
        return [cable for cable in found if lost[cable]]

    def freed_first(self, found: list[int]) -> int | None:
        """Of several motors that look free, the one that looked so
        fdi.identification_freed_lead_cycles or more before every other (freed_since): a
        cable that parts frees its motor within a period; a cable the break unloads (a
        crossed platform's partner of it) slackens over tens of periods as the end-effector
        falls towards its exit point (19 N to none in 12 periods on a drawn 8-cable
        platform). None where none leads so, or fewer than two look free. Taken alone only
        outside a disturbance (update): a push slackens one cable after another as
        gradually, and its first is weighed alone before the next (disturbed()); within
        one, only it can be proven broken (overstretched)."""
        first = self.lost_first(found, self.freed_since[found], self.fdi.identification_freed_lead_cycles)
        return None if first is None else first[0]

    def lost_first(self, cables: list[int], onsets, lead: int) -> tuple[int, int] | None:
        """(cable, tick) of the one of `cables` whose motor lost its pull `lead` ticks or
        more before every other's, by `onsets` (each one's first tick of the loss, in their
        order; -1: not lost); None where fewer than two, one is -1 or none leads so."""
        onsets = np.asarray(onsets)
        if onsets.size < 2 or np.any(onsets < 0):
            return None
        order = np.argsort(onsets, kind='stable')
        if onsets[order[1]] - onsets[order[0]] < lead:
            return None
        return cables[int(order[0])], int(onsets[order[0]])

    def leading(self, stretch: np.ndarray | None) -> list[int]:
        """Of several candidates none of which spans identification_stretch_m beyond its
        length (`stretch`, m per cable, where the others place the end-effector), the one
        that spans fdi.identification_lead_stretch_m beyond it while every other spans at
        most half of that: a cable that parted lightly loaded, still falling away, beside
        attached ones that carry little. None where no one leads so (or no stretch)."""
        if stretch is None:
            return []
        lead = self.fdi.identification_lead_stretch_m
        ranked = sorted(self.candidates, key=lambda cable: stretch[cable], reverse=True)
        if stretch[ranked[0]] >= lead and all(stretch[cable] <= 0.5 * lead for cable in ranked[1:]):
            return ranked[:1]
        return []

    def on_identified(self, tick: int, cables: list[int], angle_rad, angular_velocity_rad_s, command_nm,
                      reference: JointReference) -> list[str]:
        self.broken = sorted(cables)
        self.identified_tick = tick
        attached = self.robot.cable_mask(self.broken)
        events = [f'cable(s) {", ".join(str(c + 1) for c in self.broken)} broken: alarm at tick '
                  f'{self.alarm_tick}, identified at tick {tick}']
        try:
            check_recoverable(self.robot, attached)
            self.recovery = self.strategy.start(Naming(
                self.robot, self.recovery_config, self.distribution, self.period_s, self.planner, tick, attached,
                np.asarray(angle_rad, float), np.asarray(angular_velocity_rad_s, float),
                np.asarray(command_nm, float), reference, self.reference_tensions(reference)))
        except (RecoveryInfeasible, ValueError) as err:
            self.mode = FAULT
            self.fault_reason = str(err)
            events.append(f'FAULT: {err}')
        return events

    def planned_references(self, tick: int, count: int, due_tick: int | None = None) -> list[tuple[int, JointReference]]:
        """(tick, joint reference) of the `count` ticks after tick + VERDICT_DELAY_TICKS that the recovery's
        move already fixes (none outside one): sent ahead, a realtime controller that runs
        ahead of the supervisor finds its own tick's, not one 10 ticks old (supervisor_node).
        `due_tick`: the first tick whose reference the drives may want before the next
        call (a platform's brake waits for its tries till then; tick + VERDICT_DELAY_TICKS + count where not
        given)."""
        if self.recovery is None or self.mode == FAULT:
            return []
        return self.recovery.planned_references(tick, count, due_tick)

    def reference_tensions(self, reference: JointReference) -> np.ndarray:
        """τ_d = (J θ̈_d + b θ̇_d − c_ID) / ρ, θ̈_d from the previous reference (N)."""
        previous = self.previous_reference or reference
        tension = np.empty(self.robot.cable_count)
        self.arithmetic.reference_tensions(
            self.motor_constants, self.period_s, np.ascontiguousarray(reference.angular_velocity_rad_s, float),
            np.ascontiguousarray(previous.angular_velocity_rad_s, float),
            np.ascontiguousarray(reference.feedforward_nm, float), tension)
        return tension

    def summary(self) -> dict:
        """What happened so far, in plain types (ticks, 1-based cables, SP in m), and what
        the recovery adds (a platform's: its safe orientation, a unit quaternion w, x, y,
        z)."""
        recovery = self.recovery
        return {
            'alarm_tick': self.alarm_tick,
            'identified_tick': self.identified_tick,
            'broken_cables': [c + 1 for c in self.broken],
            'mode': self.mode,
            'phase_ticks': {} if recovery is None else dict(recovery.phase_ticks),
            'safe_point_m': None if recovery is None else recovery.safe_point_m.tolist(),
            'settle_timed_out': bool(recovery is not None and recovery.timed_out),
            'fault': self.fault_reason,
            'unidentified_alarms': self.unidentified_alarms,
            'late_commands': self.late_commands,
            'unjudged_ticks': self.unjudged_ticks,
            'disturbances': self.disturbances,
            # the most a reference asked of a motor whose τ̂ read free (N; None: none did)
            'collapse_free_reference_n': (None if self.collapse.largest_free_reference_n == -np.inf
                                          else self.collapse.largest_free_reference_n),
            **({} if recovery is None else recovery.summary()),
        }
