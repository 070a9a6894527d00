"""Running a node: the fastest executor here, clean shutdown, /diagnostics, and
subscriptions that obey one writer."""
from __future__ import annotations

import ctypes
import faulthandler
import inspect
import math
import signal
import threading
import time
from collections import Counter
from contextlib import ExitStack, contextmanager
from dataclasses import fields

import rclpy
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor, SetParametersResult
from rclpy.duration import Duration
from rclpy.exceptions import ParameterException
from rclpy.executors import ExternalShutdownException
from rclpy.impl.implementation_singleton import rclpy_implementation
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.publisher import Publisher
from rclpy.signals import SignalHandlerOptions

from . import contract, qos
from .contract import INT64_MAX, INT64_MIN
from .dds import bounded_initialisation, follow_launcher
from .conversions import InvalidMessage, joints_from_message
from .health import ERROR, OK, WARN, AcknowledgementWatch, Health, HealthLimits
from .scheduling import NICE_RANGE, PRIORITY_RANGE, apply_scheduling
from .sole_writer import Endpoint, SoleWriter, qualified_name
from .stamps import seconds_to_ns

SPIN_TIMEOUT_S = 0.05
# A condition that repeats (rejected messages, failed publishes, alarms that name no
# cable) is logged at most once per this long (s); /diagnostics counts every one.
LOG_THROTTLE_S = 1.0
# On a stop request a node keeps handling what is queued until it has been quiet this
# long (s), at most DRAIN_LIMIT_S, so the last ticks still reach the twin and the bag.
DRAIN_QUIET_S = 0.3
DRAIN_LIMIT_S = 3.0
# Watching a per-cycle writer's acknowledgements: each wait lasts at most this long (s),
# which also bounds how long stopping the watch takes; after an acknowledgement the
# watch rests this long (s), so the node's thread is woken once a second per writer.
ACKNOWLEDGEMENT_WAIT_S = 0.5
ACKNOWLEDGEMENT_REST_S = 1.0
RCL_RET_OK, RCL_RET_TIMEOUT = 0, 2
# On the way out, how long a node waits for its reliable readers to have what it sent (s).
ACKNOWLEDGE_LIMIT_S = 2.0
EXECUTOR_SHUTDOWN_S = 0.5
# The longest a node takes from a stop request to its exit (s): a launcher's grace.
SHUTDOWN_LIMIT_S = DRAIN_LIMIT_S + ACKNOWLEDGEMENT_WAIT_S + ACKNOWLEDGE_LIMIT_S + EXECUTOR_SHUTDOWN_S
# Printed on stdout once the node is constructed: launchers wait for it.
READY_MARK = 'cdpr-node-ready'
# A launcher sends it to a node that has not exited within its grace, before SIGKILL:
# the node writes every thread's Python stack to stderr, so the log says where it hung.
STACK_DUMP_SIGNAL = signal.SIGUSR1
LEVELS = {OK: DiagnosticStatus.OK, WARN: DiagnosticStatus.WARN, ERROR: DiagnosticStatus.ERROR}


def make_executor():
    """The events executor: ~0.22 ms per hop here, against ~0.3 ms for the single-threaded one."""
    from rclpy.experimental import EventsExecutor
    return EventsExecutor()


# A node that cannot be built from what it was given (a parameter's value, a config
# file): the user's mistake, said in one FATAL line.
SET_UP_ERRORS = (ValueError, OSError, ParameterException)
SET_UP_EXIT_CODE = 1


def run(node_class, args=None) -> int:
    """Create `node_class`, spin it until a stop request or until it sets `finished`.
    A node that cannot be built from its parameters logs why in one FATAL line and
    returns SET_UP_EXIT_CODE."""
    return run_composed([node_class], args)


