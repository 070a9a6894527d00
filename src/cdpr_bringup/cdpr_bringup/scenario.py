"""cdpr-scenario: one run of a named motion, through the node graph or in-process.

Writes into --out: bag/ (graph engine: every /cdpr topic), metrics.json, and prints the
twin-vs-robot KPIs next to the paper's. Detection and recovery keys stay null until
the supervisor runs in the graph.
"""
from __future__ import annotations

import argparse
import json
import shutil
import sys
import time
from pathlib import Path

from cdpr_msgs_py.contract import DEFAULT_NAMESPACE

from .bag_io import recording_from_bag
from .engine import run_inprocess
from .graph import GraphError, graph_nodes, run_to_completion
from .metrics import PAPER_KPI, tracking_error_m, twin_kpis
from .paths import DEFAULT_MOTIONS, DEFAULT_ROBOT
from .scenario_setup import ScenarioOptions, build_scenario

RUN_TIMEOUT_FACTOR = 20.0


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
    parser.add_argument('--fidelity', choices=['rigid', 'elastic'])
    parser.add_argument('--engine', choices=['graph', 'inprocess'], default='graph')
    parser.add_argument('--clock', choices=['lockstep', 'realtime'], default='lockstep')
    parser.add_argument('--detector', choices=['threshold', 'cusum'], default='threshold')
    parser.add_argument('--epsilon', type=float, metavar='NM', help='detection threshold (N·m)')
    parser.add_argument('--seed', type=int)
    parser.add_argument('--namespace', default=DEFAULT_NAMESPACE)
    parser.add_argument('--out', required=True, help='output folder')
    parser.add_argument('--quiet', action='store_true', help='do not stream node logs')
    return parser.parse_args(argv)


def node_parameters(args, scenario) -> dict:
    parameters = {
        'config_file': str(scenario.config_path.resolve()),
        'motions_file': str(scenario.motions_path.resolve()),
        'motion': args.motion, 'reverse': args.reverse, 'clock_mode': args.clock,
        'fail_cables': args.fail_cable or [0],
        'fail_at_s': -1.0 if args.fail_at is None else args.fail_at,
        'fail_at_fraction': -1.0 if args.fail_at_fraction is None else args.fail_at_fraction,
    }
    if args.fidelity:
        parameters['fidelity'] = args.fidelity
    if args.seed is not None:
        parameters['seed'] = args.seed
    return parameters


def run_graph(args, scenario, out: Path):
    bag = out / 'bag'
    log = (lambda line: None) if args.quiet else (lambda line: print(line, flush=True))
    timeout = RUN_TIMEOUT_FACTOR * scenario.cycles * scenario.period_s + 30.0
    run_to_completion(graph_nodes(node_parameters(args, scenario), str(bag)), args.namespace,
                      timeout, log)
    return recording_from_bag(bag, args.namespace)


def metrics_of(scenario, recording, wall_time_s: float) -> dict:
    true_broken = sorted({cable + 1 for _, cable in scenario.failures})
    return {
        'motion': scenario.motion.name,
        'fidelity': scenario.plant.fidelity,
        'failure_time_s': scenario.failure_time_s,
        'detection_time_s': None,
        'detection_delay_ms': None,
        'identified_cables': [],
        'true_broken_cables': true_broken,
        'false_alarm': False,
        'recovery': {'reached_safe_point': None, 'final_error_m': None,
                     'min_tension_n': float(recording.true_tension_n.min()),
                     'min_height_m': float(recording.true_position_m[:, 2].min()),
                     'duration_s': None},
        'kpi': twin_kpis(scenario.robot, recording),
        'tracking_error_m': tracking_error_m(recording),
        'cycles': int(recording.time_s.size),
        'wall_time_s': wall_time_s,
    }


def main(argv=None):
    args = parse_args(argv)
    options = ScenarioOptions(config=args.config, motions=args.motions, motion=args.motion,
                              reverse=args.reverse, fail_cables=args.fail_cable,
                              fail_at_s=args.fail_at, fail_at_fraction=args.fail_at_fraction,
                              fidelity=args.fidelity, seed=args.seed)
    scenario = build_scenario(options)
    out = Path(args.out)
    if (out / 'bag').exists():
        shutil.rmtree(out / 'bag')
    out.mkdir(parents=True, exist_ok=True)
    start = time.monotonic()
    try:
        recording = (run_graph(args, scenario, out) if args.engine == 'graph'
                     else run_inprocess(scenario))
    except GraphError as err:
        print(f'cdpr-scenario: {err}', file=sys.stderr)
        return 1
    metrics = metrics_of(scenario, recording, time.monotonic() - start)
    (out / 'metrics.json').write_text(json.dumps(metrics, indent=2))
    print(f'{scenario.motion.name} on the {scenario.plant.fidelity} plant, {args.engine} engine: '
          f'{metrics["cycles"]} cycles in {metrics["wall_time_s"]:.1f} s')
    print(f'  {"KPI":<8} {"this run":>10} {"paper":>10}')
    for key, value in metrics['kpi'].items():
        print(f'  {key:<8} {value:10.4f} {PAPER_KPI[key]:10.4f}')
    print(f'  tracking error (true pose vs reference): {metrics["tracking_error_m"] * 1000:.2f} mm')
    print(f'metrics: {out / "metrics.json"}' + (f', bag: {out / "bag"}' if args.engine == 'graph' else ''))
    return 0


if __name__ == '__main__':
    sys.exit(main())
