"""cdpr-campaign: the paper's FDI experiments as a matrix of scenario runs, in parallel.

The matrix is cables × motions × directions × fidelities × detectors × seeds, each run a
`cdpr-scenario` in its own folder DIR/runs/<run id>. A cable fails at the paper's point of
the move, at --fail-at-fraction, or (--random-instants) at a fraction drawn from the run's
seed, the same at every resumption. Failure-free runs of every
motion × direction × fidelity × detector × seed are added by default (--no-failure-free
drops them): without them the false-alarm rate has nothing to be measured on.
A run whose metrics.json exists (and is not of a run cut short) is not run again, so an
interrupted campaign resumes; delete DIR/runs/<run id> (or all of DIR/runs) to re-run.

The runs go to a pool of local processes (--jobs), or with --scheduler tcp://HOST:PORT to
the workers of a Dask scheduler (`dask scheduler`, `dask worker`, or dask-jobqueue on a
SLURM cluster); the workers then write DIR/runs/<run id> themselves, so DIR must be on a
filesystem they share (as a cluster's home or scratch).

Writes DIR/summary.csv (one row per run) and DIR/summary.md: the outcome of every failure
and failure-free run per detector × fidelity and per cable (any robot), the figures per
detector × fidelity, and our detection times per motion beside the paper's Tables 5 and 7.
"""
from __future__ import annotations

import argparse
import contextlib
import csv
import json
import multiprocessing
import os
import statistics
import sys
import time
import zlib
from concurrent.futures import ProcessPoolExecutor, as_completed
from functools import lru_cache
from pathlib import Path

import numpy as np

from cdpr_control.config import load_section
from cdpr_control.geometry.motions import motion_names
from cdpr_control.setup.robot_file import load_robot
from cdpr_msgs_py.contract import FAULT
from cdpr_twin.models.plant import FIDELITIES

from .campaign_run import WORKER_FILE, Run, SchedulerUnreachable, run_scenario
from ..cli import INTERRUPTED_EXIT_CODE, USAGE_EXIT_CODE, command
from ..paths import DEFAULT_MOTIONS, DEFAULT_ROBOT, config_file

# Tables 4 and 6 define their motions with respect to exit point A4: "along" and
# "orthogonal" describe the motion relative to cable 4, so only runs breaking it are
# compared with the paper and counted in the along/orthogonal delays.
PAPER_TEST_CABLE = 4

# Detection time (ms) after the failure at the midpoint, on the real robot at ε = 0.3 N·m.
# forward = start → finish of Tables 4/6 (for Table 4: towards exit point A4),
# reverse = the paper's t_backward.
PAPER_DETECTION_MS = {
    # Table 5: motions along cable 4.
    'along-1': {'forward': 50, 'reverse': 80},
    'along-2': {'forward': 60, 'reverse': 30},
    'along-3': {'forward': 60, 'reverse': 40},
    'along-4': {'forward': 50, 'reverse': 60},
    # Table 7: motions orthogonal to cable 4.
    'orthogonal-1': {'forward': 230, 'reverse': 210},
    'orthogonal-2': {'forward': 290, 'reverse': 230},
    'orthogonal-3': {'forward': 270, 'reverse': 210},
    'orthogonal-4': {'forward': 200, 'reverse': 240},
    # §5.3: the circle, failure after 135° of arc, detected 190 ms later (forward only).
    'circle': {'forward': 190},
}

# Where on its path each motion loses its cable when --fail-at-fraction is not given:
# the midpoint for Tables 4 and 6, 135° of the 360° circle as in §5.3.
PAPER_FAILURE_FRACTION = {'circle': 135.0 / 360.0}
MIDPOINT = 0.5
# --random-instants: the part of a move a failure is drawn in; the ends are left out, where
# the end-effector is at rest and a break is the (easier) static case.
RANDOM_FRACTION_RANGE = (0.1, 0.9)

# --motion-set shorthands: every motion of the motions file whose name starts so.
MOTION_SET_PREFIXES = {'along': 'along-', 'orthogonal': 'orthogonal-'}

