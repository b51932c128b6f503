"""Malformed input on a node's topics, transport-free: a sample that cannot be read (cut
short, empty, another message's body, another type or type hash) or whose content the node
refuses is dropped, counted by topic and reason, and the first of each topic and reason is
logged in one line. A bad peer costs one line per kind of fault, never a traceback per sample,
and the node goes on.

``boids ros2 sim|controller`` read every sample under :meth:`MalformedInput.guard` (their
decoding is ours, :class:`~boids_env.eval.ros2.node.Node`); ``boids ros sim|controller``
guard their callbacks the same way (rospy decodes the wire itself). The counts are on the
node (``malformed``), in the simulator's per-episode stats (printed after each episode's
metrics, and in ``config.json``) and printed by every node at shutdown
(:meth:`MalformedInput.summary`).
"""

from __future__ import annotations

import json
import sys
import threading
import traceback
from collections.abc import Callable
from typing import Any

UNDECODABLE = "undecodable"
"""The payload is not the topic's message in CDR: cut short, or another message's body."""
EMPTY = "empty payload"
WRONG_TYPE = "wrong type"
"""A sample of another message type on the topic (its key expression names the type)."""
WRONG_HASH = "wrong type hash"
"""The topic's type with another RIHS01 hash: a node of another ROS 2 distribution."""
NO_ATTACHMENT = "no attachment"
"""A sample without rmw_zenoh's attachment (rmw_zenoh drops those too)."""
BAD_ATTACHMENT = "bad attachment"
REJECTED = "rejected"
"""Decoded, but its content is refused by the node (a ``ValueError`` of the callback)."""
CALLBACK_ERROR = "callback error"
"""The node's callback raised on it: a bug, logged once with its traceback."""

Counts = dict[str, dict[str, int]]
"""Dropped samples by topic, then by reason."""


def _stderr(text: str) -> None:
    print(text, file=sys.stderr, flush=True)


def since(now: Counts, before: Counts) -> Counts:
    """The counts added from ``before`` to ``now`` (topics and reasons without any left
    out)."""
    out: Counts = {}
    for topic, reasons in now.items():
        added = {r: n - before.get(topic, {}).get(r, 0) for r, n in reasons.items()}
        added = {r: n for r, n in added.items() if n > 0}
        if added:
            out[topic] = added
    return out


class MalformedInput:
    """A node's dropped samples (thread-safe: the middleware's callbacks drop, anyone reads).

    Args:
        node: the node's name, heading every line.
        log: where the first sample of each topic and reason is told (stderr; ``rospy.
            logwarn`` for a ROS 1 node).
    """

    def __init__(self, node: str, log: Callable[[str], None] = _stderr) -> None:
        self.node = node
        self._log = log
        self._counts: Counts = {}
        self._lock = threading.Lock()

    def drop(self, topic: str, msgtype: str, reason: str, detail: str = "") -> None:
        """Counts one dropped sample of ``topic`` (whose type is ``msgtype``); the first of
        its topic and reason is logged, naming both and what was wrong (``detail``)."""
        with self._lock:
            reasons = self._counts.setdefault(topic, {})
            first = reason not in reasons
            reasons[reason] = reasons.get(reason, 0) + 1
        if first:
            self._log(f"{self.node}: dropped a malformed sample on {topic} (expected "
                      f"{msgtype}): {reason}" + (f": {detail}" if detail else "")
                      + " (the next ones of this topic and reason are counted, not shown)")

    def guard(self, topic: str, msgtype: str, callback: Callable[[Any], None],
              msg: Any) -> None:
        """Calls ``callback(msg)``; a ``ValueError`` (content the node refuses) drops the
        sample as :data:`REJECTED`, any other exception as :data:`CALLBACK_ERROR` (its
        traceback logged once: a bug, not the peer's fault)."""
        try:
            callback(msg)
        except ValueError as exc:
            self.drop(topic, msgtype, REJECTED, str(exc))
        except Exception as exc:  # a bug: one traceback, not one per sample
            self.drop(topic, msgtype, CALLBACK_ERROR,
                      f"{type(exc).__name__}: {exc}\n{traceback.format_exc()}")

    @property
    def counts(self) -> Counts:
        """A copy of the counts, by topic then reason."""
        with self._lock:
            return {topic: dict(reasons) for topic, reasons in self._counts.items()}

    @property
    def total(self) -> int:
        with self._lock:
            return sum(sum(r.values()) for r in self._counts.values())

    def summary(self) -> str | None:
        """The line a node prints at shutdown (None when nothing was dropped)."""
        counts = self.counts
        if not counts:
            return None
        return (f"{self.node}: malformed samples dropped (by topic and reason): "
                f"{json.dumps(counts, sort_keys=True)}")
