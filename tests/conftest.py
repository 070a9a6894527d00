"""Shared fixtures: the shipped robot configs, and a private ROS domain per session."""
from __future__ import annotations

import contextlib
import faulthandler
import functools
import os
import re
import subprocess
import sys
import time
from collections import Counter
from pathlib import Path

import numpy as np
import pytest

from cdpr_msgs_py import dds
from cdpr_msgs_py.dds import use_shipped_setup
from cdpr_msgs_py.runtime.diagnostics import LOG_THROTTLE_S

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
    # One DDS domain per test session so parallel sessions never see each other's graph;
    # a pytest-xdist worker inherits its session's and takes the next ones (102-202).
    # Claimed machine-wide (dds.claim_domain) for the session's life: a second session, or a
    # graph another user starts on this machine, never takes it (a pid-derived id did).
    worker = os.environ.get('PYTEST_XDIST_WORKER', '')
    if worker.startswith('gw'):
        os.environ.pop('ROS_DOMAIN_ID', None)   # the session's is its own; each worker claims one
    global DOMAIN_CLAIM
    DOMAIN_CLAIM = dds.claim_domain(start=1 + os.getpid() % len(dds.DOMAIN_IDS))
    # where the venv's packages are indexed, as `make test` and the venv's activate say
    os.environ.setdefault('AMENT_PREFIX_PATH', sys.prefix)
    use_shipped_setup()


# Zero-size port segments as a process killed mid-creation leaves them: 7000 is the
# shared-memory discovery port of every domain.
STALE = ('fastdds_port7000',)


def settled_parameters(clock_mode: str = 'lockstep', **options) -> dict[str, dict]:
    """Per node, the parameters cdpr-scenario gives it for the paper robot's run that
    `options` (ScenarioOptions' fields) describe."""
    from cdpr_bringup.runs.settle import ScenarioOptions, build_scenario
    return build_scenario(ScenarioOptions(config=str(PAPER_ROBOT), motions=str(MOTIONS),
                                          **options)).node_parameters(clock_mode)


# The loop topics' rows of a Recording, and the view topics'.
LOOP_ROWS = ('angle_rad', 'angular_velocity_rad_s', 'command_nm', 'reference_angle_rad', 'twin_angle_rad',
             'twin_angular_velocity_rad_s', 'twin_torque_nm', 'residual_nm')
VIEW_ROWS = ('view_time_s', 'true_position_m', 'true_tension_n', 'twin_position_m', 'reference_position_m')


def assert_close_figures(got, want, path=''):
    """Two metrics or figures documents alike, numbers to 1e-9."""
    if isinstance(want, dict):
        assert set(got) == set(want), path
        for key in want:
            assert_close_figures(got[key], want[key], f'{path}.{key}')
    elif isinstance(want, (list, tuple)):
        assert len(got) == len(want), path
        for index, (a, b) in enumerate(zip(got, want)):
            assert_close_figures(a, b, f'{path}[{index}]')
    elif isinstance(want, float) and not isinstance(want, bool):
        assert got == pytest.approx(want, rel=0, abs=1e-9), path
    else:
        assert got == want, path


def kept(sent: list, publisher):
    """A stand-in for `publisher.publish` that keeps each message in `sent` as a reader
    gets it: the loop's JointStates go out as CDR bytes (cdr.JointStateCodec), read back
    into the publisher's message type."""
    from rclpy.serialization import deserialize_message

    def publish(message):
        sent.append(deserialize_message(message, publisher.msg_type) if isinstance(message, bytes) else message)
    return publish


def every_tick(scenario):
    """`scenario` with its view topics on every tick (streams.view_rate_hz 0), for a test
    that judges the truth tick by tick, as a user sets it for a bag of every tick."""
    import dataclasses

    from cdpr_msgs_py.contract import ViewTicks
    scenario.settings.data['streams']['view_rate_hz'] = 0.0
    return dataclasses.replace(scenario, view_ticks=ViewTicks(0.0, scenario.period_s))


def every_tick_scenario(options):
    """cdpr_bringup.runs.settle.build_scenario's, with its view topics on every tick (every_tick)."""
    from cdpr_bringup.runs.settle import build_scenario
    return every_tick(build_scenario(options))


@functools.cache
def private_shm_allowed() -> bool:
    probe = subprocess.run(['unshare', '-m', 'sh', '-c', 'mount -t tmpfs tmpfs /dev/shm'],
                           capture_output=True, timeout=10)
    return probe.returncode == 0