DIRECTIONS = ('forward', 'reverse')
DETECTORS = ('threshold', 'cusum')
SECONDS_PER_HOUR = 3600.0

CSV_COLUMNS = (
    'run_id', 'motion', 'direction', 'cable', 'fidelity', 'detector', 'seed',
    'fail_at_fraction', 'failure_time_s', 'detection_delay_ms', 'detection_delay_from_signal_ms',
    'late_detection_expected', 'identified_cables', 'correct_identification',
    'false_alarm', 'mode', 'fault', 'reached_safe_point', 'final_error_m', 'final_orientation_error_deg',
    'min_tension_n', 'max_tension_n', 'ticks_under_tension_min_undetected', 'ticks_under_tension_min_jolt',
    'ticks_under_tension_min_after_jolt', 'min_height_m',
    'duration_s', 'cycles', 'control_period_s', 'wall_time_s', 'worker', 'error',
)

def expand_motion_set(motion_set: list[str], available: list[str]) -> list[str]:
    """Motion names from shorthands (`along`, `orthogonal`) and explicit names, in order."""
    names = []
    for item in motion_set:
        if item == ALL:
            names += [name for name in available if name not in names]
            continue
        prefix = MOTION_SET_PREFIXES.get(item)
        chosen = [name for name in available if name.startswith(prefix)] if prefix else [item]
        if not chosen or not set(chosen) <= set(available):
            raise ValueError(f'--motion-set {item}: not a motion of the motions file '
                             f'({", ".join(available)})')
        names += [name for name in chosen if name not in names]
    return names


def random_fraction(seed: int, motion: str, direction: str, cable: int, fidelity: str,
                    detector: str) -> float:
    """The failure point of a --random-instants run: uniform in RANDOM_FRACTION_RANGE, drawn
    from the run's seed and place in the matrix (not Python's salted hash), so that a
    resumed campaign draws the same instants."""
    key = zlib.crc32(f'{motion}/{direction}/{cable}/{fidelity}/{detector}'.encode())
    low, high = RANDOM_FRACTION_RANGE
    return float(np.random.default_rng([seed, key]).uniform(low, high))


def build_matrix(motions: list[str], cables: list[int], directions=DIRECTIONS,
                 fidelities=FIDELITIES, detectors=DETECTORS, seeds=(0,),
                 fail_at_fraction: float | None = None, failure_free: bool = True,
                 random_instants: bool = False, **settings) -> list[Run]:
    """Every failure run, then (if `failure_free`) every failure-free run.

    `settings` (config, motions_file, engine, epsilon_nm, calibration) are the same for
    every run.
    """
    runs = []
    for cable in list(cables) + ([None] if failure_free else []):
        for motion in motions:
            fraction = (fail_at_fraction if fail_at_fraction is not None
                        else PAPER_FAILURE_FRACTION.get(motion, MIDPOINT))
            for direction in directions:
                for fidelity in fidelities:
                    for detector in detectors:
                        for seed in seeds:
                            if random_instants and cable is not None:
                                fraction = random_fraction(seed, motion, direction, cable,
                                                           fidelity, detector)
                            runs.append(Run(motion, direction, cable, fidelity, detector, seed,
                                            fraction, **settings))
    return runs


# ---- running -----------------------------------------------------------------------

# How run_scenario reports a run that cdpr-scenario refused as a user's mistake.
USER_ERROR = f'cdpr-scenario exited with {USAGE_EXIT_CODE}: cdpr-scenario: '


def user_errors(rows: list[dict]) -> list[str]:
    """The distinct one-line mistakes the runs were refused for, in the order first met."""
    return list(dict.fromkeys(row['error'][len(USER_ERROR):] for row in rows
                              if row['error'] and row['error'].startswith(USER_ERROR)))


