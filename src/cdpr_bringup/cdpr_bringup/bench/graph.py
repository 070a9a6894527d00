"""cdpr-bench graph: how fast the closed loop runs, as nodes and in one process.

- lockstep: the whole graph of `graph.graph_nodes` (no bag recorder) on the paper's
  circle, in both graph forms (every node its own process; the loop's nodes composed in
  one); cycles per wall second between the plant's first and last tick, as the plant
  measures them.
- in-process: `engine.run_inprocess` on the elastic circle; simulated s per wall s
  (best of a few runs: the machine is shared).
- realtime: the same graph with the bag recorder, on the 2 ms wall-clock timer,
  scheduled as the config's `scheduling` section says (SCHED_FIFO for the control
  loop); the plant's tick rate, its deadline misses (a tick more than one period late),
  the latency from its publishing the state of a tick to its receiving the command
  stamped with it, and the % of commands that came too late to be applied (the
  supervisor's count). Alternately with
  normal scheduling for every node, to show what the scheduling buys; medians of
  REALTIME_REPEATS runs each, since one run depends on what else the machine does. Both
  graph forms are run scheduled; normal scheduling in the separate form. The ticks the
  plant published and the bag does not hold are counted: the recorder must keep them all.
- CPU: per node process (and its children), % of one core over the ticking window,
  from /proc/<pid>/stat; and the share of the machine's cores that all its processes
  left idle.

The plant reports its timing on /diagnostics (cdpr_twin.nodes.tick_timing); this bench listens
there, so no extra subscriber loads the per-cycle topics.
"""
from __future__ import annotations

import os
import tempfile
import threading
import time
from pathlib import Path

import numpy as np

from cdpr_msgs_py import qos
from cdpr_msgs_py.contract import DIAGNOSTICS

from ..bags.bag_io import LOOP_TOPICS, missing_ticks, read_topics
from ..runs.metrics import written_statuses
from ..runs.engine import run_inprocess
from ..graph.launcher import Graph, GraphError, graph_nodes, launch_environment
from ..runs.settle import GRAPH_FORMS, ScenarioOptions, build_scenario

NAMESPACE = '/cdpr_bench'
MOTION = 'circle'
REALTIME_DURATION_S = 20.0
REALTIME_REPEATS = 3
RUN_TIMEOUT_S = 300.0
INPROCESS_REPEATS = 3
CPU_SAMPLE_S = 0.1
# After the plant exits, how long its last /diagnostics may take to arrive (s).
REPORT_TIMEOUT_S = 3.0
CLOCK_TICKS_PER_S = os.sysconf('SC_CLK_TCK')

# (key, label, target text, test of the figure)
TARGETS = [
    ('lockstep_cycles_per_s', 'lockstep cycles/s, separate', '>= 1000', lambda v: v >= 1000.0),
    ('composed_lockstep_cycles_per_s', 'lockstep cycles/s, composed', '>= 2000', lambda v: v >= 2000.0),
    ('inprocess_realtime_factor', 'in-process x real time (elastic)', '>= 50', lambda v: v >= 50.0),
]
# the realtime figures (key suffix, label, per graph form its target text and test)
ANY = ('', None)
REALTIME_TARGETS = [
    ('realtime_rate_hz', 'realtime tick rate Hz', dict.fromkeys(('separate', 'composed'),
                                                             ('>= 499.5', lambda v: v >= 499.5))),
    ('realtime_deadline_miss_pct', 'realtime deadline misses %', {'separate': ('< 0.05', lambda v: v < 0.05),
                                                                 'composed': ANY}),
    ('state_to_command_p50_ms', 'state -> command p50 ms (realtime)', {}),
    ('state_to_command_p99_ms', 'state -> command p99 ms (realtime)', {'separate': ('< 1', lambda v: v < 1.0),
                                                                      'composed': ('< 2', lambda v: v < 2.0)}),
    ('realtime_late_command_pct', 'late commands % (realtime)', {}),
    ('realtime_idle_pct', 'machine idle % (realtime)', {'separate': ('>= 40', lambda v: v >= 40.0)}),
    ('realtime_ticks_lost', 'loop ticks lost by the recorder (realtime)', dict.fromkeys(
        ('separate', 'composed'), ('0', lambda v: v == 0))),
]
OTHER_FIGURES = [
    ('normal_scheduling_rate_hz', 'tick rate Hz, normal scheduling', '', None),
    ('normal_scheduling_deadline_miss_pct', 'deadline misses %, normal sched.', '', None),
    ('normal_scheduling_state_to_command_p99_ms', 'state -> command p99 ms, normal', '', None),
    ('normal_scheduling_late_command_pct', 'late commands %, normal scheduling', '', None),
    ('lockstep_state_to_command_p50_ms', 'state -> command p50 ms (lockstep)', '', None),
    ('lockstep_state_to_command_p99_ms', 'state -> command p99 ms (lockstep)', '', None),
]