needs_private_shm = pytest.mark.skipif(
    not private_shm_allowed(), reason='unshare -m with a tmpfs /dev/shm is not allowed here '
                                      '(needs root or user namespaces): these tests run as root, or as '
                                      'a user under `unshare -r`; see docs/testing.md, "Private /dev/shm"')


def in_private_shm(command: list[str], stale: tuple[str, ...] = STALE) -> list[str]:
    """`command` in a private /dev/shm holding `stale` zero-size segments; it lists
    /dev/shm on its way out."""
    plant = ' '.join(f': > /dev/shm/{name};' for name in stale)
    script = (f'mount -t tmpfs tmpfs /dev/shm && {plant} "$@"; code=$?; '
              f'echo "shm: $(ls /dev/shm | tr "\\n" " ")"; exit $code')
    return ['unshare', '-m', 'sh', '-c', script, 'sh', *command]


def keep_running(graph, since_s: float, seconds: float, what: str) -> None:
    """Until `seconds` after `since_s` (monotonic s) the started graph runs on: its run has
    not ended and no node died (Graph.check raises GraphError naming it); `what` names
    what the run goes on through, for the failure."""
    while time.monotonic() - since_s < seconds:
        assert not graph.check(), f'the run ended {time.monotonic() - since_s:.1f} s after {what}'
        time.sleep(0.05)


def assert_stopped_cleanly(codes: dict[str, int], log, but: str | None = None) -> None:
    """Every node of a stopped graph (but `but`) exited 0; failing, the message ends with
    the launcher's last lines, where a node killed after its grace left its stacks."""
    unclean = {name: code for name, code in codes.items() if code != 0 and name != but}
    assert codes.keys() - {but} and not unclean, (
        f'exit codes after the stop: {codes}; the log\'s end:\n' + '\n'.join(list(log)[-80:]))


def start_until_the_plant_runs(graph, log, timeout_s: float) -> None:
    """Start `graph` (its launcher logging into `log`) and wait until every node is up
    and its plant has started its run."""
    graph.start()
    graph.wait_until_up()
    wait_until_the_plant_runs(log, timeout_s)


def wait_until_the_plant_runs(lines, timeout_s: float) -> None:
    """Until a started graph's plant logs that it starts its run (the launcher's log
    lines gathered in `lines`, a list or a GraphLog): the start handshake is over, the
    ticks flow."""
    deadline = time.monotonic() + timeout_s
    while not any(line.startswith('[plant_simulator]') and 'starting' in line for line in lines):
        assert time.monotonic() < deadline, 'the plant did not start its run'
        time.sleep(0.05)


# CDPR_STRICT_REALTIME=1 (a reference machine): no timing check is excused.
STRICT_REALTIME = os.environ.get('CDPR_STRICT_REALTIME', '') == '1'
# The plant reports its loop's window once per /diagnostics period (s): a slip inside a
# judged window is logged up to this long after the window ended.
LOOP_REPORT_PERIOD_S = 1.0
# This session's excused timing checks, for the closing summary.
EXCUSED: list[str] = []


class GraphLog:
    """A graph launcher's log (its `log` callback): each line with the monotonic instant
    (s) it reached the test. Iterating gives the lines."""

    def __init__(self):
        self.entries: list[tuple[float, str]] = []

    def __call__(self, line: str) -> None:
        self.entries.append((time.monotonic(), line))

    def __iter__(self):
        return (line for _, line in self.entries)

    def plant_started_s(self) -> float:
        """When the plant logged that it starts its run (the first tick)."""
        return next(at for at, line in self.entries
                    if line.startswith('[plant_simulator]') and 'starting' in line)

    def repeated_lines(self) -> dict[str, int]:
        """The node log lines that came more often than once a LOG_THROTTLE_S over the
        log's length (a line's shape: its node, level and text with numbers and stamps
        taken out): shape → count. A repeated condition is throttled (issue 26 item 5)."""
        if not self.entries:
            return {}
        length_s = self.entries[-1][0] - self.entries[0][0]
        shapes = Counter(re.sub(r'[0-9.]+', '#', line) for _, line in self.entries
                         if not line.startswith('[cdpr-graph]'))
        bound = 1 + length_s / LOG_THROTTLE_S
        return {shape: count for shape, count in shapes.items() if count > bound}

    def loop_slips(self, start_s: float, end_s: float) -> list[tuple[float, float, str]]:
        """The episodes in which the plant's loop did not keep its period that overlap
        [start_s, end_s] (monotonic s): (start, end, the plant's figures). The plant logs
        an episode's first window as an ERROR and its end as 'no longer in error'; an
        episode still open at the end of the log lasts to its end."""
        episodes, opened = [], None
        for at, line in self.entries:
            if not line.startswith('[plant_simulator]'):
                continue
            if opened is None and '[ERROR]' in line and 'does not keep its period' in line:
                opened = (at - LOOP_REPORT_PERIOD_S, line.split(']: ', 1)[-1])
            elif opened is not None and 'no longer in error' in line:
                episodes.append((opened[0], at, opened[1]))
                opened = None
        if opened is not None:
            episodes.append((opened[0], self.entries[-1][0], opened[1]))
        return [(begin, end, text) for begin, end, text in episodes
                if begin <= end_s + LOOP_REPORT_PERIOD_S and end >= start_s]