@contextlib.contextmanager
def local_pool(jobs: int | None, task=run_scenario):
    """(submit, as_completed) of `jobs` local processes (default: all cores), submit(*args)
    running task(*args) on one."""
    # spawn, not fork: the workers may start rclpy (graph engine), which must not
    # inherit a forked copy of this process's threads.
    context = multiprocessing.get_context('spawn')
    pool = ProcessPoolExecutor(max_workers=jobs or os.cpu_count(), mp_context=context)
    try:
        yield (lambda *args: pool.submit(task, *args)), as_completed
    finally:
        # on Ctrl-C the runs not yet started are dropped, not run before the pool ends
        pool.shutdown(cancel_futures=True)


def worker_pool(jobs: int | None, scheduler: str | None = None, task=None):
    """(submit, as_completed) of the workers of the Dask `scheduler` (an address), else of
    `jobs` local processes; submit(*args) runs task(*args), by default a campaign's run
    (run_scenario: submit(run, run_dir)). SchedulerUnreachable where no scheduler answers."""
    if scheduler:
        from .dask_cluster import dask_scheduler  # the local pool does not pay for Dask
        return dask_scheduler(scheduler, task)
    return local_pool(jobs, task or run_scenario)


def completed(run_dir: Path) -> bool:
    """A run is done when it wrote metrics.json, and not as one cut short by Ctrl-C."""
    metrics = run_dir / 'metrics.json'
    return metrics.exists() and not json.loads(metrics.read_text()).get('interrupted')


def progress_bar(done: int, total: int, eta_s: float | None, width: int = 30) -> str:
    filled = round(width * done / total) if total else width
    eta = 'eta ?' if eta_s is None and done < total else f'eta {eta_s or 0:.0f} s'
    return f'[{"#" * filled}{"." * (width - filled)}] {done}/{total} runs, {eta}'


