"""cdpr-scenario: one run of a named motion, through the node graph or in-process.

Writes into --out: run.yaml (the run as settled: every setting it used), bag/ (graph engine:
every /cdpr topic), last_diagnostics/ (graph engine: each node's last /diagnostics status,
written as it stopped; a graph run's verdicts and final pose are read from there, so that
a recorder that lost the run's last ticks cannot change them), metrics.json (docs/design.md §7) and plots/, and prints the detection, identification and recovery figures and the
twin-vs-robot KPIs next to the paper's.

The node graph (rclpy) and the bag and plot stack (rosbags, matplotlib) are imported by
the runs that use them only: together they take ~0.7 s to import, a third of a short
in-process run with --no-plots, which is what every campaign run is.
"""
from __future__ import annotations

import argparse
import json
import multiprocessing
import shutil
import signal
import sys
import time
from pathlib import Path

import numpy as np
import yaml

from cdpr_fdi.detection.visibility import AT_THRESHOLD_N, hidden_below_n
from cdpr_fdi.detectors import make_detector
from cdpr_fdi.view.markers import Frame
from cdpr_msgs_py.contract import DEFAULT_NAMESPACE
from cdpr_twin.models.plant import FIDELITIES

from ..cli import INTERRUPTED_EXIT_CODE, command
from ..runs.engine import run_inprocess
from ..runs.metrics import KnownRun, RunSettings, metrics_json, statuses_beside, take_statuses, view_figures
from ..paths import DEFAULT_MOTIONS, DEFAULT_ROBOT, LAST_DIAGNOSTICS, SETTLED_RUN
from ..reports.summary import summary_lines
from ..runs.settle import ScenarioOptions, add_graph_form_option, add_push_option, build_scenario

RUN_TIMEOUT_FACTOR = 20.0
# How long the report's drawer may take beyond the bag, per control tick and fixed (s):
# ~0.3 ms a tick on a 2-core machine, with a margin of 20x for a loaded one.
DRAW_LIMIT_S_PER_TICK = 6e-3
DRAW_LIMIT_S = 30.0


def parse_args(argv=None):
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument('--config', default=DEFAULT_ROBOT, help='robot YAML')
    parser.add_argument('--motions', default=DEFAULT_MOTIONS, help='motions YAML')
    parser.add_argument('--motion', default='circle', help='along-1..4, orthogonal-1..4, circle')
    parser.add_argument('--reverse', action='store_true', help='run the motion backward')
    parser.add_argument('--fail-cable', type=int, action='append', default=[], metavar='K',
                        help='break cable K (1-based); repeat for several')
    when = parser.add_mutually_exclusive_group()
    when.add_argument('--fail-at', type=float, metavar='SECONDS')
    when.add_argument('--fail-at-fraction', type=float, metavar='F',
                      help='fraction of the move (default 0.5, the midpoint)')
    parser.add_argument('--fidelity', choices=FIDELITIES)
    parser.add_argument('--engine', choices=['graph', 'inprocess'], default='graph')
    parser.add_argument('--clock', choices=['lockstep', 'realtime'], default='lockstep')
    add_graph_form_option(parser)
    parser.add_argument('--detector', choices=['threshold', 'cusum'],
                        help='failure detector (default: the config file\'s fdi.detector)')
    parser.add_argument('--epsilon', type=float, metavar='NM', help='detection threshold (N·m)')
    parser.add_argument('--calibration', metavar='YAML',
                        help='detector thresholds written by cdpr-calibrate')
    parser.add_argument('--seed', type=int)
    parser.add_argument('--recovery-budget', type=float, metavar='SECONDS',
                        help='how long to run after a failure (default: derived from the '
                             'recovery phases and the distance to SP; a re-planned move takes longer)')
    add_push_option(parser)
    parser.add_argument('--namespace', default=DEFAULT_NAMESPACE)
    parser.add_argument('--out', required=True, help='output folder')
    parser.add_argument('--quiet', action='store_true', help='do not stream node logs')
    parser.add_argument('--no-plots', action='store_true',
                        help='skip bag (in-process) and plots, for batch runs')
    return parser.parse_args(argv)