def run_composed(node_classes, args=None) -> int:
    """Create a node of each of `node_classes` in this process, on one executor (ROS 2
    composition: a message between them is delivered inside the process), and spin them
    until a stop request or until one of them sets `finished`; then each drains and
    closes as it would alone. A node that cannot be built from its parameters logs why
    in one FATAL line and returns SET_UP_EXIT_CODE."""
    stopping = []

    def request_stop(signum, _frame):
        stopping.append(signum)

    signal.signal(signal.SIGINT, request_stop)
    signal.signal(signal.SIGTERM, request_stop)
    faulthandler.register(STACK_DUMP_SIGNAL, all_threads=True)
    follow_launcher(request_stop)
    nodes = []
    with bounded_initialisation(', '.join(node_class.__name__ for node_class in node_classes)):
        try:
            # rclpy's own handlers would invalidate the context on SIGINT, before the drain
            rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
        except rclpy_implementation.RCLError as err:
            # the command line (a parameters file that cannot be read, a bad remap)
            rclpy.logging.get_logger(node_classes[0].__name__).fatal(str(err).splitlines()[0])
            return SET_UP_EXIT_CODE
        for node_class in node_classes:
            try:
                nodes.append(node_class())
            except SET_UP_ERRORS as err:
                rclpy.logging.get_logger(node_class.__name__).fatal(str(err))
                for node in nodes:
                    node.destroy_node()
                rclpy.shutdown()
                return SET_UP_EXIT_CODE
    for node in nodes:
        ignored = node.ignored_parameters()
        if ignored:
            node.get_logger().warning(f'ignored, not parameters of this node: {", ".join(ignored)}')
        print(f'{READY_MARK} {node.get_name()}', flush=True)
    executor = make_executor()
    for node in nodes:
        executor.add_node(node)
    try:
        with ExitStack() as watches:
            for node in nodes:
                watches.enter_context(watching_acknowledgements(node))
            while rclpy.ok() and not stopping and not any(node.finished for node in nodes):
                executor.spin_once(timeout_sec=SPIN_TIMEOUT_S)
                for node in nodes:
                    node.idle()
            drain(executor, nodes)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except Exception:
        # the traceback that follows names the callback, and so the node, that raised
        nodes[0].get_logger().fatal('node failed' if len(nodes) == 1 else
                                    f'one of the composed nodes {", ".join(node.get_name() for node in nodes)} failed',
                                    throttle_duration_sec=0)
        raise
    finally:
        for node in nodes:
            node.close()
        executor.shutdown(timeout_sec=EXECUTOR_SHUTDOWN_S)
        for node in nodes:
            node.destroy_node()
        if rclpy.ok():
            rclpy.shutdown()
    return 0


def rcl_wait_for_all_acked():
    """rcl_publisher_wait_for_all_acked(publisher, timeout_ns), called through ctypes,
    which releases the GIL while it waits: rclpy's Publisher.wait_for_all_acked holds
    it, and a 1 s wait in a thread stopped the node's 2 ms loop for 1 s."""
    function = ctypes.CDLL('librcl.so').rcl_publisher_wait_for_all_acked   # rclpy loaded it
    function.argtypes = [ctypes.c_void_p, ctypes.c_int64]
    function.restype = ctypes.c_int
    return function


@contextmanager
def watching_acknowledgements(node):
    """Inside the block a thread per per-cycle writer of `node` waits for the instants
    its readers have acknowledged everything, and tells node.acknowledgements
    (health.AcknowledgementWatch), which /diagnostics reports lagging readers from."""
    wait = rcl_wait_for_all_acked()
    stop = threading.Event()

    def watch(publisher, topic):
        pointer = publisher.handle.pointer
        while not stop.is_set():
            result = wait(pointer, seconds_to_ns(ACKNOWLEDGEMENT_WAIT_S))
            if result == RCL_RET_OK:
                node.acknowledgements.acknowledged(topic, time.monotonic())
                stop.wait(ACKNOWLEDGEMENT_REST_S)
            elif result != RCL_RET_TIMEOUT:
                # the context is shutting down: nothing to watch, and no busy loop
                stop.wait(ACKNOWLEDGEMENT_WAIT_S)

    threads = []
    for publisher in node.stream_publishers:
        topic = publisher.topic_name
        node.acknowledgements.acknowledged(topic, time.monotonic())
        threads.append(threading.Thread(target=watch, args=(publisher, topic), daemon=True))
        threads[-1].start()
    try:
        yield
    finally:
        # before the node destroys its publishers, which the threads wait on
        stop.set()
        for thread in threads:
            thread.join()


