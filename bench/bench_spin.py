"""What a wake-up of the spin loop costs: rclpy's SingleThreadedExecutor against the node's
InputSpinner (``linkage_monitor/ros/spin.py``), on a node that does nothing with its input.

A node with the live node's entities (a raw JointState and a FluidPressure subscription, a 1 s
timer, five publishers, rclpy's parameter services) takes JointStates published at RATE Hz by a
second node in this process (its own thread) and does nothing with them; measured is the CPU time
of the spinning (main) thread per message taken — rclpy's wait-set machinery per wake-up, the take
and the dispatch. Each spinner runs REPEATS times, alternating; printed are the medians and their
ratio (InputSpinner / executor).

Run: ``.venv/bin/python bench/bench_spin.py [--rate HZ] [--seconds S] [--repeats R]``
"""

from __future__ import annotations

import argparse
import statistics
import sys
import threading
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "test"))


def one_run(spinner: str, rate: float, seconds: float, run: int) -> float:
    """Main-thread CPU µs per message taken, with ``spinner`` ('executor' or 'InputSpinner')."""
    import rclpy
    from rclpy.event_handler import PublisherEventCallbacks, SubscriptionEventCallbacks
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from sensor_msgs.msg import FluidPressure, JointState
    from std_msgs.msg import String

    from node_load import input_spinner

    qos = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)
    node = rclpy.create_node(f"spin_target_{run}")
    driver = rclpy.create_node(f"spin_driver_{run}")
    taken = [0]

    def take(_: bytes) -> None:
        taken[0] += 1
    events = SubscriptionEventCallbacks(use_default_callbacks=False)   # as the live node's inputs
    inputs = [node.create_subscription(JointState, "joint_states", take, qos, raw=True, event_callbacks=events),
              node.create_subscription(FluidPressure, "pressure", take, qos, raw=True, event_callbacks=events)]
    node.create_timer(1.0, lambda: None)
    for k in range(5):
        node.create_publisher(String, f"out_{k}", 10, event_callbacks=PublisherEventCallbacks(
            use_default_callbacks=False))
    publisher = driver.create_publisher(JointState, "joint_states", qos)
    if spinner == "executor":
        executor = SingleThreadedExecutor()
        executor.add_node(node)

        def spin_once() -> None:
            executor.spin_once(timeout_sec=0.1)
    else:   # a node belongs to one executor: the spinner's own
        lean = input_spinner(node, inputs, take)

        def spin_once() -> None:
            lean.spin_once(0.1)
    end = time.monotonic() + 1.0
    while publisher.get_subscription_count() == 0 or time.monotonic() < end:   # discovery
        spin_once()
    stop = threading.Event()

    def drive() -> None:
        message, due = JointState(name=["a", "b"], position=[1.0, 2.0]), time.perf_counter()
        while not stop.is_set():
            publisher.publish(message)
            due += 1.0 / rate
            time.sleep(max(0.0, due - time.perf_counter()))
    thread = threading.Thread(target=drive)
    thread.start()
    first, cpu, end = taken[0], time.thread_time(), time.monotonic() + seconds
    while time.monotonic() < end:
        spin_once()
    cpu, count = time.thread_time() - cpu, taken[0] - first
    stop.set()
    thread.join()
    node.destroy_node()
    driver.destroy_node()
    return 1e6 * cpu / max(count, 1)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rate", type=float, default=200.0, help="JointStates per second (default 200)")
    parser.add_argument("--seconds", type=float, default=3.0, help="seconds per run (default 3)")
    parser.add_argument("--repeats", type=int, default=3, help="runs per spinner, alternating (default 3)")
    args = parser.parse_args()
    from support.ros_env import isolate_ros_domain

    isolate_ros_domain()
    import rclpy

    rclpy.init()
    found: dict[str, list[float]] = {"executor": [], "InputSpinner": []}
    for run in range(args.repeats):
        for spinner in found:
            found[spinner].append(one_run(spinner, args.rate, args.seconds, run))
    rclpy.shutdown()
    print(f"main-thread CPU per message taken, a node that does nothing with it ({args.rate:g} Hz, "
          f"{args.seconds:g} s x {args.repeats} runs each, alternating):")
    for spinner, values in found.items():
        print(f"  {spinner:13s} median {statistics.median(values):6.0f} us  "
              f"[{', '.join(f'{v:.0f}' for v in values)}]")
    ratio = statistics.median(found["InputSpinner"]) / statistics.median(found["executor"])
    print(f"InputSpinner / rclpy's executor: x{ratio:.2f}")


if __name__ == "__main__":
    main()