def run_graph(args, scenario, out: Path):
    """The graph's recording, and whether Ctrl-C cut the run short (the graph is stopped
    cleanly either way, so the bag holds what ran); None when the graph failed (said on
    stderr)."""
    from ..bags.bag_io import missing_ticks, read_messages, recording_from_bag
    from ..graph.launcher import GraphError, graph_nodes, run_to_completion
    bag = out / 'bag'
    statuses = out / LAST_DIAGNOSTICS
    statuses.mkdir()
    log = (lambda line: None) if args.quiet else (lambda line: print(line, flush=True))
    timeout = RUN_TIMEOUT_FACTOR * scenario.cycles * scenario.period_s + 30.0
    interrupted = False
    try:
        run_to_completion(graph_nodes(scenario.node_parameters(args.clock), str(bag), form=args.graph_form,
                                      last_diagnostics=str(statuses)),
                          args.namespace, timeout, log)
    except KeyboardInterrupt:
        interrupted = True
    except GraphError as err:
        print(f'cdpr-scenario: {err}', file=sys.stderr)
        return None
    if interrupted and not bag.exists():
        return None, True
    try:
        recording = recording_from_bag(bag, args.namespace, scenario.robot.body.has_orientation)
    except ValueError:
        if interrupted:
            return None, True
        raise
    take_statuses(recording, statuses_beside(bag, read_messages(bag, ['/diagnostics'])['/diagnostics']),
                  missing_ticks(bag))
    return recording, interrupted


def break_visibility(scenario, failure_s: float, cable: int) -> dict:
    """What the residual could see of the first break (cdpr_fdi.detection.visibility): the
    tension (N) the reference asked of the 0-based `cable` when it parted at `failure_s`,
    and whether that is under what the run's detector alarms on, so that a late detection
    was to be expected."""
    row = min(int(round(failure_s / scenario.period_s)), len(scenario.reference) - 1)
    tension = float(scenario.reference.tension_n[row, cable])
    level = hidden_below_n(make_detector(scenario.fdi).least_alarming_nm, scenario.robot.motor.drum_radius_m)
    below = float(np.broadcast_to(level, (scenario.robot.cable_count,))[cable])
    return {'cable': cable + 1, 'reference_tension_n': tension, 'hidden_below_n': below,
            'late_detection_expected': tension < below - AT_THRESHOLD_N}


