"""Play the sensor messages of a bag onto live topics (`ros2 bag play` is not in the PyPI wheels).

Publishes every sensor_msgs/JointState and sensor_msgs/FluidPressure of a rosbag2 MCAP bag on
its recorded topic, in recording order, as the bytes that were recorded (as `ros2 bag play`
does: a message the recording node could not read is played as it came, too), paced at `rate` times
the recorded timing, and (as `ros2 bag play --clock`) the recorded time on /clock before each
message, so a node with `use_sim_time` judges the recorded stamps against the recorded time.
Reliable QoS with a deep history, so a node subscribed reliably loses nothing.
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

from builtin_interfaces.msg import Time
from rclpy.node import Node
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rosgraph_msgs.msg import Clock

from linkage_monitor.bag.decode import message_class
from linkage_monitor.bag.reader import read_bag_raw
from linkage_monitor.bag.step_recorder import RecordedInput
from linkage_monitor.wire.sensor_messages import FLUID_PRESSURE, JOINT_STATE, input_event

from .inputs import REFUSED

PLAYER_QOS = QoSProfile(depth=10_000, reliability=ReliabilityPolicy.RELIABLE)


def recorded_inputs(bag: Path) -> list[RecordedInput]:
    """Every sensor message of ``bag`` the node used, as recorded, in order (the stamp of bytes that do not
    read as their type: their log time); not those it refused (``<topic>/refused``, ``ros.inputs``)."""
    return [RecordedInput(raw.topic, raw.type_name,
                          input_event(raw.type_name, raw.data, raw.topic, raw.log_time_ns).stamp_ns, raw.log_time_ns,
                          raw.data)
            for raw in read_bag_raw(bag)
            if raw.type_name in (JOINT_STATE, FLUID_PRESSURE) and not raw.topic.endswith(REFUSED)]


def play(node: Node, messages: list[RecordedInput], rate: float = 1.0,
         wait_for_subscribers: float = 10.0, min_gap_s: float = 0.0) -> int:
    """Publish `messages` from `node` at `rate` × recorded speed; returns the number published.

    Waits up to `wait_for_subscribers` s until every topic has a subscriber, so nothing is
    sent before the receiving node listens. min_gap_s: s, least time between two messages;
    messages on different topics travel through different DDS writers, which keep no order
    between them, so a gap keeps the recorded order when it matters (e.g. a joint state and
    a pressure with the same stamp).
    """
    publishers: dict[str, Any] = {}
    clock = node.create_publisher(Clock, "/clock", PLAYER_QOS)
    for message in messages:
        if message.topic not in publishers:
            publishers[message.topic] = node.create_publisher(message_class(message.type_name), message.topic,
                                                              PLAYER_QOS)
    end = time.monotonic() + wait_for_subscribers
    while time.monotonic() < end and not all(p.get_subscription_count() for p in publishers.values()):
        time.sleep(0.05)
    time.sleep(0.5)  # a publisher sees the match before the subscriber does
    if not messages:
        return 0
    t0_log, t0_wall = messages[0].receive_ns, time.monotonic()
    due = -min_gap_s
    for message in messages:
        due = max((message.receive_ns - t0_log) * 1e-9 / rate, due + min_gap_s)
        delay = due - (time.monotonic() - t0_wall)
        if delay > 0:
            time.sleep(delay)
        sec, nanosec = divmod(message.stamp_ns, 1_000_000_000)
        clock.publish(Clock(clock=Time(sec=sec, nanosec=nanosec)))
        publishers[message.topic].publish(message.data)
    return len(messages)
