"""The few lines that say how a run went — the failure, its detection and the cable named,
the recovery, the KPIs beside the paper's — from its metrics (`cdpr-scenario`, `make demo`)
or from its bag (the end of `ros2 launch cdpr_bringup cdpr_demo.launch.py`)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from cdpr_control.config import Section
from cdpr_msgs_py import contract

from ..runs.metrics import PAPER_KPI, metrics_json
from ..runs.recording import holes_said


def summary_lines(metrics: dict) -> list[str]:
    """The failure, detection, recovery and KPI lines of a run's metrics (metrics.json's
    keys; a key a bag cannot tell may be missing)."""
    lines = []
    failure_s, signal_s = metrics['failure_time_s'], metrics.get('failure_signal_time_s')
    if failure_s is not None:
        lines.append(f'  cable(s) {metrics["true_broken_cables"]} broke at {failure_s:.4f} s'
                     + ('' if signal_s in (None, failure_s) else f' (signal at {signal_s:.4f} s)'))
    if metrics['detection_time_s'] is None:
        lines.append('  no failure detected')
    else:
        delay = metrics['detection_delay_ms']
        lines.append(f'  detected at {metrics["detection_time_s"]:.3f} s'
                     + ('' if delay is None else f' ({delay:.1f} ms after the failure')
                     + ('' if delay is None or signal_s in (None, failure_s)
                        else f', {metrics["detection_delay_from_signal_ms"]:.1f} ms after its signal')
                     + ('' if delay is None else ')')
                     + f', cable(s) {metrics["identified_cables"]} named'
                     + (' — FALSE ALARM' if metrics['false_alarm'] else ''))
    hidden = metrics.get('break') or {}
    if hidden.get('late_detection_expected'):
        lines.append(f'  cable {hidden["cable"]} carried {hidden["reference_tension_n"]:.2f} N (its reference) as it '
                     f'parted, under ε/ρ = {hidden["hidden_below_n"]:.2f} N: a late detection was expected (by the '
                     'tension collapse, or once another cable slackens)')
    recovery = metrics['recovery']
    if metrics['fault']:
        lines.append(f'  FAULT: {metrics["fault"]}')
    elif recovery['final_error_m'] is not None:
        safe_point = ', '.join(f'{v:.3f}' for v in metrics['safe_point_m'])
        angle = recovery.get('final_orientation_error_deg')
        lines.append(f'  recovery to SP ({safe_point}) m: final error {recovery["final_error_m"] * 1000:.1f} mm'
                     + ('' if angle is None else f', {angle:.3f}°')
                     + f' after {recovery["duration_s"] or float("nan"):.2f} s, min tension '
                     f'{recovery["min_tension_n"]:.2f} N, lowest point {recovery["min_height_m"]:.3f} m')
    lines.append(f'  {"KPI":<8} {"this run":>10} {"paper":>10}   (before any failure)')
    lines += [f'  {key:<8} {value:10.4f} {PAPER_KPI[key]:10.4f}' for key, value in metrics['kpi'].items()
              if value is not None]
    if metrics['tracking_error_m'] is not None:
        turn = metrics.get('orientation_tracking_error_rad')
        lines.append(f'  tracking error (true pose vs reference): {metrics["tracking_error_m"] * 1000:.2f} mm'
                     + ('' if turn is None else f', {np.degrees(turn):.3f}°'))
    holes = holes_said(metrics.get('bag_missing_ticks'))
    if holes:
        lines.append(f'  {holes}')
    return lines


def bag_summary(bag: str | Path, settings: Section, namespace: str = contract.DEFAULT_NAMESPACE) -> list[str]:
    """The summary of the run recorded in `bag` with the settled run `settings` (its
    document), and where the bag is."""
    from .report import load_run, settled_run_settings   # rosbags and the plots: at the end only
    try:
        run = load_run(bag, settled_run_settings(settings, f'settings: the launch\'s, {settings.path}'),
                       namespace)
    except (OSError, ValueError) as err:
        return [f'no summary of the run: {err}', f'bag: {bag}']
    metrics = metrics_json(run.known)
    plant, fdi = settings.section('plant'), settings.section('fdi')
    heading = (f'{settings.section("motion").string("name")} on the {plant.string("fidelity")} plant, '
               f'node graph, {fdi.string("detector")} detector: {metrics["cycles"]} cycles in '
               f'{metrics["wall_time_s"]:.1f} s')
    return [heading, *summary_lines(metrics),
            f'bag: {bag} (cdpr-report {bag} --out DIR draws the paper\'s figures and metrics.json)']