def metrics_of(scenario, recording, wall_time_s: float, interrupted: bool = False) -> dict:
    """metrics.json; of an interrupted run, for the ticks it ran (failures scheduled after
    its last tick did not happen)."""
    metrics = {
        'motion': scenario.motion.name,
        'fidelity': scenario.plant.fidelity,
        'detector': scenario.fdi.detector,
        'epsilon_nm': scenario.fdi.epsilon_nm,
    }
    if interrupted:
        metrics['interrupted'] = True
    if recording is not None and recording.missing_ticks is not None:
        metrics['bag_missing_ticks'] = recording.missing_ticks
    if recording is None or recording.time_s.size == 0:
        return dict(metrics, cycles=0, wall_time_s=wall_time_s)
    failures = [(at, cable) for at, cable in scenario.failures if at <= recording.time_s[-1]]
    broken = sorted({cable + 1 for _, cable in failures})
    # The failure is the instant a cable really parted (design.md §8); the signal that
    # broke it (the paper's electromagnet command, from which its Tables 5 and 7 count)
    # comes first. Without the plant's own record the two are one.
    signal = failures[0][0] if failures else None
    failure = signal
    if recording.broken_at_s is not None:
        failure = min(recording.broken_at_s.values(), default=None)
        broken = sorted(cable + 1 for cable in recording.broken_at_s)
    supervisor = recording.fdi or {}
    identified_tick = supervisor.get('identified_tick')
    detection = None if identified_tick is None else identified_tick * scenario.period_s
    # the plant's figures from every tick; of a graph run whose plant said none (killed),
    # those of the bag's view ticks
    figures = (recording.figures if recording.figures is not None
               else view_figures(scenario.robot, recording, failure, broken, detection))
    metrics.update(metrics_json(KnownRun(
        robot=scenario.robot, recording=recording, figures=figures, epsilon_nm=scenario.fdi.epsilon_nm,
        failure_time_s=failure, true_broken_cables=broken,
        detection_time_s=detection,
        identified_cables=supervisor.get('broken_cables') or [], mode=supervisor.get('mode'),
        phase_times_s={mode: tick * scenario.period_s
                       for mode, tick in (supervisor.get('phase_ticks') or {}).items()},
        safe_point_m=supervisor.get('safe_point_m'),
        reached_tolerance_m=scenario.recovery.reached_tolerance_m, supervisor=supervisor,
        wall_time_s=wall_time_s)))
    detection = metrics['detection_time_s']
    if failures:
        metrics['break'] = break_visibility(scenario, failure, failures[0][1])
    metrics['failure_signal_time_s'] = signal
    metrics['detection_delay_from_signal_ms'] = (None if detection is None or signal is None
                                                 else (detection - signal) * 1000.0)
    return metrics


def print_summary(metrics: dict, engine: str) -> None:
    print(f'{metrics["motion"]} on the {metrics["fidelity"]} plant, {engine} engine, '
          f'{metrics["detector"]} detector: {metrics["cycles"]} cycles in {metrics["wall_time_s"]:.1f} s')
    print('\n'.join(summary_lines(metrics)))


@command('cdpr-scenario')
def main(argv=None):
    try:
        return run_scenario(parse_args(argv))
    except KeyboardInterrupt:
        print('cdpr-scenario: interrupted before metrics.json was written', file=sys.stderr)
        return INTERRUPTED_EXIT_CODE


def run_scenario(args) -> int:
    options = ScenarioOptions(config=args.config, motions=args.motions, motion=args.motion,
                              reverse=args.reverse, fail_cables=args.fail_cable,
                              fail_at_s=args.fail_at, fail_at_fraction=args.fail_at_fraction,
                              fidelity=args.fidelity, seed=args.seed, detector=args.detector,
                              epsilon_nm=args.epsilon, calibration=args.calibration,
                              recovery_budget_s=args.recovery_budget,
                              pushes=[tuple(push) for push in args.push])
    scenario = build_scenario(options)
    out = Path(args.out)
    for earlier in (out / 'bag', out / LAST_DIAGNOSTICS):
        if earlier.exists():
            shutil.rmtree(earlier)
    out.mkdir(parents=True, exist_ok=True)
    (out / SETTLED_RUN).write_text(yaml.safe_dump(scenario.settings.data, sort_keys=False))
    if args.engine == 'graph':
        start = time.monotonic()
        outcome = run_graph(args, scenario, out)
        if outcome is None:
            return 1
        recording, interrupted = outcome
        return outputs(args, scenario, out, recording, interrupted, time.monotonic() - start)
    drawer = None if args.no_plots else ReportDrawer()
    try:
        start = time.monotonic()
        recording = run_inprocess(scenario)
        return outputs(args, scenario, out, recording, recording.interrupted,
                       time.monotonic() - start, drawer)
    finally:
        if drawer is not None:
            drawer.finish(DRAW_LIMIT_S)


