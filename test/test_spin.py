"""The node's spin loop (ros/spin.py InputSpinner) runs what rclpy's executor would run: inputs taken
by the node's drain, everything else (here a timer and a guard condition) through the executor.

A guard condition is the case the loop must hand on: the loop's own wait consumes its trigger, and
the executor's wait that follows would not see it (a CAN bus reader waking the node this way stalled).
"""

from __future__ import annotations

import time

import pytest
from rclpy.executors import SingleThreadedExecutor
from rclpy.qos import QoSProfile
from std_msgs.msg import String

from linkage_monitor.ros.spin import InputSpinner

pytestmark = pytest.mark.ros


@pytest.fixture
def spun(ros):
    """A node with one input subscription, spun by an InputSpinner; yields (node, spinner, taken)."""
    import rclpy

    node = rclpy.create_node("spin_probe")
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    taken: list[bytes] = []
    sub = node.create_subscription(String, "spin_probe_input", lambda m: None, QoSProfile(depth=10), raw=True)

    def take() -> None:
        while (msg := sub.handle.take_message(String, True)) is not None:
            taken.append(msg[0])

    spinner = InputSpinner(node, executor, lambda: [sub], take)
    yield node, spinner, taken
    executor.shutdown()
    node.destroy_node()


def _spin_until(spinner: InputSpinner, done, timeout_s: float = 3.0) -> bool:
    deadline = time.monotonic() + timeout_s
    while not done() and time.monotonic() < deadline:
        spinner.spin_once(0.05)
    return bool(done())


def test_a_triggered_guard_condition_runs_its_callback(spun):
    node, spinner, _ = spun
    fired: list[int] = []
    guard = node.create_guard_condition(lambda: fired.append(1))
    spinner.spin_once(0.0)   # a wake-up that is not an input's gathers the node's entities again
    spinner._gather()        # the guard condition was created after the spinner's first gathering
    guard.trigger()
    assert _spin_until(spinner, lambda: fired), "the guard condition's callback never ran"
    assert fired == [1]


def test_inputs_are_taken_and_timers_run_beside_them(spun):
    node, spinner, taken = spun
    ticks: list[int] = []
    node.create_timer(0.05, lambda: ticks.append(1))
    spinner._gather()
    publisher = node.create_publisher(String, "spin_probe_input", QoSProfile(depth=10))
    deadline = time.monotonic() + 3.0
    while publisher.get_subscription_count() == 0 and time.monotonic() < deadline:
        spinner.spin_once(0.05)
    for k in range(3):
        publisher.publish(String(data=f"input {k}"))
    assert _spin_until(spinner, lambda: len(taken) == 3 and len(ticks) >= 2), (len(taken), len(ticks))