@contextlib.contextmanager
def timing_check(log: GraphLog, window_s: tuple[float, float], check: str, recorder_lost: str = ''):
    """A check of a realtime graph run that holds only where the plant's loop kept its
    period over `window_s` (monotonic s, the part of the run the check judges): a slow
    or loaded machine starves the late messages and the niced recorder it is about. It
    fails, unless the plant reported its loop not keeping its period inside that window,
    or, for a check of what the bag holds, unless `recorder_lost` says what the niced
    recorder was measured to have lost of that window (its ticks): then the check is
    excused, saying so with those figures, and counted in the session's summary.
    CDPR_STRICT_REALTIME=1 excuses nothing. Checks that do not depend on timing stay
    outside: they are judged in every run."""
    try:
        yield
    except AssertionError as failed:
        slips = log.loop_slips(*window_s)
        if not (slips or recorder_lost) or STRICT_REALTIME:
            raise
        start, end = window_s
        overlap = sum(min(end, stop) - max(start, begin) for begin, stop, _ in slips)
        reason = (f'the plant did not keep its period for {max(overlap, 0.0):.1f} s of the '
                  f'{end - start:.1f} s judged ({"; ".join(text for _, _, text in slips)})' if slips
                  else recorder_lost)
        excuse = f'{check}: {str(failed).splitlines()[0]} -- excused: {reason}'
        EXCUSED.append(excuse)
        print(f'\n{excuse}')


def pytest_terminal_summary(terminalreporter):
    if getattr(terminalreporter.config.option, 'numprocesses', None):
        # the workers' counts do not reach this process: graph tests run in a session of their own
        terminalreporter.write_sep('-', 'realtime timing checks: counted in sessions without -n only')
        return
    terminalreporter.write_sep('-', f'realtime timing checks excused: {len(EXCUSED)}'
                                    f'{" (CDPR_STRICT_REALTIME=1 excuses none)" if STRICT_REALTIME else ""}')
    for excuse in EXCUSED:
        terminalreporter.write_line(excuse)


def load_robot(path):
    # imported here: cdpr_msgs_py's tests share this file, and that package (colcon test)
    # has no cdpr_control
    from cdpr_control.setup.robot_file import load_robot
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


# A light end-effector under long cables (0.8 kg, a 0.8 × 0.8 m frame 4 m high, τ_min
# 1 N), none of the shipped robots: its cables carry 1.3–2.8 N on its motions, and once
# one parts the three left hold it with little more than τ_min wherever phase 1 leaves
# it (robot file alone: every other setting the paper's or derived).
LIGHT_TALL_ROBOT = {'robot': {
    'name': 'light_tall_robot', 'gravity_m_s2': [0.0, 0.0, -9.81],
    'end_effector': {'mass_kg': 0.8, 'radius_m': 0.04},
    'exit_points_m': [[0.0, 0.0, 4.0], [0.0, 0.8, 4.0], [0.8, 0.8, 4.0], [0.8, 0.0, 4.0]],
    'workspace_m': {'min': [0.0, 0.0, 0.0], 'max': [0.8, 0.8, 3.6]},
    'home_position_m': [0.4, 0.4, 2.0],
    'motor': {'inertia_kg_m2': 2.0e-4, 'drum_radius_m': 0.030, 'viscous_friction_nm_s_rad': 0.001,
              'static_friction_nm': 0.1, 'nominal_torque_nm': 0.64, 'nominal_speed_rpm': 3000,
              'torque_limit_nm': 1.9},
    'cables': {'tension_min_n': 1.0, 'tension_max_n': 50.0}}}
LIGHT_TALL_MOTIONS = {
    'motion_defaults': {'peak_speed_m_s': 0.4, 'rest_before_s': 1.0, 'rest_after_s': 1.5},
    'motions': {'line-x': {'type': 'line', 'start': [0.25, 0.4, 2.0], 'goal': [0.55, 0.4, 2.0]}}}

