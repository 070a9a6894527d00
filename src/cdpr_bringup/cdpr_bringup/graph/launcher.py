"""cdpr-graph: start the node graph, each node its own OS process, as `ros2 run` would,
or the control loop's nodes composed in one process (`--graph-form composed`).

Waits until every node is up, streams their logs with node prefixes, stops them all
cleanly on Ctrl-C, and stops the graph with a clear message when a node dies. The
plant simulator ending with code 0 means the run is complete.
"""
from __future__ import annotations

import argparse
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path

import yaml

from cdpr_msgs_py import contract
from cdpr_control.config import Section
from cdpr_msgs_py.contract import DEFAULT_NAMESPACE
from cdpr_twin.models.plant import FIDELITIES
from cdpr_msgs_py.dds import (INITIALISATION_LIMIT_S, LAUNCHER_PID_VARIABLE, DomainInUse, claim_domain,
                              shipped_environment, use_shipped_setup)
from cdpr_msgs_py.runtime.spin import READY_MARK, SHUTDOWN_LIMIT_S, STACK_DUMP_SIGNAL

from ..cli import INTERRUPTED_EXIT_CODE, command
from .composed_loop import COMPOSABLE
from ..paths import DEFAULT_MOTIONS, DEFAULT_ROBOT
from ..runs.settle import ScenarioOptions, add_graph_form_option, add_push_option, build_scenario

# After SIGINT a node drains, waits for acknowledgements and exits; SIGKILL comes only
# after that has had its time (a killed node can leave DDS state behind).
STOP_GRACE_S = SHUTDOWN_LIMIT_S + 2.0
# How long a node that outlived its grace has to write its stacks before SIGKILL (s).
STACK_DUMP_S = 0.5
# Longer than a node's own bound on its DDS start, so that its one-line reason arrives first.
UP_TIMEOUT_S = INITIALISATION_LIMIT_S + 10.0
TEMP_PREFIX = 'cdpr-graph-'
LAST_LINES = 5
# How long to wait for the rest of an exited node's output (s): it ends when the node does.
READER_JOIN_S = 1.0

class GraphError(RuntimeError):
    """A node died or did not come up; the message names it."""


COMPOSED_EXECUTABLE = 'composed_loop'


@dataclass
class NodeSpec:
    """One process of the graph: a node's own executable, or (`members`) the nodes
    composed in one process by composed_loop."""
    package: str
    executable: str
    parameters: dict = field(default_factory=dict)
    members: tuple['NodeSpec', ...] = ()

    @property
    def name(self) -> str:
        return self.executable

    @property
    def node_names(self) -> list[str]:
        """The nodes this process runs."""
        return [member.name for member in self.members] if self.members else [self.name]

    def parameters_document(self) -> dict:
        """Its parameters file: a node's own for every node it runs."""
        if not self.members:
            return {'/**': {'ros__parameters': self.parameters}}
        return {f'/**/{member.name}': {'ros__parameters': member.parameters} for member in self.members}

    def arguments(self) -> list[str]:
        """What its executable takes before --ros-args."""
        return self.node_names if self.members else []


def composed(specs: list[NodeSpec]) -> list[NodeSpec]:
    """`specs` with the control loop's nodes (those composed_loop can run) in one process
    on one executor; the others (recorder, markers) stay apart. SCHED_FIFO is a process's:
    the loop's process gets the highest priority any of its nodes asks for."""
    loop = [spec for spec in specs if spec.name in COMPOSABLE]
    if len(loop) < 2:
        return specs
    priority = max(spec.parameters.get('realtime_priority', 0) for spec in loop)
    members = tuple(NodeSpec(spec.package, spec.executable,
                             dict(spec.parameters, **({'realtime_priority': priority} if priority else {})))
                    for spec in loop)
    return ([NodeSpec('cdpr_bringup', COMPOSED_EXECUTABLE, members=members)]
            + [spec for spec in specs if spec.name not in COMPOSABLE])


