"""cdpr-bench cycle: the in-process engine's speed, and where each µs of a cycle goes.

On the elastic circle with the supervisor (the figure `cdpr-bench graph` reports against
its goal of 50x real time), for each kernel of the elastic sub-steps
(cdpr_twin.models.elastic_substeps: compiled by numba, pure Python), side by side in one
process: simulated seconds per wall second, the best of its repeats, and the µs of a
cycle; then, on one more run per kernel, the µs per cycle of each stage, timed around
the calls the engine makes (the timer's own cost, ~0.2 µs a call, included).
"""
from __future__ import annotations

import dataclasses
import os
import time
from contextlib import ExitStack, contextmanager

from cdpr_control.control.setpoints import Setpoints
from cdpr_fdi.supervision.supervisor import Supervisor
from cdpr_twin.models.elastic_model import ElasticCableRobot
from cdpr_control.kernels import KERNELS
from cdpr_twin.models.elastic_substeps import kernel
from cdpr_twin.models.plant import PlantSimulator
from cdpr_twin.models.twin import DigitalTwin

from ..runs.engine import run_inprocess
from ..runs.settle import ScenarioOptions, build_scenario

MOTION = 'circle'
REPEATS = 3
GOAL_REALTIME_FACTOR = 50.0
# stage → the call the engine makes for it (the plant's step includes its sub-steps)
STAGES = {'plant_step': (PlantSimulator, 'step'), 'elastic_substeps': (ElasticCableRobot, 'integrate'),
          'plant_measure': (PlantSimulator, 'measure'), 'controller': (Setpoints, 'command'),
          'twin': (DigitalTwin, 'step'), 'supervisor': (Supervisor, 'update')}


@contextmanager
def timed(owner, name: str, spent: dict, stage: str):
    """`owner.name` adds its wall time to spent[stage] while the context lasts."""
    original = getattr(owner, name)

    def call(*args, **kwargs):
        start = time.perf_counter()
        try:
            return original(*args, **kwargs)
        finally:
            spent[stage] += time.perf_counter() - start

    setattr(owner, name, call)
    try:
        yield
    finally:
        setattr(owner, name, original)


def stage_us(scenario) -> dict[str, float]:
    """µs per cycle of each stage on one run, and of the whole cycle."""
    spent = dict.fromkeys(STAGES, 0.0)
    with ExitStack() as stack:
        for stage, (owner, name) in STAGES.items():
            stack.enter_context(timed(owner, name, spent, stage))
        start = time.perf_counter()
        cycles = run_inprocess(scenario).time_s.size
        spent['cycle'] = time.perf_counter() - start
    return {stage: seconds / cycles * 1e6 for stage, seconds in spent.items()}


def bench_cycle(config: str, repeats: int = REPEATS) -> dict:
    base = build_scenario(ScenarioOptions(config=config, motion=MOTION, fidelity='elastic'))
    scenarios = {name: dataclasses.replace(base, plant=dataclasses.replace(base.plant, kernel=name))
                 for name in KERNELS}
    for scenario in scenarios.values():   # numba compiles (or loads its cache) once
        run_inprocess(dataclasses.replace(scenario, options=dataclasses.replace(
            scenario.options, duration_s=10 * scenario.period_s)))
    best = dict.fromkeys(KERNELS, float('inf'))
    for _ in range(repeats):    # alternated: a change of load falls on both
        for name, scenario in scenarios.items():
            start = time.perf_counter()
            cycles = run_inprocess(scenario).time_s.size
            best[name] = min(best[name], time.perf_counter() - start)
    figures: dict = {'kernels': {name: kernel(name).name for name in KERNELS}, 'cycles': cycles,
                     'goal_realtime_factor': GOAL_REALTIME_FACTOR, 'body': base.robot.body.kind}
    for name in KERNELS:
        figures[f'{name}_realtime_factor'] = cycles * base.period_s / best[name]
        figures[f'{name}_cycle_us'] = best[name] / cycles * 1e6
    figures['compiled_speedup'] = best['python'] / best['compiled']
    for name, scenario in scenarios.items():
        figures[f'{name}_stage_us'] = stage_us(scenario)
    figures['load_average_1min'] = os.getloadavg()[0]
    return figures


def table(figures: dict) -> list[str]:
    lines = [f'  {"kernel of the elastic sub-steps":<34} {"x real time":>11} {"µs/cycle":>9}  '
             f'goal >= {figures["goal_realtime_factor"]:g}x']
    for name in KERNELS:
        factor = figures[f'{name}_realtime_factor']
        ran = figures['kernels'][name]
        lines.append(f'  {name + ("" if ran == name else f" (ran {ran}: numba missing)"):<34} '
                     f'{factor:11.1f} {figures[f"{name}_cycle_us"]:9.1f}  '
                     f'{"met" if factor >= figures["goal_realtime_factor"] else "NO"}')
    lines.append(f'  compiled / python speed: {figures["compiled_speedup"]:.2f}; '
                 f'{figures["cycles"]} cycles of {MOTION}, best of {REPEATS}')
    if figures['platform']:
        lines.append('  a platform: the kernels above are the point mass\'s; its own models run compiled in '
                     'both (cdpr_control.platform.substeps)')
    lines.append(f'  {"µs per cycle by stage (one timed run each)":<44}'
                 + ' '.join(f'{name:>9}' for name in KERNELS))
    for stage in [*STAGES, 'cycle']:
        lines.append(f'    {stage:<42}' + ' '.join(
            f'{figures[f"{name}_stage_us"][stage]:9.1f}' for name in KERNELS))
    lines.append(f'  machine load average (1 min) at the end: {figures["load_average_1min"]}')
    return lines
