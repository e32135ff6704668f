"""What a bag says about itself as rosbag2 does: its topics (type, offered QoS, message count), the span
of its messages, the ROS distribution, in a version-9 `metadata.yaml` (and each MCAP file's `rosbag2`
metadata record)."""

from __future__ import annotations

import functools
import importlib.metadata
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Iterable

import yaml
from rclpy.qos import DurabilityPolicy, HistoryPolicy, LivelinessPolicy, QoSProfile, ReliabilityPolicy

ROSBAG2_VERSION = 9
_YAML_DUMPER = getattr(yaml, "CSafeDumper", yaml.SafeDumper)   # libyaml: 4x faster, the same text
# rclpy's release series of each ROS 2 distribution (ros2/rclpy: humble 3.3, iron 5.x, jazzy 7.x, kilted 9.x)
_RCLPY_SERIES = {3: "humble", 5: "iron", 7: "jazzy", 9: "kilted"}


def yaml_text(data: Any, **options: Any) -> str:
    """``yaml.safe_dump(data, sort_keys=False, **options)``'s text, written by libyaml where PyYAML has it
    (a bag's metadata at every flush and file, each channel's QoS, the mechanism it records)."""
    return yaml.dump(data, Dumper=_YAML_DUMPER, sort_keys=False, **options)


def qos_to_dict(qos: QoSProfile) -> dict[str, Any]:
    """Return `qos` as one entry of rosbag2 v9 `offered_qos_profiles` (policy names, sec/nsec)."""

    def duration(ns: int) -> dict[str, int]:
        return {"sec": ns // 1_000_000_000, "nsec": ns % 1_000_000_000}

    return {
        "history": HistoryPolicy(qos.history).name.lower(),
        "depth": int(qos.depth),
        "reliability": ReliabilityPolicy(qos.reliability).name.lower(),
        "durability": DurabilityPolicy(qos.durability).name.lower(),
        "deadline": duration(qos.deadline.nanoseconds),
        "lifespan": duration(qos.lifespan.nanoseconds),
        "liveliness": LivelinessPolicy(qos.liveliness).name.lower(),
        "liveliness_lease_duration": duration(qos.liveliness_lease_duration.nanoseconds),
        "avoid_ros_namespace_conventions": bool(qos.avoid_ros_namespace_conventions),
    }


@functools.lru_cache(maxsize=1)
def ros_distro() -> str:
    """The ROS 2 distribution this process runs on, for metadata.yaml's ``ros_distro``: ROS_DISTRO when
    set (a sourced ROS install), else the distribution in the name of the installed rclpy wheel
    (`ros-<distro>-rclpy`), else the one of rclpy's version (its release series); 'unknown' when none says."""
    if os.environ.get("ROS_DISTRO"):
        return os.environ["ROS_DISTRO"]
    for distro in _RCLPY_SERIES.values():   # the known ones looked up by name: the scan below reads every wheel's
        try:                                # metadata (~0.06 s with ~200 installed)
            importlib.metadata.distribution(f"ros-{distro}-rclpy")
            return distro
        except importlib.metadata.PackageNotFoundError:
            pass
    for distribution in importlib.metadata.distributions():
        name = (distribution.metadata["Name"] or "").lower().replace("_", "-")
        if name.startswith("ros-") and name.endswith("-rclpy") and name.count("-") == 2:
            return name.split("-")[1]
    try:
        return _RCLPY_SERIES.get(int(importlib.metadata.version("rclpy").split(".")[0]), "unknown")
    except (importlib.metadata.PackageNotFoundError, ValueError):
        return "unknown"


@dataclass
class Topic:
    """A recorded topic: its type, offered QoS (rosbag2 v9 form) and messages written in all files."""

    name: str
    type_name: str
    qos: dict[str, Any]
    count: int = 0


@dataclass
class Span:
    """Receive-time span of the messages written, ns since the epoch."""

    start: int | None = None
    end: int | None = None
    count: int = 0

    def add(self, log_time_ns: int) -> None:
        self.start = log_time_ns if self.start is None else min(self.start, log_time_ns)
        self.end = log_time_ns if self.end is None else max(self.end, log_time_ns)
        self.count += 1

    def add_many(self, first_ns: int, last_ns: int, count: int) -> None:
        """``count`` messages logged from ``first_ns`` to ``last_ns`` (ns, in order), as ``add`` of each."""
        self.start = first_ns if self.start is None else min(self.start, first_ns)
        self.end = last_ns if self.end is None else max(self.end, last_ns)
        self.count += count

    def information(self) -> dict[str, Any]:
        """rosbag2's starting_time, duration and message_count of this span."""
        start = self.start or 0
        return {"starting_time": {"nanoseconds_since_epoch": start},
                "duration": {"nanoseconds": (self.end or start) - start},
                "message_count": self.count}


@dataclass(frozen=True)
class FileSpan:
    """One storage file of a bag: its name in the bag directory and the span of its messages."""

    name: str
    span: Span


def bag_information(files: list[FileSpan], span: Span, topics: Iterable[Topic]) -> dict[str, Any]:
    """rosbag2 `rosbag2_bagfile_information` (metadata version 9) of a bag of ``files`` whose messages span
    ``span`` on ``topics``."""
    return {
        "version": ROSBAG2_VERSION,
        "storage_identifier": "mcap",
        **span.information(),
        "topics_with_message_count": [
            {"topic_metadata": {"name": t.name, "type": t.type_name,
                                "serialization_format": "cdr",
                                "offered_qos_profiles": [t.qos]},
             "message_count": t.count}
            for t in topics],
        "compression_format": "",
        "compression_mode": "",
        "relative_file_paths": [file.name for file in files],
        "files": [{"path": file.name, **file.span.information()} for file in files],
        "custom_data": None,
        "ros_distro": ros_distro(),
    }


def write_metadata_yaml(directory: Path, information: dict[str, Any]) -> None:
    """Write ``directory``/metadata.yaml holding ``information`` (``bag_information``), replaced whole."""
    text = yaml_text({"rosbag2_bagfile_information": information})
    tmp = directory / "metadata.yaml.tmp"
    tmp.write_text(text, encoding="utf-8")
    os.replace(tmp, directory / "metadata.yaml")
