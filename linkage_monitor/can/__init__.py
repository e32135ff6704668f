"""CAN bus inputs of the monitor: ISO 11783 / SAE J1939 parameter groups and maker frames
(DBC files, cantools) read from a bus or a log (python-can), mapped onto the mechanism's
measurements (mapping YAML, docs/can-mapping.md) and handed to the monitoring core as the
events its other drivers give it. ROS-free except ``node`` (the live bridge) and ``frame_msg``
(can_msgs/msg/Frame).
"""