# Its elastic-plant thresholds as cdpr-calibrate gives them on its motions (line-x, line-y
# and a lift; seeds 0-2, 18 runs, 2026-12-07).
LIGHT_TALL_FDI = {
    'coulomb_friction_nm': 0.05151, 'epsilon_nm': 0.07276,
    'cusum': {'sigma_nm': [0.004173, 0.00417, 0.00418, 0.004177], 'drift': 5.0, 'threshold': 93.11,
              'limit': 13.8, 'epsilon_nm': 0.07443}}


# A drawn 1.4 kg point mass on six cables (cdpr-bench robots --seed 2, its second robot;
# τ_min 2.11 N), none of the shipped robots: once cable 1 parts, the five left hold the
# end-effector with little more than τ_min near where it broke.
LIGHT_SIX_CABLE_ROBOT = {'robot': {
    'name': 'light_six_cable_robot', 'gravity_m_s2': [0.0, 0.0, -9.81],
    'end_effector': {'mass_kg': 1.441, 'radius_m': 0.05},
    'exit_points_m': [[4.419, 2.386, 3.399], [2.907, 5.342, 2.894], [0.0, 5.282, 2.857],
                      [0.0, 3.369, 3.507], [0.173, 0.0, 3.13], [2.795, 0.0, 3.04]],
    'workspace_m': {'min': [0.663, 0.801, 0.0], 'max': [3.757, 4.541, 2.152]},
    'home_position_m': [2.21, 2.671, 1.076],
    'motor': {'inertia_kg_m2': 0.000859, 'drum_radius_m': 0.05, 'viscous_friction_nm_s_rad': 0.0029,
              'static_friction_nm': 0.073, 'nominal_torque_nm': 2.723, 'nominal_speed_rpm': 3378,
              'torque_limit_nm': 8.49},
    'cables': {'tension_min_n': 2.11, 'tension_max_n': 87.8}}}
LIGHT_SIX_CABLE_MOTIONS = {
    'motion_defaults': {'peak_speed_m_s': 0.4, 'rest_before_s': 0.5, 'rest_after_s': 1.0},
    'motions': {'down': {'type': 'line', 'start': [2.3887, 2.8874, 1.4898], 'goal': [2.0313, 2.4546, 0.6622]}}}


# A drawn suspended 7.2 kg platform on seven cables at mixed heights (cdpr-bench robots
# --seed 2, family2_039), none of the shipped robots: after cable 5 parts, the six left
# hold its safe pose, but not the safe orientation anywhere near where the cable broke.
DRAWN_SEVEN_CABLE_PLATFORM = {'robot': {
    'name': 'drawn_seven_cable_platform', 'gravity_m_s2': [0.0, 0.0, -9.81],
    'end_effector': {'mass_kg': 7.241, 'radius_m': 0.215},
    'platform': {
        'attachment_points_m': [[0.1361, 0.0852, 0.0815], [0.18, 0.0573, 0.0815], [-0.0676, 0.0852, 0.0815],
                                [-0.0438, 0.0852, 0.0815], [-0.1154, -0.0852, 0.0815],
                                [-0.0693, -0.0852, 0.0815], [0.1161, -0.0852, 0.0815]],
        'centre_of_mass_m': [0.0, 0.0, 0.0],
        'inertia_kg_m2': [[0.033527, 0.0, 0.0], [0.0, 0.0942323, 0.0], [0.0, 0.0, 0.0957226]],
        'home_orientation': [1.0, 0.0, 0.0, 0.0]},
    'exit_points_m': [[5.18, 2.404, 2.85], [4.831, 4.234, 2.338], [2.111, 4.234, 2.389], [0.0, 4.073, 2.864],
                      [0.0, 1.627, 2.469], [2.085, 0.0, 2.681], [3.716, 0.0, 2.343]],
    'workspace_m': {'min': [0.992, 0.85, 0.215], 'max': [4.188, 3.384, 1.542]},
    'home_position_m': [2.59, 2.117, 0.879],
    'motor': {'inertia_kg_m2': 0.00135, 'drum_radius_m': 0.0548, 'viscous_friction_nm_s_rad': 0.0018,
              'static_friction_nm': 0.116, 'nominal_torque_nm': 2.12, 'nominal_speed_rpm': 3043,
              'torque_limit_nm': 7.085},
    'cables': {'tension_min_n': 2.61, 'tension_max_n': 115.7}}}
