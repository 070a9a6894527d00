"""Lockstep does not depend on the machine's load: a run whose loop and recorder are
stopped now and then (SIGSTOP, as a loaded machine's scheduler may hold a process) and
that shares the cores with busy loops equals the same run alone, to the bit, on every
loop topic of its bag, its view topics and every figure of its metrics.json. The stops
make the plant hold states for the recorder (lockstep waits for it), and resend its state
(command_timeout_s) where a stop keeps the command from it.

(A run that once failed in a fresh clone's make test — cable 4 named, the safe point not
reached — was not the load's doing: a second graph in the same ROS domain and namespace,
whose supervisor's latched NOMINAL took the first run's controller out of its recovery.
The launcher and the test sessions now claim their domain on the machine, dds.claim_domain;
tests/test_dds_and_launcher.py shows a second graph refused.)"""
from __future__ import annotations

import json
import os
import random
import signal
import subprocess
import sys
import threading
import time

import numpy as np
import pytest

from cdpr_bringup.bags.bag_io import read_messages, stamp_ns
from cdpr_bringup.graph.launcher import node_environment

from test_dds_and_launcher import RUN_LIMIT_S, run_bounded, scenario_command

pytestmark = pytest.mark.graph
LOOP = ('joint_states', 'reference', 'effort_command', 'twin/joint_states', 'fdi/residual',
        'recovery/reference', 'ground_truth/pose', 'ground_truth/tensions', 'twin/pose', 'reference/pose',
        'mode', 'fdi/broken_cable')
STALLS = 4
STALL_S = 0.7


def loop_topics(bag) -> dict[str, list]:
    """Per loop topic, every message (resent ones too) as (stamp, bytes of its fields)."""
    found = read_messages(bag, [f'/cdpr/{topic}' for topic in LOOP])
    def fields(message):
        if hasattr(message, 'data'):
            return (None, message.data)
        if hasattr(message, 'pose'):
            return stamp_ns(message), repr(message.pose)
        return stamp_ns(message), b''.join(np.asarray(getattr(message, name)).tobytes()
                                           for name in ('position', 'velocity', 'effort'))
    # a resent state (or its answer) is the same message again: compare each stamp's set
    return {topic: sorted(set(map(fields, (m for _, m in messages)))) for topic, messages in found.items()}


def descendants(pid: int) -> list[int]:
    children = {}
    for entry in os.listdir('/proc'):
        if entry.isdigit():
            try:
                parent = int(open(f'/proc/{entry}/stat').read().rsplit(')', 1)[1].split()[1])
            except (OSError, IndexError, ValueError):
                continue
            children.setdefault(parent, []).append(int(entry))
    found, todo = [], [pid]
    while todo:
        for child in children.get(todo.pop(), []):
            found.append(child)
            todo.append(child)
    return found


def stall(root: int, done: threading.Event, seed: int = 1) -> None:
    """STALLS times at most, until `done`: stop the loop's process, the recorder's or both
    for STALL_S, 0.5-1 s apart."""
    rng = random.Random(seed)
    stalls = 0
    while stalls < STALLS and not done.wait(rng.uniform(0.5, 1.0)):
        names = {pid: open(f'/proc/{pid}/cmdline').read() for pid in descendants(root)
                 if os.path.exists(f'/proc/{pid}/cmdline')}
        targets = [pid for pid, line in names.items() if 'composed_loop' in line or 'bag_recorder' in line]
        if not targets:
            continue
        chosen = rng.sample(targets, rng.randint(1, len(targets)))
        for pid in chosen:
            os.kill(pid, signal.SIGSTOP)
        time.sleep(STALL_S)
        for pid in chosen:
            os.kill(pid, signal.SIGCONT)
        stalls += 1


def test_a_lockstep_run_stalled_and_loaded_equals_the_run_alone(tmp_path):
    alone = run_bounded(scenario_command(tmp_path / 'alone', '--quiet', '--fail-at', '0.5',
                                         '--graph-form', 'composed'), RUN_LIMIT_S, env=node_environment())
    assert alone.returncode == 0, alone.stderr[-2000:]
    hogs = [subprocess.Popen([sys.executable, '-c', 'while True: pass']) for _ in range(2)]
    done = threading.Event()
    try:
        process = subprocess.Popen(scenario_command(tmp_path / 'loaded', '--quiet', '--fail-at', '0.5',
                                                    '--graph-form', 'composed'),
                                   stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                                   start_new_session=True, env=node_environment())
        staller = threading.Thread(target=stall, args=(process.pid, done))
        staller.start()
        _, err = process.communicate(timeout=RUN_LIMIT_S)
    finally:
        done.set()
        for hog in hogs:
            hog.kill()
    staller.join()
    assert process.returncode == 0, err[-2000:]
    plant = json.loads((tmp_path / 'loaded' / 'last_diagnostics' / 'plant_simulator.json').read_text())['values']
    # the stalls did what they are for: the plant held states for the stopped recorder (and
    # resent a state where a stop kept its command from it)
    assert int(plant.get('states held for the recorder total', 0)) + int(plant.get('resent states total', 0)) > 0, plant
    metrics = [json.loads((tmp_path / run / 'metrics.json').read_text()) for run in ('alone', 'loaded')]
    for figures in metrics:
        figures.pop('wall_time_s')
    assert metrics[0] == metrics[1]
    assert metrics[0]['recovery']['reached_safe_point']
    assert loop_topics(tmp_path / 'alone' / 'bag') == loop_topics(tmp_path / 'loaded' / 'bag')
