"""rclpy message objects stamped like the package's outputs (the outputs themselves are written as
CDR bytes by ``wire.outputs``): a std_msgs/Header of an input's stamp."""

from __future__ import annotations

from builtin_interfaces.msg import Time
from std_msgs.msg import Header

from linkage_monitor.wire.cdr import stamp_fields
from linkage_monitor.wire.outputs import FRAME_ID


def header(stamp_ns: int, frame_id: str = FRAME_ID) -> Header:
    """A std_msgs/Header with the given stamp (ns since the epoch) and ``frame_id``."""
    sec, nanosec = stamp_fields(stamp_ns)
    return Header(stamp=Time(sec=int(sec), nanosec=int(nanosec)), frame_id=frame_id)