DRAWN_SEVEN_CABLE_PLATFORM_MOTIONS = {
    'motion_defaults': {'peak_speed_m_s': 0.4, 'rest_before_s': 0.5, 'rest_after_s': 1.0},
    'motions': {'climb': {'type': 'line', 'start': [2.5639, 1.9694, 0.6191], 'goal': [2.6161, 2.2646, 1.1389],
                          'turn': {'axis': [0.3836, 0.6726, -0.6328], 'angle_deg': 7.624}}}}

# A suspended 5.6 kg platform on eight cables, drawn by `cdpr-bench robots --seed 3`
# (family3_017_suspended), and its first motion: named 16 cm from its safe pose, where the
# seven cables left hold it 1.4 N above τ_min, a platform whose steered approach keeps its
# tensions 4 N above τ_min (0.8 of the safe pose's margin) is pulled up to the frame's top.
DRAWN_SUSPENDED_PLATFORM = {'robot': {
    'name': 'family3_017_suspended', 'gravity_m_s2': [0.0, 0.0, -9.81],
    'end_effector': {'mass_kg': 5.554, 'radius_m': 0.298},
    'platform': {
        'attachment_points_m': [[0.1911, 0.134, 0.1474], [0.1911, 0.0768, 0.1474], [-0.075, 0.1754, 0.1474],
                                [-0.0341, 0.1754, 0.1474], [-0.1911, -0.0658, 0.1474],
                                [-0.1911, -0.1287, 0.1474], [0.0366, -0.1754, 0.1474],
                                [0.0396, -0.1754, 0.1474]],
        'centre_of_mass_m': [0.0, 0.0, 0.0],
        'inertia_kg_m2': [[0.09714, 0.0, 0.0], [0.0, 0.1078245, 0.0], [0.0, 0.0, 0.1245467]],
        'home_orientation': [1.0, 0.0, 0.0, 0.0]},
    'exit_points_m': [[2.787, 2.589, 2.854], [2.787, 3.643, 3.181], [1.368, 4.557, 3.257], [0.0, 4.384, 3.207],
                      [0.0, 2.364, 3.452], [0.0, 0.176, 3.312], [0.963, 0.0, 3.281], [2.787, 0.304, 3.257]],
    'workspace_m': {'min': [0.716, 0.982, 0.298], 'max': [2.071, 3.575, 1.848]},
    'home_position_m': [1.393, 2.279, 1.073],
    'motor': {'inertia_kg_m2': 0.00128, 'drum_radius_m': 0.0322, 'viscous_friction_nm_s_rad': 0.0027,
              'static_friction_nm': 0.091, 'nominal_torque_nm': 1.267, 'nominal_speed_rpm': 3959,
              'torque_limit_nm': 3.805},
    'cables': {'tension_min_n': 2.93, 'tension_max_n': 74.2}}}
DRAWN_SUSPENDED_PLATFORM_MOTIONS = {
    'motion_defaults': {'peak_speed_m_s': 0.4, 'rest_before_s': 0.5, 'rest_after_s': 1.0},
    'motions': {'017-line-1': {'type': 'line', 'start': [1.4586, 2.4412, 1.0306], 'goal': [1.3274, 2.1168, 1.1154],
                               'turn': {'axis': [0.7757, 0.5802, 0.2483], 'angle_deg': 3.959}}}}


@pytest.fixture
def light_tall_robot_files(tmp_path):
    """(robot file, motions file) of LIGHT_TALL_ROBOT, written to the test's folder."""
    return written_robot(tmp_path, LIGHT_TALL_ROBOT, LIGHT_TALL_MOTIONS)[:2]