def drain(executor, nodes) -> None:
    """Spin until none of `nodes` has done anything for DRAIN_QUIET_S (at most DRAIN_LIMIT_S).

    Their timers first stop: what is queued is handled, nothing new is started (a timer
    that kept firing, the markers' frames, kept the node and the recorder busy for the
    whole DRAIN_LIMIT_S)."""
    for node in nodes:
        for timer in node.timers:
            timer.cancel()
    deadline = time.monotonic() + DRAIN_LIMIT_S
    quiet_since = time.monotonic()
    seen = sum(node.diagnostics.activity for node in nodes)
    while rclpy.ok() and time.monotonic() < deadline:
        executor.spin_once(timeout_sec=SPIN_TIMEOUT_S)
        activity = sum(node.diagnostics.activity for node in nodes)
        if activity != seen:
            seen = activity
            quiet_since = time.monotonic()
        elif time.monotonic() - quiet_since > DRAIN_QUIET_S:
            break


class Diagnostics:
    """Counts of what a node did and rejected, and its health (health.py), published on
    /diagnostics once a second."""

    def __init__(self, node: Node, period_s: float = 1.0):
        self.node = node
        self.totals: Counter = Counter()
        self.window: Counter = Counter()
        self.rejected: Counter = Counter()
        self.publish_failures: Counter = Counter()
        # What the node wants reported besides counts (key → text), e.g. its verdicts.
        self.facts: dict[str, str] = {}
        # A condition the node cannot do its job in (stale inputs, braked drums), reported
        # as ERROR while it lasts; '' when none.
        self.error = ''
        self.health = Health(HealthLimits())
        self.level = OK   # of the last status published
        self.activity = 0
        self.period_s = period_s
        self.last_publish = time.monotonic()
        self.publisher = node.create_publisher(DiagnosticArray, contract.DIAGNOSTICS, qos.DIAGNOSTICS)

    def count(self, key: str) -> None:
        """One more handled `key` (a message, a tick)."""
        self.totals[key] += 1
        self.window[key] += 1
        self.activity += 1

    def warn(self, key: str, text: str) -> None:
        """An event worth a warning (held for the config's `health.warning_hold_s`)."""
        self.health.warn(key, text, time.monotonic())

    def reject(self, topic: str, reason: str) -> None:
        self.rejected[topic] += 1
        self.activity += 1
        self.warn(f'rejected {topic}', f'rejected messages on {topic}')
        self.node.get_logger().warning(f'rejected a message on {topic}: {reason}',
                                       throttle_duration_sec=LOG_THROTTLE_S)

    def publish_failed(self, topic: str, error: Exception) -> None:
        """A publish raised: the sample is lost (lockstep sends its state again), the node
        goes on."""
        self.publish_failures[topic] += 1
        self.warn(f'publish failed {topic}', f'publishing on {topic} failed')
        self.node.get_logger().warning(f'publishing on {topic} failed: {error}',
                                       throttle_duration_sec=LOG_THROTTLE_S)

    def maybe_publish(self) -> None:
        now = time.monotonic()
        if now - self.last_publish >= self.period_s:
            self.publish(now - self.last_publish)
            self.last_publish = now

    def publish(self, elapsed_s: float = 0.0) -> None:
        now = time.monotonic()
        readers = self.node.stream_readers()
        for topic, seconds in self.node.acknowledgements.lagging(now, readers).items():
            matched, graph = readers[topic]
            key = f'lagging {topic}'
            text = (f'a reader of {topic} lags: not everything acknowledged for {seconds:.1f} s '
                    f'({matched} readers, {"?" if graph is None else graph} of the graph)')
            if key not in self.health.events:
                self.node.get_logger().warning(text)
            self.warn(key, text)
        errors, warnings = self.node.current_problems()
        level, text = self.health.assess(now, [self.error, *errors], warnings)
        if level == ERROR and self.level != ERROR:
            # the console too: whoever watches the node's output, not /diagnostics, learns
            # that it cannot do its job (once per episode, not once a second)
            self.node.get_logger().error(text)
        elif self.level == ERROR and level != ERROR:
            # and that the episode is over, so a log alone tells how long it lasted
            self.node.get_logger().info(f'no longer in error: {text}')
        self.level = level
        status = DiagnosticStatus(level=LEVELS[level], message=text, hardware_id='cdpr',
                                  name=self.node.get_fully_qualified_name())
        pairs = [(f'{key} total', str(value)) for key, value in self.totals.items()]
        if elapsed_s > 0:
            pairs += [(f'{key} rate hz', f'{value / elapsed_s:.1f}') for key, value in self.window.items()]
        pairs += [(f'rejected {key}', str(value)) for key, value in self.rejected.items()]
        pairs += [(f'publish failed {key}', str(value)) for key, value in self.publish_failures.items()]
        pairs += list({**self.facts, **self.node.current_facts()}.items())
        status.values = [KeyValue(key=k, value=v) for k, v in pairs]
        message = DiagnosticArray()
        message.header.stamp = self.node.get_clock().now().to_msg()
        message.status = [status]
        self.publisher.publish(message)
        self.window.clear()