def executable_command(package: str, executable: str) -> list[str]:
    """The executable `ros2 run` would start (lib/PACKAGE/ of the ament prefixes), else the
    venv's entry point: started directly, so that it is this launcher's child."""
    candidates = [Path(prefix) / 'lib' / package / executable
                  for prefix in filter(None, os.environ.get('AMENT_PREFIX_PATH', '').split(os.pathsep))]
    candidates.append(Path(sys.prefix) / 'bin' / executable)
    for candidate in candidates:
        if candidate.is_file() and os.access(candidate, os.X_OK):
            return [str(candidate)]
    raise GraphError(f'no executable {executable} of package {package} '
                     f'(looked in {", ".join(map(str, candidates))})')


def launch_environment(namespace: str = DEFAULT_NAMESPACE) -> str:
    """Settle this launcher's DDS environment before it or its nodes start a participant:
    the shipped set-up (dds.py) and a domain of its own unless the caller set
    ROS_DOMAIN_ID, so that two users (or two runs) on one machine never see each other's
    robot; `namespace` in that domain is claimed for this process's life (dds.claim_domain:
    GraphError when another graph or test session on this machine holds it). Returns the
    domain id."""
    use_shipped_setup()
    key = (os.environ.get('ROS_DOMAIN_ID'), namespace)
    if key not in _CLAIMS:
        try:
            files = claim_domain(namespace)
        except DomainInUse as err:
            raise GraphError(str(err)) from None
        _CLAIMS[(os.environ['ROS_DOMAIN_ID'], namespace)] = files
    return os.environ['ROS_DOMAIN_ID']


# (domain, namespace) claimed by this process: its graphs follow one another
_CLAIMS: dict[tuple[str, str], list] = {}


def node_environment() -> dict:
    """The caller's environment, plus what nodes from a venv need and the shipped DDS
    set-up (loopback only, no shared memory; dds.py), and this launcher's PID, whose death
    stops them."""
    environment = shipped_environment(os.environ)
    environment.update(PYTHONUNBUFFERED='1', **{LAUNCHER_PID_VARIABLE: str(os.getpid())})
    environment.setdefault('AMENT_PREFIX_PATH', sys.prefix)
    return environment


def speaker(line: str, spec: NodeSpec) -> str:
    """Which node of `spec`'s process said `line`: a composed node's log line names it
    (`[INFO] [stamp] [namespace.node]: …`), so it reads as it would from its own process."""
    if spec.members:
        logger = line.split('] [', 2)[-1].split(']', 1)[0] if line.startswith('[') else ''
        node = logger.rsplit('.', 1)[-1]
        if node in spec.node_names:
            return node
    return spec.name


