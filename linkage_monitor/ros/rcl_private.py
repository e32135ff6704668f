"""The node's only uses of rclpy's private rcl binding (``rclpy.impl.implementation_singleton``), in
one place: what a ROS 2 distribution may change without notice is here and in
test/test_rcl_private.py, which calls exactly these and fails by name when a distribution breaks them.

Why private: rclpy's public executors (SingleThreadedExecutor, EventsExecutor) build their wait set
anew at every wake-up, in Python; bench/bench_spin.py measures that cost per input message against
``ros.spin.InputSpinner``, which keeps one ``wait_set`` of the node's handles. The inputs'
QoS events (lost messages, incompatible QoS) are taken on request at the heartbeat
(``ros.input_events``) through ``event_handle``, where the public API only offers callbacks run by
an executor.

- ``wait_set``: an rcl wait set; used: ``clear_entities``, ``add_subscription`` / ``add_timer`` /
  ``add_service`` / ``add_client`` / ``add_guard_condition`` (rclpy handles), ``wait(timeout_ns)``,
  ``get_ready_entities(kind)`` (handle pointers).
- ``event_handle``: an rcl event of a subscription; used: as a context manager, ``take_event()``
  (a status with ``total_count_change``, ``last_policy_kind``), ``destroy_when_not_in_use()``.
"""

from __future__ import annotations

from typing import Any

from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy


def wait_set(subscriptions: int, guard_conditions: int, timers: int, clients: int, services: int,
             context_handle: Any) -> Any:
    """An rcl wait set sized for these entities (no events) in the context ``context_handle``."""
    return _rclpy.WaitSet(subscriptions, guard_conditions, timers, clients, services, 0, context_handle)


def event_handle(subscription_handle: Any, event_type: Any) -> Any:
    """The rcl event ``event_type`` (a QoSSubscriptionEventType) of a subscription's handle."""
    return _rclpy.EventHandle(subscription_handle, event_type)
