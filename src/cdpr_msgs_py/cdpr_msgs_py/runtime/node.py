"""CdprNode: a node of the graph, with settled parameters, diagnostics, guarded and
watched publishers, sole-writer subscriptions, the start handshake, idle and close hooks."""
from __future__ import annotations

import json
import time
from dataclasses import fields
from pathlib import Path

from rcl_interfaces.msg import SetParametersResult
from rclpy.duration import Duration
from rclpy.node import Node

from .. import contract, qos
from ..conversions import InvalidMessage, joints_from_message
from ..health import AcknowledgementWatch, HealthLimits
from ..scheduling import NICE_RANGE, PRIORITY_RANGE, apply_scheduling
from .acknowledgements import ACKNOWLEDGE_LIMIT_S
from .diagnostics import Diagnostics
from . import local_bus
from .handshake import StartHandshake, parse_matches
from .parameters import DeclaredParameters
from .publishers import GuardedPublisher
from .subscriptions import GraphProbe, SoleWriterSubscription


class CdprNode(DeclaredParameters, StartHandshake, Node):
    """A node of the graph: settled parameters, diagnostics, idle and close hooks.

    Each parameter is declared with a description (`parameter`); one it is given but does
    not declare is reported as ignored (the settled sections of a run are dotted names:
    cdpr_control.setup.settings declares them).
    """

    # The settings a node takes while it runs: the /diagnostics limits. Every other one is
    # read-only (read once; changing it would need the node, or the run, anew).
    CHANGEABLE_SETTINGS = frozenset(f'health.{field.name}' for field in fields(HealthLimits))

    def __init__(self, name: str):
        # composed with the loop's other nodes: their messages to this one stay in the
        # process (local_bus); None alone. Before rclpy's Node makes its own publishers.
        self.bus: local_bus.LocalBus | None = local_bus.current
        # /cdpr unless the command line says otherwise: a node started alone (ros2 run)
        # joins the graph's topics, and `-r __ns:=…` (what launchers pass) overrides this
        super().__init__(name, namespace=contract.DEFAULT_NAMESPACE)
        self.sole_writers: list[SoleWriterSubscription] = []
        self.required_writers: list[SoleWriterSubscription] = []
        self.graph_probe = GraphProbe(self)
        self.clock_mode = self.parameter('clock_mode', 'lockstep',
                                         'lockstep: each tick waits for its command, repeatable; '
                                         'realtime: on the wall clock, as hardware')
        if self.clock_mode not in ('lockstep', 'realtime'):
            raise ValueError(f"parameter clock_mode must be lockstep or realtime, got {self.clock_mode!r}")
        self.diagnostics = Diagnostics(self)
        # configure() sets these from the config file, which this package cannot read
        self.stream_qos = None
        self.view_ticks: contract.ViewTicks | None = None
        self.acknowledgements = AcknowledgementWatch(HealthLimits().reader_lag_limit_s)
        self.add_on_set_parameters_callback(self.on_parameter_changes)
        self.stream_publishers: list[GuardedPublisher] = []
        self.finished = False
        self.match_requirements = parse_matches(self.parameter(
            'matches', [''], "the endpoints to match before subscribing to the tick "
            "('publisher:TOPIC=N', 'subscription:TOPIC=N'; cdpr-graph sets them)"))
        self.last_diagnostics_path = self.parameter(
            'last_diagnostics_path', '', "a file (JSON) this node writes its last /diagnostics "
            "status into as it stops, where a launcher reads what the node did whatever a "
            "recorder kept (cdpr-scenario sets it); '': none")
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
        (`streams`) and which ticks are view ticks, and the limits of the /diagnostics
        levels (`health`); a missing section or key takes its default. Before the first
        create_stream_publisher."""
        streams = config.section('streams', {})
        self.stream_qos = qos.stream_writer(streams, period_s)
        self.view_ticks = contract.ViewTicks.of_streams(streams, period_s)
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
        """As rclpy's, with publishing never fatal (GuardedPublisher); composed, a topic
        of the loop's goes to the process's other nodes inside it (local_bus)."""
        options.setdefault('publisher_class', GuardedPublisher)
        publisher = super().create_publisher(msg_type, topic, qos_profile, **options)
        # looked up when it fails: the diagnostics' own publisher exists before they do
        publisher.failed = lambda name, err: self.diagnostics.publish_failed(name, err)
        if self.bus is not None and self.bus.writes(topic):
            publisher.deliver_locally(self.bus)
        return publisher

    def create_subscription(self, msg_type, topic, callback, qos_profile, **options):
        """As rclpy's; composed, a topic another node of this process writes is taken from
        it inside the process (local_bus), not from DDS (None is returned then). A
        JointState stream of the contract is taken as its CDR bytes, which
        conversions.joints_from_message reads in place (contract.raw_stream)."""
        if self.bus is not None and self.bus.writes(topic):
            self.bus.subscribe(self.resolve_topic_name(topic), callback)
            return None
        options.setdefault('raw', contract.raw_stream(topic))
        return super().create_subscription(msg_type, topic, callback, qos_profile, **options)

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

    def joints_or_reject(self, message, topic: str,
                         fields: tuple[str, ...] = ('position', 'velocity', 'effort')):
        """The message's arrays in `self.names` order, or None after counting a rejection."""
        try:
            return joints_from_message(message, self.names, fields)
        except InvalidMessage as err:
            self.diagnostics.reject(topic, str(err))
            return None

    # When the node's clocked work is due next (monotonic s; None: it has none): the spin
    # loop waits no longer than that, and calls on_due once it is (spin.run_composed).
    due_s: float | None = None

    def on_due(self) -> None:
        """The node's clocked work, at `due_s` (a realtime plant's period): the node sets
        `due_s` again for the next."""

    def idle(self) -> None:
        """Called after every spin: periodic work that needs no timer."""
        self.diagnostics.maybe_publish()
        self.try_start()
        self.graph_probe.idle()

    def write_last_diagnostics(self, path: Path) -> None:
        """The status just published, as JSON into `path` (written whole or not at all)."""
        partial = path.with_name(f'.{path.name}.partial')
        try:
            partial.write_text(json.dumps(self.diagnostics.last_status(), indent=1))
            partial.replace(path)
        except OSError as err:
            self.get_logger().error(f'parameter last_diagnostics_path: cannot write {path}: {err}')

    def keeps_draining(self) -> bool:
        """Whether, stopping, the node keeps draining though quiet (at most
        runtime.spin.DRAIN_LIMIT_S): what it waits for may still come (the recorder's
        writers' last ticks; the recorder's progress, for a plant waiting for it)."""
        return False

    def drain_step(self) -> None:
        """Called after every spin while the node drains (timers no longer fire)."""

    def close(self) -> None:
        """Called once on the way out."""
        self.graph_probe.close()
        self.diagnostics.publish()
        if self.last_diagnostics_path:
            self.write_last_diagnostics(Path(self.last_diagnostics_path))
        # Samples a writer still holds go with its process: a reader that lags (the
        # recorder) would lose the last ticks. Wait until every reliable reader has them.
        deadline = time.monotonic() + ACKNOWLEDGE_LIMIT_S
        for publisher in self.publishers:
            publisher.wait_for_all_acked(Duration(seconds=max(deadline - time.monotonic(), 0.0)))