class Graph:
    """A set of node processes in one namespace, started and stopped together.

    Nodes die with this launcher (dds.follow_launcher). Their parameter files live in a
    folder that is removed as soon as every node has read its own (and, should this
    launcher be killed before that, by the next launch).
    """

    def __init__(self, nodes: list[NodeSpec], namespace: str = DEFAULT_NAMESPACE,
                 completion: str | None = None, log=print):
        self.nodes = nodes
        self.specs = {spec.name: spec for spec in nodes}
        self.namespace = namespace
        self.completion = completion
        self.log = log
        self.processes: dict[str, subprocess.Popen] = {}
        self.readers: dict[str, threading.Thread] = {}   # of each node's output, by node
        self.ready: set[str] = set()
        self.last_lines: dict[str, list[str]] = {}
        remove_abandoned_folders()
        self.folder = Path(tempfile.mkdtemp(prefix=f'{TEMP_PREFIX}{os.getpid()}-'))

    def start(self) -> None:
        self.log(f'[cdpr-graph] ROS_DOMAIN_ID={launch_environment(self.namespace)} (set it to listen from another shell)')
        for spec in self.nodes:
            params = self.folder / f'{spec.name}.yaml'
            params.write_text(yaml.safe_dump(spec.parameters_document()))
            command = executable_command(spec.package, spec.executable) + spec.arguments() + [
                '--ros-args', '-r', f'__ns:={self.namespace}', '--params-file', str(params)]
            process = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                                       stdin=subprocess.DEVNULL, text=True, start_new_session=True,
                                       env=node_environment())
            self.processes[spec.name] = process
            self.log(f'[cdpr-graph] started {spec.name} (pid {process.pid})')
            self.readers[spec.name] = threading.Thread(target=self._stream, args=(spec, process), daemon=True)
            self.readers[spec.name].start()

    def _stream(self, spec: NodeSpec, process: subprocess.Popen) -> None:
        lines = self.last_lines.setdefault(spec.name, [])
        for line in process.stdout:
            line = line.rstrip()
            if line.startswith(READY_MARK):
                self.ready.add(line[len(READY_MARK):].strip() if spec.members else spec.name)
                continue
            lines[:] = lines[-(LAST_LINES - 1):] + [line]
            self.log(f'[{speaker(line, spec)}] {line}')

    def wait_until_up(self, timeout_s: float = UP_TIMEOUT_S) -> None:
        """Block until every node has started DDS and built itself (each says so on its
        stdout), then remove the parameter files, which every node has read."""
        deadline = time.monotonic() + timeout_s
        wanted = {name for spec in self.nodes for name in spec.node_names}
        while not wanted <= self.ready:
            self.check()
            if time.monotonic() > deadline:
                raise GraphError(f'nodes not up after {timeout_s:.0f} s: '
                                 f'{", ".join(sorted(wanted - self.ready))}')
            time.sleep(0.02)
        shutil.rmtree(self.folder, ignore_errors=True)

    def check(self) -> bool:
        """True when the completion node has finished; GraphError if any node died."""
        for name, process in self.processes.items():
            code = process.poll()
            if code is None:
                continue
            if self.completion in self.specs[name].node_names and code == 0:
                return True
            # its last words: its output ends with it (the others' reader threads go on)
            self.readers[name].join(timeout=READER_JOIN_S)
            last = self.last_lines.get(name)
            raise GraphError(f'node {", ".join(self.specs[name].node_names)} died (exit code {code})'
                             + (f': {last[-1]}' if last else '') + '; stopping the graph')
        return False

    def wait(self, timeout_s: float | None = None) -> None:
        """Until the completion node finishes (or forever without one)."""
        deadline = None if timeout_s is None else time.monotonic() + timeout_s
        while not self.check():
            if deadline is not None and time.monotonic() > deadline:
                raise GraphError(f'the run did not complete within {timeout_s:.0f} s')
            time.sleep(0.02)

    def stop(self) -> dict[str, int]:
        """SIGINT every node; SIGKILL only those still there after STOP_GRACE_S, longer
        than a node's own shutdown; exit codes."""
        for process in self.processes.values():
            if process.poll() is None:
                os.killpg(process.pid, signal.SIGINT)
        deadline = time.monotonic() + STOP_GRACE_S
        for name, process in self.processes.items():
            try:
                process.wait(timeout=max(deadline - time.monotonic(), 0.1))
            except subprocess.TimeoutExpired:
                self.log(f'[cdpr-graph] {name} still running {STOP_GRACE_S:.1f} s after SIGINT; '
                         f'killing it (its threads\' stacks follow)')
                os.kill(process.pid, STACK_DUMP_SIGNAL)
                time.sleep(STACK_DUMP_S)
                os.killpg(process.pid, signal.SIGKILL)
                process.wait(timeout=STOP_GRACE_S)
        for reader in self.readers.values():
            reader.join(timeout=READER_JOIN_S)
        shutil.rmtree(self.folder, ignore_errors=True)
        return {name: process.returncode for name, process in self.processes.items()}


def remove_abandoned_folders() -> None:
    """Parameter folders of launchers that were killed before their nodes were up."""
    for folder in Path(tempfile.gettempdir()).glob(f'{TEMP_PREFIX}*'):
        owner = folder.name[len(TEMP_PREFIX):].split('-')[0]
        if owner.isdigit() and not Path(f'/proc/{owner}').exists():
            shutil.rmtree(folder, ignore_errors=True)


