"""Figures of a run: the twin-vs-robot KPIs of paper §5.1 and the metrics.json keys."""
from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from cdpr_control.geometry.rotation import difference
from cdpr_control.model.robot import Robot
from cdpr_fdi.settings.config import FdiConfig, RecoveryConfig
from cdpr_msgs_py.contract import BROKEN_AT_KEY, JOINT_STATES, PLANT_SIMULATOR, RUN_FIGURES_KEY, SAFE_HOLD, SUPERVISOR
from cdpr_twin.models.run_figures import RunFigures

from ..paths import LAST_DIAGNOSTICS
from .recording import Recording

# The loop topics the plant simulator writes with every state it publishes, and the key
# of its /diagnostics that counts those states.
PER_STATE_TOPICS = (JOINT_STATES,)
STATES_TOTAL_KEY = 'states total'
PAPER_KPI = {'K_c_m': 0.0143, 'K_j_rad': 0.0583, 'K_t_nm': 0.1566}


def twin_kpis(robot: Robot, recording, ticks: slice = slice(None)) -> dict:
    """Largest Cartesian (forward kinematics of the measured angles against the twin's:
    the loop topics of every tick), joint and torque gap to the twin.

    Over `ticks`: after a failure the twin is meant to differ, so callers pass the
    ticks before it.
    """
    angles = recording.angle_rad[ticks]
    twin_poses = robot.body.poses_of_angles(robot, recording.twin_angle_rad[ticks])
    measured = robot.body.poses_of_angles(robot, angles, hints=twin_poses)[0]
    twin = twin_poses[0]
    return {
        'K_c_m': float(np.max(np.linalg.norm(measured - twin, axis=1))),
        'K_j_rad': float(np.max(np.abs(angles - recording.twin_angle_rad[ticks]))),
        'K_t_nm': float(np.max(np.abs(recording.command_nm[ticks] - recording.twin_torque_nm[ticks]))),
    }


def ticks_before(recording, time_s: float | None) -> int:
    """How many ticks of the recording are stamped before `time_s` (all when None).

    A tick stamped at the instant itself counts as after it: a failure time read off the
    ground truth, like a detection time, is the first tick that shows the failure. (A
    failure scheduled on a tick's stamp breaks the cable right after that tick's state,
    so there one nominal tick is left out.)
    """
    if time_s is None:
        return recording.time_s.size
    return int(np.searchsorted(recording.time_s, time_s, side='left'))


def period_of(recording) -> float:
    """The control period (s) of a recording's ticks."""
    steps = np.diff(recording.time_s)
    return float(np.median(steps)) if steps.size else 0.0


def figures_from_rows(robot: Robot, period_s: float, time_s, position_m, orientation, tension_n,
                      reference_position_m, reference_orientation, failure_time_s: float | None,
                      broken_cables: list[int], detection_time_s: float | None) -> dict:
    """The figures of cdpr_twin.models.run_figures from the rows a bag holds (times s), for a run
    whose plant did not say them: its view ticks' truth, or a real robot's pose and
    tensions as measured and estimated at every tick (`reference_position_m` None: no
    tracking error). Cables 1-based."""
    figures = RunFigures(robot.cable_count, period_s, robot.body.has_orientation, tension_min_n=robot.tension_min_n)
    for cable in broken_cables:
        if failure_time_s is not None:
            figures.failure_at(failure_time_s, cable - 1)
        else:
            figures.cable_broken(cable - 1)
    if detection_time_s is not None:
        figures.detection_at(round(detection_time_s / period_s))
    ticks = np.round(np.asarray(time_s) / period_s).astype(int)
    figures.add_rows(ticks, position_m, orientation, tension_n, reference_position_m, reference_orientation)
    return figures.summary()


def view_figures(robot: Robot, recording, failure_time_s: float | None, broken_cables: list[int],
                 detection_time_s: float | None) -> dict:
    """figures_from_rows of a simulated run's view ticks (its truth where the plant did not
    say its figures from every tick: a bag without its status)."""
    return figures_from_rows(robot, period_of(recording), recording.view_time_s, recording.true_position_m,
                             recording.true_orientation, recording.true_tension_n,
                             recording.reference_position_m, recording.reference_orientation,
                             failure_time_s, broken_cables, detection_time_s)


@dataclass(frozen=True)
class RunSettings:
    """Of a run's settings, what its report needs."""

    robot: Robot
    fdi: FdiConfig
    recovery: RecoveryConfig
    source: str


