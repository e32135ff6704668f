"""The floors of bench_node.py: rclpy nodes that do what linkage_monitor's node must do per input,
with nothing solved.

- default (the relay): republishes every JointState's header as a HitchState on `hitch_state`
  (same QoS as linkage_monitor's node, nothing recorded);
- `--outputs` (the product's floor): takes every JointState serialized (as the node does), records
  it, publishes the node's three outputs of one solved belarus_1221 pose (HingeReactions,
  HitchState, Steerability: bytes made once by the node's encoder, the input's header stamp copied
  in) and records them — the node's per-input publishing and recording, without the monitoring
  step, the markers or /diagnostics. It spins as the node does (``ros.spin.InputSpinner``: its
  input taken from one rcl wait set, not through rclpy's executor); the relay spins with rclpy's.

Usage: .venv/bin/python bench/node_load.py [--outputs --record-dir DIR]   (run by bench/bench_node.py;
Ctrl-C ends it)
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import Any, Callable

import rclpy
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.qos import QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import JointState
from std_msgs.msg import String

from linkage_monitor.msg import HingeReactions, HitchState, Steerability
from linkage_monitor.ros.publishing import LATCHED, OUTPUT_QOS
from linkage_monitor.ros.spin import InputSpinner

INPUT_QOS = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)  # the node's sensor_qos = reliable
STAMP = slice(4, 12)   # CDR bytes of header.stamp: after the 4-byte encapsulation, first in every message here


def solved_outputs() -> tuple[bytes, bytes, bytes]:
    """The node's three output messages of one solved belarus_1221 pose (as bench_node drives it)."""
    from linkage_monitor.mechanics import load_preset
    from linkage_monitor.mechanics.constants import ATMOSPHERIC_PRESSURE
    from linkage_monitor.monitoring.config import MonitorConfig
    from linkage_monitor.monitoring.core import Monitor
    from linkage_monitor.monitoring.events import Event, JointStateEvent, PressureEvent
    from linkage_monitor.wire.outputs import OutputEncoder

    sys.path.insert(0, str(Path(__file__).parent))
    from bench_node import GAUGE, JOINTS, POSE

    mech = load_preset("belarus_1221")
    config = MonitorConfig.default("belarus_1221", mech)
    monitor = Monitor(mech, config)
    now = time.time_ns()
    events: list[Event] = [PressureEvent(next(iter(config.pressure_topics)), GAUGE + ATMOSPHERIC_PRESSURE, now, now),
              JointStateEvent(config.topics.joint_states, JOINTS, POSE, (), now + 1000, now + 1000)]
    out = OutputEncoder().outputs(monitor, monitor.run(events).steps[-1])
    assert out is not None, "the bench pose does not solve"
    return out.hinge_reactions, out.hitch_state, out.steerability


def input_spinner(node: Any, subscriptions: list[Any], take: Callable[[bytes], None]) -> InputSpinner:
    """``node`` spun as linkage_monitor's node spins (``ros.spin.InputSpinner``), every message
    waiting on ``subscriptions`` (raw) handed to ``take``."""
    def take_inputs() -> None:
        for sub in subscriptions:
            while (message := sub.handle.take_message(sub.msg_type, sub.raw)) is not None:
                take(message[0])
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    return InputSpinner(node, executor, lambda: subscriptions, take_inputs)


def main() -> None:
    """Spin until Ctrl-C; publishes a latched `mechanism_description` so the bench knows it is up."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--outputs", action="store_true", help="the product's floor (module docstring)")
    parser.add_argument("--record-dir", type=Path, help="with --outputs: the bag directory to record into")
    args, ros_args = parser.parse_known_args()
    rclpy.init(args=[sys.argv[0], *ros_args])
    node = rclpy.create_node("bench_relay")
    pub = node.create_publisher(HitchState, "hitch_state", OUTPUT_QOS)
    node.create_publisher(String, "mechanism_description", LATCHED).publish(String(data="relay"))
    if args.outputs:
        from linkage_monitor.bag.writer import BagWriter
        from linkage_monitor.wire.outputs import HINGE_REACTIONS, HITCH_STATE, STEERABILITY

        recorder = BagWriter(args.record_dir)
        outputs = [(node.create_publisher(msg_type, topic, OUTPUT_QOS) if topic != "hitch_state" else pub,
                    topic, type_name, bytearray(data))
                   for (msg_type, topic, type_name), data in zip(
                       ((HingeReactions, "hinge_reactions", HINGE_REACTIONS), (HitchState, "hitch_state", HITCH_STATE),
                        (Steerability, "steerability", STEERABILITY)), solved_outputs())]

        def take(data: bytes) -> None:
            now = time.time_ns()
            recorder.write("joint_states", data, now, type_name="sensor_msgs/msg/JointState", qos=INPUT_QOS,
                           log_time_ns=now)
            for publisher, topic, type_name, message in outputs:
                message[STAMP] = data[STAMP]
                out = bytes(message)
                publisher.publish(out)
                recorder.write(topic, out, now, type_name=type_name, qos=OUTPUT_QOS, log_time_ns=now)
        callback: Any = take
        sub = node.create_subscription(JointState, "joint_states", callback, INPUT_QOS, raw=True)

        spinner = input_spinner(node, [sub], take)

        def spin() -> None:   # as the node's main() spins
            while rclpy.ok():
                spinner.spin_once(0.1)
    else:
        recorder = None
        node.create_subscription(JointState, "joint_states", lambda msg: pub.publish(HitchState(header=msg.header)),
                                 INPUT_QOS)

        def spin() -> None:
            rclpy.spin(node)
    try:
        spin()
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        if recorder is not None:
            recorder.close()
        node.destroy_node()
        rclpy.try_shutdown()


if __name__ == "__main__":
    main()