def outputs(args, scenario, out: Path, recording, interrupted: bool, wall_time_s: float,
            drawer: ReportDrawer | None = None) -> int:
    """metrics.json, the summary, and unless --no-plots the bag and the report (an
    in-process run's drawn by `drawer`); the exit code."""
    metrics = metrics_of(scenario, recording, wall_time_s, interrupted)
    (out / 'metrics.json').write_text(json.dumps(metrics, indent=2))
    if interrupted:
        print(f'cdpr-scenario: interrupted after {metrics["cycles"]} of {scenario.cycles} cycles; '
              f'metrics of what ran: {out / "metrics.json"}', file=sys.stderr)
        return INTERRUPTED_EXIT_CODE
    print_summary(metrics, args.engine)
    print(f'metrics: {out / "metrics.json"}')
    if not args.no_plots:
        settings = RunSettings(scenario.robot, scenario.fdi, scenario.recovery,
                               f'settings: the run\'s own, {out / SETTLED_RUN}')
        if drawer is None:
            from ..reports.report import write_report
            # the bag as the run read it already: not read again
            write_report(out / 'bag', out / 'plots', settings, args.namespace, recording)
        elif not record_beside_report(drawer, recording, settings, metrics, out, args.namespace,
                                      scenario.marker_frame()):
            return 1
        print(f'bag: {out / "bag"}, plots and report: {out / "plots" / "report.md"}')
    return 0


def record(recording, bag: Path, namespace: str, frame: Frame) -> None:
    """The in-process run as a bag, as the graph would have recorded it, markers included."""
    from ..bags.bag_io import BagWriter, write_recording
    writer = BagWriter(bag)
    writer.open()
    try:
        write_recording(writer, recording, namespace, frame)
    finally:
        writer.close()


class ReportDrawer:
    """A forked process that draws the report of an in-process run from the run in memory,
    which reading its bag back would give (tests/test_report.py). Started before the run,
    it imports the report's stack (matplotlib, ~0.5 s) while this process simulates; once
    sent the run it draws the figures while this process writes the bag: the two take
    about as long and share nothing but the run."""

    def __init__(self):
        context = multiprocessing.get_context('fork')
        self.connection, drawer_end = context.Pipe()
        self.process = context.Process(target=draw_when_sent, args=(drawer_end,),
                                       name='report drawer')
        self.process.start()
        drawer_end.close()

    def draw(self, recording, settings, metrics: dict, out: Path) -> None:
        self.connection.send((recording, settings, metrics['failure_time_s'],
                              metrics['true_broken_cables'], out))

    def finish(self, limit_s: float) -> int | None:
        """Its exit code once it has drawn what it was sent (or, sent nothing, at once),
        killed after `limit_s`: None then."""
        self.connection.close()
        self.process.join(limit_s)
        if self.process.exitcode is None:
            self.process.kill()
            self.process.join(limit_s)
            return None
        return self.process.exitcode


def draw_when_sent(connection) -> None:
    """The drawer's work. Ctrl-C is the parent's to handle: it closes the pipe, and a
    drawer sent nothing ends."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    from ..reports.report import run_of_recording, write_run_report
    try:
        recording, settings, failure_time_s, true_broken_cables, out = connection.recv()
    except EOFError:
        return
    write_run_report(run_of_recording(recording, settings, failure_time_s, true_broken_cables),
                     out / 'bag', out / 'plots')


def record_beside_report(drawer: ReportDrawer, recording, settings, metrics: dict, out: Path,
                         namespace: str, frame: Frame) -> bool:
    """The run's bag, written here while `drawer` draws its report; False (said on stderr)
    when either is missing."""
    drawer.draw(recording, settings, metrics, out)
    written = False
    try:
        record(recording, out / 'bag', namespace, frame)
        written = True
    except OSError as err:
        print(f'cdpr-scenario: writing the bag {out / "bag"}: {err}', file=sys.stderr)
    finally:
        code = drawer.finish(DRAW_LIMIT_S + DRAW_LIMIT_S_PER_TICK * recording.time_s.size)
    if code != 0:
        print(f'cdpr-scenario: no whole report in {out / "plots"}: its drawer ended with '
              + ('no exit (killed)' if code is None else f'exit code {code}'), file=sys.stderr)
    return written and code == 0


if __name__ == '__main__':
    sys.exit(main())
