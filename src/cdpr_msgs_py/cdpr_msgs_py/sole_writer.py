"""Which publisher a topic obeys: the one of a named node, pinned by its endpoint GID.

DDS lets any participant on the domain publish on any topic, so a stray `ros2 topic
pub`, a second controller started by hand or a test tool left running would otherwise
drive the motors. The middleware tells a subscriber, with every message, the GID of the
publisher that sent it (rmw message info), and, per topic, which node each publisher GID
belongs to (the ROS graph). This class holds the decision; a node only feeds it those two.

The writer is pinned the first time the graph shows exactly one publisher of the named
node, and stays pinned while that publisher is in the graph: a second node of the same
name that appears later is rejected like any other. When two publishers carry the name
and none is pinned, neither is obeyed (which one is the graph's cannot be told). When the
pinned publisher has left the graph, the next sole publisher of that name is pinned: a
restarted controller is obeyed again.

Names are not credentials: a node that takes the writer's name while no writer is pinned
is obeyed. This guards against accidents; against a malicious participant only DDS
Security (SROS2) can, which the Fast DDS build cdpr installs lacks (docs/hardware.md,
bridge").
"""
from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

# How often (s) the ROS graph is asked about a publisher it could not name yet: a flood
# from an unknown GID must not turn into a flood of graph queries.
LOOKUP_INTERVAL_S = 1.0
# How long (s) the graph may show publishers of the topic without their node, no writer
# pinned, before a second look is due (runtime.subscriptions.GraphProbe): a node's name
# follows its endpoints by ~0.1 s here, by seconds on a loaded machine; a graph that
# dropped the writer's participant and found it again never names it.
UNNAMED_GRACE_S = 2.0


@dataclass(frozen=True)
class Endpoint:
    """A publisher as the ROS graph shows it: its node's fully qualified name (None while
    the graph has seen the publisher but not yet its node) and its GID."""

    node: str | None
    gid: bytes


def qualified_name(namespace: str, name: str) -> str:
    """'/ns/name' of a node (namespace '/' gives '/name')."""
    return f'{namespace.rstrip("/")}/{name}'


class SoleWriter:
    """Admits the messages of one publisher: the one of node `writer` (fully qualified)."""

    def __init__(self, writer: str, lookup_interval_s: float = LOOKUP_INTERVAL_S,
                 unnamed_grace_s: float = UNNAMED_GRACE_S):
        if not writer.startswith('/'):
            raise ValueError(f'the writer must be a fully qualified node name, got {writer!r}')
        self.writer = writer
        self.lookup_interval_s = lookup_interval_s
        self.unnamed_grace_s = unnamed_grace_s
        self.pinned: bytes | None = None
        # The publishers the graph showed without their node when last asked, and since
        # when (no writer pinned) it has shown some.
        self.unnamed: set[bytes] = set()
        self.unnamed_since: float | None = None
        # What the graph said each GID belongs to, and when an unnamed one was last asked about.
        self.names: dict[bytes, str] = {}
        self.asked_at: dict[bytes, float] = {}
        # Why no writer is pinned although publishers of its name exist; '' when none.
        self.problem = ''
        # Rejected publishers: how many of their messages, and how each was last reported.
        self.rejected: dict[bytes, int] = {}
        self.reported: dict[bytes, str] = {}

    def admits(self, gid: bytes) -> bool:
        """The message of publisher `gid` may be obeyed (the per-message check)."""
        return gid == self.pinned

    def lookup_due(self, gid: bytes, now_s: float) -> bool:
        """Ask the graph now about `gid`? Yes for a GID it has not named yet, at most once
        per LOOKUP_INTERVAL_S (counted as asked); a named one needs no second look unless
        no writer is pinned (it may be the writer, restarted)."""
        if gid in self.names and self.pinned is not None:
            return False
        last = self.asked_at.get(gid)
        if last is not None and now_s - last < self.lookup_interval_s:
            return False
        self.asked_at[gid] = now_s
        return True

    def learn(self, endpoints: Iterable[Endpoint]) -> None:
        """What the graph says publishes the topic now: names every GID in it, unpins a
        writer that has left, and pins the writer's publisher when it is the only one."""
        endpoints = list(endpoints)
        for endpoint in endpoints:
            if endpoint.node is not None:
                self.names[endpoint.gid] = endpoint.node
        self.unnamed = {endpoint.gid for endpoint in endpoints if endpoint.node is None}
        if self.pinned is not None and self.pinned not in {e.gid for e in endpoints}:
            self.pinned = None
        if self.pinned is not None:
            return
        candidates = [e.gid for e in endpoints if e.node == self.writer]
        if len(candidates) == 1:
            self.pinned = candidates[0]
            self.problem = ''
        elif candidates:
            self.problem = (f'{len(candidates)} publishers belong to nodes named {self.writer} '
                            f'(GIDs {", ".join(gid.hex() for gid in candidates)}): none is obeyed '
                            f'while it cannot be told which is the graph\'s')

    def second_look_due(self, now_s: float) -> bool:
        """After learning what the node's own graph says: whether it is time to ask another
        participant's — no writer pinned, and the graph has shown publishers of the topic
        without their node for `unnamed_grace_s`."""
        if self.pinned is not None or not self.unnamed:
            self.unnamed_since = None
            return False
        if self.unnamed_since is None:
            self.unnamed_since = now_s
        return now_s - self.unnamed_since >= self.unnamed_grace_s

    def describe(self, gid: bytes) -> str:
        """Who publisher `gid` is, as far as the graph has told."""
        name = self.names.get(gid)
        if name is None:
            return f'a publisher the ROS graph does not name (GID {gid.hex()})'
        if name == self.writer:
            return f'another node named {name} (GID {gid.hex()})'
        return f'node {name} (GID {gid.hex()})'

    def reject(self, gid: bytes) -> tuple[str, bool]:
        """Count a rejected message of `gid`: (who sent it, whether that is news to report
        — a new writer, or one the graph has named since)."""
        self.rejected[gid] = self.rejected.get(gid, 0) + 1
        who = self.describe(gid)
        news = self.reported.get(gid) != who
        self.reported[gid] = who
        return who, news

    def rejected_writers(self) -> str:
        """Every rejected publisher with its count of messages, for /diagnostics."""
        return '; '.join(f'{self.reported[gid]}: {count}' for gid, count in self.rejected.items())
