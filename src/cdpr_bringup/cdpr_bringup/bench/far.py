"""cdpr-bench far: each detector's operating point from its false-alarm rate.

Per plant, failure-free runs (every named motion of the motions file, both directions,
plant seeds from FIRST_SEED on, the calibration's were 0-2) until `hours` of simulated
motion, each with one push drawn from its seed (PUSH_FORCE_N for PUSH_DURATION_S, any
direction, anywhere in the run) and the plant's resolver noise (elastic, field); and the
campaign's failure matrix (campaign.build_matrix: every cable × motion × direction, each
cable breaking at an instant drawn from the run's seed). As cdpr-bench roc does, each
run is simulated once with nothing judging it and every detector at every sensitivity
(a factor on the calibrated ε, or the CUSUM's h, limit and ε) judges the recording
offline as the supervisor does (roc.judge).

What is counted on the failure-free runs (roc.episode_counts): alarm episodes (alarm
ticks less than roc.EPISODE_GAP_S apart are one), each once; an episode in which the
supervisor's wrench balance reported a disturbance and no cable was named is a push and
left out; every other episode is a false alarm, named or only warned of (the detector
alarmed on a healthy robot). Per plant × detector × sensitivity: k false alarms in T
hours, k/T per hour with its exact Poisson 95 % upper bound, ARL₀ = T/k (the mean time
between false alarms) and its 95 % lower bound; and at the same sensitivity the delay
from each failure's instant (the field plant's electromagnet signal, as the paper counts)
to its naming: median, p95, max, and the failures missed within roc.JUDGED_AFTER_FAILURE_S.

Runs go to local processes (`jobs`) or to the workers of a Dask scheduler
(campaign.worker_pool). Writes far.csv (a row per run × detector × sensitivity) and
far.png (delay against ARL₀ per detector and plant). cdpr-calibrate --from-far chooses
thresholds from far.csv (`choose`).
"""
from __future__ import annotations

import sys
import time
import zlib
from pathlib import Path

import numpy as np

from cdpr_control.geometry.motions import motion_names
from cdpr_control.setup.robot_file import load_robot
from cdpr_fdi.detectors import DETECTORS

from .fdi import fmt
from .roc import FACTORS, FAILURE_SEEDS, RocRun, judged_run, write_rows
from ..campaigns.campaign import DIRECTIONS, build_matrix, progress_bar, worker_pool
from ..campaigns.campaign_run import SchedulerUnreachable
from ..campaigns.operating_point import far_points
from ..cli import UsageError
from ..paths import DEFAULT_MOTIONS, config_file
from ..runs.settle import ScenarioOptions, build_scenario

FIRST_SEED = 100
PUSH_FORCE_N = (10.0, 30.0)
PUSH_DURATION_S = (0.05, 0.5)
SECONDS_PER_HOUR = 3600.0


def drawn_push(seed: int, motion: str, reverse: bool, fidelity: str,
               duration_s: float) -> tuple[float, float, float, float, float]:
    """A push for a failure-free run, as ScenarioOptions.pushes takes it: its force uniform
    in PUSH_FORCE_N along a direction uniform on the sphere, its length in PUSH_DURATION_S,
    starting anywhere it ends within the run; drawn from the run's seed and place (not
    Python's salted hash), so the same command pushes the same."""
    key = zlib.crc32(f'{motion}/{reverse}/{fidelity}'.encode())
    rng = np.random.default_rng([seed, key])
    direction = rng.normal(size=3)
    force = rng.uniform(*PUSH_FORCE_N) * direction / np.linalg.norm(direction)
    length = rng.uniform(*PUSH_DURATION_S)
    return (float(rng.uniform(0.0, duration_s - length)), float(length), *force.tolist())


def far_runs(config: str, plants: list[str], hours: float, factors=FACTORS,
             motions_file: str = DEFAULT_MOTIONS, motions: list[str] | None = None,
             cables: list[int] | None = None, failure_seeds=FAILURE_SEEDS) -> list[RocRun]:
    """Per plant, failure-free pushed runs (seed after seed, every motion both directions)
    until `hours` of motion, then the failure matrix (every cable, a random instant each).
    Each scenario is settled here once, so a refused option is said before a worker starts."""
    motions = motions or motion_names(config_file(motions_file))
    cables = cables or list(range(1, load_robot(config_file(config)).cable_count + 1))
    runs = []
    for plant in plants:
        duration_s = {(motion, reverse): build_scenario(ScenarioOptions(
                          config=config, motions=motions_file, motion=motion, reverse=reverse,
                          fidelity=plant)).duration_s
                      for motion in motions for reverse in (False, True)}
        simulated_s, seed = 0.0, FIRST_SEED
        while simulated_s < hours * SECONDS_PER_HOUR:
            for (motion, reverse), length_s in duration_s.items():
                if simulated_s >= hours * SECONDS_PER_HOUR:
                    break
                runs.append(RocRun(config, motions_file, plant, motion, reverse, None, seed, tuple(factors),
                                   pushes=(drawn_push(seed, motion, reverse, plant, length_s),)))
                simulated_s += length_s
            seed += 1
    # one simulation per failure, judged by every detector: the matrix's detector is a label
    matrix = build_matrix(motions, cables, DIRECTIONS, plants, DETECTORS[:1], failure_seeds,
                          failure_free=False, random_instants=True)
    runs += [RocRun(config, motions_file, run.fidelity, run.motion, run.direction == 'reverse',
                    run.cable, run.seed, tuple(factors), fail_at_fraction=run.fail_at_fraction)
             for run in matrix]
    return runs