# A suspended 12 kg platform on 8 cables in the crossed-pairs layout of the shipped one,
# at 2.2 times its size (a 4.4 × 3.4 × 3 m frame, τ_min 5 N, τ_max 200 N), none of the
# shipped robots; and its elastic-plant thresholds as `cdpr-calibrate` gives them on
# DRAWN_PLATFORM_MOTIONS (seeds 0–2, 24 runs, 2026-12-07).
DRAWN_PLATFORM_ROBOT = {'robot': {
    'name': 'drawn_platform_robot', 'gravity_m_s2': [0.0, 0.0, -9.81],
    'end_effector': {'mass_kg': 12.0, 'radius_m': 0.2},
    'platform': {
        'attachment_points_m': [[0.2, -0.15, 0.075], [-0.2, 0.15, -0.075], [-0.2, -0.15, 0.075],
                                [0.2, 0.15, -0.075], [-0.2, 0.15, 0.075], [0.2, -0.15, -0.075],
                                [0.2, 0.15, 0.075], [-0.2, -0.15, -0.075]],
        'centre_of_mass_m': [0.0, 0.0, 0.0],
        'inertia_kg_m2': [[0.1125, 0.0, 0.0], [0.0, 0.1825, 0.0], [0.0, 0.0, 0.25]],
        'home_orientation': [1.0, 0.0, 0.0, 0.0]},
    'exit_points_m': [[0.0, 0.1, 3.0], [0.1, 0.0, 3.0], [4.3, 0.0, 3.0], [4.4, 0.1, 3.0], [4.4, 3.3, 3.0],
                      [4.3, 3.4, 3.0], [0.1, 3.4, 3.0], [0.0, 3.3, 3.0]],
    'workspace_m': {'min': [0.2, 0.2, 0.3], 'max': [4.2, 3.2, 2.7]},
    'home_position_m': [2.2, 1.7, 1.5],
    'motor': {'inertia_kg_m2': 0.0015, 'drum_radius_m': 0.05, 'viscous_friction_nm_s_rad': 0.003,
              'static_friction_nm': 0.15, 'nominal_torque_nm': 4.0, 'nominal_speed_rpm': 3000,
              'torque_limit_nm': 12.0},
    'cables': {'tension_min_n': 5.0, 'tension_max_n': 200.0}}}
DRAWN_PLATFORM_MOTIONS = {
    'motion_defaults': {'peak_speed_m_s': 0.4, 'rest_before_s': 0.5, 'rest_after_s': 1.0},
    'motions': {
        'low-line': {'type': 'line', 'start': [1.2, 1.7, 0.8], 'goal': [3.2, 1.7, 0.8]},
        'climb-tilt': {'type': 'line', 'start': [1.5, 1.2, 0.9], 'goal': [2.9, 2.2, 1.9],
                       'turn': {'axis': [1, 0, 0], 'angle_deg': 8.0}},
        'across-yaw': {'type': 'line', 'start': [2.2, 1.0, 1.5], 'goal': [2.2, 2.4, 1.5],
                       'turn': {'axis': [0, 0, 1], 'angle_deg': 10.0}},
        'loop': {'type': 'circle', 'centre': [2.2, 1.7, 1.4], 'radius_m': 0.7, 'start_angle_deg': 180.0,
                 'sweep_deg': 360.0}}}
DRAWN_PLATFORM_FDI = {
    'coulomb_friction_nm': 0.07548, 'epsilon_nm': 0.41769,
    'cusum': {'sigma_nm': [0.028286, 0.027796, 0.028115, 0.02818, 0.030133, 0.030056, 0.028379, 0.028723],
              'drift': 5.0, 'threshold': 11.076, 'limit': 14.733, 'epsilon_nm': 0.4417}}


@pytest.fixture
def drawn_platform_files(tmp_path):
    """(robot file, motions file, elastic calibration file) of DRAWN_PLATFORM_ROBOT."""
    return written_robot(tmp_path, DRAWN_PLATFORM_ROBOT, DRAWN_PLATFORM_MOTIONS, DRAWN_PLATFORM_FDI)


# A point mass of 1.6 kg on eight cables at mixed heights (4.2–5.1 m) over a 6.6 × 5.7 m
# frame, τ_min 1.58 N, 21 mm drums: drawn by `cdpr-bench robots --seed 1` (family1_007),
# none of the shipped robots; its line and its elastic-plant thresholds as that bench
# made them (cdpr-calibrate on its motions, seed 0, 2026-12-07).
DRAWN_EIGHT_CABLE_ROBOT = {'robot': {
    'name': 'family1_007', 'gravity_m_s2': [0.0, 0.0, -9.81],
    'end_effector': {'mass_kg': 1.557, 'radius_m': 0.05},
    'exit_points_m': [[6.576, 3.084, 4.266], [5.866, 5.701, 4.406], [3.924, 5.701, 4.613], [0.621, 5.701, 4.664],
                      [0.0, 2.563, 5.104], [0.0, 0.486, 4.511], [3.134, 0.0, 4.203], [5.072, 0.0, 5.044]],
    'workspace_m': {'min': [0.986, 0.855, 0.0], 'max': [5.589, 4.846, 3.157]},
    'home_position_m': [3.288, 2.851, 1.579],
    'motor': {'inertia_kg_m2': 0.000322, 'drum_radius_m': 0.0209, 'viscous_friction_nm_s_rad': 0.0022,
              'static_friction_nm': 0.076, 'nominal_torque_nm': 1.354, 'nominal_speed_rpm': 2529,
              'torque_limit_nm': 3.874},
    'cables': {'tension_min_n': 1.58, 'tension_max_n': 99.9}}}
