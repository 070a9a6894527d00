"""The DDS set-up cdpr ships, and the guards around a node's DDS start and its launcher.

Fast DDS's default transports on one machine include shared memory: segments in
/dev/shm named fastdds_port<N>, port 7000 being the discovery port of every domain. A
process killed while it created such a segment leaves it at zero size, and every later
participant that opens it spins for ever inside rcl_node_init, deaf to SIGTERM and
holding the GIL. The shipped profile (fastdds_loopback.xml) uses UDP on the loopback
interface only: no segment is ever opened, and traffic stays on this machine as with
ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST — which cannot be used with it, since rmw_fastrtps
then adds the shared-memory transport back.
"""
from __future__ import annotations

import ctypes
import fcntl
import os
import select
import signal
import sys
import tempfile
from contextlib import contextmanager
from pathlib import Path

PROFILE = Path(__file__).with_name('fastdds_loopback.xml')
PROFILE_VARIABLE = 'FASTDDS_DEFAULT_PROFILES_FILE'
SHARED_MEMORY = Path('/dev/shm')
# How long rclpy.init and the node's construction may take (s) before the node gives
# up: a healthy start takes well under a second, a few under full load of two cores.
# ROS parameters do not exist yet at that point: LIMIT_VARIABLE overrides it.
INITIALISATION_LIMIT_S = 20.0
LIMIT_VARIABLE = 'CDPR_DDS_START_LIMIT_S'
# Set by a launcher for its nodes: its PID, whose death stops them.
LAUNCHER_PID_VARIABLE = 'CDPR_LAUNCHER_PID'
PR_SET_PDEATHSIG = 1


