"""cdpr-bench soak: the graph in realtime, failure-free, for minutes on end.

The end-effector shuttles between two points of the workspace (a goal every few
seconds on /cdpr/goal), so the whole graph works all the time. Reported: the memory
growth of every node (resident set after a warm-up against at the end, and over the
second half alone), the plant's deadline misses and tick rate, the supervisor's alarms
(false, since nothing fails), the commands that came too late to be applied, the ticks
left unjudged after bursts of them and how far judging trailed, and the state→command
latency; then each judged against its target (TARGETS):

- memory: a node whose resident set grows in the second half (after the warm-up) by more
  than MEMORY_KIB_PER_5_MIN for every 5 minutes leaks; a high-water mark reached early
  does not grow there. A node meant to run for days must not grow at all; the bound
  leaves room for the allocator's pages.
- false alarms: none.
- late commands: at most LATE_COMMAND_PCT of the ticks. One late command changes the
  residual less than its noise; bursts of them make the supervisor stop judging.
- unjudged ticks: at most UNJUDGED_PCT: the FDI blind for at most 1.5 s in 5 minutes,
  in stretches of fdi.late_command_guard_cycles (60 ms), each delaying a detection by at
  most that.
"""
from __future__ import annotations

import json
import time

from geometry_msgs.msg import PointStamped

from cdpr_msgs_py import qos
from cdpr_msgs_py.contract import GOAL

from .graph import DiagnosticsListener, graph_parameters
from ..graph.launcher import Graph, graph_nodes, launch_environment

NAMESPACE = '/cdpr_soak'
WARM_UP_S = 30.0
GOAL_PERIOD_S = 6.0
GOALS_M = ((0.6, 1.2, 1.2), (1.1, 0.8, 1.35))
SAMPLE_S = 1.0
MEMORY_KIB_PER_5_MIN = 64.0
LATE_COMMAND_PCT = 0.1
UNJUDGED_PCT = 0.5


def resident_kib(pid: int) -> int:
    """Resident memory (KiB) of `pid` and the processes it started."""
    try:
        with open(f'/proc/{pid}/status') as file:
            rss = next(int(line.split()[1]) for line in file if line.startswith('VmRSS:'))
        with open(f'/proc/{pid}/task/{pid}/children') as file:
            children = [int(child) for child in file.read().split()]
    except (FileNotFoundError, ProcessLookupError, StopIteration):
        return 0
    return rss + sum(resident_kib(child) for child in children)


def graph_memory_kib(graph: Graph) -> dict[str, int]:
    """Resident memory (KiB) of every node of the graph."""
    return {name: resident_kib(process.pid) for name, process in graph.processes.items()}


def bench_soak(config: str, minutes: float, log=lambda line: None) -> dict:
    launch_environment()
    duration_s = minutes * 60.0
    parameters = graph_parameters(config, 'realtime', duration_s + 60.0)
    listener = DiagnosticsListener()
    goal = listener.node.create_publisher(PointStamped, f'{NAMESPACE}/{GOAL}', qos.of_readers(GOAL))
    graph = Graph(graph_nodes(parameters), NAMESPACE, log=log)
    try:
        graph.start()
        graph.wait_until_up()
        start = time.monotonic()
        memory_after_warm_up = memory_halfway = None
        sent = 0
        while time.monotonic() - start < duration_s:
            graph.check()
            elapsed = time.monotonic() - start
            if elapsed >= sent * GOAL_PERIOD_S:
                message = PointStamped()
                message.header.frame_id = 'world'
                message.point.x, message.point.y, message.point.z = GOALS_M[sent % 2]
                goal.publish(message)
                sent += 1
            if memory_after_warm_up is None and elapsed >= WARM_UP_S:
                memory_after_warm_up = graph_memory_kib(graph)
            if memory_halfway is None and elapsed >= (WARM_UP_S + duration_s) / 2:
                memory_halfway = graph_memory_kib(graph)
            time.sleep(SAMPLE_S)
        memory_end = graph_memory_kib(graph)
        plant = dict(listener.latest.get(f'{NAMESPACE}/plant_simulator', {}))
        supervisor = dict(listener.latest.get(f'{NAMESPACE}/supervisor', {}))
    finally:
        graph.stop()
        listener.close()
    return {
        'minutes': minutes,
        'goals': sent,
        'memory_growth_kib': {name: memory_end[name] - memory_after_warm_up[name]
                              for name in memory_end},
        # a leak grows as much in the second half; a high-water mark does not
        'memory_growth_second_half_kib': {name: memory_end[name] - memory_halfway[name]
                                          for name in memory_end},
        'memory_end_kib': memory_end,
        'realtime_rate_hz': float(plant.get('tick rate wall hz', 'nan')),
        'realtime_deadline_miss_pct': float(plant.get('deadline misses pct', 'nan')),
        'state_to_command_p99_ms': float(plant.get('state to command p99 ms', 'nan')),
        'false_alarms': len(json.loads(supervisor.get('fdi broken_cables', '[]'))),
        'unidentified_alarms': int(json.loads(supervisor.get('fdi unidentified_alarms', '0'))),
        'ticks_judged': int(supervisor.get('ticks total', '0')),
        'late_commands': int(json.loads(supervisor.get('fdi late_commands', '0'))),
        # ticks not judged after bursts of late commands: detection was blind then
        'unjudged_ticks': int(json.loads(supervisor.get('fdi unjudged_ticks', '0'))),
        'judging_lag_max_ms': float(supervisor.get('judging lag max ms', 'nan')),
        'brake': plant.get('command watchdog', 'never engaged'),
    }


def targets(figures: dict) -> list[tuple[str, str, str, bool]]:
    """(figure, value, target, met) of the soak's figures against TARGETS (docstring)."""
    second_half_min = (figures['minutes'] * 60.0 - WARM_UP_S) / 2.0 / 60.0
    bound = MEMORY_KIB_PER_5_MIN * second_half_min / 5.0
    growth = figures['memory_growth_second_half_kib']
    ticks = max(figures['ticks_judged'], 1)
    late = 100.0 * figures['late_commands'] / ticks
    unjudged = 100.0 * figures['unjudged_ticks'] / ticks
    return [
        ('memory growth, second half, largest', f'{max(growth.values())} KiB ({max(growth, key=growth.get)})',
         f'<= {bound:.0f} KiB', max(growth.values()) <= bound),
        ('false alarms', str(figures['false_alarms']), '0', figures['false_alarms'] == 0),
        ('late commands', f'{late:.3f} %', f'<= {LATE_COMMAND_PCT} %', late <= LATE_COMMAND_PCT),
        ('unjudged ticks', f'{unjudged:.3f} %', f'<= {UNJUDGED_PCT} %', unjudged <= UNJUDGED_PCT),
    ]

