"""cdpr-bench recorder: does the bag keep every tick in realtime while outside readers
read, or stop reading?

RUNS realtime runs of the paper's circle (RUN_S each, the graph with its recorder and the
control loop scheduled as `scheduling` says), in each of two conditions, alternated:

- frozen: one outside reader (cdpr_bringup.graph.outside_reader: plain rclpy, reliable,
  keep-all) of every loop topic, suspended (SIGSTOP) FREEZE_AFTER_S after it first
  has every topic, for the rest of the run — a user's `ros2 topic echo` stopped by Ctrl-Z;
- two readers: two such readers of every loop topic, reading all along.

Per run: the ticks the plant published against the joint states in the bag (lost), the
recorder's own count of the ticks it lacks (the bag's metadata), the plant's tick rate
and deadline misses, and the machine left idle.
"""
from __future__ import annotations

import os
import select
import signal
import subprocess
import sys
import threading
import time

from cdpr_msgs_py import contract

from .graph import NAMESPACE, graph_parameters, run_graph
from ..graph.launcher import launch_environment, node_environment

RUN_S = 20.0
RUNS = 10
FREEZE_AFTER_S = 2.0
# How long a reader may take to have a message on every topic (s): DDS discovery.
RECEIVING_TIMEOUT_S = 30.0
READER_LIFETIME_S = 600.0
CONDITIONS = {'frozen': 1, 'two readers': 2}
# Every loop topic of the graph (written every tick from the first), which a user's tool
# might read.
TOPICS = [topic.name for topic in contract.TOPICS.values()
          if topic.rate is contract.Rate.TICK and topic.from_first_tick]


class OutsideReader:
    """An outside reader process of every loop topic; `freeze_after_s` (None: never)
    after it first has them all, it is suspended."""

    def __init__(self, freeze_after_s: float | None):
        self.process = subprocess.Popen(
            [sys.executable, '-m', 'cdpr_bringup.graph.outside_reader', NAMESPACE, str(READER_LIFETIME_S), *TOPICS],
            stdout=subprocess.PIPE, text=True, env=node_environment(), start_new_session=True)
        self.frozen = False
        self.thread = threading.Thread(target=self.watch, args=(freeze_after_s,), daemon=True)
        self.thread.start()

    def watch(self, freeze_after_s: float | None) -> None:
        deadline = time.monotonic() + RECEIVING_TIMEOUT_S
        while time.monotonic() < deadline and self.process.poll() is None:
            if (select.select([self.process.stdout], [], [], 0.1)[0]
                    and self.process.stdout.readline().strip() == 'receiving'):
                break
        else:
            return
        if freeze_after_s is not None:
            time.sleep(freeze_after_s)
            if self.process.poll() is None:
                os.killpg(self.process.pid, signal.SIGSTOP)
                self.frozen = True

    def end(self) -> None:
        if self.process.poll() is None:
            os.killpg(self.process.pid, signal.SIGCONT)
            os.killpg(self.process.pid, signal.SIGKILL)
        self.process.wait(timeout=10)


def recorded_run(parameters: dict, condition: str, log) -> dict:
    """One run in `condition`: the plant's figures, what the bag lost and what its
    recorder says it lacks."""
    readers = [OutsideReader(FREEZE_AFTER_S if condition == 'frozen' else None)
               for _ in range(CONDITIONS[condition])]
    try:
        facts, cpu = run_graph(parameters, log, recorded=True)
    finally:
        for reader in readers:
            reader.end()
    return {'ticks': int(facts['ticks timed']), 'lost': facts['ticks lost'],
            'recorder says missing': facts['ticks counted missing'],
            'tick rate hz': float(facts['tick rate wall hz']),
            'deadline misses pct': float(facts['deadline misses pct']),
            'idle pct': cpu.get('machine idle', float('nan')),
            'reader frozen': all(reader.frozen for reader in readers) if condition == 'frozen' else None}


def bench_recorder(config: str, log=lambda line: None) -> dict:
    launch_environment()
    parameters = graph_parameters(config, 'realtime', RUN_S)
    runs = {condition: [] for condition in CONDITIONS}
    for _ in range(RUNS):
        for condition in CONDITIONS:
            runs[condition].append(recorded_run(parameters, condition, log))
    return {'run_s': RUN_S, 'runs': runs}


def table(figures: dict) -> list[str]:
    lines = [f'  {len(next(iter(figures["runs"].values())))} realtime runs of {figures["run_s"]:.0f} s '
             f'per condition, alternated; goal: no tick lost in any']
    for condition, runs in figures['runs'].items():
        lost = [run['lost'] for run in runs]
        lines.append(f'  {condition:<12} runs losing a tick: {sum(1 for n in lost if n > 0)} of {len(runs)}; '
                     f'ticks lost per run: {lost}')
        lines.append(f'  {"":<12} the recorder\'s own count: {[run["recorder says missing"] for run in runs]}')
        lines.append(f'  {"":<12} tick rate Hz: {[round(run["tick rate hz"], 1) for run in runs]}, '
                     f'deadline misses %: {[round(run["deadline misses pct"], 3) for run in runs]}, '
                     f'machine idle %: {[round(run["idle pct"], 1) for run in runs]}')
        if condition == 'frozen':
            lines.append(f'  {"":<12} reader frozen in every run: '
                         f'{all(run["reader frozen"] for run in runs)}')
    return lines
