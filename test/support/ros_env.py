"""Isolation of DDS traffic for tests: every test run gets its own ROS domain."""

from __future__ import annotations

import os
import random


def isolate_ros_domain() -> int:
    """Pick a random ROS_DOMAIN_ID for this run (inherited by child processes)."""
    if "LINKAGE_MONITOR_TEST_DOMAIN" not in os.environ:
        os.environ["LINKAGE_MONITOR_TEST_DOMAIN"] = str(random.SystemRandom().randint(1, 101))
    os.environ["ROS_DOMAIN_ID"] = os.environ["LINKAGE_MONITOR_TEST_DOMAIN"]
    os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    return int(os.environ["ROS_DOMAIN_ID"])