def form_key(form: str, key: str) -> str:
    """A figure's key for graph `form`: the separate form's keys are unprefixed."""
    return key if form == 'separate' else f'{form}_{key}'


class DiagnosticsListener:
    """The latest /diagnostics key-values of every node, received in a background thread."""

    def __init__(self):
        import rclpy
        from diagnostic_msgs.msg import DiagnosticArray
        from rclpy.executors import SingleThreadedExecutor
        self.rclpy = rclpy
        self.context = rclpy.Context()
        rclpy.init(context=self.context)
        self.node = rclpy.create_node('cdpr_bench_listener', context=self.context)
        self.latest: dict[str, dict[str, str]] = {}
        self.node.create_subscription(DiagnosticArray, DIAGNOSTICS, self.on_diagnostics,
                                      qos.of_readers(DIAGNOSTICS))
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self.stopping = threading.Event()
        self.thread = threading.Thread(target=self.spin, daemon=True)
        self.thread.start()

    def spin(self) -> None:
        while not self.stopping.is_set():
            self.executor.spin_once(timeout_sec=0.1)

    def on_diagnostics(self, message) -> None:
        for status in message.status:
            self.latest[status.name] = {pair.key: pair.value for pair in status.values}

    def close(self) -> None:
        self.stopping.set()
        self.thread.join()
        self.executor.shutdown(timeout_sec=0.5)
        self.node.destroy_node()
        self.rclpy.shutdown(context=self.context)


def process_cpu_s(pid: int) -> float:
    """CPU time (s) used so far by `pid` and the processes it started (0 once it is gone)."""
    try:
        with open(f'/proc/{pid}/stat') as file:
            fields = file.read().rsplit(')', 1)[1].split()
        with open(f'/proc/{pid}/task/{pid}/children') as file:
            children = [int(child) for child in file.read().split()]
    except (FileNotFoundError, ProcessLookupError):
        return 0.0
    # after the command name: state is field 3, utime 14, stime 15 (proc(5))
    own = (int(fields[11]) + int(fields[12])) / CLOCK_TICKS_PER_S
    return own + sum(process_cpu_s(child) for child in children)


def machine_busy_s() -> float:
    """CPU time (s) every process of the machine has used so far. Summed per process, not
    read from /proc/stat, whose idle time the kernel samples on its tick: a 500 Hz loop
    that wakes between ticks showed there as twice the idle its processes left."""
    busy = 0.0
    for entry in os.scandir('/proc'):
        if entry.name.isdigit():
            try:
                with open(f'/proc/{entry.name}/stat') as file:
                    fields = file.read().rsplit(')', 1)[1].split()
            except OSError:
                continue
            busy += (int(fields[11]) + int(fields[12])) / CLOCK_TICKS_PER_S
    return busy


def inside_window(samples, first_s: float, last_s: float):
    """The first and last of the samples inside the ticking window (all if too few)."""
    inside = [sample for sample in samples if first_s <= sample[0] <= last_s]
    inside = inside if len(inside) >= 2 else samples
    return (inside[0], inside[-1]) if len(inside) >= 2 else None


def cpu_percent(samples, first_s: float, last_s: float) -> dict[str, float]:
    """% of one core per node between the samples that bound the ticking window best."""
    bounds = inside_window(samples, first_s, last_s)
    if bounds is None:
        return {}
    (start, before, _), (end, after, _) = bounds
    cpu = {name: round(100.0 * (after[name] - before[name]) / (end - start), 1) for name in before}
    busy = (bounds[1][2] - bounds[0][2]) / ((end - start) * os.cpu_count())
    cpu['machine idle'] = round(100.0 * (1.0 - busy), 1)
    return cpu


