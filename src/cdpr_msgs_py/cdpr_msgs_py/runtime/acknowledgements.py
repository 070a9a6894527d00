"""Watching a node's per-cycle writers: the instants their readers have acknowledged
everything (health.AcknowledgementWatch reports a reader that lags), and the wait on the
way out for every reliable reader to have what was sent."""
from __future__ import annotations

import ctypes
import threading
import time
from contextlib import contextmanager

from ..stamps import seconds_to_ns

# Each wait lasts at most this long (s), which also bounds how long stopping the watch
# takes; after an acknowledgement the watch rests this long (s), so the node's thread is
# woken once a second per writer.
ACKNOWLEDGEMENT_WAIT_S = 0.5
ACKNOWLEDGEMENT_REST_S = 1.0
RCL_RET_OK, RCL_RET_TIMEOUT = 0, 2
# On the way out, how long a node waits for its reliable readers to have what it sent (s).
ACKNOWLEDGE_LIMIT_S = 2.0


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
