"""cdpr-bench run: how long one run takes, as a user waits for it.

The whole process of `cdpr-scenario --engine inprocess --fidelity elastic --motion along-2
--fail-cable 4` (bag, metrics and plots included; imports too) against the goal of
issue 24 (1.2 s; issue 16's was 1.5 s), and where its time goes, stage by stage in this
process: settling the run, the simulation, the bag, the report from the run in memory,
both as cdpr-scenario runs them (the report drawn by a forked process while the bag is
written) and, for comparison, the report read back from the bag (what cdpr-report does).
"""
from __future__ import annotations

import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from ..runs.engine import run_inprocess
from ..runs.metrics import RunSettings
from ..reports.report import run_of_recording, write_report, write_run_report
from ..scenario.command import ReportDrawer, metrics_of, record, record_beside_report
from ..runs.settle import ScenarioOptions, build_scenario

OPTIONS = ('--engine', 'inprocess', '--fidelity', 'elastic', '--motion', 'along-2', '--fail-cable', '4')
GOAL_S = 1.2
REPEATS = 3


def bench_run(config: str, out: str | Path, repeats: int = REPEATS) -> dict:
    out = Path(out)
    shutil.rmtree(out, ignore_errors=True)
    whole = []
    for index in range(repeats):
        start = time.monotonic()
        subprocess.run([sys.executable, '-m', 'cdpr_bringup.scenario.command', *OPTIONS, '--config', config,
                        '--quiet', '--out', str(out / f'whole-{index}')],
                       check=True, stdout=subprocess.DEVNULL, timeout=600)
        whole.append(time.monotonic() - start)
    stages: dict[str, list[float]] = {}

    def timed(name, call, *args):
        start = time.perf_counter()
        result = call(*args)
        stages.setdefault(name, []).append(time.perf_counter() - start)
        return result

    for index in range(repeats):
        folder = out / f'stages-{index}'
        folder.mkdir(parents=True)
        scenario = timed('settle_s', build_scenario, ScenarioOptions(
            config=config, motion='along-2', fail_cables=[4], fidelity='elastic'))
        recording = timed('simulate_s', run_inprocess, scenario)
        metrics = metrics_of(scenario, recording, 0.0, False)
        timed('bag_s', record, recording, folder / 'bag', '/cdpr', scenario.marker_frame())
        settings = RunSettings(scenario.robot, scenario.fdi, scenario.recovery, 'bench')
        timed('report_from_memory_s', lambda: write_run_report(run_of_recording(
            recording, settings, metrics['failure_time_s'], metrics['true_broken_cables']),
            folder / 'bag', folder / 'plots'))
        timed('report_from_bag_s', write_report, folder / 'bag', folder / 'bag-plots', settings)
        timed('bag_beside_report_s', record_beside_report, ReportDrawer(), recording, settings,
              metrics, folder / 'beside', '/cdpr', scenario.marker_frame())
    figures = {'repeats': repeats, 'whole_process_best_s': min(whole), 'whole_process_median_s': float(np.median(whole)),
               'goal_s': GOAL_S, 'robot_time_s': float(recording.time_s[-1]),
               'load_average_1min': os.getloadavg()[0]}
    figures.update({name: min(values) for name, values in stages.items()})
    return figures


def table(figures: dict) -> list[str]:
    best, goal = figures['whole_process_best_s'], figures['goal_s']
    return ([f'  {key:<28} {value:8.3f}' for key, value in figures.items()]
            + [f'  whole process, best of {figures["repeats"]}: {best:.2f} s; goal <= {goal:g} s: '
               + ('met' if best <= goal else 'NO')])
