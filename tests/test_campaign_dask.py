"""cdpr-campaign --scheduler: a real `dask scheduler` and two `dask worker` processes on
127.0.0.1 run a tiny campaign; interrupted with Ctrl-C, the same command runs only what
is missing, and once all is done nothing; a scheduler that is not there is one line."""
from __future__ import annotations

import csv
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest
from distributed import Client

from cdpr_bringup.campaigns.campaign import main
from cdpr_bringup.campaigns import dask_cluster
from cdpr_bringup.campaigns.dask_cluster import local_dask_cluster

from conftest import CONFIG_DIR, MOTIONS

pytestmark = pytest.mark.cluster

# Four short failure-free runs (about 7 s of motion each) for two single-thread workers.
TINY = ['--motion-set', 'along-4,along-1', '--cables', '', '--directions', 'forward,reverse',
        '--fidelities', 'rigid', '--detectors', 'threshold',
        '--config', str(CONFIG_DIR / 'paper_robot.yaml'), '--motions', str(MOTIONS)]
RUNS = 4
WAIT_LIMIT_S = 120.0  # a loaded machine: the workers import the scenario first


def wait_for(condition, what: str, limit_s: float = WAIT_LIMIT_S) -> None:
    deadline = time.monotonic() + limit_s
    while not condition():
        assert time.monotonic() < deadline, f'{what}: not within {limit_s:.0f} s'
        time.sleep(0.05)


def finished(out):
    """{run folder name: mtime of its metrics.json} of the runs that wrote one."""
    return {path.parent.name: path.stat().st_mtime_ns for path in (out / 'runs').glob('*/metrics.json')}


def started(out):
    return {path.name for path in (out / 'runs').glob('*')} if (out / 'runs').exists() else set()


def test_a_campaign_on_a_dask_cluster_resumes_after_ctrl_c(tmp_path):
    out = tmp_path / 'campaign'
    with local_dask_cluster(2, tmp_path / 'dask') as address:
        with Client(address, timeout=10) as client:
            workers = set(client.scheduler_info()['workers'])
        assert len(workers) == 2
        argv = [*TINY, '--scheduler', address, '--out', str(out)]

        # Ctrl-C's default action even where this session was started with SIGINT ignored
        # (a background job of a shell without job control): Python then installs no
        # KeyboardInterrupt handler, and the campaign would run to its end
        campaign = subprocess.Popen([str(Path(sys.executable).parent / 'cdpr-campaign'), *argv],
                                    stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                                    preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
        try:
            # Ctrl-C once the first runs started: with one run at a time per worker, the
            # others have not
            wait_for(lambda: started(out) or campaign.poll() is not None, 'a run started')
            assert campaign.poll() is None, campaign.communicate()
            campaign.send_signal(signal.SIGINT)
            _, said = campaign.communicate(timeout=WAIT_LIMIT_S)
        finally:
            campaign.kill()
            campaign.wait(timeout=10)
        assert campaign.returncode == 130, said
        assert said.strip().splitlines()[-1] == ('cdpr-campaign: interrupted; the same command '
                                                  'runs what is missing')
        # The runs under way end on their workers and write their metrics.json.
        wait_for(lambda: set(finished(out)) == started(out), 'the started runs finished')
        before = finished(out)
        assert 1 <= len(before) < RUNS

        assert main(argv) == 0
        after = finished(out)
        assert len(after) == RUNS
        assert {run: after[run] for run in before} == before, 'a finished run ran again'
        assert main(argv) == 0
        assert finished(out) == after, 'a finished campaign ran again'

    with open(out / 'summary.csv') as stream:
        rows = list(csv.DictReader(stream))
    assert len(rows) == RUNS
    assert all(row['error'] == '' and int(row['cycles']) > 0 for row in rows)
    # which worker ran which run is the scheduler's choice; that each is one of ours is not
    assert {row['worker'] for row in rows} <= workers


def free_port() -> int:
    with socket.socket() as probe:
        probe.bind(('127.0.0.1', 0))
        return probe.getsockname()[1]


def test_a_scheduler_that_is_not_there_is_one_line(tmp_path, capsys, monkeypatch):
    # Dask's client retries a refused connection until its timeout: 10 s shipped
    monkeypatch.setattr(dask_cluster, 'SCHEDULER_CONNECT_TIMEOUT_S', 1.0)
    address = f'tcp://127.0.0.1:{free_port()}'
    assert main([*TINY, '--scheduler', address, '--out', str(tmp_path)]) == 1
    said = capsys.readouterr().err.strip().splitlines()
    assert len(said) == 1 and said[0].startswith(f'cdpr-campaign: --scheduler {address}: '), said
    assert not (tmp_path / 'runs').exists()