def run_graph(parameters: dict, log, form: str = 'separate', recorded: bool = False) -> tuple[dict, dict]:
    """Run the graph in `form` (with the bag recorder if `recorded`) to completion; the
    plant's final timing facts (with the supervisor's late-command %, the ticks the bag
    lacks of its loop topics and those its recorder counted missing) and CPU % per process
    and of the machine left idle."""
    with tempfile.TemporaryDirectory(prefix='cdpr-bench-') as folder:
        bag = Path(folder) / 'bag' if recorded else None
        statuses = Path(folder) / 'statuses'
        statuses.mkdir()
        facts, cpu = timed_run(graph_nodes(parameters, None if bag is None else str(bag), form=form,
                                           last_diagnostics=str(statuses)), statuses, log)
        if bag is not None:
            names = [f'{NAMESPACE}/{topic}' for topic in LOOP_TOPICS]
            held = read_topics(bag, names)
            facts['ticks lost'] = max(int(facts['ticks timed']) - len(held[name]) for name in names)
            counted = missing_ticks(bag) or {}
            facts['ticks counted missing'] = max((counted.get(topic, 0) for topic in LOOP_TOPICS), default=0)
    return facts, cpu


def timed_run(nodes, statuses: Path, log) -> tuple[dict, dict]:
    """Run the graph of `nodes`, sampling the CPU of each process and of the machine; the
    plant's final timing facts (its last status, which its node writes into `statuses` as it
    stops: no DDS delivery) and the CPU figures of its ticking window."""
    graph = Graph(nodes, NAMESPACE, completion='plant_simulator', log=log)
    samples = []
    try:
        graph.start()
        graph.wait_until_up()
        deadline = time.monotonic() + RUN_TIMEOUT_S
        while not graph.check():
            if time.monotonic() > deadline:
                raise GraphError(f'the run did not complete within {RUN_TIMEOUT_S:.0f} s')
            samples.append((time.monotonic(), {name: process_cpu_s(process.pid)
                                               for name, process in graph.processes.items()},
                            machine_busy_s()))
            time.sleep(CPU_SAMPLE_S)
    finally:
        graph.stop()
    said = written_statuses(statuses)
    facts = dict(said.get('plant_simulator', {}))
    if 'last tick monotonic s' not in facts:
        raise GraphError(f'the plant simulator wrote no tick timing into {statuses}')
    judged = said.get('supervisor', {})
    if 'ticks total' in judged:
        facts['late command pct'] = (100.0 * int(judged['fdi late_commands'])
                                     / max(int(judged['ticks total']), 1))
    cpu = cpu_percent(samples, float(facts['first tick monotonic s']),
                      float(facts['last tick monotonic s']))
    return facts, cpu


MEDIAN_KEYS = ('tick rate wall hz', 'deadline misses pct', 'state to command p50 ms',
               'state to command p99 ms', 'late command pct')


def median_facts(runs: list[tuple[dict, dict]]) -> dict[str, float]:
    """Per timing figure, its median over the runs (nan where a run did not report it)."""
    return {key: float(np.median([float(facts.get(key, 'nan')) for facts, _ in runs]))
            for key in MEDIAN_KEYS}


def inprocess_realtime_factor(config: str) -> float:
    scenario = build_scenario(ScenarioOptions(config=config, motion=MOTION, fidelity='elastic'))
    best = float('inf')
    for _ in range(INPROCESS_REPEATS):
        start = time.perf_counter()
        recording = run_inprocess(scenario)
        best = min(best, time.perf_counter() - start)
    # the simulated time that ran: a run whose recovery ends sooner is shorter than scheduled
    return recording.time_s.size * scenario.period_s / best


def graph_parameters(config: str, clock_mode: str, duration_s: float | None = None,
                     scheduling: bool = True) -> dict[str, dict]:
    """The nodes' parameters for the circle as cdpr-scenario settles it, `duration_s` long
    (default: the motion)."""
    return build_scenario(ScenarioOptions(config=config, motion=MOTION, duration_s=duration_s)
                          ).node_parameters(clock_mode, scheduling)


