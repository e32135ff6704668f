"""Send a CAN log's frames in a separate process, paced, then FAULTS: an error frame, a bus-off
error frame, and a rear hitch status whose position reads 'not available' (0xFF): onto a python-can bus (`bus SPEC`) or as
can_msgs/msg/Frame on a ROS topic (`topic NAME`). The frames keep their identifiers and data; the
bus stamps them on receipt, the topic's messages are stamped with the send time (the bridge's
stamp check judges them against its clock). Prints the number of frames sent.

python test/support/can_sender.py bus udp_multicast:239.74.163.9 LOG FRAMES_PER_S
python test/support/can_sender.py topic /from_can_bus LOG FRAMES_PER_S
"""

from __future__ import annotations

import sys
import time
from dataclasses import replace

import can

from linkage_monitor.can.frames import Frame

FAULTS = (Frame(0, 0x004, False, False, True, 8, bytes(8)),        # error frame: controller problems (class 0x4)
          Frame(0, 0x040, False, False, True, 8, bytes(8)),        # error frame: bus-off (CAN_ERR_BUSOFF)
          Frame(0, 0x0CFE45F0, True, False, False, 8, bytes([0xFF, 0x40, 0xFF, 0xFF, 0xFF, 0x3F, 0, 0])))


def main() -> int:
    mode, target, log, rate = sys.argv[1], sys.argv[2], sys.argv[3], float(sys.argv[4])
    from linkage_monitor.can.frames import to_message
    from linkage_monitor.can.sources import open_bus, read_log

    frames = list(read_log(log)) + list(FAULTS)
    if mode == "bus":
        bus = open_bus(target)

        def send(frame) -> None:
            bus.send(to_message(frame))
    else:
        import rclpy
        from rclpy.qos import QoSProfile, ReliabilityPolicy

        from can_msgs.msg import Frame as FrameMsg
        from linkage_monitor.can.frame_msg import to_msg

        rclpy.init()
        node = rclpy.create_node("can_sender")
        pub = node.create_publisher(FrameMsg, target, QoSProfile(depth=10000, reliability=ReliabilityPolicy.RELIABLE))
        end = time.monotonic() + 30
        while pub.get_subscription_count() == 0 and time.monotonic() < end:
            time.sleep(0.05)

        def send(frame) -> None:
            pub.publish(to_msg(replace(frame, stamp_ns=time.time_ns() // 1000 * 1000)))
    start = time.monotonic()
    for k, frame in enumerate(frames):
        delay = start + k / rate - time.monotonic()
        if delay > 0:
            time.sleep(delay)
        send(frame)
    time.sleep(0.5)
    if mode == "bus":
        bus.shutdown()
    else:
        node.destroy_node()
        rclpy.shutdown()
    print(len(frames))
    return 0


if __name__ == "__main__":
    sys.exit(main())
