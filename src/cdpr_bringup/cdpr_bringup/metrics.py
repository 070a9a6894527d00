"""Figures of a run: the twin-vs-robot KPIs of paper §5.1 and the metrics.json keys."""
from __future__ import annotations

import json

import numpy as np

from cdpr_control.kinematics import forward_kinematics
from cdpr_control.robot import Robot

PAPER_KPI = {'K_c_m': 0.0143, 'K_j_rad': 0.0583, 'K_t_nm': 0.1566}


def twin_kpis(robot: Robot, recording, ticks: slice = slice(None)) -> dict:
    """Largest Cartesian (FK of the measured angles), joint and torque gap to the twin.

    Over `ticks`: after a failure the twin is meant to differ, so callers pass the
    ticks before it.
    """
    angles = recording.angle_rad[ticks]
    measured = np.array([forward_kinematics(robot, angle) for angle in angles])
    return {
        'K_c_m': float(np.max(np.linalg.norm(measured - recording.twin_position_m[ticks], axis=1))),
        'K_j_rad': float(np.max(np.abs(angles - recording.twin_angle_rad[ticks]))),
        'K_t_nm': float(np.max(np.abs(recording.command_nm[ticks] - recording.twin_torque_nm[ticks]))),
    }


def tracking_error_m(recording, ticks: slice = slice(None)) -> float:
    """Largest distance between the true end-effector and the reference pose (m)."""
    return float(np.max(np.linalg.norm(recording.true_position_m[ticks]
                                       - recording.reference_position_m[ticks], axis=1)))


def ticks_before(recording, time_s: float | None) -> int:
    """How many ticks of the recording come at or before `time_s` (all when None)."""
    if time_s is None:
        return recording.time_s.size
    return int(np.searchsorted(recording.time_s, time_s, side='right'))


def fdi_metrics(robot: Robot, period_s: float, failure_time_s: float | None,
                true_broken: list[int], recording, reached_tolerance_m: float) -> dict:
    """The detection and recovery keys of metrics.json (docs/design.md §7) from a run's recording
    and its supervisor summary (`recording.fdi`, ticks and 1-based cables)."""
    fdi = recording.fdi or {}
    identified_tick = fdi.get('identified_tick')
    detection_time = None if identified_tick is None else identified_tick * period_s
    after = slice(ticks_before(recording, failure_time_s) if failure_time_s is not None else 0, None)
    remaining = robot.cable_mask([cable - 1 for cable in true_broken])
    safe_point = fdi.get('safe_point_m')
    phases = fdi.get('phase_ticks') or {}
    final_error = (None if safe_point is None
                   else float(np.linalg.norm(recording.true_position_m[-1] - np.array(safe_point))))
    hold_tick = phases.get('SAFE_HOLD')
    return {
        'failure_time_s': failure_time_s,
        'detection_time_s': detection_time,
        'detection_delay_ms': (None if detection_time is None or failure_time_s is None
                               else (detection_time - failure_time_s) * 1000.0),
        'identified_cables': list(fdi.get('broken_cables') or []),
        'true_broken_cables': list(true_broken),
        'false_alarm': bool(detection_time is not None
                            and (failure_time_s is None or detection_time < failure_time_s)),
        'mode': fdi.get('mode'),
        'fault': fdi.get('fault') or None,
        'safe_point_m': safe_point,
        'recovery': {
            'reached_safe_point': None if final_error is None else final_error <= reached_tolerance_m,
            'final_error_m': final_error,
            'min_tension_n': (float(np.min(recording.true_tension_n[after][:, remaining]))
                              if recording.true_tension_n[after].size else None),
            'min_height_m': float(np.min(recording.true_position_m[:, 2])),
            'duration_s': (None if hold_tick is None or identified_tick is None
                           else (hold_tick - identified_tick) * period_s),
            'phase_times_s': {mode: tick * period_s for mode, tick in phases.items()},
            'settle_timed_out': fdi.get('settle_timed_out'),
        },
    }


def fdi_summary_from_diagnostics(messages) -> dict:
    """The supervisor's last summary among /diagnostics messages (its `fdi *` key-values)."""
    summary = {}
    for _, message in messages:
        for status in message.status:
            if status.name.endswith('/supervisor'):
                facts = {value.key[len('fdi '):]: json.loads(value.value)
                         for value in status.values if value.key.startswith('fdi ')}
                if facts:
                    summary = facts
    return summary
