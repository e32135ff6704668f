"""The node's spin loop: its inputs taken straight from one rcl wait set, the rest through rclpy.

rclpy's SingleThreadedExecutor gathers the node's entities and builds a new wait set in Python at
every wake-up (``Executor._wait_for_ready_callbacks``: a context manager per entity, a readiness
check per waitable): ~250-300 µs of CPU per wake-up for a node whose callback does nothing
(docs/performance.md) — once per input message, as much as the monitoring step itself.
``InputSpinner`` keeps one wait set of the node's waitable handles (subscriptions, timers,
services, clients, guard conditions; gathered again after every wake-up that is not an input's,
the only time the node can create an entity) and at each wake-up:

- anything else is ready (the heartbeat timer, a parameter service, /clock with use_sim_time, a
  guard condition): first one ``executor.spin_once(timeout_sec=0)``, rclpy's own dispatch for these
  rare wake-ups (a guard condition's trigger is consumed by the wait that saw it, so the spinner
  triggers it again for the executor's own wait to see)
  (first: a /clock message that arrived with an input sets the node's clock before the input is
  judged by it, as under rclpy's executor, which takes /clock first; ``make demo`` replays with
  use_sim_time and depends on it);
- an input subscription is ready: ``take_inputs`` (the node's drain) takes the queued inputs
  itself, in arrival order;
- nothing within the timeout: it returns, so that the caller's loop (and a signal handler) runs.

rclpy's event handlers of the node's own publishers (/rosout, /parameter_events QoS events) are
not in the wait set: rclpy's dispatch serves them at the next wake-up that is not an input's (the
heartbeat's, at the latest). The inputs' own events are taken at the heartbeat
(``ros.input_events``).
"""

from __future__ import annotations

from typing import Any, Callable, Literal

from rclpy.executors import Executor
from rclpy.node import Node

from .rcl_private import wait_set

# wait-set entities that are never inputs
OTHER_KINDS: tuple[Literal["timer", "service", "client", "guard_condition"], ...] = (
    "timer", "service", "client", "guard_condition")


class InputSpinner:
    """Spins ``node`` (added to ``executor``), the subscriptions ``inputs()`` gives worked off by
    ``take_inputs``. ``inputs`` is asked again with every gathering: a managed node subscribes its
    inputs at activation, a wake-up that is not an input's."""

    def __init__(self, node: Node, executor: Executor, inputs: Callable[[], list[Any]],
                 take_inputs: Callable[[], None]) -> None:
        self._node, self._executor, self._take_inputs, self._input_subscriptions = node, executor, take_inputs, inputs
        self._gather()

    def _gather(self) -> None:
        """The node's waitable handles, and a wait set sized for them."""
        node = self._node
        self._inputs = {sub.handle.pointer for sub in self._input_subscriptions()}
        self._subscriptions = [s.handle for s in node.subscriptions]
        self._timers = [t.handle for t in node.timers]
        self._services = [s.handle for s in node.services]
        self._clients = [c.handle for c in node.clients]
        self._guard_conditions = {g.handle.pointer: g for g in node.guards}
        self._guards = [g.handle for g in node.guards]
        context = node.context.handle
        assert context is not None, "the node's context is shut down"
        self._wait_set = wait_set(len(self._subscriptions), len(self._guards), len(self._timers),
                                  len(self._clients), len(self._services), context)

    def spin_once(self, timeout_s: float) -> None:
        """Wait up to ``timeout_s`` for work and do what is ready."""
        wait_set = self._wait_set
        wait_set.clear_entities()
        for subscription in self._subscriptions:
            wait_set.add_subscription(subscription)
        for timer in self._timers:
            wait_set.add_timer(timer)
        for service in self._services:
            wait_set.add_service(service)
        for client in self._clients:
            wait_set.add_client(client)
        for guard in self._guards:
            wait_set.add_guard_condition(guard)
        wait_set.wait(int(timeout_s * 1e9))
        ready = wait_set.get_ready_entities("subscription")
        inputs = sum(1 for pointer in ready if pointer in self._inputs)
        if len(ready) > inputs or any(wait_set.get_ready_entities(kind) for kind in OTHER_KINDS):
            for pointer in wait_set.get_ready_entities("guard_condition"):
                self._guard_conditions[pointer].trigger()   # this wait consumed the trigger
            # first, as rclpy's executor would: /clock (use_sim_time) before the inputs judged by it
            self._executor.spin_once(timeout_sec=0)
            self._gather()
        if inputs:
            self._take_inputs()
