"""rmw_zenoh's conventions, as plain Python (no Zenoh, no ROS needed): what a ROS 2 node that
uses ``rmw_zenoh_cpp`` (Tier 1 since Kilted) puts on a Zenoh network, so that ``ros2 node
list`` / ``ros2 topic echo`` see our nodes and talk to them.

From ``ros2/rmw_zenoh`` (``docs/design.md``; ``liveliness_utils.cpp``,
``attachment_helpers.cpp``, ``qos.cpp``, ``type_support_common.cpp`` of the Jazzy, Kilted and
rolling branches):

- **Topic key expression** ``<domain>/<topic without its outer slashes>/<type>/<hash>``, e.g.
  ``0/robot_1/odom/nav_msgs::msg::dds_::Odometry_/RIHS01_3cc9…``: the DDS type name
  (``pkg::msg::dds_::Name_``) and the type's RIHS01 hash (REP 2011).
- **Payload**: the message in CDR with its 4-byte encapsulation header (little endian).
- **Attachment** on every sample, 33 bytes: the publisher's sequence number (int64 LE, from 1),
  the source timestamp (int64 LE, ns since the Unix epoch), the GID's length (1 byte, 16) and
  the 16-byte publisher GID (zenoh-ext serialization of ``int64, int64, uint8[16]``).
- **Liveliness tokens** for the graph: ``@ros2_lv/<domain>/<zid>/<nid>/<eid>/<kind>/<enclave>/
  <namespace>/<node>`` for a node (kind ``NN``, ``eid == nid``), and for a publisher (``MP``) or
  subscription (``MS``) also ``/<topic>/<type>/<hash>/<qos>``; every ``/`` inside a name is
  written ``%``, an empty namespace or enclave is ``%``.
- **QoS** in a token: ``<reliability>:<durability>:<history>,<depth>:<deadline s>,<ns>:
  <lifespan s>,<ns>:<liveliness>,<lease s>,<ns>``, each field empty where it is rmw_zenoh's
  default (reliable, volatile, keep last, depth 42, infinite durations, automatic liveliness)
  and otherwise the number of ``rmw/types.h``'s enum.
"""

from __future__ import annotations

import hashlib
import re
import struct
from dataclasses import dataclass

ADMIN_SPACE = "@ros2_lv"
ENTITY_KINDS = ("NN", "MP", "MS", "SS", "SC")
"""Node, publisher, subscription, service server, service client."""
DISTRIBUTIONS = ("jazzy", "kilted", "lyrical")
"""The ROS 2 distributions whose message definitions (and so type hashes) we speak."""
DEFAULT_DISTRIBUTION = "jazzy"
DEFAULT_ROUTER = "tcp/localhost:7447"
"""Where ``ros2 run rmw_zenoh_cpp rmw_zenohd`` listens, and rmw_zenoh's nodes connect."""
GID_SIZE = 16
ATTACHMENT_SIZE = 8 + 8 + 1 + GID_SIZE
CDR_LE_HEADER = b"\x00\x01\x00\x00"

# rmw/types.h enums
RELIABLE, BEST_EFFORT = 1, 2
TRANSIENT_LOCAL, VOLATILE = 1, 2
KEEP_LAST, KEEP_ALL = 1, 2
DEFAULT_DEPTH = 42
"""rmw_zenoh's depth for KEEP_LAST when none is given (an empty depth field)."""

_NAME = re.compile(r"^(/[A-Za-z_][A-Za-z0-9_]*)+$")
_TYPE = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*/msg/[A-Za-z][A-Za-z0-9_]*$")
_HASH = re.compile(r"^RIHS01_[0-9a-f]{64}$")


def check_domain(domain: int) -> int:
    """A ROS domain id (0–232, as ``ROS_DOMAIN_ID``); ``ValueError`` otherwise."""
    if isinstance(domain, bool) or not isinstance(domain, int) or not 0 <= domain <= 232:
        raise ValueError(f"domain must be an integer in [0, 232] (ROS_DOMAIN_ID), got "
                         f"{domain!r}")
    return domain


def check_distribution(distribution: str) -> str:
    """One of :data:`DISTRIBUTIONS`; ``ValueError`` otherwise."""
    if distribution not in DISTRIBUTIONS:
        raise ValueError(f"distribution must be one of {DISTRIBUTIONS}, got {distribution!r}")
    return distribution


def check_topic(name: str) -> str:
    """A fully qualified ROS topic name (``/robot_1/odom``)."""
    if not isinstance(name, str) or not _NAME.match(name):
        raise ValueError(f"topic must be a fully qualified ROS name such as /robot_1/odom, got "
                         f"{name!r}")
    return name


def dds_type(msgtype: str) -> str:
    """``nav_msgs/msg/Odometry`` -> ``nav_msgs::msg::dds_::Odometry_`` (rmw_zenoh's type
    name, the DDS one)."""
    if not _TYPE.match(msgtype):
        raise ValueError(f"msgtype must be a ROS 2 message type such as nav_msgs/msg/Odometry, "
                         f"got {msgtype!r}")
    package, _, name = msgtype.split("/")
    return f"{package}::msg::dds_::{name}_"