def run_to_completion(nodes: list[NodeSpec], namespace: str, timeout_s: float | None,
                      log=print) -> None:
    """Start the graph, wait until the plant completes its run, stop every node."""
    graph = Graph(nodes, namespace, completion='plant_simulator', log=log)
    try:
        graph.start()
        graph.wait_until_up()
        log('[cdpr-graph] all nodes up')
        graph.wait(timeout_s)
        log('[cdpr-graph] run complete')
    finally:
        graph.stop()


def run_until_stopped(nodes: list[NodeSpec], namespace: str, log=print) -> None:
    """Start the graph and keep it until Ctrl-C or until a node dies."""
    graph = Graph(nodes, namespace, log=log)
    try:
        graph.start()
        graph.wait_until_up()
        log('[cdpr-graph] all nodes up; waiting for the hardware bridge on joint_states')
        graph.wait()
    finally:
        graph.stop()


def graph_nodes(parameters: dict[str, dict], bag_path: str | None = None,
                supervised: bool = True, plant: bool = True, form: str = 'separate',
                last_diagnostics: str | None = None) -> list[NodeSpec]:
    """The closed loop: generator, controller, twin, supervisor, plant, a recorder and the
    markers, each with its settled parameters (Scenario.node_parameters). With
    `last_diagnostics` (a folder) each node writes its last /diagnostics status there as
    it stops, into NODE.json.

    Each node gets the `matches` its per-cycle endpoints must reach before it subscribes
    to its tick (CdprNode.start_when_matched); the plant starts when all have. Without
    the plant, a hardware bridge takes its place on the same topics.
    """
    specs = [('cdpr_control', 'trajectory_generator', {}),
             ('cdpr_control', 'controller', {'wait_for_supervisor': supervised}),
             ('cdpr_twin', 'digital_twin', {})]
    if supervised:
        specs.append(('cdpr_fdi', 'supervisor', {}))
    if bag_path is not None:
        specs.append(('cdpr_bringup', 'bag_recorder', {'bag_path': bag_path}))
    specs.append(('cdpr_fdi', 'markers', {'ground_truth': plant}))
    if plant:
        specs.append(('cdpr_twin', 'plant_simulator', {'wait_for_recorder': bag_path is not None}))
    realtime = parameters['controller']['clock_mode'] == 'realtime'
    # Without the plant a hardware bridge keeps its end of the handshake: it reads the
    # commands and writes the states, but not what only a simulation has.
    started = {executable for _, executable, _ in specs}
    handshake = start_handshake(started | {contract.PLANT_SIMULATOR}, lockstep=not realtime,
                                simulated=plant, composed=set(COMPOSABLE) & started if form == 'composed' else set())
    # A node with nothing to match gets no `matches`: ROS cannot type an empty array (the
    # node died declaring one), and the node's default is to wait for nothing.
    nodes = [NodeSpec(package, executable, dict(parameters[executable], **extra,
                                                **({'matches': handshake[executable]}
                                                   if handshake[executable] else {}),
                                                **({'last_diagnostics_path': f'{last_diagnostics}/{executable}.json'}
                                                   if last_diagnostics is not None else {})))
             for package, executable, extra in specs]
    return composed(nodes) if form == 'composed' else nodes


def start_handshake(nodes: set[str], lockstep: bool, simulated: bool = True,
                    composed: set[str] = frozenset()) -> dict[str, list[str]]:
    """Per node of `nodes`, the `matches` of its start (CdprNode.start_when_matched), from
    the topics written from the first tick (contract.TOPICS: loop and view topics) by a node of `nodes` (the plant
    simulator's simulated topics only when it is one, not a bridge in its place): their
    writer waits until it has all their readers in `nodes`; each reader, except on its
    tick (which it subscribes to only once started), waits until it has the writer. A
    display's reader (the markers') waits for nothing, but its writer counts it: it is
    one of the graph's readers, whose lag is never reported as an outside reader's. Of the
    nodes `composed` in one process, a reader of another's topic takes it inside the
    process (cdpr_msgs_py.runtime.local_bus): that pair has nothing to match."""
    publishers = {node: [] for node in nodes}
    subscriptions = {node: [] for node in nodes}
    for topic in contract.TOPICS.values():
        if (not topic.from_first_tick or topic.writer not in nodes or (topic.lockstep and not lockstep)
                or (topic.simulated and not simulated)):
            continue
        readers = [reader for reader in topic.readers if reader.node in nodes
                   and not (reader.node in composed and topic.writer in composed)
                   and (not reader.pacing or (lockstep and topic.writer in nodes))
                   and (not reader.lockstep or lockstep)
                   and (simulated or not reader.simulated)]
        if readers:
            publishers[topic.writer].append(f'publisher:{topic.name}={len(readers)}')
        for reader in readers:
            if not reader.tick and not reader.display:
                subscriptions[reader.node].append(f'subscription:{topic.name}=1')
    return {node: publishers[node] + subscriptions[node] for node in nodes}


