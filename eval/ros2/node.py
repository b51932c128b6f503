"""A minimal ROS 2 node over Zenoh, as ``rmw_zenoh_cpp`` makes one (see
:mod:`boids_env.eval.ros2.wire`): one Zenoh session per node, a liveliness token for the node
and for each of its publishers and subscriptions, CDR payloads with rmw_zenoh's attachment,
transient-local topics through Zenoh's advanced publishers (a cache) and subscribers (history),
as rmw_zenoh implements them.

Messages are rosbags' message objects of the node's distribution
(:class:`Codec`), serialised to CDR by rosbags.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from boids_env.eval.graph.malformed import UNDECODABLE, Counts, MalformedInput
from boids_env.eval.ros2.wire import (
    DEFAULT_ROUTER,
    RELIABLE_VOLATILE,
    TRANSIENT_LOCAL,
    Qos,
    Token,
    attachment,
    check_distribution,
    check_domain,
    check_topic,
    gid,
    node_token,
    parse_token,
    sample_fault,
    topic_key,
)
from boids_env.extras import import_extra


def _zenoh() -> Any:
    return import_extra("zenoh", "ROS 2 over Zenoh needs eclipse-zenoh and rosbags: pip "
                        "install -e '.[ros2]'")


class Codec:
    """One distribution's message types (rosbags' type store): RIHS01 hashes, CDR."""

    def __init__(self, distribution: str) -> None:
        from rosbags.typesys import Stores, get_typestore

        check_distribution(distribution)
        self.distribution = distribution
        self.store = get_typestore(getattr(Stores, f"ROS2_{distribution.upper()}"))
        self.types = self.store.types
        self._hashes: dict[str, str] = {}

    def type_hash(self, msgtype: str) -> str:
        if msgtype not in self._hashes:
            self._hashes[msgtype] = self.store.hash_rihs01(msgtype)
        return self._hashes[msgtype]

    def encode(self, msg: Any, msgtype: str) -> bytes:
        return bytes(self.store.serialize_cdr(msg, msgtype))

    def decode(self, data: bytes, msgtype: str) -> Any:
        return self.store.deserialize_cdr(data, msgtype)


@dataclass(frozen=True)
class Endpoints:
    """Where a node's Zenoh session connects and listens.

    The default is rmw_zenoh's: a peer that connects to the router at
    ``tcp/localhost:7447`` (``ros2 run rmw_zenoh_cpp rmw_zenohd``), listens on a free local
    port, and does no multicast scouting.
    """

    connect: tuple[str, ...] = (DEFAULT_ROUTER,)
    listen: tuple[str, ...] = ("tcp/localhost:0",)

    def config(self) -> Any:
        import json

        zenoh = _zenoh()
        conf = zenoh.Config()
        conf.insert_json5("mode", json.dumps("peer"))
        conf.insert_json5("connect/endpoints", json.dumps(list(self.connect)))
        conf.insert_json5("listen/endpoints", json.dumps(list(self.listen)))
        conf.insert_json5("scouting/multicast/enabled", "false")
        conf.insert_json5("timestamping/enabled", "true")
        return conf


class Publisher:
    """A topic's publisher: :meth:`publish` puts a message's CDR with rmw_zenoh's
    attachment."""

    def __init__(self, node: Node, topic: str, msgtype: str, qos: Qos) -> None:
        zenoh = _zenoh()
        self.topic, self.msgtype, self.qos = topic, msgtype, qos
        self._codec = node.codec
        key = topic_key(node.domain, topic, msgtype, node.codec.type_hash(msgtype))
        # reliable, and blocking rather than dropping: lockstep waits on every message
        options = dict(congestion_control=zenoh.CongestionControl.BLOCK,
                       reliability=zenoh.Reliability.RELIABLE)
        if qos.durability == TRANSIENT_LOCAL:
            import zenoh.ext as zext

            self._pub = zext.declare_advanced_publisher(
                node.session, key, cache=zext.CacheConfig(max(qos.depth, 1)),
                publisher_detection=True, **options)
        else:
            self._pub = node.session.declare_publisher(key, **options)
        self.token = node.declare_endpoint("MP", topic, msgtype, qos)
        self._gid = gid(self.token.key())
        self._sequence = 0
        self._lock = threading.Lock()

    def publish(self, msg: Any) -> None:
        self.publish_bytes(self._codec.encode(msg, self.msgtype))

    def publish_bytes(self, data: bytes) -> None:
        with self._lock:
            self._sequence += 1
            self._pub.put(data, attachment=attachment(self._sequence, time.time_ns(),
                                                      self._gid))


class Node:
    """A ROS 2 node on a Zenoh session.

    Args:
        name: the node's name (``boids_sim``).
        domain: the ROS domain id (``ROS_DOMAIN_ID``).
        distribution: whose message definitions and type hashes (``jazzy`` …).
        endpoints: where the session connects and listens.
        namespace: the node's namespace (``/``).
    """

    def __init__(self, name: str, *, domain: int = 0, distribution: str = "jazzy",
                 endpoints: Endpoints | None = None, namespace: str = "/") -> None:
        zenoh = _zenoh()
        self.name, self.domain, self.namespace = name, check_domain(domain), namespace
        self.codec = Codec(distribution)
        self.endpoints = endpoints or Endpoints()
        self.session = zenoh.open(self.endpoints.config())
        self.zid = str(self.session.zid())
        self._tokens: list[Any] = []
        self._subscribers: list[Any] = []
        self._next_id = 0
        self._graph: dict[str, Token] = {}
        self._graph_lock = threading.Lock()
        self.node = node_token(domain, self.zid, self._new_id(), name, namespace)
        self.dropped = MalformedInput(self.node.fqn)
        """The malformed samples of this node's subscriptions (:attr:`malformed`)."""
        self._tokens.append(self.session.liveliness().declare_token(self.node.key()))
        self._graph_sub = self.session.liveliness().declare_subscriber(
            f"@ros2_lv/{domain}/**", self._on_token, history=True)

    @property
    def fqn(self) -> str:
        return self.node.fqn

    def _new_id(self) -> int:
        value = self._next_id
        self._next_id += 1
        return value

    # ------------------------------------------------------------------------- the graph
    def _on_token(self, sample: Any) -> None:
        key = str(sample.key_expr)
        try:
            token = parse_token(key)
        except ValueError:
            return  # another middleware's, or a newer grammar: not ours to read
        with self._graph_lock:
            if sample.kind == _zenoh().SampleKind.DELETE:
                self._graph.pop(key, None)
            else:
                self._graph[key] = token

    def graph(self) -> list[Token]:
        """Every entity of the domain currently alive (ours included)."""
        with self._graph_lock:
            return list(self._graph.values())

    def endpoints_on(self, topic: str, kind: str) -> list[Token]:
        """The publishers (``MP``) or subscriptions (``MS``) of ``topic`` on the graph, other
        nodes' only."""
        return [t for t in self.graph() if t.kind == kind and t.topic == topic
                and not (t.zid == self.zid and t.node_id == self.node.node_id)]

    def declare_endpoint(self, kind: str, topic: str, msgtype: str, qos: Qos) -> Token:
        token = Token(self.domain, self.zid, self.node.node_id, self._new_id(), kind, "",
                      self.namespace, self.name, check_topic(topic), msgtype,
                      self.codec.type_hash(msgtype), qos)
        self._tokens.append(self.session.liveliness().declare_token(token.key()))
        return token

    # ---------------------------------------------------------------------------- topics
    def publisher(self, topic: str, msgtype: str, qos: Qos = RELIABLE_VOLATILE) -> Publisher:
        return Publisher(self, topic, msgtype, qos)

    def subscribe(self, topic: str, msgtype: str, callback: Callable[[Any], None],
                  qos: Qos = RELIABLE_VOLATILE) -> Token:
        """Calls ``callback(message)`` for every message of ``topic`` (decoded). A sample
        that cannot be read (no rmw_zenoh attachment, an empty or undecodable payload,
        another type or type hash on the topic) or that ``callback`` refuses with a
        ``ValueError`` is dropped and counted in :attr:`malformed`, the first of each topic
        and reason logged (:class:`~boids_env.eval.graph.malformed.MalformedInput`). The
        Zenoh subscriber is declared before the token, so a node that sees the token reaches
        it."""
        on_sample = self._reader(topic, msgtype, callback)
        # any type and hash of the topic (the last two chunks): another distribution's node,
        # or a wrong type, is told once rather than silently never heard
        key = f"{self.domain}/{topic.strip('/')}/*/*"
        if qos.durability == TRANSIENT_LOCAL:
            import zenoh.ext as zext

            sub = zext.declare_advanced_subscriber(
                self.session, key, on_sample,
                history=zext.HistoryConfig(detect_late_publishers=True))
        else:
            sub = self.session.declare_subscriber(key, on_sample)
        self._subscribers.append(sub)
        return self.declare_endpoint("MS", topic, msgtype, qos)

    def _reader(self, topic: str, msgtype: str, callback: Callable[[Any], None]
                ) -> Callable[[Any], None]:
        """The Zenoh callback of a subscription: every sample read under one guard."""
        codec, dropped = self.codec, self.dropped
        expected = topic_key(self.domain, topic, msgtype, codec.type_hash(msgtype))

        def on_sample(sample: Any) -> None:
            payload = b""
            try:
                attached = None if sample.attachment is None else sample.attachment.to_bytes()
                payload = sample.payload.to_bytes()
                fault = sample_fault(str(sample.key_expr), expected, attached, payload,
                                     codec.distribution)
                if fault is not None:
                    dropped.drop(topic, msgtype, *fault)
                    return
                msg = codec.decode(payload, msgtype)
            except Exception as exc:  # rosbags raises several kinds on a bad buffer
                dropped.drop(topic, msgtype, UNDECODABLE,
                             f"{len(payload)} bytes that are not its CDR (cut short, or "
                             f"another message): {exc}")
                return
            dropped.guard(topic, msgtype, callback, msg)

        return on_sample

    @property
    def malformed(self) -> Counts:
        """The samples dropped so far, by topic and reason (see :meth:`subscribe`)."""
        return self.dropped.counts

    def close(self) -> None:
        """Leaves the graph (its tokens vanish) and closes the session."""
        for item in (*self._tokens, *self._subscribers, self._graph_sub):
            try:
                item.undeclare()
            except Exception:  # closing anyway; the session is closed next
                pass
        self._tokens.clear()
        self.session.close()
