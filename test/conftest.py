"""Test-wide set-up: DDS isolation before any rclpy context exists."""

import pytest
import rclpy

from support.ros_env import isolate_ros_domain

isolate_ros_domain()


@pytest.fixture(scope="module")
def ros():
    """An rclpy context in this test process for the tests of one module."""
    rclpy.init()
    yield
    rclpy.shutdown()
