"""Running nodes: the fastest executor here, one node or a composed group spun until a
stop request, what is queued drained, and a clean shutdown within SHUTDOWN_LIMIT_S."""
from __future__ import annotations

import faulthandler
import gc
import signal
import time
from contextlib import ExitStack

import rclpy
from rclpy.exceptions import ParameterException
from rclpy.executors import ExternalShutdownException
from rclpy.impl.implementation_singleton import rclpy_implementation
from rclpy.signals import SignalHandlerOptions

from ..dds import bounded_initialisation, follow_launcher
from . import local_bus
from .acknowledgements import ACKNOWLEDGE_LIMIT_S, ACKNOWLEDGEMENT_WAIT_S, watching_acknowledgements

SPIN_TIMEOUT_S = 0.05
# On a stop request a node keeps handling what is queued until it has been quiet this
# long (s), at most DRAIN_LIMIT_S, so the last ticks still reach the twin and the bag.
DRAIN_QUIET_S = 0.3
DRAIN_LIMIT_S = 3.0
EXECUTOR_SHUTDOWN_S = 0.5
# The longest a node takes from a stop request to its exit (s): a launcher's grace.
SHUTDOWN_LIMIT_S = DRAIN_LIMIT_S + ACKNOWLEDGEMENT_WAIT_S + ACKNOWLEDGE_LIMIT_S + EXECUTOR_SHUTDOWN_S
# Printed on stdout once the node is constructed: launchers wait for it.
READY_MARK = 'cdpr-node-ready'
# A launcher sends it to a node that has not exited within its grace, before SIGKILL:
# the node writes every thread's Python stack to stderr, so the log says where it hung.
STACK_DUMP_SIGNAL = signal.SIGUSR1


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


def run_composed(node_classes, args=None, names=()) -> int:
    """Create a node of each of `node_classes` in this process, on one executor (ROS 2
    composition), and spin them until a stop request or until one of them sets
    `finished`; then each drains and closes as it would alone. The messages between the
    nodes `names` (their node names) stay in the process (local_bus). A node that cannot
    be built from its parameters logs why in one FATAL line and returns SET_UP_EXIT_CODE."""
    bus = local_bus.current = local_bus.LocalBus(names) if len(names) > 1 else None
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
    # What the nodes hold once built (modules, models, tables: most of the process's
    # objects) leaves the collector's generations: a full collection walked them all and
    # held a realtime loop up for ~20 ms once every few seconds (a tick missed, ~10 lost).
    gc.collect()
    gc.freeze()
    try:
        with ExitStack() as watches:
            for node in nodes:
                watches.enter_context(watching_acknowledgements(node))
            while rclpy.ok() and not stopping and not any(node.finished for node in nodes):
                executor.spin_once(timeout_sec=wait_s(nodes, bus))
                now = time.monotonic()
                for node in nodes:
                    if node.due_s is not None and now >= node.due_s:
                        node.on_due()
                if bus is not None:
                    bus.dispatch()
                for node in nodes:
                    node.idle()
            drain(executor, nodes, bus)
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

def wait_s(nodes, bus) -> float:
    """How long the next spin may wait for a message (s): not at all while the process's own
    messages wait (local_bus), at most until a node's clocked work is due (CdprNode.due_s),
    and at most SPIN_TIMEOUT_S, after which the nodes' idle work runs."""
    if bus is not None and bus.pending:
        return 0.0
    due = [node.due_s for node in nodes if node.due_s is not None]
    return SPIN_TIMEOUT_S if not due else min(SPIN_TIMEOUT_S, max(0.0, min(due) - time.monotonic()))


def drain(executor, nodes, bus=None) -> None:
    """Spin until none of `nodes` has done anything for DRAIN_QUIET_S and none keeps
    draining (CdprNode.keeps_draining), at most DRAIN_LIMIT_S.

    Their timers first stop: what is queued is handled, nothing new is started (a timer
    that kept firing, the markers' frames, kept the node and the recorder busy for the
    whole DRAIN_LIMIT_S)."""
    for node in nodes:
        node.due_s = None
        for timer in node.timers:
            timer.cancel()
    deadline = time.monotonic() + DRAIN_LIMIT_S
    quiet_since = time.monotonic()
    seen = sum(node.diagnostics.activity for node in nodes)
    while rclpy.ok() and time.monotonic() < deadline:
        executor.spin_once(timeout_sec=0.0 if bus is not None and bus.pending else SPIN_TIMEOUT_S)
        if bus is not None:
            bus.dispatch()
        for node in nodes:
            node.drain_step()
        activity = sum(node.diagnostics.activity for node in nodes)
        if activity != seen:
            seen = activity
            quiet_since = time.monotonic()
        elif time.monotonic() - quiet_since > DRAIN_QUIET_S and not any(node.keeps_draining() for node in nodes):
            break
