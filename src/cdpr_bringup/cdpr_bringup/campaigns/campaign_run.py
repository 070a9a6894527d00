"""One run of a campaign: what it is (`Run`, its cdpr-scenario command line) and how a
worker does it (`run_scenario`), whichever runs it — the campaign's local pool or a Dask
worker (dask_cluster). Both import this; neither the other's module."""
from __future__ import annotations

import contextlib
import os
import re
import time
import traceback
from dataclasses import dataclass
from pathlib import Path

from ..paths import DEFAULT_MOTIONS, DEFAULT_ROBOT


# Written by the worker into the run's folder before the run: who ran it, also for the
# rows of runs a resumed campaign skips, and of a run whose worker died.
WORKER_FILE = 'worker.txt'
# A --scheduler that does not answer within this is reported, not waited for.
SCHEDULER_CONNECT_TIMEOUT_S = 10.0


@dataclass(frozen=True)
class Run:
    """One scenario run of the campaign; `cable` is 1-based, None for a failure-free run."""

    motion: str
    direction: str
    cable: int | None
    fidelity: str
    detector: str
    seed: int
    fail_at_fraction: float
    config: str = DEFAULT_ROBOT
    motions_file: str = DEFAULT_MOTIONS
    engine: str = 'inprocess'
    epsilon_nm: float | None = None
    calibration: str | None = None

    @property
    def id(self) -> str:
        failure = (f'cable{self.cable}_at{self.fail_at_fraction:.3f}' if self.cable is not None
                   else 'no-failure')
        return f'{self.motion}_{self.direction}_{failure}_{self.fidelity}_{self.detector}_seed{self.seed}'

    def scenario_argv(self, out_dir: Path) -> list[str]:
        argv = ['--config', self.config, '--motions', self.motions_file, '--motion', self.motion,
                '--fidelity', self.fidelity, '--detector', self.detector, '--seed', str(self.seed),
                '--engine', self.engine, '--quiet', '--no-plots', '--out', str(out_dir)]
        if self.direction == 'reverse':
            argv.append('--reverse')
        if self.cable is not None:
            argv += ['--fail-cable', str(self.cable), '--fail-at-fraction', str(self.fail_at_fraction)]
        if self.epsilon_nm is not None:
            argv += ['--epsilon', str(self.epsilon_nm)]
        if self.calibration is not None:
            argv += ['--calibration', self.calibration]
        if self.engine == 'graph':
            # Graph runs in parallel share the DDS domain: each gets its own namespace.
            argv += ['--namespace', '/cdpr_' + re.sub(r'\W', '_', self.id)]
        return argv


def run_scenario(run: Run, run_dir: Path, worker: str | None = None) -> dict:
    """Worker: one `cdpr-scenario` in this process, its output in run_dir/scenario.log,
    the name of the `worker` running it (default local:<pid>) in run_dir/WORKER_FILE.

    Returns {'error': None or why it failed, 'wall_time_s'}; never raises, so one bad run
    does not stop the campaign.
    """
    from ..scenario import command  # imported in the worker: the parent never loads rclpy
    run_dir.mkdir(parents=True, exist_ok=True)
    (run_dir / WORKER_FILE).write_text((worker or f'local:{os.getpid()}') + '\n')
    start = time.monotonic()
    error = None
    with open(run_dir / 'scenario.log', 'w') as log, \
            contextlib.redirect_stdout(log), contextlib.redirect_stderr(log):
        try:
            status = command.main(run.scenario_argv(run_dir))
            if status:
                error = f'cdpr-scenario exited with {status}'
        except SystemExit as exit_:  # argparse rejected the arguments
            error = f'cdpr-scenario exited with {exit_.code}'
        except Exception as err:  # noqa: BLE001 - recorded in the row, the campaign goes on
            traceback.print_exc()
            error = f'{type(err).__name__}: {err}'
    if error and error.startswith('cdpr-scenario exited'):
        # its last line says why (a user error is one line)
        said = (run_dir / 'scenario.log').read_text().strip().splitlines()
        error += f': {said[-1]}' if said else ''
    return {'error': error, 'wall_time_s': time.monotonic() - start}


class SchedulerUnreachable(Exception):
    """--scheduler names an address where no Dask scheduler answered."""
