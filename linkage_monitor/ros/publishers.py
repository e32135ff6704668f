"""Who published an input message: its publisher's GID (the message info's ``publisher_gid``,
``rcl_private.SerializedTaker``) and the name of the node that owns it, from the ROS graph
(``get_publishers_info_by_topic``), cached by GID and asked again when a GID not in the cache
arrives (at most every REFRESH_S per topic: the graph learns a node's name a little after its
publisher, and a name not yet known stays None until then). Names are full: ``/namespace/node``.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any, Callable

REFRESH_S = 0.1   # s, the graph is asked at most this often per topic for GIDs it did not name


@dataclass(frozen=True)
class Publisher:
    """A message's publisher: its GID (None when the message info does not give it and the topic has not
    exactly one publisher) and its node's full name (None while the graph does not name it)."""

    gid: bytes | None
    name: str | None


def publisher_gid(info: dict) -> bytes | None:
    """The publisher's GID of a message info (``{'data': ...}`` under ``publisher_gid``), None if not given."""
    gid = info.get("publisher_gid")
    return bytes(gid["data"]) if isinstance(gid, dict) and "data" in gid else None


def full_name(namespace: str, name: str) -> str:
    """``/namespace/node`` (``/node`` in the root namespace)."""
    return f"{namespace.rstrip('/')}/{name}"


class PublisherNames:
    """The publishers of the node's input topics by GID; ``graph``: the node's
    ``get_publishers_info_by_topic``."""

    def __init__(self, graph: Callable[[str], list[Any]]) -> None:
        self._graph = graph
        self._names: dict[bytes, str] = {}
        self._asked: dict[str, float] = {}   # topic -> when the graph was last asked (time.monotonic)
        self._only: dict[str, Publisher | None] = {}   # topic -> its one publisher at the last asking

    def of(self, topic: str, info: dict) -> Publisher:
        """The publisher of a message of ``topic`` with message info ``info``."""
        gid = publisher_gid(info)
        name = self._names.get(gid) if gid is not None else None
        if name is not None:
            return Publisher(gid, name)
        self._refresh(topic)
        if gid is None:   # rclpy's own take on Jazzy: the topic's one publisher, if it has one
            return self._only.get(topic) or Publisher(None, None)
        return Publisher(gid, self._names.get(gid))

    def _refresh(self, topic: str) -> None:
        now = time.monotonic()
        if now - self._asked.get(topic, -REFRESH_S) < REFRESH_S:
            return
        self._asked[topic] = now
        publishers = [Publisher(bytes(bytearray(p.endpoint_gid)), full_name(p.node_namespace, p.node_name))
                      for p in self._graph(topic)]
        for p in publishers:
            assert p.gid is not None
            self._names[p.gid] = p.name or ""
        self._only[topic] = publishers[0] if len(publishers) == 1 else None
