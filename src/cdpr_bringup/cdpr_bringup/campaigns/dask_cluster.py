"""cdpr-campaign --scheduler on Dask distributed: the task a worker runs, the client
that hands the runs to a scheduler's workers, and a cluster on this machine as on a real
one (a `dask scheduler` process and `dask worker` processes of one thread each) for the
tests and cdpr-bench campaign. Imported only when a campaign has a --scheduler: the local
pool, the default, does not pay for Dask."""
from __future__ import annotations

import contextlib
import json
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

from distributed import Client, as_completed, get_worker

from .campaign_run import SCHEDULER_CONNECT_TIMEOUT_S, Run, SchedulerUnreachable, run_scenario

# run_scenario redirects this process's stdout and stderr: a worker with several threads
# runs one scenario at a time.
ONE_RUN_PER_PROCESS = threading.Lock()


def run_on_dask_worker(run: Run, run_dir: Path) -> dict:
    """Dask task: run_scenario on the worker this runs on, named by its address."""
    with ONE_RUN_PER_PROCESS:
        return run_scenario(run, run_dir, worker=get_worker().address)


@contextlib.contextmanager
def dask_scheduler(address: str, task=None):
    """(submit, as_completed) of the workers of the Dask scheduler at `address`, submit(*args)
    running task(*args) on one (default: a campaign's run, run_on_dask_worker)."""
    try:
        client = Client(address, timeout=SCHEDULER_CONNECT_TIMEOUT_S)
    except Exception as err:  # noqa: BLE001 - a timeout (OSError), a malformed address
        # (ValueError), another server's answer (anything): no scheduler there, in one line
        said = str(err).strip().splitlines()
        raise SchedulerUnreachable(
            f'--scheduler {address}: no Dask scheduler answered ({type(err).__name__}'
            f'{": " + said[0][:200] if said else ""})') from err
    # Closing the client (also on Ctrl-C) releases the runs not started; those running
    # end on their workers and write their metrics.json.
    with client:
        # pure=False: a run is an experiment, never a cached result
        yield (lambda *args: client.submit(task or run_on_dask_worker, *args, pure=False)), \
            as_completed


# Bounds on the cluster's start (the workers import numpy & co.) and on each process's stop.
START_LIMIT_S = 60.0
STOP_LIMIT_S = 10.0


def _dask(*arguments: str, log) -> subprocess.Popen:
    # this interpreter's dask CLI: the workers import cdpr_bringup from the same environment
    return subprocess.Popen([sys.executable, '-m', 'dask', *arguments], stdout=log,
                            stderr=subprocess.STDOUT)


def _stop(process: subprocess.Popen) -> None:
    process.terminate()
    try:
        process.wait(timeout=STOP_LIMIT_S)
    except subprocess.TimeoutExpired:
        process.kill()
        process.wait(timeout=STOP_LIMIT_S)


@contextlib.contextmanager
def local_dask_cluster(workers: int, log_dir: str | Path | None = None):
    """Yield the address (tcp://127.0.0.1:PORT) of a scheduler with `workers` workers
    connected; every process is stopped on the way out. Their output goes to
    log_dir/scheduler.log and log_dir/worker-<i>.log (default: a temporary folder)."""
    with contextlib.ExitStack() as stack:
        folder = Path(log_dir or stack.enter_context(tempfile.TemporaryDirectory(prefix='cdpr-dask-')))
        folder.mkdir(parents=True, exist_ok=True)
        # The scheduler takes a free port and says which in this file: no port to guess.
        scheduler_file = folder / 'scheduler.json'
        scheduler_file.unlink(missing_ok=True)
        processes = []
        stack.callback(lambda: [_stop(process) for process in reversed(processes)])
        scheduler_log = stack.enter_context(open(folder / 'scheduler.log', 'w'))
        processes.append(_dask('scheduler', '--host', '127.0.0.1', '--port', '0', '--no-dashboard',
                               '--scheduler-file', str(scheduler_file), log=scheduler_log))
        for index in range(workers):
            worker_log = stack.enter_context(open(folder / f'worker-{index}.log', 'w'))
            processes.append(_dask('worker', '--scheduler-file', str(scheduler_file),
                                   '--host', '127.0.0.1', '--nworkers', '1', '--nthreads', '1',
                                   '--no-nanny', '--no-dashboard', '--name', f'worker-{index}',
                                   '--local-directory', str(folder / f'worker-{index}'),
                                   log=worker_log))
        deadline = time.monotonic() + START_LIMIT_S
        address = None
        while address is None:
            if time.monotonic() > deadline or processes[0].poll() is not None:
                raise RuntimeError(f'dask scheduler did not start: {folder / "scheduler.log"}')
            time.sleep(0.1)
            with contextlib.suppress(FileNotFoundError, ValueError):  # not yet (all) written
                address = json.loads(scheduler_file.read_text())['address']
        with Client(address, timeout=max(deadline - time.monotonic(), 1.0)) as client:
            client.wait_for_workers(workers, timeout=max(deadline - time.monotonic(), 1.0))
        yield address