def ros_type(dds: str) -> str:
    """The inverse of :func:`dds_type`."""
    match = re.match(r"^([A-Za-z_][A-Za-z0-9_]*)::msg::dds_::([A-Za-z][A-Za-z0-9_]*)_$", dds)
    if match is None:
        raise ValueError(f"not a DDS message type name: {dds!r}")
    return f"{match.group(1)}/msg/{match.group(2)}"


def topic_key(domain: int, topic: str, msgtype: str, type_hash: str) -> str:
    """The key expression a topic's samples are put on."""
    check_domain(domain)
    check_topic(topic)
    if not _HASH.match(type_hash):
        raise ValueError(f"type_hash must be RIHS01_ and 64 hex digits, got {type_hash!r}")
    return f"{domain}/{topic.strip('/')}/{dds_type(msgtype)}/{type_hash}"


def mangle(name: str) -> str:
    """A name as one chunk of a token: every ``/`` written ``%`` (``%`` alone if empty)."""
    return name.replace("/", "%") or "%"


def demangle(chunk: str) -> str:
    return chunk.replace("%", "/")


@dataclass(frozen=True)
class Qos:
    """The QoS settings rmw_zenoh encodes in a token (durations are left infinite)."""

    reliability: int = RELIABLE
    durability: int = VOLATILE
    history: int = KEEP_LAST
    depth: int = DEFAULT_DEPTH

    def __post_init__(self) -> None:
        for name, value, allowed in (("reliability", self.reliability, (RELIABLE, BEST_EFFORT)),
                                     ("durability", self.durability, (TRANSIENT_LOCAL, VOLATILE)),
                                     ("history", self.history, (KEEP_LAST, KEEP_ALL))):
            if value not in allowed:
                raise ValueError(f"{name} must be one of {allowed}, got {value!r}")
        if isinstance(self.depth, bool) or not isinstance(self.depth, int) or self.depth < 0:
            raise ValueError(f"depth must be a non-negative integer, got {self.depth!r}")

    def to_key(self) -> str:
        """The token's QoS chunk: defaults as empty fields."""
        rel = "" if self.reliability == RELIABLE else str(self.reliability)
        dur = "" if self.durability == VOLATILE else str(self.durability)
        hist = "" if self.history == KEEP_LAST else str(self.history)
        depth = "" if self.depth == DEFAULT_DEPTH else str(self.depth)
        return f"{rel}:{dur}:{hist},{depth}:,:,:,,"

    @classmethod
    def from_key(cls, chunk: str) -> Qos:
        """Parses a QoS chunk (durations and liveliness must be rmw_zenoh's defaults, or are
        ignored); ``ValueError`` for a malformed one."""
        parts = chunk.split(":")
        if len(parts) != 6 or "," not in parts[2]:
            raise ValueError(f"not an rmw_zenoh QoS chunk: {chunk!r}")
        hist, depth = parts[2].split(",", 1)
        try:
            return cls(int(parts[0]) if parts[0] else RELIABLE,
                       int(parts[1]) if parts[1] else VOLATILE,
                       int(hist) if hist else KEEP_LAST,
                       int(depth) if depth else DEFAULT_DEPTH)
        except ValueError as exc:
            raise ValueError(f"not an rmw_zenoh QoS chunk: {chunk!r} ({exc})") from None


RELIABLE_VOLATILE = Qos()
"""Odometry, commands, /tf, /clock: reliable, volatile, keep last 42 (lockstep never has more
than one tick in flight)."""
LATCHED = Qos(durability=TRANSIENT_LOCAL, depth=1)
"""/map, /tf_static, the simulator's config and episode: transient local, depth 1 (ROS 2's
latched topics)."""


@dataclass(frozen=True)
class Token:
    """One parsed liveliness token (an entity of the ROS 2 graph)."""

    domain: int
    zid: str
    node_id: int
    entity_id: int
    kind: str
    enclave: str
    namespace: str
    node: str
    topic: str | None = None
    msgtype: str | None = None
    type_hash: str | None = None
    qos: Qos | None = None

    def key(self) -> str:
        """The token's key expression."""
        head = (f"{ADMIN_SPACE}/{self.domain}/{self.zid}/{self.node_id}/{self.entity_id}/"
                f"{self.kind}/{mangle(self.enclave)}/{mangle(self.namespace)}/{self.node}")
        if self.kind == "NN":
            return head
        assert self.topic and self.msgtype and self.type_hash and self.qos
        return (f"{head}/{mangle(self.topic)}/{dds_type(self.msgtype)}/{self.type_hash}/"
                f"{self.qos.to_key()}")

    @property
    def fqn(self) -> str:
        """The node's fully qualified name (``/reynolds_controller``)."""
        return f"{self.namespace.rstrip('/')}/{self.node}"


def node_token(domain: int, zid: str, node_id: int, node: str, namespace: str = "/",
               enclave: str = "") -> Token:
    return Token(check_domain(domain), zid, node_id, node_id, "NN", enclave, namespace, node)


