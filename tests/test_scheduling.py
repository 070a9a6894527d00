"""Realtime scheduling: what the nodes ask the OS for, and what they do when refused."""
from __future__ import annotations

import multiprocessing
import os
import re
import resource
import subprocess
import sys
import threading
from pathlib import Path

import pytest
import yaml

from cdpr_bringup.graph.launcher import graph_nodes
from cdpr_bringup.runs.settle import BACKGROUND, CONTROL_LOOP, FDI, ScenarioOptions, build_scenario
from cdpr_control.config import ConfigError, load_section
from cdpr_msgs_py import scheduling

from conftest import MOTIONS, PAPER_ROBOT, settled_parameters


def thread_settings() -> list[tuple[int, int]]:
    """(policy, nice) of every thread of this process."""
    return [(os.sched_getscheduler(tid), os.getpriority(os.PRIO_PROCESS, tid))
            for tid in scheduling.process_threads()]


def schedule_in_child(priority: int, nice: int, results) -> None:
    """A thread started before the call and one started after must both be set."""
    stop = threading.Event()
    before = threading.Thread(target=stop.wait)
    before.start()
    applied, outcome = scheduling.apply_scheduling(priority, nice)
    after = threading.Thread(target=stop.wait)
    after.start()
    results.put((applied, outcome, len(scheduling.process_threads()), thread_settings()))
    stop.set()
    before.join()
    after.join()


def run_in_child(priority: int, nice: int):
    context = multiprocessing.get_context('fork')
    results = context.Queue()
    child = context.Process(target=schedule_in_child, args=(priority, nice, results))
    child.start()
    outcome = results.get(timeout=30)
    child.join(timeout=30)
    assert child.exitcode == 0
    return outcome


def test_niceness_reaches_every_thread_including_later_ones():
    applied, outcome, threads, settings = run_in_child(0, 7)
    assert applied and outcome == 'nice 7'
    assert threads == 3 and len(settings) == 3
    assert all(nice == 7 for _, nice in settings)


CAP_SYS_NICE = 23  # bit of the capability in /proc/<pid>/status (linux/capability.h)
REFUSED_BY_THE_KERNEL = 3


def fifo_privileged(priority: int) -> bool:
    """What sched(7) requires of a process for SCHED_FIFO at `priority`: CAP_SYS_NICE, or
    an RLIMIT_RTPRIO soft limit of at least `priority`."""
    effective = re.search(r'^CapEff:\s*([0-9a-f]+)$', Path('/proc/self/status').read_text(), re.M)
    soft, _ = resource.getrlimit(resource.RLIMIT_RTPRIO)
    return (bool(int(effective.group(1), 16) >> CAP_SYS_NICE & 1)
            or soft == resource.RLIM_INFINITY or soft >= priority)


def fifo_granted(priority: int) -> bool:
    """Asked of the kernel by a process of its own: the privilege may be there and the
    request still refused (a container's or cgroup's realtime budget)."""
    probe = subprocess.run(
        [sys.executable, '-c', 'import os, sys\ntry:\n    os.sched_setscheduler(0, os.SCHED_FIFO, '
         f'os.sched_param({priority}))\nexcept PermissionError:\n    sys.exit({REFUSED_BY_THE_KERNEL})'],
        capture_output=True, text=True, timeout=30)
    assert probe.returncode in (0, REFUSED_BY_THE_KERNEL), probe.stderr
    return probe.returncode == 0


def test_sched_fifo_reaches_every_thread_exactly_where_the_kernel_grants_it():
    granted, privileged = fifo_granted(20), fifo_privileged(20)
    assert privileged or not granted, 'granted without CAP_SYS_NICE or RLIMIT_RTPRIO: a broken probe'
    applied, outcome, threads, settings = run_in_child(20, 0)
    print(f'\nSCHED_FIFO 20: privileged {privileged}, granted {granted}; the node says: {outcome}')
    assert threads == 3 and len(settings) == 3
    if granted:
        assert applied and outcome == 'SCHED_FIFO priority 20'
        assert all(policy == os.SCHED_FIFO for policy, _ in settings)
    else:
        assert not applied and outcome.startswith('SCHED_FIFO priority 20 refused (')
        assert 'ulimit -r 20' in outcome
        assert all(policy != os.SCHED_FIFO for policy, _ in settings)


