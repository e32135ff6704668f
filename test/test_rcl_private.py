"""The private rclpy calls the node relies on (linkage_monitor/ros/rcl_private.py), exactly as
ros/spin.py and ros/input_events.py make them: a distribution that changes them fails here by name.

In this process: one node with a subscription, a publisher, a timer and a guard condition. The
wait set sees the published message ready (the subscription's handle pointer), the timer ready after
its period and the triggered guard condition; the subscription's two event handles take statuses;
the serialized taker takes what rclpy's raw take takes, with the publisher's GID the graph gives.
"""

from __future__ import annotations

import time

import pytest
from rclpy.event_handler import QoSSubscriptionEventType
from rclpy.qos import QoSProfile, ReliabilityPolicy
from std_msgs.msg import String

from linkage_monitor.ros.rcl_private import SerializedTaker, event_handle, wait_set


@pytest.fixture
def node(ros):
    import rclpy

    node = rclpy.create_node("rcl_private_probe")
    yield node
    node.destroy_node()


def _ready(node, kind: str, timeout_s: float = 2.0) -> list[int]:
    """The ready ``kind`` entities of a wait set of all of ``node``'s handles (as InputSpinner builds it)."""
    subs, guards, timers = list(node.subscriptions), list(node.guards), list(node.timers)
    clients, services = list(node.clients), list(node.services)
    ws = wait_set(len(subs), len(guards), len(timers), len(clients), len(services), node.context.handle)
    deadline = time.monotonic() + timeout_s
    while True:
        ws.clear_entities()   # every wait: the entities added anew (as InputSpinner.spin_once)
        for s in subs:
            ws.add_subscription(s.handle)
        for t in timers:
            ws.add_timer(t.handle)
        for s in services:
            ws.add_service(s.handle)
        for c in clients:
            ws.add_client(c.handle)
        for g in guards:
            ws.add_guard_condition(g.handle)
        ws.wait(int(0.1 * 1e9))
        ready = ws.get_ready_entities(kind)
        if ready or time.monotonic() > deadline:
            return list(ready)


def test_wait_set_sees_a_message_a_timer_and_a_guard_condition(node):
    sub = node.create_subscription(String, "rcl_private_topic", lambda _: None, 10)
    pub = node.create_publisher(String, "rcl_private_topic", 10)
    deadline = time.monotonic() + 5.0
    while sub.get_publisher_count() == 0 and time.monotonic() < deadline:
        time.sleep(0.01)
    pub.publish(String(data="x"))
    assert sub.handle.pointer in _ready(node, "subscription")
    timer = node.create_timer(0.01, lambda: None)
    assert timer.handle.pointer in _ready(node, "timer")
    guard = node.create_guard_condition(lambda: None)
    guard.trigger()
    assert guard.handle.pointer in _ready(node, "guard_condition")
    for kind in ("service", "client"):
        assert _ready(node, kind, timeout_s=0.0) == []


def test_event_handles_take_their_statuses(node):
    """Both events ros/input_events.py takes: a status each with the fields it reads, nothing counted
    on a subscription without publishers (the counting itself: the node tests across processes)."""
    sub = node.create_subscription(String, "rcl_private_events", lambda _: None,
                                   QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE))
    with sub.handle:
        handles = [event_handle(sub.handle, event_type) for event_type in (
            QoSSubscriptionEventType.RCL_SUBSCRIPTION_MESSAGE_LOST,
            QoSSubscriptionEventType.RCL_SUBSCRIPTION_REQUESTED_INCOMPATIBLE_QOS)]
    for handle in handles:
        with handle:
            status = handle.take_event()
        assert status.total_count_change == 0
    assert hasattr(status, "last_policy_kind")
    for handle in handles:
        handle.destroy_when_not_in_use()


def test_serialized_taker_takes_rclpy_s_bytes_and_the_publisher(node):
    """Two messages of two publishers: each taken as rclpy's own raw take gives its bytes (the oracle:
    rclpy's serialize_message), in order, with its sequence number and the GID of the publisher that
    sent it (the graph's endpoint GID, get_publishers_info_by_topic); then nothing (None)."""
    from rclpy.serialization import serialize_message

    qos = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
    sub = node.create_subscription(String, "rcl_private_taker", lambda _: None, qos, raw=True)
    other = node.__class__("rcl_private_other")
    pubs = [node.create_publisher(String, "rcl_private_taker", qos),
            other.create_publisher(String, "rcl_private_taker", qos)]
    deadline = time.monotonic() + 5.0
    while sub.get_publisher_count() < 2 and time.monotonic() < deadline:
        time.sleep(0.01)
    gids = {i.node_name: bytes(bytearray(i.endpoint_gid)) for i in node.get_publishers_info_by_topic("/rcl_private_taker")}
    taker = SerializedTaker(sub)
    sent = [String(data="from the probe"), String(data="from the other node")]
    taken = []
    for pub, msg in zip(pubs, sent):
        pub.publish(msg)
        assert sub.handle.pointer in _ready(node, "subscription")
        taken.append(taker.take())
    assert taker.take() is None
    taker.release()
    other.destroy_node()
    assert [data for data, _ in taken] == [serialize_message(m) for m in sent]
    assert [info["publisher_gid"]["data"] for _, info in taken] == [gids["rcl_private_probe"], gids["rcl_private_other"]]
    assert [info["publication_sequence_number"] for _, info in taken] == [1, 1]
    assert all(info["received_timestamp"] > 0 for _, info in taken)