DRAWN_EIGHT_CABLE_MOTIONS = {
    'motion_defaults': {'peak_speed_m_s': 0.4, 'rest_before_s': 0.5, 'rest_after_s': 1.0},
    'motions': {'007-line-2': {'type': 'line', 'start': [2.9731, 3.1715, 1.7983], 'goal': [3.6029, 2.5305, 1.3597]}}}
DRAWN_EIGHT_CABLE_FDI = {
    'coulomb_friction_nm': 0.03566, 'epsilon_nm': 0.08621,
    'cusum': {'sigma_nm': [0.009258, 0.014561, 0.008603, 0.016626, 0.010082, 0.015917, 0.009088, 0.009348],
              'drift': 5.0, 'threshold': 1.491, 'limit': 6.491, 'epsilon_nm': 0.08849}}

# A point mass of 1.5 kg on four cables (1.9–2.2 m high) over a 5.0 × 7.0 m frame: drawn
# by `cdpr-bench robots --seed 6` (family6_006). Its motors' inertia seen at the cable,
# J/ρ² = 2.2 kg, outweighs the end-effector.
DRAWN_FOUR_CABLE_ROBOT = {'robot': {
    'name': 'family6_006', 'gravity_m_s2': [0.0, 0.0, -9.81],
    'end_effector': {'mass_kg': 1.518, 'radius_m': 0.05},
    'exit_points_m': [[5.012, 2.81, 2.166], [2.122, 7.028, 1.922], [0.0, 2.803, 1.955], [2.818, 0.0, 1.896]],
    'workspace_m': {'min': [0.752, 1.054, 0.0], 'max': [4.26, 5.974, 1.44]},
    'home_position_m': [2.506, 3.514, 0.72],
    'motor': {'inertia_kg_m2': 0.00125, 'drum_radius_m': 0.0237, 'viscous_friction_nm_s_rad': 0.0017,
              'static_friction_nm': 0.112, 'nominal_torque_nm': 1.929, 'nominal_speed_rpm': 3972,
              'torque_limit_nm': 5.653},
    'cables': {'tension_min_n': 2.89, 'tension_max_n': 164.8}}}

# A suspended 7.4 kg platform on seven cables (2.2–2.6 m high) over a 7.2 × 1.4 m frame,
# τ_min 1.59 N, 48 mm drums (δ/ρ = 2.78 N): drawn by `cdpr-bench robots --seed 7`
# (family7_079_suspended), its line and elastic-plant thresholds as that bench made them
# (2026-12-07). Its cable 1 carries 2.3–2.9 N on the line, about δ/ρ.
DRAWN_HOVERING_CABLE_PLATFORM = {'robot': {
    'name': 'family7_079_suspended', 'gravity_m_s2': [0.0, 0.0, -9.81],
    'end_effector': {'mass_kg': 7.393, 'radius_m': 0.181},
    'platform': {'attachment_points_m': [[0.127, 0.0926, 0.0892], [0.127, 0.0651, 0.0892], [-0.0431, 0.0935, 0.0892],
                                         [-0.0689, 0.0935, 0.0892], [-0.0854, -0.0935, 0.0892],
                                         [-0.0402, -0.0935, 0.0892], [0.127, -0.0466, 0.0892]],
                 'centre_of_mass_m': [0.0, 0.0, 0.0], 'home_orientation': [1.0, 0.0, 0.0, 0.0],
                 'inertia_kg_m2': [[0.0411264, 0.0, 0.0], [0.0, 0.0593746, 0.0], [0.0, 0.0, 0.061297]]},
    'exit_points_m': [[7.151, 1.335, 2.41], [4.09, 1.359, 2.388], [3.587, 1.359, 2.609], [2.291, 1.359, 2.241],
                      [1.882, 0.0, 2.636], [3.604, 0.0, 2.556], [4.235, 0.0, 2.427]],
    'workspace_m': {'min': [1.254, 0.385, 0.181], 'max': [5.897, 0.974, 1.513]},
    'home_position_m': [3.575, 0.679, 0.847],
    'motor': {'inertia_kg_m2': 0.00132, 'drum_radius_m': 0.0478, 'viscous_friction_nm_s_rad': 0.0024,
              'static_friction_nm': 0.072, 'nominal_torque_nm': 3.434, 'nominal_speed_rpm': 3832,
              'torque_limit_nm': 8.781},
    'cables': {'tension_min_n': 1.59, 'tension_max_n': 149.8}}}