def judged(runs: list[RocRun], jobs: int | None, scheduler: str | None) -> list[dict]:
    """Every run simulated and judged (roc.judged_run) on `jobs` local processes or the
    workers of the Dask `scheduler`; their rows in the order of `runs`, a progress line on
    stderr per tenth of them."""
    rows, start = {}, time.monotonic()
    try:
        with worker_pool(jobs, scheduler, judged_run) as (submit, as_they_complete):
            futures = {submit(run): index for index, run in enumerate(runs)}
            for done, future in enumerate(as_they_complete(futures), start=1):
                rows[futures[future]] = future.result()
                if done == len(runs) or done % max(len(runs) // 10, 1) == 0:
                    eta_s = (time.monotonic() - start) / done * (len(runs) - done)
                    print(progress_bar(done, len(runs), eta_s), file=sys.stderr, flush=True)
    except SchedulerUnreachable as err:
        raise UsageError(str(err)) from None   # one line, as cdpr-campaign says it
    return [row for index in range(len(runs)) for row in rows[index]]


def bench_far(config: str, out_dir: str | Path, plants: list[str], hours: float,
              jobs: int | None = None, scheduler: str | None = None, factors=FACTORS, **matrix) -> dict:
    """Judge the runs (far_runs; `matrix`: its motions_file, motions, cables), write far.csv
    and far.png into `out_dir`; the figures per plant × detector and sensitivity."""
    rows = judged(far_runs(config, plants, hours, factors, **matrix), jobs, scheduler)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    write_rows(rows, out / 'far.csv')
    points = far_points(rows)
    plot_far(points, out / 'far.png')
    return points


def plot_far(points: dict, path: Path) -> None:
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    plants = sorted({plant for plant, _ in points})
    figure, axes = plt.subplots(1, len(plants), figsize=(6 * len(plants), 4.5), squeeze=False)
    for axis, plant in zip(axes[0], plants):
        for detector in sorted(detector for of, detector in points if of == plant):
            shown = [p for p in points[(plant, detector)] if p['delay_p95_ms'] is not None]
            # every point at its ARL₀'s 95 % lower bound: defined with no false alarm too
            axis.plot([p['arl0_lower_h'] for p in shown], [p['delay_p95_ms'] for p in shown], 'o-',
                      label=f'{detector}, p95')
            axis.plot([p['arl0_lower_h'] for p in shown], [p['delay_median_ms'] for p in shown], 'x--',
                      label=f'{detector}, median')
            for p in shown:
                axis.annotate(f'×{p["factor"]:g}', (p['arl0_lower_h'], p['delay_p95_ms']), fontsize=7,
                              textcoords='offset points', xytext=(3, 3))
        axis.set_xscale('log')
        axis.set_xlabel('ARL₀, mean time between false alarms (h, 95 % lower bound)')
        axis.set_ylabel('detection delay (ms)')
        axis.set_title(f'{plant} plant')
        axis.grid(True, alpha=0.3)
        axis.legend(fontsize=8)
    figure.suptitle('Detection delay against ARL₀ (labels: factor on the calibrated thresholds)')
    figure.tight_layout()
    figure.savefig(path, dpi=110)
    plt.close(figure)


KEYS = ('factor', 'epsilon_nm', 'cusum_h', 'false_alarms', 'false_alarms_per_hour', 'upper_per_hour',
        'arl0_h', 'pushes_named', 'delay_median_ms', 'delay_p95_ms', 'delay_max_ms', 'missed')


def table(points: dict) -> list[str]:
    lines = []
    for (plant, detector), curve in points.items():
        first = curve[0]
        lines.append(f'  {plant} plant, {detector}: {first["failure_free_hours"]:.2f} h failure-free '
                     f'({first["pushes_applied"]} pushes), {first["failure_runs"]} failures')
        lines.append('    ' + ' '.join(f'{key.replace("_ms", " ms").replace("_per_hour", "/h"):>15}'
                                       for key in KEYS))
        for point in curve:
            lines.append('    ' + ' '.join(f'{fmt(point[key]):>15}' for key in KEYS))
    return lines