def bench_graph(config: str, log=lambda line: None) -> dict:
    """The figures of this module's docstring, by the keys of the targets, plus CPU per
    process."""
    launch_environment()
    figures = {'inprocess_realtime_factor': round(inprocess_realtime_factor(config), 1)}
    stepped = graph_parameters(config, 'lockstep')
    scheduled = graph_parameters(config, 'realtime', REALTIME_DURATION_S)
    normal = graph_parameters(config, 'realtime', REALTIME_DURATION_S, scheduling=False)
    lockstep = {form: run_graph(stepped, log, form) for form in GRAPH_FORMS}
    scheduled_runs = {form: [] for form in GRAPH_FORMS}
    normal_runs = []
    for _ in range(REALTIME_REPEATS):
        for form in GRAPH_FORMS:
            scheduled_runs[form].append(run_graph(scheduled, log, form, recorded=True))
        normal_runs.append(run_graph(normal, log))
    for form in GRAPH_FORMS:
        realtime = median_facts(scheduled_runs[form])
        figures.update({form_key(form, key): value for key, value in {
            'lockstep_cycles_per_s': float(lockstep[form][0]['tick rate wall hz']),
            'realtime_rate_hz': realtime['tick rate wall hz'],
            'realtime_deadline_miss_pct': realtime['deadline misses pct'],
            'state_to_command_p50_ms': realtime['state to command p50 ms'],
            'state_to_command_p99_ms': realtime['state to command p99 ms'],
            'realtime_late_command_pct': round(realtime['late command pct'], 3),
            'realtime_idle_pct': float(np.median([cpu['machine idle'] for _, cpu in scheduled_runs[form]])),
            'realtime_ticks_lost': sum(facts['ticks lost'] for facts, _ in scheduled_runs[form]),
            'cpu_pct': lockstep[form][1],
            'realtime_cpu_pct': scheduled_runs[form][0][1],
        }.items()})
    normal = median_facts(normal_runs)
    figures.update({
        'normal_scheduling_rate_hz': normal['tick rate wall hz'],
        'normal_scheduling_deadline_miss_pct': normal['deadline misses pct'],
        'normal_scheduling_state_to_command_p99_ms': normal['state to command p99 ms'],
        'normal_scheduling_late_command_pct': round(normal['late command pct'], 3),
        'realtime_runs_each': REALTIME_REPEATS,
        'realtime_run_s': REALTIME_DURATION_S,
        'lockstep_state_to_command_p50_ms': float(lockstep['separate'][0]['state to command p50 ms']),
        'lockstep_state_to_command_p99_ms': float(lockstep['separate'][0]['state to command p99 ms']),
        'state_to_command_measured_by': 'plant_simulator',
        # The graph's figures depend on what else runs on the machine.
        'load_average_1min': round(os.getloadavg()[0], 2),
    })
    return figures


def targets() -> list[tuple]:
    """Every figure the table shows, in its order: (key, label, target text, test)."""
    per_form = [(form_key(form, key), f'{label}, {form}', *goals.get(form, ANY))
                for form in GRAPH_FORMS for key, label, goals in REALTIME_TARGETS]
    return TARGETS + per_form + OTHER_FIGURES


def table(figures: dict) -> list[str]:
    """The figures next to their targets, then CPU per process, as printable lines."""
    lines = [f'  {"figure":<46} {"value":>9}  {"target":<8} met']
    for key, label, target, met in targets():
        value = figures[key]
        verdict = '' if met is None else ('yes' if met(value) else 'NO')
        lines.append(f'  {label:<46} {value:9.3f}  {target:<8} {verdict}')
    lines.append('  latency: the plant times its joint_states publish to the receipt of the '
                 'effort_command with that stamp')
    lines.append(f'  realtime figures: medians of {figures["realtime_runs_each"]} runs of '
                 f'{figures["realtime_run_s"]:.0f} s of each form and scheduling, alternated')
    lines.append(f'  machine load average (1 min) at the end: {figures["load_average_1min"]}')
    for form in GRAPH_FORMS:
        for key, label in (('cpu_pct', 'lockstep'), ('realtime_cpu_pct', 'realtime')):
            lines.append(f'  CPU % of one core, {label}, {form}: ' + ', '.join(
                f'{name} {value:.0f}' for name, value in sorted(figures[form_key(form, key)].items())))
    return lines
