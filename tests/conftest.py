"""Shared fixtures: the shipped robot configs, and a private ROS domain per session."""
from __future__ import annotations

import contextlib
import faulthandler
import functools
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from cdpr_msgs_py.dds import use_shipped_setup

REPO = Path(__file__).resolve().parents[1]
CONFIG_DIR = REPO / 'src' / 'cdpr_bringup' / 'config'
PAPER_ROBOT = CONFIG_DIR / 'robots' / 'paper_robot.yaml'
EIGHT_CABLE_ROBOT = CONFIG_DIR / 'robots' / 'eight_cable_robot.yaml'
MOTIONS = CONFIG_DIR / 'motions.yaml'


# No test may take longer (s), setup and teardown included. A test stuck in C code that
# holds the GIL (a DDS start that spins) is beyond pytest's reach; faulthandler's
# watchdog thread is not: it prints every thread's stack and ends the session, so
# `make test` can fail but cannot hang.
TEST_LIMIT_S = 600.0


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_protocol(item, nextitem):
    faulthandler.dump_traceback_later(TEST_LIMIT_S, exit=True)
    yield
    faulthandler.cancel_dump_traceback_later()


def pytest_configure(config):
    # One DDS domain per test session so parallel sessions never see each other's graph.
    os.environ.setdefault('ROS_DOMAIN_ID', str(1 + os.getpid() % 101))
    # where the venv's packages are indexed, as `make test` and the venv's activate say
    os.environ.setdefault('AMENT_PREFIX_PATH', sys.prefix)
    use_shipped_setup()


# Zero-size port segments as a process killed mid-creation leaves them: 7000 is the
# shared-memory discovery port of every domain.
STALE = ('fastdds_port7000',)


def settled_parameters(clock_mode: str = 'lockstep', **options) -> dict[str, dict]:
    """Per node, the parameters cdpr-scenario gives it for the paper robot's run that
    `options` (ScenarioOptions' fields) describe."""
    from cdpr_bringup.scenario_setup import ScenarioOptions, build_scenario
    return build_scenario(ScenarioOptions(config=str(PAPER_ROBOT), motions=str(MOTIONS),
                                          **options)).node_parameters(clock_mode)


@functools.cache
def private_shm_allowed() -> bool:
    probe = subprocess.run(['unshare', '-m', 'sh', '-c', 'mount -t tmpfs tmpfs /dev/shm'],
                           capture_output=True, timeout=10)
    return probe.returncode == 0


needs_private_shm = pytest.mark.skipif(
    not private_shm_allowed(), reason='unshare -m with a tmpfs /dev/shm is not allowed here '
                                      '(needs root or user namespaces)')


def in_private_shm(command: list[str], stale: tuple[str, ...] = STALE) -> list[str]:
    """`command` in a private /dev/shm holding `stale` zero-size segments; it lists
    /dev/shm on its way out."""
    plant = ' '.join(f': > /dev/shm/{name};' for name in stale)
    script = (f'mount -t tmpfs tmpfs /dev/shm && {plant} "$@"; code=$?; '
              f'echo "shm: $(ls /dev/shm | tr "\\n" " ")"; exit $code')
    return ['unshare', '-m', 'sh', '-c', script, 'sh', *command]


def wait_until_the_plant_runs(lines: list[str], timeout_s: float) -> None:
    """Until a started graph's plant logs that it starts its run (the launcher's log
    lines gathered in `lines`): the start handshake is over, the ticks flow."""
    deadline = time.monotonic() + timeout_s
    while not any(line.startswith('[plant_simulator]') and 'starting' in line for line in lines):
        assert time.monotonic() < deadline, 'the plant did not start its run'
        time.sleep(0.05)


@contextlib.contextmanager
def judged_if_the_loop_kept_its_period(lines: list[str]):
    """Checks of a realtime graph run (its launcher's log `lines`): a failed one is a
    failure, unless the plant logged that its loop did not keep its period — a machine
    too slow or too loaded for five Python nodes at 500 Hz on its cores, where late
    messages and a starved recorder say nothing about the graph. Then the test is
    skipped, saying so; `cdpr-bench graph` measures what the machine sustains."""
    try:
        yield
    except AssertionError as failed:
        slow = next((line for line in lines if line.startswith('[plant_simulator] [ERROR]')
                     and 'does not keep its period' in line), None)
        if slow is None:
            raise
        pytest.skip(f'not judged, the machine did not keep the realtime loop ({slow.split("]: ")[-1]}); '
                    f'the check that failed: {str(failed).splitlines()[0]}')


def load_robot(path):
    # imported here: cdpr_msgs_py's tests share this file, and that package (colcon test)
    # has no cdpr_control
    from cdpr_control.robot import load_robot
    return load_robot(path)


@pytest.fixture(scope='session')
def paper_robot():
    return load_robot(PAPER_ROBOT)


@pytest.fixture(scope='session', params=[PAPER_ROBOT, EIGHT_CABLE_ROBOT], ids=['paper', 'eight_cable'])
def robot(request):
    """Every model test runs on the paper robot and on an irregular 8-cable robot."""
    return load_robot(request.param)


# ---- shared helpers for the model tests -------------------------------------------

@pytest.fixture
def rng():
    """A seeded generator, fresh for every test, so failures reproduce."""
    return np.random.default_rng(20240611)


def random_positions(robot, rng, count, margin_m=0.1):
    """`count` points drawn uniformly in the robot's workspace box shrunk by `margin_m`.

    Every such point lies below all exit points (the config loader enforces it).
    """
    low = robot.workspace_min_m + margin_m
    high = robot.workspace_max_m - margin_m
    return low + (high - low) * rng.random((count, 3))


def random_unit_vectors(rng, count):
    v = rng.normal(size=(count, 3))
    return v / np.linalg.norm(v, axis=1)[:, None]


@pytest.fixture(scope='session')
def eight_cable_robot():
    return load_robot(EIGHT_CABLE_ROBOT)


def cable_masks(robot):
    """(label, attached mask): every cable, then each single cable broken in turn."""
    yield 'all', np.ones(robot.cable_count, dtype=bool)
    for broken in range(robot.cable_count):
        yield f'cable {broken + 1} broken', robot.cable_mask([broken])