@dataclass
class KnownRun:
    """What is known about one run, from the run itself (cdpr-scenario: its recording, the
    plant's figures and the supervisor's summary) or from its bag (cdpr-report, where the
    ground truth or the supervisor may be missing): the input of `metrics_json`. Times in
    s, cables 1-based."""

    robot: Robot
    recording: Recording
    figures: dict                     # cdpr_twin.models.run_figures' summary: from every tick, or what the bag holds
    epsilon_nm: float                 # the detection threshold ε
    failure_time_s: float | None      # the first cable's break; None: none, or unknown
    true_broken_cables: list[int] | None  # None: unknown (no ground truth)
    detection_time_s: float | None    # the tick whose verdict first named a cable
    identified_cables: list[int]
    mode: str | None                  # the last one; None: no supervisor
    phase_times_s: dict[str, float]   # the first tick of each recovery mode
    safe_point_m: list[float] | np.ndarray | None
    reached_tolerance_m: float | None  # distance to SP that counts as reached
    supervisor: dict                  # its last summary (Supervisor.summary()); {}: none
    wall_time_s: float

    @property
    def event_time_s(self) -> float | None:
        """Where the run stops being nominal: the failure, else its detection."""
        return self.failure_time_s if self.failure_time_s is not None else self.detection_time_s

    @property
    def event_figures(self) -> dict:
        """The figures relative to the event: the failure's, else the detection's."""
        return self.figures['failure' if self.failure_time_s is not None else 'detection']


def final_orientation_error_deg(run: KnownRun) -> float | None:
    """The angle (deg) between a platform's last true orientation and the safe
    orientation its supervisor's recovery steered to; None before a recovery (or without
    the supervisor's word)."""
    safe = run.supervisor.get('safe_orientation')
    last = run.figures.get('final_orientation')
    if safe is None or last is None:
        return None
    return math.degrees(float(np.linalg.norm(difference(safe, last))))


def metrics_json(run: KnownRun) -> dict:
    """The metrics.json keys of docs/design.md §7 (and `epsilon_nm`).

    The KPIs cover the ticks before the failure (or its detection): from then on the twin
    is meant to differ. The figures of the end-effector are `run.figures`: the tracking
    error over the same ticks, recovery.min_tension_n and max_tension_n (the plant's, measured)
    over the remaining cables from then on, min_height_m the whole run; duration_s is the detection to
    SAFE_HOLD. Unknowable figures are None: the tracking error without ground truth,
    false_alarm when nothing tells whether a cable broke.
    """
    detection, failure = run.detection_time_s, run.failure_time_s
    nominal = slice(0, ticks_before(run.recording, run.event_time_s))
    window = run.event_figures
    final = run.figures['final_position_m']
    final_error = (None if run.safe_point_m is None or final is None
                   else float(np.linalg.norm(np.asarray(final) - np.asarray(run.safe_point_m))))
    hold = run.phase_times_s.get(SAFE_HOLD)
    failure_known = failure is not None or run.true_broken_cables is not None
    has_orientation = run.robot.body.has_orientation
    return {
        'epsilon_nm': run.epsilon_nm,
        'failure_time_s': failure,
        'detection_time_s': detection,
        'detection_delay_ms': (None if detection is None or failure is None
                               else (detection - failure) * 1000.0),
        'identified_cables': list(run.identified_cables),
        'true_broken_cables': (None if run.true_broken_cables is None
                               else list(run.true_broken_cables)),
        'false_alarm': (detection is not None and (failure is None or detection < failure)
                        if failure_known else None),
        'mode': run.mode,
        'fault': run.supervisor.get('fault') or None,
        # pushes and contacts the supervisor told from failures (wrench_balance)
        'disturbances': run.supervisor.get('disturbances'),
        'safe_point_m': None if run.safe_point_m is None else [float(v) for v in run.safe_point_m],
        'recovery': {
            'reached_safe_point': (None if final_error is None or run.reached_tolerance_m is None
                                   else final_error <= run.reached_tolerance_m),
            'final_error_m': final_error,
            'min_tension_n': window['min_tension_n'],
            'max_tension_n': window['max_tension_n'],
            # the ticks a cable left carried less than τ_min: within the break's jolt
            # (run_figures.JOLT_S of the event) and after it
            'ticks_under_tension_min': window.get('ticks_under_tension_min'),
            'min_height_m': run.figures['lowest_point_m'],
            'duration_s': None if hold is None or detection is None else hold - detection,
            'phase_times_s': dict(run.phase_times_s),
            'settle_timed_out': run.supervisor.get('settle_timed_out'),
            # where the motors put the end-effector from the safe pose as the last move's end
            # was judged (SAFE_HOLD only within reached_tolerance_m / _deg), the re-plans
            # from there, and the ticks forward kinematics fell back on
            'hold_error_m': run.supervisor.get('hold_error_m'),
            **({'hold_error_deg': run.supervisor.get('hold_error_deg')} if has_orientation else {}),
            'hold_replans': run.supervisor.get('hold_replans'),
            'kinematics_fallbacks': run.supervisor.get('kinematics_fallbacks'),
            # a platform's: the angle (deg) from its last true orientation to the safe one
            **({'final_orientation_error_deg': final_orientation_error_deg(run)} if has_orientation else {}),
        },
        'kpi': twin_kpis(run.robot, run.recording, nominal),
        'tracking_error_m': window['tracking_error_m'] if run.recording.has_ground_truth else None,
        'cycles': int(run.recording.time_s.size),
        'wall_time_s': run.wall_time_s,
        # a platform's: the largest angle between its true and its reference orientation
        **({'orientation_tracking_error_rad': window['orientation_tracking_error_rad']
            if run.recording.has_ground_truth else None} if has_orientation else {}),
    }


