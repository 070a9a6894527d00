"""cdpr-bench campaign: simulated hours per wall hour of cdpr-campaign --scheduler on a
Dask scheduler and 1, 2, … single-thread workers started on this machine (dask_cluster).

The same small campaign each time, from scratch: cable 4 breaking at the paper's instant
on the four motions along it, and the same motions failure-free (forward, one seed, the
threshold detector). Wall time is the campaign's, once the workers are connected;
simulated time is the cycles every run ran.
"""
from __future__ import annotations

import shutil
import time
from pathlib import Path

from .fdi import fmt
from ..campaigns.campaign import SECONDS_PER_HOUR, build_matrix, run_campaign
from ..campaigns.dask_cluster import local_dask_cluster

MOTIONS = ('along-1', 'along-2', 'along-3', 'along-4')
CABLE = 4


def bench_campaign(config: str, out: str | Path, fidelity: str, workers: list[int]) -> dict:
    """{worker count: figures} of the campaign run on that many workers."""
    runs = build_matrix(list(MOTIONS), [CABLE], directions=('forward',), fidelities=(fidelity,),
                        detectors=('threshold',), config=config)
    figures = {}
    for count in workers:
        folder = Path(out) / f'workers-{count}'
        shutil.rmtree(folder, ignore_errors=True)  # from scratch: a resumed one would skip all
        with local_dask_cluster(count, folder / 'dask') as address:
            start = time.monotonic()
            rows = run_campaign(runs, folder, scheduler=address, show_progress=False)
            wall_s = time.monotonic() - start
        simulated_s = sum(row['cycles'] * row['control_period_s'] for row in rows
                          if row['error'] is None)
        figures[count] = {
            'runs': len(rows),
            'errors': sum(row['error'] is not None for row in rows),
            'workers_used': len({row['worker'] for row in rows}),
            'simulated_h': simulated_s / SECONDS_PER_HOUR,
            'wall_s': wall_s,
            'simulated_h_per_wall_h': simulated_s / wall_s,
        }
    return figures


def table(figures: dict) -> list[str]:
    keys = ('runs', 'errors', 'workers_used', 'simulated_h', 'wall_s', 'simulated_h_per_wall_h')
    lines = [f'  {"workers":<24} ' + ' '.join(f'{count:>10}' for count in figures)]
    lines += [f'  {key:<24} ' + ' '.join(f'{fmt(figures[count][key]):>10}' for count in figures)
              for key in keys]
    return lines
