"""The middleware's events of the node's input subscriptions, taken at the heartbeat.

Two events tell what the node cannot see in the messages themselves: samples lost (the
middleware knows it missed them) and a publisher offering a QoS the subscription cannot match.
rclpy attaches such events to a subscription as event handlers (three per subscription by
default), and its executor adds every handler to its wait set and asks it whether it is ready at
every wake-up — for every input message: ~60-150 µs of the executor's Python per input message
for the node's six handlers (docs/performance.md). The events are rare and reported at the
heartbeat anyway, so the node subscribes without handlers and takes the events' status from the
middleware once per heartbeat: the status carries the count changed since the last take, nothing
is missed between two takes (test_node_trust.py). (rclpy's third default event, a publisher of another type on the
topic, is never raised by the middleware, rmw_fastrtps, with a waited handler either: a String
publisher on a FluidPressure topic raises none.)
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from rclpy.event_handler import QoSSubscriptionEventType

from .rcl_private import event_handle   # rcl's events, as rclpy.event_handler.EventHandler creates and takes them

LOST, INCOMPATIBLE_QOS = "lost", "incompatible QoS"
EVENT_TYPES = {LOST: QoSSubscriptionEventType.RCL_SUBSCRIPTION_MESSAGE_LOST,
               INCOMPATIBLE_QOS: QoSSubscriptionEventType.RCL_SUBSCRIPTION_REQUESTED_INCOMPATIBLE_QOS}


@dataclass(frozen=True)
class InputNotice:
    """``count`` new events of ``kind`` (LOST: samples; INCOMPATIBLE_QOS: publishers) on ``topic``;
    ``policy``: the last incompatible QoS policy's name (INCOMPATIBLE_QOS), else ''."""

    topic: str
    kind: str
    count: int
    policy: str = ""


class InputEvents:
    """The events of the watched subscriptions, taken on request (``take``)."""

    def __init__(self) -> None:
        self._handles: list[tuple[str, str, Any]] = []   # (topic, kind, rcl event handle)

    def watch(self, topic: str, subscription: Any) -> None:
        """Take the events of ``subscription`` (an rclpy Subscription created without event handlers)."""
        for kind, event_type in EVENT_TYPES.items():
            with subscription.handle:
                self._handles.append((topic, kind, event_handle(subscription.handle, event_type)))

    def take(self) -> list[InputNotice]:
        """The events since the last take, one notice per topic and kind that had any."""
        notices = []
        for topic, kind, handle in self._handles:
            with handle:
                status = handle.take_event()
            count = int(getattr(status, "total_count_change", 0)) if status is not None else 0
            if count > 0:
                policy = getattr(status, "last_policy_kind", None)
                notices.append(InputNotice(topic, kind, count, _policy_name(policy) if policy is not None else ""))
        return notices

    def destroy(self) -> None:
        """Release the event handles (before the subscriptions are destroyed)."""
        for _, _, handle in self._handles:
            handle.destroy_when_not_in_use()
        self._handles = []


def _policy_name(policy: Any) -> str:
    """``RMW_QOS_POLICY_RELIABILITY`` -> ``reliability``."""
    return str(getattr(policy, "name", policy)).removeprefix("RMW_QOS_POLICY_").lower()