def last_statuses(messages) -> dict[str, dict[str, str]]:
    """Per node (the last part of its name), the key-values of its last status among
    /diagnostics messages."""
    return {status.name.rsplit('/', 1)[-1]: {value.key: value.value for value in status.values}
            for _, message in messages for status in message.status}


def written_statuses(folder: str | Path) -> dict[str, dict[str, str]]:
    """Per node, the key-values of the last status it wrote into `folder` as it stopped
    (CdprNode's `last_diagnostics_path`, NODE.json); a node that wrote none (killed) or
    whose file cannot be read is left out."""
    statuses = {}
    for path in Path(folder).glob('*.json'):
        try:
            statuses[path.stem] = json.loads(path.read_text())['values']
        except (OSError, ValueError, KeyError):
            continue
    return statuses


def broken_at_of(plant: dict[str, str] | None) -> dict[int, float] | None:
    """0-based cable → the instant (s) the plant really parted it, from the plant
    simulator's status key-values (None when it never said)."""
    if plant is None or BROKEN_AT_KEY not in plant:
        return None
    return {int(cable) - 1: float(at) for cable, at in json.loads(plant[BROKEN_AT_KEY]).items()}


def run_figures_of(plant: dict[str, str] | None) -> dict | None:
    """The figures of the end-effector from every tick (cdpr_twin.models.run_figures) the plant
    simulator said in its status key-values (None when it never said)."""
    if plant is None or RUN_FIGURES_KEY not in plant:
        return None
    return json.loads(plant[RUN_FIGURES_KEY])


def fdi_summary_of(supervisor: dict[str, str] | None) -> dict:
    """The supervisor's summary (Supervisor.summary()) from its status key-values (its
    `fdi *` keys); {} without them."""
    return {key[len('fdi '):]: json.loads(value) for key, value in (supervisor or {}).items()
            if key.startswith('fdi ')}


def fdi_summary_from_diagnostics(messages) -> dict:
    """fdi_summary_of the supervisor's last status among /diagnostics messages."""
    return fdi_summary_of(last_statuses(messages).get(SUPERVISOR))


def statuses_beside(bag: Path, diagnostics) -> dict[str, dict[str, str]]:
    """Per node, its last status's key-values: as it wrote it stopping, into
    LAST_DIAGNOSTICS beside `bag` (cdpr-scenario's run folder), which no recorder can have
    lost; else its last in the bag's /diagnostics (`diagnostics`: (time, message) pairs),
    as for a node that wrote nothing (killed) or a bag recorded otherwise."""
    return {**last_statuses(diagnostics), **written_statuses(Path(bag).parent / LAST_DIAGNOSTICS)}


def take_statuses(recording: Recording, said: dict[str, dict[str, str]], counted: dict[str, int] | None) -> None:
    """Into a bag's `recording`, what its nodes said (`said`, statuses_beside): the
    supervisor's summary, the instants cables parted and the figures from every tick (the
    plant's), and the ticks the bag lacks — its recorder's count (`counted`), and against
    the plant's own count of states."""
    plant = said.get(PLANT_SIMULATOR)
    recording.fdi = fdi_summary_of(said.get(SUPERVISOR))
    recording.broken_at_s = broken_at_of(plant)
    recording.figures = run_figures_of(plant)
    states = None if plant is None or STATES_TOTAL_KEY not in plant else int(plant[STATES_TOTAL_KEY])
    recording.missing_ticks = missing_against_the_plant(counted, states, recording.ticks_held or {})


def missing_against_the_plant(counted: dict[str, int] | None, states_total: int | None,
                              held: dict[str, int]) -> dict[str, int] | None:
    """The ticks each per-tick topic lacks in a bag: its recorder's count of the holes
    (`counted`), and on the topics the plant writes with every state at least the
    plant's own count of its states less the ticks the bag holds (`held`, per topic) —
    which also counts the ticks after the recorder's last, which it cannot."""
    if states_total is None:
        return counted
    missing = dict(counted or {})
    for topic in PER_STATE_TOPICS:
        if topic in held:
            missing[topic] = max(missing.get(topic, 0), states_total - held[topic])
    return missing