def parse_token(key: str) -> Token:
    """Parses a liveliness token's key expression by rmw_zenoh's grammar; ``ValueError``
    names what is wrong."""
    chunks = str(key).split("/")
    if len(chunks) < 9 or chunks[0] != ADMIN_SPACE:
        raise ValueError(f"not an rmw_zenoh liveliness token (@ros2_lv/<domain>/<zid>/<nid>/"
                         f"<id>/<kind>/<enclave>/<namespace>/<node>[/...]): {key!r}")
    _, domain, zid, nid, eid, kind, enclave, namespace, node, *rest = chunks
    if kind not in ENTITY_KINDS:
        raise ValueError(f"unknown entity kind {kind!r} in {key!r} (one of {ENTITY_KINDS})")
    if not (domain.isdigit() and nid.isdigit() and eid.isdigit()):
        raise ValueError(f"domain, node id and entity id must be decimal in {key!r}")
    if not re.fullmatch(r"[0-9a-f]+", zid):
        raise ValueError(f"the zenoh id must be lowercase hex in {key!r}")
    base = dict(domain=int(domain), zid=zid, node_id=int(nid), entity_id=int(eid), kind=kind,
                enclave=demangle(enclave) if enclave != "%" else "",
                namespace=demangle(namespace), node=node)
    if kind == "NN":
        if rest:
            raise ValueError(f"a node token has 9 chunks, got {len(chunks)}: {key!r}")
        return Token(**base)  # type: ignore[arg-type]
    if len(rest) not in (4, 5):  # rolling adds an optional buffer-backends chunk
        raise ValueError(f"an endpoint token has 13 chunks, got {len(chunks)}: {key!r}")
    topic, dds, type_hash, qos = rest[:4]
    return Token(**base, topic=demangle(topic), msgtype=ros_type(dds),  # type: ignore[arg-type]
                 type_hash=type_hash, qos=Qos.from_key(qos))


def gid(token_key: str) -> bytes:
    """A 16-byte publisher GID derived from its token (rmw_zenoh hashes the token with
    XXH3-128; any stable 16 bytes serve, the GID only tells publishers apart)."""
    return hashlib.blake2b(token_key.encode(), digest_size=GID_SIZE).digest()


def attachment(sequence: int, timestamp_ns: int, source_gid: bytes) -> bytes:
    """A sample's attachment (33 bytes: sequence, timestamp, GID length, GID)."""
    if len(source_gid) != GID_SIZE:
        raise ValueError(f"source_gid must be {GID_SIZE} bytes, got {len(source_gid)}")
    return struct.pack("<qqB", sequence, timestamp_ns, GID_SIZE) + bytes(source_gid)


def parse_attachment(data: bytes) -> tuple[int, int, bytes]:
    """(sequence number, source timestamp ns, GID) of an attachment; ``ValueError`` for
    anything else."""
    data = bytes(data)
    if len(data) != ATTACHMENT_SIZE or data[16] != GID_SIZE:
        raise ValueError(f"an rmw_zenoh attachment is {ATTACHMENT_SIZE} bytes with a GID of "
                         f"{GID_SIZE}, got {len(data)} bytes")
    sequence, stamp = struct.unpack_from("<qq", data)
    return sequence, stamp, data[17:]


def sample_fault(key: str, expected: str, attachment_bytes: bytes | None, payload: bytes,
                 distribution: str) -> tuple[str, str] | None:
    """What is wrong with a sample received by a topic's subscription, before its payload is
    decoded: ``(reason, detail)`` (reasons of :mod:`boids_env.eval.graph.malformed`), or None.

    Args:
        key: the sample's key expression (the subscription takes any type and hash of the
            topic, so that those of other nodes are told, not silently missed).
        expected: the topic's key expression with our type and hash (:func:`topic_key`).
        attachment_bytes: the sample's attachment (None: it has none).
        payload: the sample's payload.
        distribution: whose type hashes are ours, for the message.
    """
    from boids_env.eval.graph.malformed import (
        BAD_ATTACHMENT,
        EMPTY,
        NO_ATTACHMENT,
        WRONG_HASH,
        WRONG_TYPE,
    )

    if key != expected:
        *_, dds, their_hash = key.split("/")
        *_, our_dds, our_hash = expected.split("/")
        if dds != our_dds:
            try:
                name = ros_type(dds)
            except ValueError:
                name = repr(dds)
            return WRONG_TYPE, f"a sample of {name} was put on it"
        return WRONG_HASH, (f"{their_hash} is not {distribution}'s {our_hash}: a node of "
                            f"another ROS 2 distribution? (ours is chosen with "
                            f"--distribution)")
    if attachment_bytes is None:
        return NO_ATTACHMENT, "rmw_zenoh puts its attachment on every sample"
    try:
        parse_attachment(attachment_bytes)
    except ValueError as exc:
        return BAD_ATTACHMENT, str(exc)
    if not payload:
        return EMPTY, "0 bytes"
    return None