def run_campaign(runs: list[Run], out_dir: str | Path, jobs: int | None = None,
                 show_progress: bool = True, scheduler: str | None = None) -> list[dict]:
    """Run what is not yet done (see `completed`) on `jobs` local processes (default: all
    cores), or on the workers of the Dask `scheduler` (an address), with a progress bar on
    stderr; one row per run, in the order of `runs`."""
    runs_dir = Path(out_dir) / 'runs'
    pending = [run for run in runs if not completed(runs_dir / run.id)]
    outcomes = {}
    done, total = len(runs) - len(pending), len(runs)
    start = time.monotonic()

    live = sys.stderr.isatty()

    def show(eta_s):
        # A terminal gets a redrawn bar; a log file one line per tenth of the runs.
        if show_progress and live:
            print('\r' + progress_bar(done, total, eta_s), end='', file=sys.stderr, flush=True)
        elif show_progress and (done == total or done % max(total // 10, 1) == 0):
            print(progress_bar(done, total, eta_s), file=sys.stderr, flush=True)

    if not pending:
        show(None)
    else:
        with worker_pool(jobs, scheduler) as (submit, as_they_complete):
            show(None)  # once connected: a scheduler that is not there is one line
            futures = {submit(run, runs_dir / run.id): run for run in pending}
            for fresh_done, future in enumerate(as_they_complete(futures), start=1):
                run = futures[future]
                try:
                    outcomes[run.id] = future.result()
                except Exception as err:  # noqa: BLE001 - a worker process died (or was lost)
                    outcomes[run.id] = {'error': f'worker failed: {type(err).__name__}: {err}',
                                        'wall_time_s': None}
                done += 1
                show((time.monotonic() - start) / fresh_done * (len(pending) - fresh_done))
    if show_progress and live:
        print(file=sys.stderr)
    return [row_of(run, runs_dir / run.id, outcomes.get(run.id)) for run in runs]


@lru_cache(maxsize=None)
def control_period_s(config: str) -> float:
    return load_section(config_file(config), 'control').number('period_s', positive=True)


def row_of(run: Run, run_dir: Path, outcome: dict | None) -> dict:
    """The summary row of a run from its metrics.json; `outcome` is None for a skipped run."""
    row = {column: None for column in CSV_COLUMNS}
    row.update(run_id=run.id, motion=run.motion, direction=run.direction, cable=run.cable,
               fidelity=run.fidelity, detector=run.detector, seed=run.seed,
               fail_at_fraction=run.fail_at_fraction if run.cable is not None else None,
               control_period_s=control_period_s(run.config))
    worker_path = run_dir / WORKER_FILE
    row['worker'] = worker_path.read_text().strip() if worker_path.exists() else None
    metrics_path = run_dir / 'metrics.json'
    error = outcome['error'] if outcome else None
    if error is None and not metrics_path.exists():
        error = 'no metrics.json written'
    if error is not None:
        return {**row, 'error': error, 'wall_time_s': outcome['wall_time_s'] if outcome else None}
    metrics = json.loads(metrics_path.read_text())
    recovery = metrics.get('recovery') or {}
    under = recovery.get('ticks_under_tension_min') or {}
    identified = sorted(metrics.get('identified_cables') or [])
    detected = metrics.get('detection_time_s') is not None
    failure = run.cable is not None
    row.update(
        failure_time_s=metrics.get('failure_time_s'),
        detection_delay_ms=metrics.get('detection_delay_ms'),
        detection_delay_from_signal_ms=metrics.get('detection_delay_from_signal_ms'),
        late_detection_expected=(metrics.get('break') or {}).get('late_detection_expected'),
        identified_cables=identified,
        correct_identification=(detected and identified == sorted(metrics['true_broken_cables'])
                                if failure else None),
        # With no failure, any detection is a false alarm, whatever the supervisor says.
        false_alarm=bool(metrics.get('false_alarm')) or (not failure and (detected or bool(identified))),
        mode=metrics.get('mode'),
        fault=metrics.get('fault'),
        reached_safe_point=recovery.get('reached_safe_point'),
        final_error_m=recovery.get('final_error_m'),
        final_orientation_error_deg=recovery.get('final_orientation_error_deg'),
        min_tension_n=recovery.get('min_tension_n'),
        max_tension_n=recovery.get('max_tension_n'),
        ticks_under_tension_min_undetected=under.get('undetected'),
        ticks_under_tension_min_jolt=under.get('jolt'),
        ticks_under_tension_min_after_jolt=under.get('after_jolt'),
        min_height_m=recovery.get('min_height_m'),
        duration_s=recovery.get('duration_s'),
        cycles=metrics.get('cycles'),
        wall_time_s=metrics.get('wall_time_s'),
    )
    return row


# ---- summary statistics ------------------------------------------------------------

def group_key(row: dict) -> str:
    return f'{row["detector"]}/{row["fidelity"]}'


def _median_max(values: list[float]) -> tuple[float | None, float | None]:
    return (statistics.median(values), max(values)) if values else (None, None)


def _percent(hits: int, count: int) -> float | None:
    return 100.0 * hits / count if count else None


def summarize(rows: list[dict]) -> dict:
    """The campaign's figures per detector × fidelity, keyed 'detector/fidelity'.

    Delays are over detected failure runs of cable 4 on the along-*/orthogonal-* motions;
    identification % and recovery success % over all failure runs that completed
    (a missed detection counts as a wrong identification); false alarms per hour over the
    failure-free runs' simulated time (cycles × control period). None: nothing to measure.
    """
    summary = {}
    for key in sorted({group_key(row) for row in rows}):
        group = [row for row in rows if group_key(row) == key]
        completed = [row for row in group if row['error'] is None]
        failures = [row for row in completed if row['cable'] is not None]
        failure_free = [row for row in completed if row['cable'] is None]

        def delays(prefix):
            return [row['detection_delay_ms'] for row in failures
                    if row['motion'].startswith(prefix) and row['cable'] == PAPER_TEST_CABLE
                    and row['detection_delay_ms'] is not None]

        along_median, along_max = _median_max(delays(MOTION_SET_PREFIXES['along']))
        orthogonal_median, orthogonal_max = _median_max(delays(MOTION_SET_PREFIXES['orthogonal']))
        failure_free_hours = sum(row['cycles'] * row['control_period_s']
                                 for row in failure_free) / SECONDS_PER_HOUR
        false_alarms = sum(bool(row['false_alarm']) for row in failure_free)
        min_tensions = [row['min_tension_n'] for row in completed if row['min_tension_n'] is not None]
        summary[key] = {
            'runs': len(group),
            'errors': len(group) - len(completed),
            'detection_pct': _percent(sum(row['detection_delay_ms'] is not None for row in failures),
                                      len(failures)),
            'along_delay_median_ms': along_median,
            'along_delay_max_ms': along_max,
            'orthogonal_delay_median_ms': orthogonal_median,
            'orthogonal_delay_max_ms': orthogonal_max,
            'identification_pct': _percent(sum(bool(row['correct_identification']) for row in failures),
                                           len(failures)),
            'false_alarms_per_hour': false_alarms / failure_free_hours if failure_free_hours else None,
            'failure_free_hours': failure_free_hours,
            'recovery_success_pct': _percent(sum(bool(row['reached_safe_point']) for row in failures),
                                             len(failures)),
            'min_tension_n': min(min_tensions) if min_tensions else None,
            'final_error_max_m': outcome(group)['final_error_max_m'],
        }
    return summary


def outcome(rows: list[dict]) -> dict:
    """What happened in `rows` (any robot, any motion): failure runs detected, named
    (exactly the broken cable), brought to the safe point, ended in FAULT; the lowest
    tension of the remaining cables after a failure; the true detection delays (from the
    instant the cable broke); failure-free runs and their false alarms. Runs that did
    not complete are counted apart."""
    completed = [row for row in rows if row['error'] is None]
    failures = [row for row in completed if row['cable'] is not None]
    failure_free = [row for row in completed if row['cable'] is None]
    delays = [row['detection_delay_ms'] for row in failures if row['detection_delay_ms'] is not None]
    tensions = [row['min_tension_n'] for row in failures if row['min_tension_n'] is not None]
    greatest = [row['max_tension_n'] for row in failures if row['max_tension_n'] is not None]
    errors = [row['final_error_m'] for row in failures if row['final_error_m'] is not None]
    angles = [row['final_orientation_error_deg'] for row in failures if row['final_orientation_error_deg'] is not None]
    median, largest = _median_max(delays)
    return {
        'failure_runs': len(failures),
        'detected': len(delays),
        'named': sum(bool(row['correct_identification']) for row in failures),
        'reached_safe_point': sum(bool(row['reached_safe_point']) for row in failures),
        'faults': sum(row['mode'] == FAULT for row in completed),
        'min_tension_n': min(tensions) if tensions else None,
        'max_tension_n': max(greatest) if greatest else None,
        'final_error_max_m': max(errors) if errors else None,
        'final_orientation_error_max_deg': max(angles) if angles else None,
        'delay_median_ms': median,
        'delay_max_ms': largest,
        'failure_free_runs': len(failure_free),
        'false_alarms': sum(bool(row['false_alarm']) for row in completed),
        'not_completed': len(rows) - len(completed),
    }


def outcome_lines(rows: list[dict]) -> list[str]:
    """The outcome tables: per detector × fidelity with a total, and per cable."""
    header = ('| {} | failure runs | detected | named | reached SP | FAULT | final error max (mm / °) '
              '| min / max tension after the failure (N) | delay median / max (ms) | failure-free runs '
              '| false alarms | not completed |')
    rule = '|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|'

    def line(label, figures):
        millimetres = None if figures['final_error_max_m'] is None else 1000.0 * figures['final_error_max_m']
        return (f'| {label} | {figures["failure_runs"]} | {figures["detected"]} | {figures["named"]} '
                f'| {figures["reached_safe_point"]} | {figures["faults"]} '
                f'| {_fmt(millimetres)} / {_fmt(figures["final_orientation_error_max_deg"], 3)} '
                f'| {_fmt(figures["min_tension_n"], 2)} / {_fmt(figures["max_tension_n"], 1)} '
                f'| {_fmt(figures["delay_median_ms"])} / '
                f'{_fmt(figures["delay_max_ms"])} | {figures["failure_free_runs"]} '
                f'| {figures["false_alarms"]} | {figures["not_completed"]} |')

    groups = sorted({group_key(row) for row in rows})
    lines = [header.format('detector/fidelity'), rule]
    lines += [line(key, outcome([row for row in rows if group_key(row) == key])) for key in groups]
    lines += [line('**all**', outcome(rows)), '', header.format('cable'), rule]
    cables = sorted({row['cable'] for row in rows if row['cable'] is not None})
    lines += [line(cable, outcome([row for row in rows if row['cable'] == cable])) for cable in cables]
    return lines


def detection_by_motion(rows: list[dict]) -> dict:
    """{(motion, direction): {'detector/fidelity': median delay (ms) over seeds, or 'missed'}}
    of the cable-4 failure runs, to set beside the paper's Tables 5 and 7: counted as the
    paper counts, from the signal that broke the cable."""
    delays = {}
    for row in rows:
        if row['cable'] == PAPER_TEST_CABLE and row['error'] is None:
            cell = delays.setdefault((row['motion'], row['direction']), {})
            delay = row.get('detection_delay_from_signal_ms')
            cell.setdefault(group_key(row), []).append(
                row['detection_delay_ms'] if delay is None else delay)
    table = {}
    for motion_direction, groups in delays.items():
        table[motion_direction] = {}
        for key, group_delays in groups.items():
            detected = [delay for delay in group_delays if delay is not None]
            table[motion_direction][key] = statistics.median(detected) if detected else 'missed'
    return table


# ---- writing -----------------------------------------------------------------------

def _csv_cell(value):
    if value is None:
        return ''
    if isinstance(value, list):
        return ' '.join(str(item) for item in value)
    return value


def write_summary_csv(rows: list[dict], path: str | Path, columns: tuple[str, ...] = CSV_COLUMNS) -> None:
    """A row per run, of `columns` (a campaign's; a bench may add its own to them)."""
    with open(path, 'w', newline='') as stream:
        writer = csv.DictWriter(stream, fieldnames=columns)
        writer.writeheader()
        for row in rows:
            writer.writerow({column: _csv_cell(row[column]) for column in columns})


def _fmt(value, digits: int = 1) -> str:
    if value is None:
        return '–'
    if isinstance(value, str):
        return value
    return f'{value:.{digits}f}'


def summary_markdown(rows: list[dict]) -> str:
    summary = summarize(rows)
    failure_runs = sum(row['cable'] is not None for row in rows)
    failed = [row for row in rows if row['error'] is not None]
    lines = [
        '# FDI campaign',
        '',
        f'{len(rows)} runs: {failure_runs} with a cable failure, {len(rows) - failure_runs} '
        f'failure-free; {len(failed)} did not complete.',
        '',
        '## Outcome of every run',
        '',
        'Failure runs: detected (the supervisor named a broken cable after the failure), '
        'named (exactly the broken one), reached SP (within the recovery tolerance when the run '
        'ended), FAULT (the supervisor gave up). Min / max tension: the lowest and the highest '
        'tension of a remaining cable after the failure, over the runs. Delays: from the instant the cable really broke '
        'to the detection, every detected failure. False alarms: any run where a detection came '
        'before the failure, or with none.',
        '',
        *outcome_lines(rows),
        '',
        '## Per detector × fidelity',
        '',
        f'Delays: detected failures of cable {PAPER_TEST_CABLE} on the along-* (Table 4) and '
        'orthogonal-* (Table 6) motions. Identification and recovery: % of failure runs '
        '(a missed detection is a wrong identification). False alarms: failure-free runs '
        'with any detection, per hour of simulated failure-free motion. Min tension: lowest '
        'cable tension of any run; final error: largest recovery end error.',
        '',
        '| detector/fidelity | runs | detected % | along delay median / max (ms) '
        '| orthogonal delay median / max (ms) | identification % | false alarms / h '
        '| failure-free h | recovery success % | min tension (N) | final error max (m) |',
        '|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|',
    ]
    for key, figures in summary.items():
        lines.append(
            f'| {key} | {figures["runs"]} | {_fmt(figures["detection_pct"])} '
            f'| {_fmt(figures["along_delay_median_ms"])} / {_fmt(figures["along_delay_max_ms"])} '
            f'| {_fmt(figures["orthogonal_delay_median_ms"])} / {_fmt(figures["orthogonal_delay_max_ms"])} '
            f'| {_fmt(figures["identification_pct"])} | {_fmt(figures["false_alarms_per_hour"], 2)} '
            f'| {_fmt(figures["failure_free_hours"], 3)} | {_fmt(figures["recovery_success_pct"])} '
            f'| {_fmt(figures["min_tension_n"], 2)} | {_fmt(figures["final_error_max_m"], 4)} |')
    by_motion = detection_by_motion(rows)
    keys = list(summary)
    lines += [
        '',
        f'## Detection time per motion, cable {PAPER_TEST_CABLE}: the paper vs this campaign',
        '',
        'Paper: Table 5 (along cable 4), Table 7 (orthogonal to cable 4) and §5.3 (circle), '
        'measured on the real robot at ε = 0.3 N·m. Forward = start → finish of Tables 4/6 '
        '(towards A4 for the along motions), reverse = the paper\'s t_backward. Ours: median '
        'over seeds of the detection delay (ms), counted as the paper counts from the signal '
        'that broke the cable (on the field plant the electromagnet parts it later; the table '
        'above counts from the parting); "missed" = not detected, "–" = not run.',
        '',
        '| motion | direction | paper t (ms) | ' + ' | '.join(keys) + ' |',
        '|---|---|---:|' + '---:|' * len(keys),
    ]
    motions = list(PAPER_DETECTION_MS) + sorted({motion for motion, _ in by_motion} - set(PAPER_DETECTION_MS))
    for motion in motions:
        for direction in DIRECTIONS:
            ours = by_motion.get((motion, direction))
            paper = PAPER_DETECTION_MS.get(motion, {}).get(direction)
            if ours is None and paper is None:
                continue
            ours = ours or {}
            lines.append(f'| {motion} | {direction} | {_fmt(paper, 0)} | '
                         + ' | '.join(_fmt(ours.get(key)) for key in keys) + ' |')
    if failed:
        lines += ['', '## Runs that did not complete', '']
        lines += [f'- `{row["run_id"]}`: {row["error"]}' for row in failed]
    return '\n'.join(lines) + '\n'


# ---- command line ------------------------------------------------------------------

def _names(text: str) -> list[str]:
    return [item.strip() for item in text.split(',') if item.strip()]


def _integers(text: str) -> list[int]:
    return [int(item) for item in _names(text)]


ALL = 'all'


def _cables(text: str) -> list[int] | str:
    return ALL if text.strip() == ALL else _integers(text)


def _choices(allowed):
    def parse(text):
        names = _names(text)
        unknown = set(names) - set(allowed)
        if unknown:
            raise argparse.ArgumentTypeError(
                f'{", ".join(sorted(unknown))}: choose from {", ".join(allowed)}')
        return names
    return parse


def parse_args(argv=None):
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--config', default=DEFAULT_ROBOT, help='robot YAML')
    parser.add_argument('--motions', default=DEFAULT_MOTIONS, help='motions YAML')
    parser.add_argument('--cables', type=_cables, default=[PAPER_TEST_CABLE],
                        help=f'cables to break, 1-based, comma-separated, or all (default '
                             f'{PAPER_TEST_CABLE}, the paper\'s)')
    parser.add_argument('--motion-set', type=_names, default=['along', 'orthogonal', 'circle'],
                        help='along (Table 4), orthogonal (Table 6), all (every motion of the '
                             'motions file), or motion names, comma-separated (default '
                             'along,orthogonal,circle)')
    parser.add_argument('--directions', type=_choices(DIRECTIONS), default=list(DIRECTIONS))
    parser.add_argument('--fidelities', type=_choices(FIDELITIES), default=list(FIDELITIES))
    parser.add_argument('--detectors', type=_choices(DETECTORS), default=list(DETECTORS))
    parser.add_argument('--seeds', type=_integers, default=[0], help='comma-separated (default 0)')
    parser.add_argument('--fail-at-fraction', type=float, metavar='F',
                        help='fraction of the move at which the cable breaks (default: the '
                             'paper\'s, the midpoint; 135° of arc on the circle)')
    parser.add_argument('--random-instants', action='store_true',
                        help='break each cable at a point of its move drawn from the run\'s seed '
                             f'(uniform in {RANDOM_FRACTION_RANGE[0]}–{RANDOM_FRACTION_RANGE[1]} '
                             'of the move) instead of the paper\'s')
    parser.add_argument('--failure-free', action=argparse.BooleanOptionalAction, default=True,
                        help='also run every motion without failure, for false alarms (default on)')
    parser.add_argument('--engine', choices=['inprocess', 'graph'], default='inprocess')
    parser.add_argument('--epsilon', type=float, metavar='NM', help='detection threshold (N·m)')
    parser.add_argument('--calibration', metavar='YAML',
                        help='detector thresholds (cdpr-calibrate) for every run; default: the '
                             "set-up's, else the shipped calibration made on this robot")
    parser.add_argument('--jobs', type=int, default=os.cpu_count(),
                        help='parallel runs on this machine (default: all cores)')
    parser.add_argument('--scheduler', metavar='ADDRESS',
                        help='run on the workers of this Dask scheduler (tcp://HOST:PORT) '
                             'instead of local processes; --out must be on a filesystem the '
                             'workers share')
    parser.add_argument('--out', required=True, help='campaign folder')
    return parser.parse_args(argv)


@command('cdpr-campaign')
def main(argv=None):
    args = parse_args(argv)
    if args.random_instants and args.fail_at_fraction is not None:
        print('cdpr-campaign: --random-instants and --fail-at-fraction: choose one', file=sys.stderr)
        return 2
    try:
        motions = expand_motion_set(args.motion_set, motion_names(config_file(args.motions)))
    except ValueError as err:
        print(f'cdpr-campaign: {err}', file=sys.stderr)
        return 2
    cable_count = load_robot(config_file(args.config)).cable_count
    if args.cables == ALL:
        args.cables = list(range(1, cable_count + 1))
    if not all(1 <= cable <= cable_count for cable in args.cables):
        print(f'cdpr-campaign: --cables: the robot has cables 1..{cable_count}', file=sys.stderr)
        return 2
    runs = build_matrix(motions, args.cables, args.directions, args.fidelities, args.detectors,
                        args.seeds, args.fail_at_fraction, args.failure_free,
                        args.random_instants, config=args.config,
                        motions_file=args.motions, engine=args.engine, epsilon_nm=args.epsilon,
                        calibration=args.calibration)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    try:
        rows = run_campaign(runs, out, args.jobs, scheduler=args.scheduler)
    except SchedulerUnreachable as err:
        print(f'cdpr-campaign: {err}', file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        # after the progress bar's line on a terminal
        print(('\n' if sys.stderr.isatty() else '') + 'cdpr-campaign: interrupted; the same '
              'command runs what is missing', file=sys.stderr)
        return INTERRUPTED_EXIT_CODE
    write_summary_csv(rows, out / 'summary.csv')
    (out / 'summary.md').write_text(summary_markdown(rows))
    mistakes = user_errors(rows)
    if mistakes:
        # the same mistake in every run it reaches: said once, as this command's own
        for mistake in mistakes:
            print(f'cdpr-campaign: {mistake}', file=sys.stderr)
        return USAGE_EXIT_CODE
    failed = sum(row['error'] is not None for row in rows)
    print(f'{len(rows)} runs, {failed} did not complete; summary: {out / "summary.md"}, '
          f'{out / "summary.csv"}')
    return 1 if failed else 0


if __name__ == '__main__':
    sys.exit(main())
