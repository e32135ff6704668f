"""The node's only uses of rclpy's private rcl binding (``rclpy.impl.implementation_singleton``), in
one place: what a ROS 2 distribution may change without notice is here and in
test/test_rcl_private.py, which calls exactly these and fails by name when a distribution breaks them.

Why private: rclpy's public executors (SingleThreadedExecutor, EventsExecutor) build their wait set
anew at every wake-up, in Python; bench/bench_spin.py measures that cost per input message against
``ros.spin.InputSpinner``, which keeps one ``wait_set`` of the node's handles. The inputs'
QoS events (lost messages, incompatible QoS) are taken on request at the heartbeat
(``ros.input_events``) through ``event_handle``, where the public API only offers callbacks run by
an executor. The inputs are taken with rcl's own ``rcl_take_serialized_message`` (``SerializedTaker``,
through ctypes): its message info names the publisher (``publisher_gid``), which rclpy's take gives
only from Kilted on (rclpy 9.1; Jazzy's 7.1 leaves it out), and the node tells an input's sources apart
by it (``ros.publishers``, ``monitoring.sources``).

- ``wait_set``: an rcl wait set; used: ``clear_entities``, ``add_subscription`` / ``add_timer`` /
  ``add_service`` / ``add_client`` / ``add_guard_condition`` (rclpy handles), ``wait(timeout_ns)``,
  ``get_ready_entities(kind)`` (handle pointers).
- ``event_handle``: an rcl event of a subscription; used: as a context manager, ``take_event()``
  (a status with ``total_count_change``, ``last_policy_kind``), ``destroy_when_not_in_use()``.
- ``SerializedTaker``: ``rcl_take_serialized_message`` of librcl on a subscription handle's ``pointer``
  (rclpy's rcl_subscription_t *), ``rcutils_uint8_array_init`` / ``_fini`` and
  ``rcutils_get_default_allocator`` of librcutils; the structs rcutils_uint8_array_t,
  rcutils_allocator_t, rmw_message_info_t and rmw_gid_t (RMW_GID_STORAGE_SIZE 16) as Jazzy and
  Kilted declare them.
"""

from __future__ import annotations

import ctypes
from typing import Any

from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy


def wait_set(subscriptions: int, guard_conditions: int, timers: int, clients: int, services: int,
             context_handle: Any) -> Any:
    """An rcl wait set sized for these entities (no events) in the context ``context_handle``."""
    return _rclpy.WaitSet(subscriptions, guard_conditions, timers, clients, services, 0, context_handle)


def event_handle(subscription_handle: Any, event_type: Any) -> Any:
    """The rcl event ``event_type`` (a QoSSubscriptionEventType) of a subscription's handle."""
    return _rclpy.EventHandle(subscription_handle, event_type)


RCL_RET_OK, RCL_RET_SUBSCRIPTION_TAKE_FAILED = 0, 401   # rcl/types.h
GID_STORAGE_SIZE = 16   # rmw/types.h RMW_GID_STORAGE_SIZE (Jazzy, Kilted)
BUFFER_BYTES = 4096     # a taker's first buffer; rcl grows it for a larger message


class _Allocator(ctypes.Structure):
    _fields_ = [("allocate", ctypes.c_void_p), ("deallocate", ctypes.c_void_p), ("reallocate", ctypes.c_void_p),
                ("zero_allocate", ctypes.c_void_p), ("state", ctypes.c_void_p)]


class _Uint8Array(ctypes.Structure):
    _fields_ = [("buffer", ctypes.c_void_p), ("buffer_length", ctypes.c_size_t),
                ("buffer_capacity", ctypes.c_size_t), ("allocator", _Allocator)]


class _Gid(ctypes.Structure):
    _fields_ = [("implementation_identifier", ctypes.c_char_p), ("data", ctypes.c_uint8 * GID_STORAGE_SIZE)]


class _MessageInfo(ctypes.Structure):
    _fields_ = [("source_timestamp", ctypes.c_int64), ("received_timestamp", ctypes.c_int64),
                ("publication_sequence_number", ctypes.c_uint64), ("reception_sequence_number", ctypes.c_uint64),
                ("publisher_gid", _Gid), ("from_intra_process", ctypes.c_bool)]


_rcl = ctypes.CDLL("librcl.so")         # already loaded by rclpy: the same library
_rcutils = ctypes.CDLL("librcutils.so")
_rcutils.rcutils_get_default_allocator.restype = _Allocator
_take = _rcl.rcl_take_serialized_message
_take.argtypes = [ctypes.c_void_p, ctypes.POINTER(_Uint8Array), ctypes.POINTER(_MessageInfo), ctypes.c_void_p]


class SerializedTaker:
    """Takes a subscription's messages serialized with their publisher: ``take`` gives (CDR bytes, message
    info) as rclpy's raw take does — the info a dict of ``source_timestamp``, ``received_timestamp`` (ns),
    ``publication_sequence_number`` and ``publisher_gid`` (``{'implementation_identifier', 'data'}``, the
    shape of Kilted's rclpy) — or None when nothing is waiting. One buffer, reused; ``release`` frees it."""

    def __init__(self, subscription: Any) -> None:
        self._subscription = subscription
        self._buffer = _Uint8Array()
        self._info = _MessageInfo()
        allocator = _rcutils.rcutils_get_default_allocator()
        if _rcutils.rcutils_uint8_array_init(ctypes.byref(self._buffer), ctypes.c_size_t(BUFFER_BYTES),
                                             ctypes.byref(allocator)) != RCL_RET_OK:
            raise MemoryError("rcutils_uint8_array_init failed")
        self._buffer_ref, self._info_ref = ctypes.byref(self._buffer), ctypes.byref(self._info)

    def take(self) -> tuple[bytes, dict] | None:
        """The next message waiting and its info, None if none; InvalidHandle if the subscription is destroyed."""
        handle = self._subscription.handle
        with handle:
            ret = _take(handle.pointer, self._buffer_ref, self._info_ref, None)
        if ret == RCL_RET_SUBSCRIPTION_TAKE_FAILED:
            return None
        if ret != RCL_RET_OK:
            raise RuntimeError(f"rcl_take_serialized_message failed ({ret})")
        info, gid = self._info, self._info.publisher_gid
        return (ctypes.string_at(self._buffer.buffer, self._buffer.buffer_length),
                {"source_timestamp": info.source_timestamp, "received_timestamp": info.received_timestamp,
                 "publication_sequence_number": info.publication_sequence_number,
                 "publisher_gid": {"implementation_identifier": (gid.implementation_identifier or b"").decode(),
                                   "data": bytes(gid.data)}})

    def release(self) -> None:
        """Free the buffer (once; the taker takes nothing after)."""
        if self._buffer.buffer:
            _rcutils.rcutils_uint8_array_fini(ctypes.byref(self._buffer))
            self._buffer.buffer = None
