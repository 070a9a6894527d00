"""How the OS schedules a node: SCHED_FIFO priority and niceness, for all its threads.

In realtime mode a command must reach the drive within the 2 ms period. Under the
default time-sharing scheduler, five or six Python processes on two cores delay it in
bursts (measured here: 14–30 % of commands late, the robot drifting from the twin).
So the nodes ask for what cdpr-graph passes them from the config's `scheduling`
section: SCHED_FIFO for the loop (plant or hardware bridge, controller, trajectory
generator), as ros2_control's controller manager does; a lower SCHED_FIFO priority for
the twin and the supervisor, whose recovery setpoints the loop needs after a failure;
niceness for the recorder, which may lag without harm.

Linux applies both per thread: every thread of the process is set, and threads
created later inherit the setting of the thread that creates them.
"""
from __future__ import annotations

import os

PRIORITY_RANGE = (0, 99)
NICE_RANGE = (-20, 19)


def validate(realtime_priority: int, nice: int) -> None:
    """ValueError naming the parameter when a value is outside what Linux accepts."""
    for name, value, (low, high) in (('realtime_priority', realtime_priority, PRIORITY_RANGE),
                                     ('nice', nice, NICE_RANGE)):
        if not isinstance(value, int) or isinstance(value, bool) or not low <= value <= high:
            raise ValueError(f'parameter {name} must be an integer in [{low}, {high}], got {value!r}')


def process_threads() -> list[int]:
    """Thread ids of this process (0, the calling thread, where /proc is absent)."""
    try:
        return [int(tid) for tid in os.listdir('/proc/self/task')]
    except OSError:
        return [0]


def apply_scheduling(realtime_priority: int, nice: int) -> tuple[bool, str]:
    """Set every thread of this process: SCHED_FIFO at `realtime_priority` (0 leaves the
    policy alone), then `nice` (0 leaves it alone). (all applied, what was done or why not).

    A refusal is not an error: the node runs on with normal scheduling and says so.
    """
    validate(realtime_priority, nice)
    done, refused = [], []
    threads = process_threads()
    if realtime_priority:
        try:
            for tid in threads:
                os.sched_setscheduler(tid, os.SCHED_FIFO, os.sched_param(realtime_priority))
            done.append(f'SCHED_FIFO priority {realtime_priority}')
        except (OSError, AttributeError) as err:
            refused.append(f'SCHED_FIFO priority {realtime_priority} refused ({err}); '
                           f'allow it with `ulimit -r {realtime_priority}` (limits.conf rtprio)')
    if nice:
        try:
            for tid in threads:
                os.setpriority(os.PRIO_PROCESS, tid, nice)
            done.append(f'nice {nice}')
        except (OSError, AttributeError) as err:
            refused.append(f'nice {nice} refused ({err})')
    return not refused, '; '.join(done + refused) or 'normal scheduling'


def time_sharing_for_this_thread() -> None:
    """Put the calling thread (not the process: Linux schedules threads) under the normal
    time-sharing policy: a worker of a SCHED_FIFO node that must not take the cores from
    the loop. Where the OS refuses, the thread keeps what it inherited."""
    try:
        os.sched_setscheduler(0, os.SCHED_OTHER, os.sched_param(0))
    except (OSError, AttributeError):
        pass


def below_the_creating_thread() -> None:
    """Put the calling thread one SCHED_FIFO priority below the one it inherited from the
    thread that started it: a worker that takes the cores whenever that thread waits, and
    never while it runs (a worker at the same priority is not preempted by it on a
    core, and their turns at the GIL stalled a node's tick 19 ms here). Left as it is
    where it is not SCHED_FIFO above 1, or where the OS refuses."""
    try:
        priority = os.sched_getparam(0).sched_priority
        if os.sched_getscheduler(0) == os.SCHED_FIFO and priority > 1:
            os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(priority - 1))
    except (OSError, AttributeError):
        pass