# What the ROS graph (rmw_dds_common) calls the node of a publisher it has discovered
# before that node's own announcement.
UNKNOWN_NODE_NAME = '_NODE_NAME_UNKNOWN_'
# A callback of this signature gets the message info too (rclpy looks at the parameters).
MESSAGE_AND_INFO = inspect.Signature([inspect.Parameter(name, inspect.Parameter.POSITIONAL_ONLY)
                                      for name in ('message', 'info')])


def message_info_callback(handler):
    """`handler(message, info)` as a subscription callback that rclpy hands the message
    info (the publisher's GID) to. rclpy picks that form from the callback's signature;
    its EventsExecutor (rclpy 9.1.2) then calls the callback with one (message, info)
    tuple, its other executors with two arguments: this takes both."""
    def callback(*arguments):
        handler(*(arguments[0] if len(arguments) == 1 else arguments))

    callback.__signature__ = MESSAGE_AND_INFO
    return callback


class SoleWriterSubscription:
    """A subscription whose handler gets only the messages of one node's publisher
    (the SoleWriter rule); any other is rejected, counted as `rejected <topic>` in
    /diagnostics, and its writer named there and in the log (WARN). With `other`, a
    message of any other writer goes there instead, counted as `<topic> from other
    writers` (a recorder keeps it apart)."""

    def __init__(self, node: CdprNode, msg_type, topic: str, handler, qos_profile, writer: str,
                 other=None, raw: bool = False):
        self.node = node
        self.topic = topic
        self.handler = handler
        self.other = other
        self.resolved_topic = node.resolve_topic_name(topic)
        self.core = SoleWriter(writer if writer.startswith('/')
                               else qualified_name(node.get_namespace(), writer))
        self.problem = ''
        node.create_subscription(msg_type, topic, message_info_callback(self.on_message), qos_profile,
                                 raw=raw)

    def on_message(self, message, info) -> None:
        gid = info['publisher_gid']['data']
        if not self.core.admits(gid) and self.core.lookup_due(gid, time.monotonic()):
            self.look_up()
        if self.core.admits(gid):
            self.handler(message)
            return
        who, news = self.core.reject(gid)
        if self.other is not None:
            if news:
                self.node.get_logger().warning(
                    f'a second writer on {self.resolved_topic}: {who}; its messages are kept apart '
                    f'from those of {self.core.writer}')
            self.node.diagnostics.count(f'{self.topic} from other writers')
            self.other(message)
            return
        if news:
            self.node.get_logger().warning(
                f'a second writer on {self.resolved_topic}: {who}; only {self.core.writer} is '
                f'obeyed, the messages of any other are rejected')
        self.node.diagnostics.reject(self.topic, f'not from {self.core.writer} but from {who}')

    def look_up(self) -> None:
        """Tell the core what the ROS graph says publishes the topic."""
        pinned = self.core.pinned
        self.core.learn(Endpoint(None if info.node_name == UNKNOWN_NODE_NAME
                                 else qualified_name(info.node_namespace, info.node_name),
                                 bytes(info.endpoint_gid))
                        for info in self.node.get_publishers_info_by_topic(self.resolved_topic))
        if self.core.pinned is not None and self.core.pinned != pinned:
            self.node.get_logger().info(f'{self.resolved_topic}: obeying {self.writer_fact()}')
        if self.core.problem != self.problem:
            self.problem = self.core.problem
            if self.problem:
                self.node.get_logger().warning(f'{self.resolved_topic}: {self.problem}')

    def known(self) -> bool:
        """Whether the writer is pinned; asks the graph while it is not (before the run)."""
        if self.core.pinned is None:
            self.look_up()
        return self.core.pinned is not None

    def writer_fact(self) -> str:
        if self.core.pinned is None:
            return f'{self.core.writer}, not seen yet' + (f': {self.problem}' if self.problem else '')
        return f'{self.core.writer} (GID {self.core.pinned.hex()})'

    def facts(self) -> dict[str, str]:
        facts = {f'{self.topic} writer': self.writer_fact()}
        if self.core.rejected:
            facts[f'rejected {self.topic} from'] = self.core.rejected_writers()
        return facts


