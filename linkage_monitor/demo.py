"""`make demo`: the main job on the bundled data (grows with the node and the sample bags)."""

from __future__ import annotations

import sys

from rclpy.serialization import serialize_message

from linkage_monitor import msg


def main() -> int:
    """Show the generated message types and their serialized size (foundation stage)."""
    for name in ("HingeReactions", "HitchState", "Steerability"):
        cls = getattr(msg, name)
        print(f"linkage_monitor/msg/{name}: fields {list(cls.get_fields_and_field_types())}, "
              f"empty message {len(serialize_message(cls()))} bytes CDR")
    return 0


if __name__ == "__main__":
    sys.exit(main())
