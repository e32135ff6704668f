"""Test-wide set-up: DDS isolation before any rclpy context exists."""

from support.ros_env import isolate_ros_domain

isolate_ros_domain()