class GuardedPublisher(Publisher):
    """Every publisher of a CdprNode: a publish that fails is counted and reported, never
    fatal (an exception in a callback would end the node, and with it the graph)."""

    failed = None   # CdprNode.create_publisher sets it: failed(topic, error)

    def publish(self, msg) -> None:
        try:
            super().publish(msg)
        except rclpy_implementation.RCLError as err:
            self.failed(self.topic_name, err)

    def publish_if_subscribed(self, build) -> None:
        """Publish `build()` only while a reader is matched: for a topic that no node of
        the loop reads, only the recorder or a viewer (contract.Topic.on_demand). A
        volatile topic loses nothing to an empty room, and building and publishing a
        message costs ~15 µs of CPU (several times that on a loaded machine); the start
        handshake has the recorder matched before the first tick, and a reader that
        joins later gets every message from then on."""
        if self.get_subscription_count():
            self.publish(build())


def parse_matches(entries) -> list[tuple[str, str, int]]:
    """'publisher:TOPIC=N' / 'subscription:TOPIC=N' entries as (kind, topic, N)."""
    requirements = []
    for entry in filter(None, entries):
        kind, _, rest = entry.partition(':')
        topic, _, count = rest.rpartition('=')
        if kind not in ('publisher', 'subscription') or not topic or not count.isdigit():
            raise ValueError(f"parameter matches: expected 'publisher:TOPIC=N' or "
                             f"'subscription:TOPIC=N', got {entry!r}")
        requirements.append((kind, topic, int(count)))
    return requirements


