"""Where a platform's move to its safe pose is planned: at once, or beside a realtime loop.

A recovery sends its brake's first ticks at the naming, and plans the rest of the brake
(its tries), then the move from where the brake brings the platform to rest
(recovery_strategies/braked.py). The in-process engine and a lockstep graph plan them at once:
nothing moves meanwhile. A realtime supervisor cannot stop judging ticks and sending
the brake's references for the up to ~25 ms and ~0.7 s they take to plan on this
machine (docs/platform.md): it plans them on a thread of its own while the platform
brakes.

A planner's `submit(plan, *args, urgent=False)` returns a concurrent.futures.Future of
plan(*args). An urgent plan (the brake's rest, due tens of ms after the naming) is
planned at once by whatever the node's own thread leaves; the others (the move, due
when the brake ends) take what the node and the loop leave.
"""
from __future__ import annotations

import sys
import threading
from concurrent.futures import Future

from cdpr_msgs_py.scheduling import below_the_creating_thread, time_sharing_for_this_thread

# The interpreter's switch interval beside a planning thread (s): a tenth of a 2 ms tick.
SWITCH_INTERVAL_S = 0.0002


def _settle(future: Future, plan, args) -> None:
    try:
        future.set_result(plan(*args))
    except Exception as err:   # handed to whoever reads the future: the recovery's FAULT
        future.set_exception(err)


class PlanAtOnce:
    """Plans on the caller's thread before returning."""

    def submit(self, plan, *args, urgent: bool = False) -> Future:
        future = Future()
        _settle(future, plan, args)
        return future


class PlanInBackground:
    """Plans on a daemon thread. An urgent plan one SCHED_FIFO priority below the node's
    (realtime: below the FDI's, the loop's above both; at time-sharing priority the
    brake's tries took 0.15–0.53 s of wall time for 17–21 ms of CPU on two cores the loop
    mostly fills, 78 ms one below, docs/platform.md); the others at time-sharing
    priority, so that a move planned for up to a second leaves the cores to the node and
    the loop. A thread computing holds the GIL until the interpreter's switch interval
    has passed (5 ms by default) when another asks for it: the node's callbacks, which
    must publish the brake's references within a tick or two, would wait that long at
    each. The planner sets it to `switch_interval_s` for the process."""

    def __init__(self, switch_interval_s: float = SWITCH_INTERVAL_S):
        sys.setswitchinterval(switch_interval_s)

    def submit(self, plan, *args, urgent: bool = False) -> Future:
        future = Future()

        def work():
            if urgent:
                below_the_creating_thread()
            else:
                time_sharing_for_this_thread()
            _settle(future, plan, args)

        threading.Thread(target=work, name='recovery planning', daemon=True).start()
        return future