def parser() -> argparse.ArgumentParser:
    """cdpr-graph's options, which are also the launch files' arguments (launching.py)."""
    options = argparse.ArgumentParser(description=__doc__)
    options.add_argument('--config', default=DEFAULT_ROBOT, help='robot file or set-up (YAML)')
    options.add_argument('--motions', default=DEFAULT_MOTIONS, help='motions YAML')
    options.add_argument('--motion', default='circle', help='named motion')
    options.add_argument('--fidelity', choices=FIDELITIES,
                         help="plant model (default: the config's plant.fidelity); the supervisor "
                              "gets the thresholds calibrated for it")
    options.add_argument('--clock', choices=['lockstep', 'realtime'], default='lockstep')
    add_graph_form_option(options)
    options.add_argument('--detector', choices=['threshold', 'cusum'],
                         help="failure detector (default: the config's fdi.detector)")
    options.add_argument('--calibration', help='detector thresholds (cdpr-calibrate) for the supervisor')
    options.add_argument('--fail-cable', type=int, action='append', default=[], metavar='K',
                         help='break cable K (1-based) during the motion; repeat for several')
    options.add_argument('--fail-at-fraction', type=float, metavar='F',
                         help='when, as a fraction of the move (default 0.5, the midpoint)')
    add_push_option(options)
    options.add_argument('--namespace', default=DEFAULT_NAMESPACE)
    options.add_argument('--bag', help='record every topic into this bag folder')
    options.add_argument('--hardware', action='store_true',
                         help='no plant simulator: a hardware bridge publishes joint_states and '
                              'applies effort_command (see docs/hardware.md); realtime; runs '
                              'until Ctrl-C')
    return options


def requested_graph(args: argparse.Namespace) -> tuple[list[NodeSpec], Section]:
    """The nodes `args` (parser()'s) ask for, each with the parameters of the run settled
    as cdpr-scenario settles it (thresholds that match the plant, among the rest), and
    that settled run."""
    scenario = build_scenario(ScenarioOptions(
        config=args.config, motions=args.motions, motion=args.motion, fidelity=args.fidelity,
        detector=args.detector, calibration=args.calibration, fail_cables=args.fail_cable,
        fail_at_fraction=args.fail_at_fraction, pushes=[tuple(push) for push in args.push]))
    parameters = scenario.node_parameters('realtime' if args.hardware else args.clock)
    return graph_nodes(parameters, args.bag, plant=not args.hardware, form=args.graph_form), scenario.settings


@command('cdpr-graph')
def main(argv=None):
    args = parser().parse_args(argv)
    nodes, _ = requested_graph(args)
    signal.signal(signal.SIGTERM, stop_on_sigterm)
    log = lambda line: print(line, flush=True)  # noqa: E731
    try:
        if args.hardware:
            run_until_stopped(nodes, args.namespace, log)
        else:
            run_to_completion(nodes, args.namespace, timeout_s=None, log=log)
    except KeyboardInterrupt:
        print('[cdpr-graph] stopped on request', flush=True)
        return INTERRUPTED_EXIT_CODE
    except GraphError as err:
        print(f'[cdpr-graph] {err}', flush=True)
        return 1
    return 0


def stop_on_sigterm(_signum, _frame):
    """Let SIGTERM stop the graph the way Ctrl-C does."""
    raise KeyboardInterrupt


if __name__ == '__main__':
    sys.exit(main())
