"""QoS profiles of the contract (rclpy)."""
import math

from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

from . import contract

# Per-cycle streams, as their readers ask for them: reliable and keep-all, so a node
# that falls behind for a moment (two cores, many processes) catches up instead of
# losing ticks.
STREAM = QoSProfile(history=HistoryPolicy.KEEP_ALL,
                    reliability=ReliabilityPolicy.RELIABLE,
                    durability=DurabilityPolicy.VOLATILE)

# The default of the config's `streams.history_s` (s of ticks a writer keeps).
HISTORY_S = 10.0


def stream_writer(streams, period_s: float) -> QoSProfile:
    """What the writer of a per-cycle stream offers: reliable, keep-last `history_s`
    (the config's `streams` section) of ticks.

    Not keep-all: a keep-all writer keeps every sample until every reliable reader has
    acknowledged it, so one reader that stops reading (`ros2 topic echo` suspended with
    Ctrl-Z) filled its history (5000 samples, 10 s) and every publish then blocked for
    100 ms and failed, which killed the node. A keep-last writer drops its oldest sample
    for such a reader instead and never blocks. Readers that keep up — every node of the
    graph, and the recorder, which may lag — still get every tick as long as they trail by
    less than `history_s`: 10 s is what keep-all allowed before it failed, and memory is
    only used while a reader lags (a volatile writer drops what all have acknowledged).
    """
    history_s = streams.number('history_s', HISTORY_S, positive=True)
    return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=math.ceil(history_s / period_s),
                      reliability=ReliabilityPolicy.RELIABLE,
                      durability=DurabilityPolicy.VOLATILE)


# Verdicts and modes: a late subscriber still gets the last value.
LATCHED = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1,
                     reliability=ReliabilityPolicy.RELIABLE,
                     durability=DurabilityPolicy.TRANSIENT_LOCAL)

DIAGNOSTICS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=10,
                         reliability=ReliabilityPolicy.RELIABLE,
                         durability=DurabilityPolicy.VOLATILE)

# Markers: a second of frames at the default rate (defaults/markers.yaml); a viewer or
# recorder that lags longer loses the oldest, never holds up the writer. Reliable, since
# RViz and Foxglove ask for reliable by default and would not match a best-effort writer.
DISPLAY = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=20,
                     reliability=ReliabilityPolicy.RELIABLE,
                     durability=DurabilityPolicy.VOLATILE)

# What the graph's readers ask for, per kind of topic (contract.Delivery).
FOR_READERS = {contract.Delivery.STREAM: STREAM, contract.Delivery.LATCHED: LATCHED,
               contract.Delivery.DIAGNOSTICS: DIAGNOSTICS, contract.Delivery.DISPLAY: DISPLAY}


def of_readers(topic: str) -> QoSProfile:
    """The QoS the graph's readers of `topic` (as contract.TOPICS names it) ask for: what
    the recorder subscribes with, and what `ros2 bag play` offers again."""
    return FOR_READERS[contract.TOPICS[topic].delivery]