def workers_in_child(results) -> None:
    """The scheduling of a worker started by a SCHED_FIFO 20 thread, and of one started
    by a time-sharing thread, each after below_the_creating_thread."""
    def worker(out):
        scheduling.below_the_creating_thread()
        out.append((os.sched_getscheduler(0), os.sched_getparam(0).sched_priority))

    seen = []
    for policy, priority in ((os.SCHED_OTHER, 0), (os.SCHED_FIFO, 20)):
        os.sched_setscheduler(0, policy, os.sched_param(priority))
        thread = threading.Thread(target=worker, args=(seen,))
        thread.start()
        thread.join()
    results.put(seen)


def test_a_planning_worker_runs_just_below_the_thread_that_started_it():
    """A realtime supervisor's urgent planning thread (cdpr_fdi.recovery_planning.planning): one SCHED_FIFO
    priority below its node's, so the node's thread takes the core back whenever it has
    work; under time-sharing it stays there."""
    if not fifo_granted(20):
        pytest.skip('SCHED_FIFO is not granted here: nothing to place below')
    context = multiprocessing.get_context('fork')
    results = context.Queue()
    child = context.Process(target=workers_in_child, args=(results,))
    child.start()
    seen = results.get(timeout=30)
    child.join(timeout=30)
    assert child.exitcode == 0
    assert seen == [(os.SCHED_OTHER, 0), (os.SCHED_FIFO, 19)]


def test_a_refusal_leaves_normal_scheduling_and_says_how_to_allow_it(monkeypatch):
    def refuse(*_args):
        raise PermissionError(1, 'Operation not permitted')
    monkeypatch.setattr(os, 'sched_setscheduler', refuse)
    applied, outcome = scheduling.apply_scheduling(50, 0)
    assert not applied
    assert outcome.startswith('SCHED_FIFO priority 50 refused') and 'ulimit -r 50' in outcome


def test_zero_asks_for_nothing():
    assert scheduling.apply_scheduling(0, 0) == (True, 'normal scheduling')


@pytest.mark.parametrize('priority, nice, name', [(100, 0, 'realtime_priority'), (-1, 0, 'realtime_priority'),
                                                  (True, 0, 'realtime_priority'), (0, 20, 'nice'),
                                                  (0, -21, 'nice'), (0, 1.5, 'nice')])
def test_out_of_range_values_name_the_parameter(priority, nice, name):
    with pytest.raises(ValueError, match=f'parameter {name}'):
        scheduling.apply_scheduling(priority, nice)


def scheduling_of(nodes) -> dict[str, dict]:
    return {node.name: {key: node.parameters[key] for key in ('realtime_priority', 'nice')
                        if key in node.parameters} for node in nodes}


def test_realtime_graph_puts_the_loop_first_as_configured(tmp_path):
    section = load_section(PAPER_ROBOT, 'scheduling')
    nodes = graph_nodes(settled_parameters('realtime'), str(tmp_path))
    settings = scheduling_of(nodes)
    assert set(settings) == set(CONTROL_LOOP) | set(FDI) | set(BACKGROUND)
    for name in CONTROL_LOOP:
        assert settings[name] == {'realtime_priority': section.integer('control_loop_priority')}
    for name in FDI:
        assert settings[name] == {'realtime_priority': section.integer('fdi_priority')}
    for name in BACKGROUND:
        assert settings[name] == {'nice': section.integer('background_nice')}
    # the loop first, then the FDI, then the rest
    assert section.integer('control_loop_priority') > section.integer('fdi_priority') > 0
    assert section.integer('background_nice') > 0


def test_lockstep_graph_leaves_scheduling_alone(tmp_path):
    nodes = graph_nodes(settled_parameters('lockstep'), str(tmp_path))
    assert all(not values for values in scheduling_of(nodes).values())


def test_a_bad_scheduling_value_names_the_key_and_the_file(tmp_path):
    config = yaml.safe_load(PAPER_ROBOT.read_text())
    config['scheduling'] = {'control_loop_priority': 120}
    path = tmp_path / 'robot.yaml'
    path.write_text(yaml.safe_dump(config))
    with pytest.raises(ConfigError, match=r'scheduling\.control_loop_priority') as error:
        build_scenario(ScenarioOptions(config=str(path), motions=str(MOTIONS))).node_parameters('realtime')
    assert str(path) in str(error.value)
