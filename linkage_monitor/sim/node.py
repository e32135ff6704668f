"""rclpy publisher of a simulated sensor stream (the physics is in :mod:`linkage_monitor.sim.telemetry`).

Publishes, with ``qos_profile_sensor_data``, at the stream's rate:
- ``<prefix>joint_states`` (``sensor_msgs/JointState``): the angle sensors (rad) and the
  measured cylinders (pin-to-pin length, m), named as in the mechanism's ``measurements``;
- ``<prefix>pressure/<sensor name>`` (``sensor_msgs/FluidPressure``): one per pressure sensor,
  Pa absolute (gauge + 101325 Pa), or gauge with ``gauge=True``; variance = noise sigma².
Every sample of one tick carries the same header stamp: the stream's stamp, which starts at
the node's current time (so a live monitor does not see the samples as stale).
"""

from __future__ import annotations

import time
from typing import Sequence

import rclpy
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rclpy.timer import Timer
from rclpy.qos import qos_profile_sensor_data
from sensor_msgs.msg import FluidPressure, JointState

from linkage_monitor.mechanics import Mechanism
from linkage_monitor.sim.telemetry import Noise, SimulatedStream, simulate


SUBSCRIBER_WAIT_S = 5.0  # s


class SimulatorNode(Node):
    """Publishes ``stream`` one sample per timer tick; ``done`` once it has run out (unless ``loop``)."""

    def __init__(self, mechanism: Mechanism, scenario: str, rate_hz: float, noise: Noise,
                 duration_s: float | None, gauge: bool, prefix: str, loop: bool, seed: int) -> None:
        super().__init__("linkage_simulator")
        self.stream: SimulatedStream = simulate(mechanism, scenario, rate_hz, duration_s, noise, seed,
                                                start_ns=self.get_clock().now().nanoseconds)
        self.gauge = gauge
        self.loop = loop
        self.count = 0            # samples published so far (over all passes)
        self.done = False
        self.joint_pub = self.create_publisher(JointState, f"{prefix}joint_states", qos_profile_sensor_data)
        self.pressure_pubs = {name: self.create_publisher(FluidPressure, f"{prefix}pressure/{name}",
                                                          qos_profile_sensor_data)
                              for name in self.stream.pressure_names}
        self.timer: Timer | None = None
        self._t0_ns = int(self.stream.stamps_ns[0])

    def start(self) -> None:
        """Start publishing, stamping from now."""
        self._t0_ns = self.get_clock().now().nanoseconds
        self.timer = self.create_timer(1.0 / self.stream.rate_hz, self._tick)

    def _tick(self) -> None:
        stream = self.stream
        n = len(stream)
        if self.count >= n and not self.loop:
            self.done = True
            return
        i = self.count % n
        stamp = self._t0_ns + round(self.count * 1e9 / stream.rate_hz)   # continues over passes
        self.joint_pub.publish(stream.joint_state(i, stamp_ns=stamp))
        for name, msg in stream.pressures(i, gauge=self.gauge, stamp_ns=stamp).items():
            self.pressure_pubs[name].publish(msg)
        self.count += 1


def run(mechanism: Mechanism, scenario: str = "lift", rate_hz: float = 50.0, noise: Noise = Noise(),
        duration_s: float | None = None, gauge: bool = False, prefix: str = "", loop: bool = False,
        seed: int = 0, args: Sequence[str] | None = None) -> int:
    """Publish a simulated ``scenario`` of ``mechanism`` until it ends (or forever with ``loop``); returns 0.

    ``args``: ROS arguments for ``rclpy.init`` (``--ros-args -r ...``). Ctrl-C ends it cleanly.
    """
    rclpy.init(args=list(args) if args is not None else None)
    node = None
    try:
        node = SimulatorNode(mechanism, scenario, rate_hz, noise, duration_s, gauge, prefix, loop, seed)
        topics = ", ".join([node.joint_pub.topic_name] + [p.topic_name for p in node.pressure_pubs.values()])
        # Best-effort samples sent before a subscriber has matched are lost: give a monitor that
        # is already running up to SUBSCRIBER_WAIT_S to be found (then publish anyway).
        end = time.monotonic() + SUBSCRIBER_WAIT_S
        publishers = [node.joint_pub, *node.pressure_pubs.values()]
        while time.monotonic() < end and not all(p.get_subscription_count() for p in publishers):
            rclpy.spin_once(node, timeout_sec=0.05)
        node.start()
        node.get_logger().info(f"simulating '{scenario}' of {mechanism.name}: {len(node.stream)} samples at "
                               f"{rate_hz:g} Hz{' (looping)' if loop else ''} on {topics}")
        while rclpy.ok() and not node.done:
            rclpy.spin_once(node, timeout_sec=0.1)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
    return 0