class CdprNode(Node):
    """A node of the graph: settled parameters, diagnostics, idle and close hooks.

    Each parameter is declared with a description (`parameter`); one it is given but does
    not declare is reported as ignored (the settled sections of a run are dotted names:
    cdpr_control.settings declares them).
    """

    # The settings a node takes while it runs: the /diagnostics limits. Every other one is
    # read-only (read once; changing it would need the node, or the run, anew).
    CHANGEABLE_SETTINGS = frozenset(f'health.{field.name}' for field in fields(HealthLimits))

    def __init__(self, name: str):
        # /cdpr unless the command line says otherwise: a node started alone (ros2 run)
        # joins the graph's topics, and `-r __ns:=…` (what launchers pass) overrides this
        super().__init__(name, namespace=contract.DEFAULT_NAMESPACE)
        self.sole_writers: list[SoleWriterSubscription] = []
        self.required_writers: list[SoleWriterSubscription] = []
        self.clock_mode = self.parameter('clock_mode', 'lockstep',
                                         'lockstep: each tick waits for its command, repeatable; '
                                         'realtime: on the wall clock, as hardware')
        if self.clock_mode not in ('lockstep', 'realtime'):
            raise ValueError(f"parameter clock_mode must be lockstep or realtime, got {self.clock_mode!r}")
        self.diagnostics = Diagnostics(self)
        # configure() sets these from the config file, which this package cannot read
        self.stream_qos = None
        self.acknowledgements = AcknowledgementWatch(HealthLimits().reader_lag_limit_s)
        self.add_on_set_parameters_callback(self.on_parameter_changes)
        self.stream_publishers: list[GuardedPublisher] = []
        self.finished = False
        self.match_requirements = parse_matches(self.parameter(
            'matches', [''], "the endpoints to match before subscribing to the tick "
            "('publisher:TOPIC=N', 'subscription:TOPIC=N'; cdpr-graph sets them)"))
        self.pending_start = None
        self.schedule()

    def schedule(self) -> None:
        """The OS scheduling the `realtime_priority` and `nice` parameters ask for
        (cdpr-graph sets them in realtime mode from the config's scheduling section)."""
        applied, outcome = apply_scheduling(
            self.parameter('realtime_priority', 0, 'SCHED_FIFO priority of every thread; 0: normal',
                           value_range=PRIORITY_RANGE),
            self.parameter('nice', 0, 'niceness of every thread; 0: normal', value_range=NICE_RANGE))
        self.diagnostics.facts['scheduling'] = outcome
        if applied:
            self.get_logger().info(f'scheduling: {outcome}')
        else:
            self.get_logger().warning(f'scheduling: {outcome}')

    def configure(self, config, period_s: float) -> None:
        """From the config file (a cdpr_control.config.Section of it: this package reads
        no file) and the control period: how deep the per-cycle writers' history is
        (`streams`), and the limits of the /diagnostics levels (`health`); a missing
        section or key takes its default. Before the first create_stream_publisher."""
        self.stream_qos = qos.stream_writer(config.section('streams', {}), period_s)
        self.set_health_limits(HealthLimits.from_section(config.section('health', {})))

    def set_health_limits(self, limits: HealthLimits) -> None:
        self.diagnostics.health.limits = limits
        self.acknowledgements.limit_s = limits.reader_lag_limit_s

    def on_parameter_changes(self, parameters) -> SetParametersResult:
        """health.* changed while the node runs: the /diagnostics levels follow at once; a
        value they cannot take is refused, saying why. (rclpy refuses read-only ones.)"""
        limits = self.diagnostics.health.limits
        for parameter in parameters:
            if parameter.name in self.CHANGEABLE_SETTINGS:
                try:
                    limits = limits.with_value(parameter.name.split('.', 1)[1], parameter.value)
                except ValueError as err:
                    return SetParametersResult(successful=False, reason=f'{parameter.name} {err}')
        self.set_health_limits(limits)
        return SetParametersResult(successful=True)

    def create_publisher(self, msg_type, topic, qos_profile, **options):
        """As rclpy's, with publishing never fatal (GuardedPublisher)."""
        options.setdefault('publisher_class', GuardedPublisher)
        publisher = super().create_publisher(msg_type, topic, qos_profile, **options)
        # looked up when it fails: the diagnostics' own publisher exists before they do
        publisher.failed = lambda name, err: self.diagnostics.publish_failed(name, err)
        return publisher

    def create_stream_publisher(self, msg_type, topic: str) -> GuardedPublisher:
        """The writer of a per-cycle stream (qos.stream_writer), its readers' lag watched
        while the node runs (watching_acknowledgements)."""
        if self.stream_qos is None:
            raise RuntimeError('configure() the node before creating a stream publisher')
        publisher = self.create_publisher(msg_type, topic, self.stream_qos)
        self.stream_publishers.append(publisher)
        return publisher

    def stream_readers(self) -> dict[str, tuple[int, int | None]]:
        """Per per-cycle topic written here: (readers matched, readers of the graph), the
        latter from the `matches` parameter (None for a node started alone)."""
        graph = {self.resolve_topic_name(topic): count
                 for kind, topic, count in self.match_requirements if kind == 'publisher'}
        return {publisher.topic_name: (publisher.get_subscription_count(),
                                       graph.get(publisher.topic_name, 0) if self.match_requirements else None)
                for publisher in self.stream_publishers}

    def current_problems(self) -> tuple[list[str], list[str]]:
        """(errors, warnings) the node's core finds when /diagnostics goes out, from what
        it counted in the window (before the window is cleared); '' entries are none."""
        return [], []

    def current_facts(self) -> dict[str, str]:
        """Figures computed when /diagnostics goes out (key → text), besides `facts`."""
        return {key: value for subscription in self.sole_writers
                for key, value in subscription.facts().items()}

    def create_sole_writer_subscription(self, msg_type, topic: str, handler, qos_profile,
                                        writer: str, required: bool = True, other=None,
                                        raw: bool = False) -> SoleWriterSubscription:
        """Subscribe `handler` to the messages of node `writer`'s publisher only (a name
        relative to this node's namespace, or fully qualified); if `required`, the node
        starts (see `matched`) only once it knows that publisher. `other`, `raw`: see
        SoleWriterSubscription, rclpy's create_subscription."""
        subscription = SoleWriterSubscription(self, msg_type, topic, handler, qos_profile, writer,
                                              other, raw)
        self.sole_writers.append(subscription)
        if required:
            self.required_writers.append(subscription)
        return subscription

    def parameter(self, name: str, default, description: str, read_only: bool = True,
                  value_range: tuple[float | None, float | None] | None = None,
                  constraints: str = ''):
        """Declare one parameter, read-only unless told; its value. Typed as given (the
        node's loaders judge the value, naming the parameter), an integer given for a
        number taken as that number; typed as `default` when not given. `value_range`
        (low, high; None: unbounded) becomes the descriptor's integer or floating-point
        range, as the value is typed; `constraints` says it in words."""
        if self.has_parameter(name):
            return self.get_parameter(name).value
        value = self.given_value(name, default)
        # A changeable one takes what `ros2 param set` sends (5 for 5.0): the change's
        # callback judges the value.
        descriptor = ParameterDescriptor(description=description, read_only=read_only,
                                         dynamic_typing=not read_only,
                                         additional_constraints=constraints)
        if value_range is not None and not isinstance(value, bool):
            low, high = value_range
            if isinstance(value, int):
                descriptor.integer_range = [IntegerRange(
                    from_value=INT64_MIN if low is None else math.ceil(low),
                    to_value=INT64_MAX if high is None else math.floor(high), step=1)]
            elif isinstance(value, float):
                descriptor.floating_point_range = [FloatingPointRange(
                    from_value=-math.inf if low is None else float(low),
                    to_value=math.inf if high is None else float(high), step=0.0)]
        return self.declare_parameter(name, value, descriptor).value

    def given_value(self, name: str, default):
        """What the command line gave for `name` (an integer given for a number taken as
        that number), else `default`; declares nothing."""
        given = self._parameter_overrides.get(name)   # rclpy keeps what --ros-args gave here
        if given is None:
            return default
        if isinstance(default, float) and given.type_ == Parameter.Type.INTEGER:
            given = Parameter(name, Parameter.Type.DOUBLE, float(given.value))
            self._parameter_overrides[name] = given
        return given.value

    def given_parameters(self) -> dict:
        """Name → value of every parameter this node was started with (--ros-args)."""
        return {name: parameter.value for name, parameter in self._parameter_overrides.items()}

    def ignored_parameters(self) -> list[str]:
        """The parameters the node was given but does not have (a misspelt name)."""
        return sorted(name for name in self._parameter_overrides if not self.has_parameter(name))

    def joints_or_reject(self, message, topic: str,
                         fields: tuple[str, ...] = ('position', 'velocity', 'effort')):
        """The message's arrays in `self.names` order, or None after counting a rejection."""
        try:
            return joints_from_message(message, self.names, fields)
        except InvalidMessage as err:
            self.diagnostics.reject(topic, str(err))
            return None

    def start_when_matched(self, start) -> None:
        """Call `start` (which subscribes to the tick, /cdpr/joint_states) once every
        endpoint named in the `matches` parameter has matched its peers.

        DDS matches endpoints pairwise and late under load: a per-cycle message sent
        before its subscriber matched is lost. The graph launcher names what each node
        must be matched with, and the plant starts only when it sees every node's
        subscription to the tick, so nothing is sent before everyone listens.
        """
        self.pending_start = start
        self.try_start()

    def try_start(self) -> None:
        if self.pending_start is None or not self.matched():
            return
        start, self.pending_start = self.pending_start, None
        start()

    def matched(self) -> bool:
        """True when every required endpoint has matched at least its count of peers and
        every sole-writer subscription knows its writer's publisher, so that the first
        messages of the run are neither lost nor rejected."""
        endpoints = {('publisher', p.topic_name): p.get_subscription_count for p in self.publishers}
        endpoints.update({('subscription', s.topic_name): s.get_publisher_count
                          for s in self.subscriptions})
        for kind, topic, count in self.match_requirements:
            matched = endpoints.get((kind, self.resolve_topic_name(topic)))
            if matched is None or matched() < count:
                return False
        return all(subscription.known() for subscription in self.required_writers)

    def idle(self) -> None:
        """Called after every spin: periodic work that needs no timer."""
        self.diagnostics.maybe_publish()
        self.try_start()

    def close(self) -> None:
        """Called once on the way out."""
        self.diagnostics.publish()
        # Samples a writer still holds go with its process: a reader that lags (the
        # recorder) would lose the last ticks. Wait until every reliable reader has them.
        deadline = time.monotonic() + ACKNOWLEDGE_LIMIT_S
        for publisher in self.publishers:
            publisher.wait_for_all_acked(Duration(seconds=max(deadline - time.monotonic(), 0.0)))