DRAWN_HOVERING_CABLE_MOTIONS = {
    'motion_defaults': {'peak_speed_m_s': 0.4, 'rest_before_s': 0.5, 'rest_after_s': 1.0},
    'motions': {'079-line-2': {'type': 'line', 'start': [3.5565, 0.6782, 0.7406], 'goal': [3.5935, 0.6798, 0.9534],
                               'turn': {'axis': [0.8834, -0.0759, 0.4624], 'angle_deg': 2.352}}}}
DRAWN_HOVERING_CABLE_FDI = {
    'coulomb_friction_nm': 0.03784, 'epsilon_nm': 0.22689,
    'cusum': {'sigma_nm': [0.025166, 0.027148, 0.027651, 0.027658, 0.026989, 0.028091, 0.030116],
              'drift': 5.0, 'threshold': 2.92, 'limit': 7.92, 'epsilon_nm': 0.23515}}

# A point mass of 2.2 kg on eight cables (3.5–4.2 m high) over a 3.4 × 5.9 m frame, τ_min
# 2.7 N, 22 mm drums: drawn by `cdpr-bench robots --seed 6` (family6_090), its line and
# elastic-plant thresholds as that bench made them (2026-12-07). Two of its cables carry
# 1–2 N on the line with a residual above δ all along (the twin's mismatch).
DRAWN_HIDDEN_BREAK_ROBOT = {'robot': {
    'name': 'family6_090', 'gravity_m_s2': [0.0, 0.0, -9.81],
    'end_effector': {'mass_kg': 2.219, 'radius_m': 0.05},
    'exit_points_m': [[3.406, 2.77, 4.017], [3.406, 4.174, 3.606], [1.499, 5.858, 3.479], [0.0, 4.14, 4.039],
                      [0.0, 2.807, 3.953], [0.0, 0.379, 3.553], [1.094, 0.0, 4.023], [3.406, 0.91, 4.203]],
    'workspace_m': {'min': [0.511, 0.879, 0.0], 'max': [2.895, 4.979, 2.637]},
    'home_position_m': [1.703, 2.929, 1.319],
    'motor': {'inertia_kg_m2': 0.000753, 'drum_radius_m': 0.0217, 'viscous_friction_nm_s_rad': 0.0013,
              'static_friction_nm': 0.136, 'nominal_torque_nm': 2.152, 'nominal_speed_rpm': 2700,
              'torque_limit_nm': 6.687},
    'cables': {'tension_min_n': 2.7, 'tension_max_n': 229.0}}}
DRAWN_HIDDEN_BREAK_MOTIONS = {
    'motion_defaults': {'peak_speed_m_s': 0.4, 'rest_before_s': 0.5, 'rest_after_s': 1.0},
    'motions': {'090-line-3': {'type': 'line', 'start': [1.5812, 2.4484, 1.384], 'goal': [1.8248, 3.4096, 1.254]}}}
DRAWN_HIDDEN_BREAK_FDI = {
    'coulomb_friction_nm': 0.06575, 'epsilon_nm': 0.13253, 'collapse_reference_share': 1.5,
    'cusum': {'sigma_nm': [0.017479, 0.01192, 0.010326, 0.015978, 0.019619, 0.011735, 0.010777, 0.010258],
              'drift': 5.0, 'threshold': 1.31, 'limit': 6.31, 'epsilon_nm': 0.13769}}


def written_robot(tmp_path, robot: dict, motions: dict, fdi: dict | None = None) -> tuple:
    """(robot file, motions file, elastic calibration file or None) of a robot of the tests,
    written to the test's folder; the calibration made on that robot (its fingerprint)."""
    import yaml
    name = robot['robot']['name']
    robot_file, motions_file = tmp_path / f'{name}.yaml', tmp_path / f'{name}_motions.yaml'
    robot_file.write_text(yaml.safe_dump(robot))
    motions_file.write_text(yaml.safe_dump(motions))
    if fdi is None:
        return robot_file, motions_file, None
    calibration = tmp_path / f'{name}_calibration_elastic.yaml'
    calibration.write_text(yaml.safe_dump({'fdi': fdi, 'calibration': {
        'robot': name, 'robot_fingerprint': load_robot(robot_file).fingerprint(), 'fidelity': 'elastic'}}))
    return robot_file, motions_file, calibration