def shipped_environment(environment) -> dict:
    """`environment` with the shipped DDS set-up, unless it names a Fast DDS profile of
    its own (then it is taken as it is: the user has chosen their DDS set-up)."""
    result = dict(environment)
    result.setdefault('RMW_IMPLEMENTATION', 'rmw_fastrtps_cpp')
    if PROFILE_VARIABLE not in result:
        result[PROFILE_VARIABLE] = str(PROFILE)
        result['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'SUBNET'
    return result


def use_shipped_setup() -> None:
    """Give this process (and what it starts) the shipped DDS set-up, before rclpy.init."""
    os.environ.update(shipped_environment(os.environ))


def stale_segments(folder: Path = SHARED_MEMORY) -> list[Path]:
    """Fast DDS port segments of zero size: half-created by a process that died."""
    try:
        return sorted(path for path in folder.glob('fastdds_port*')
                      if not path.name.endswith('_el') and path.stat().st_size == 0)
    except OSError:
        return []


def initialisation_failure(name: str, limit_s: float) -> str:
    """The one line a node prints when its DDS start did not finish."""
    stale = stale_segments()
    if stale:
        cause = (f'stale Fast DDS shared-memory segment(s) {", ".join(map(str, stale))} '
                 f'(left by a killed process)')
    else:
        cause = 'the DDS participant did not start (a stale Fast DDS segment in /dev/shm is the usual cause)'
    return (f'{name}: DDS initialisation did not finish within {limit_s:.0f} s: {cause}; '
            f'fix: use the shipped set-up ({PROFILE_VARIABLE}={PROFILE}, '
            f'ROS_AUTOMATIC_DISCOVERY_RANGE=SUBNET), or remove the segment(s) once no ROS 2 '
            f'process runs')


def initialisation_limit_s() -> float:
    """INITIALISATION_LIMIT_S, or the positive number of seconds LIMIT_VARIABLE gives."""
    text = os.environ.get(LIMIT_VARIABLE)
    if text is None:
        return INITIALISATION_LIMIT_S
    try:
        value = float(text)
    except ValueError:
        value = float('nan')
    if not value > 0 or value == float('inf'):
        raise SystemExit(f'{LIMIT_VARIABLE} must be a positive number of seconds, got {text!r}')
    return value


@contextmanager
def bounded_initialisation(name: str):
    """Run the body (rclpy.init, node construction); if it has not finished within
    initialisation_limit_s(), print one line naming the cause and the fix, and kill
    this process.

    A thread cannot do this: the stuck call holds the GIL. A forked watchdog waits on a
    pipe that the body's end (or this process's death) closes.
    """
    limit_s = initialisation_limit_s()
    read_end, write_end = os.pipe()
    parent = os.getpid()
    watchdog = os.fork()
    if watchdog == 0:
        os.close(write_end)
        finished, _, _ = select.select([read_end], [], [], limit_s)
        if not finished:
            os.write(2, (initialisation_failure(name, limit_s) + '\n').encode())
            os.kill(parent, signal.SIGKILL)
        os._exit(0)
    os.close(read_end)
    try:
        yield
    finally:
        os.close(write_end)
        os.waitpid(watchdog, 0)


def follow_launcher(stop) -> None:
    """When a launcher started this process (LAUNCHER_PID_VARIABLE), ask the kernel for
    SIGTERM at its parent's death (the launcher starts its nodes directly), so a killed
    launcher leaves no orphans; call `stop` now if the launcher is already gone."""
    launcher = os.environ.get(LAUNCHER_PID_VARIABLE)
    if not launcher or not sys.platform.startswith('linux'):
        return
    libc = ctypes.CDLL(None, use_errno=True)
    libc.prctl(PR_SET_PDEATHSIG, signal.SIGTERM, 0, 0, 0)
    if not Path(f'/proc/{launcher}').exists():
        stop(signal.SIGTERM, None)


# Two cdpr graphs in one ROS domain and namespace drive each other's nodes (a second
# supervisor's latched NOMINAL takes the first's controller out of its recovery), so a
# domain is claimed machine-wide: a test session claims a whole domain, a launcher its
# namespace in one. Lock files in the temp folder, held (flock) while the claim lasts.
DOMAIN_CLAIM_VARIABLE = 'CDPR_DOMAIN_CLAIM'   # "<domain>:<pid>" of a whole-domain claim
DOMAIN_IDS = range(1, 233)


class DomainInUse(RuntimeError):
    """Another cdpr process on this machine holds the domain (or its namespace there)."""


def _lock(name: str, exclusive: bool):
    """The open lock file `name`, locked, or None when another process holds it."""
    file = open(Path(tempfile.gettempdir()) / f'cdpr-ros-domain-{name}.lock', 'a+')
    try:
        fcntl.flock(file, (fcntl.LOCK_EX if exclusive else fcntl.LOCK_SH) | fcntl.LOCK_NB)
    except BlockingIOError:
        file.close()
        return None
    return file


def _claimed_by_an_ancestor(domain: int) -> bool:
    held, _, pid = os.environ.get(DOMAIN_CLAIM_VARIABLE, '').partition(':')
    return held == str(domain) and pid.isdigit() and Path(f'/proc/{pid}').exists()


def _claim(domain: int, namespace: str | None) -> list | None:
    if namespace is None:
        if _claimed_by_an_ancestor(domain):
            return []   # a session started by the holder (colcon test's pytest) is part of it
        whole = _lock(str(domain), exclusive=True)
        return None if whole is None else [whole]
    files = [] if _claimed_by_an_ancestor(domain) else [_lock(str(domain), exclusive=False)]
    files.append(_lock(f'{domain}{namespace.replace("/", "_")}', exclusive=True))
    if None in files:
        for file in files:
            if file is not None:
                file.close()
        return None
    return files


def claim_domain(namespace: str | None = None, start: int | None = None) -> list:
    """Claim ROS_DOMAIN_ID machine-wide (all of it without `namespace`, else that namespace
    in it) and set it in os.environ: the one set (DomainInUse if another process holds it),
    else the first free one from `start`. Returns the held lock files: closing them ends
    the claim, as does this process's end."""
    given = os.environ.get('ROS_DOMAIN_ID')
    if given is not None:
        files = _claim(int(given), namespace)
        if files is None:
            raise DomainInUse(f'ROS_DOMAIN_ID={given} is in use by another cdpr graph or test session on '
                              f'this machine' + (f' (namespace {namespace})' if namespace else '')
                              + '; give this run a domain of its own, or unset ROS_DOMAIN_ID')
    else:
        first = (start if start is not None else 1 + os.getpid() % len(DOMAIN_IDS)) - DOMAIN_IDS.start
        for offset in range(len(DOMAIN_IDS)):
            given = str(DOMAIN_IDS[(first + offset) % len(DOMAIN_IDS)])
            files = _claim(int(given), namespace)
            if files is not None:
                break
        else:
            raise DomainInUse('every ROS domain id is claimed on this machine')
        os.environ['ROS_DOMAIN_ID'] = given
    if namespace is None:
        os.environ[DOMAIN_CLAIM_VARIABLE] = f'{given}:{os.getpid()}'
    return files
