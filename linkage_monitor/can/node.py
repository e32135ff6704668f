"""The live CAN bridge: the monitor's node fed from CAN frames instead of sensor topics.

Frames come from a python-can bus (``--bus INTERFACE:CHANNEL``, read by the node's own thread
every POLL_PERIOD_S: the kernel's socket buffer holds them meanwhile) or from ``can_msgs/msg/Frame`` messages on a topic
(``/from_can_bus``, beside ros2_socketcan). Each frame is recorded raw (can_msgs/msg/Frame on the
raw topic), decoded (``decoder``), each decoded input recorded as the sensor message it stands for
and handed to the monitoring core; the outputs, markers, /diagnostics and the bag are the node's
own (``ros.node.LinkageMonitorNode``: ``CanFrames`` is only its input source, ``ros.inputs``). A refused frame,
an error frame, bus-off, a receive error and a silent bus are findings on /diagnostics; the frame
counts (decoded + ignored + refused = received) are a status ``linkage_monitor: can`` at every
heartbeat and at shutdown. Units SI; stamps: the frames' own (µs), receive times the node's clock.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import can
from can_msgs.msg import Frame as FrameMsg

from linkage_monitor.mechanics import Mechanism
from linkage_monitor.mechanics.overrides import with_sensor_resolutions
from linkage_monitor.monitoring.config import MonitorConfig
from linkage_monitor.monitoring.core import Step
from linkage_monitor.monitoring.events import UnreadableEvent
from linkage_monitor.monitoring.findings import Code, Finding, Level, fmt
from linkage_monitor.ros.inputs import InputHost
from linkage_monitor.ros.node import LinkageMonitorNode

from .decoder import CanDecoder, load_databases
from .frame_msg import FRAME_TYPE, from_cdr, to_cdr
from .frames import Frame, from_message
from .mapping import CanMapping
from .routes import Routing
from .sources import DropCount, open_bus
from .to_bag import RAW_TOPIC, input_record

# s, the node's thread reads the bus this often, everything waiting each time. Not a reader thread:
# its every receive releases the GIL (a system call) and waits up to the interpreter's switch
# interval (5 ms) to get it back while the node solves, ~200 frames/s, and the socket overflows
# (bench/bench_can.py shows it); not a guard condition either (the node's spin loop,
# ros.spin.InputSpinner, consumes its trigger before rclpy's executor would run the callback).
POLL_PERIOD_S = 0.01
POLL_LIMIT = 5000      # frames worked off per poll at most (then timers and services run)
RETRY_S = 1.0          # s, a receive error is reported at most this often


@dataclass(frozen=True)
class CanSource:
    """Where the bridge's frames come from: ``bus`` (INTERFACE:CHANNEL) or else ``topic`` (can_msgs/Frame);
    the DBC files and the mapping; ``raw_topic``: where raw frames are recorded."""

    mapping: CanMapping
    dbc: tuple[Path, ...]
    bus: str | None = None
    topic: str = RAW_TOPIC
    raw_topic: str = RAW_TOPIC


class CanFrames:
    """The node's input source: the frames of ``source`` (see the module docstring)."""

    def __init__(self, source: CanSource) -> None:
        self.source = source
        self.bus: can.BusABC | None = None
        self._node: InputHost | None = None

    @property
    def node(self) -> InputHost:
        """The node this source feeds (``start``)."""
        assert self._node is not None, "the CAN source is not started"
        return self._node

    def described(self, description: Mechanism, config: MonitorConfig) -> Mechanism:
        """``description`` whose error budget takes each mapped input's DBC scale as its resolution
        (unless the mechanism file declares a coarser one; ``mechanics.overrides.with_sensor_resolutions``):
        monitored and recorded so."""
        routing = Routing(load_databases(self.source.dbc), self.source.mapping, description, config)
        return with_sensor_resolutions(description, routing.resolutions)

    def start(self, node: InputHost) -> None:
        """The decoder for the node's mechanism; the bus opened (read every POLL_PERIOD_S) or the
        frames' topic subscribed; the silence check started."""
        source = self.source
        self._node = node
        self.source_name = source.bus or node.resolve_topic_name(source.topic)
        self.decoder = CanDecoder(load_databases(source.dbc), source.mapping, node.monitor.description,
                                  node.monitor.config, self.source_name)
        self.silence_s = source.mapping.silence_timeout_s
        self._last_frame = time.monotonic()
        self._silent = False
        self._last_error = -RETRY_S
        if source.bus is not None:
            self.bus = open_bus(source.bus)
            self.drops = DropCount(self.bus)
            if not self.drops.known:
                node.get_logger().warning(f"the frames {source.bus} drops cannot be counted here")
            node.create_timer(POLL_PERIOD_S, self._poll_bus)
        else:
            node.subscribe(FrameMsg, self.source_name, self._on_frame_message)
        node.create_timer(min(0.1, self.silence_s / 4), self._check_silence)
        node.get_logger().info(f"CAN frames from {self.source_name}, {len(source.mapping.inputs)} mapped input(s)")

    # ---- the bus: read by the node's thread ------------------------------------------------------------
    def _poll_bus(self) -> None:
        """Work off the frames waiting on the bus (at most POLL_LIMIT); a receive error is a finding."""
        assert self.bus is not None
        node = self.node
        dropped = self.drops.new()
        if dropped:
            now = node.now()
            node.outputs.publish(Step(now, self.source_name, (self.decoder.counts.lose(dropped, self.source_name),)),
                                 now)
        for _ in range(POLL_LIMIT):
            try:
                msg = self.bus.recv(0.0)
            except (can.CanError, OSError) as exc:
                now = node.now()
                if time.monotonic() - self._last_error >= RETRY_S:
                    self._last_error = time.monotonic()
                    node.outputs.publish(Step(now, self.source_name, (Finding(Code.INPUTS_LOST, (
                        f"receiving from {self.source_name} failed ({type(exc).__name__}: {exc}); frames meanwhile "
                        "are lost")),)), now)
                return
            if msg is None:
                return
            now = node.now()
            try:
                frame = from_message(msg)
                self._take_frame(frame, to_cdr(frame), now)
            except Exception as exc:  # noqa: BLE001 - the adapter boundary: report, the next frame goes on
                node.publish_status("internal", Level.ERROR, f"internal error while taking a frame from "
                                    f"{self.source_name}: {type(exc).__name__}: {exc}", now)

    # ---- the topic (each message counted by the node's subscription) -------------------------------------
    def _on_frame_message(self, data: bytes, info: dict) -> None:
        node = self.node
        now = node.now()
        try:
            frame = from_cdr(data)
        except Exception as exc:  # noqa: BLE001 - rclpy raises its own errors for bytes that are not the type
            self.decoder.counts.received += 1
            self.decoder.counts.refused += 1
            event = UnreadableEvent(topic=self.source_name, type_name=FRAME_TYPE, size=len(data), reason=str(exc),
                                    receive_ns=now)
            node.recording.input(self.source.raw_topic, FRAME_TYPE, data, event.stamp_ns, now)
            node.outputs.publish(node.monitor.step(event), now)
            return
        self._take_frame(frame, data, now)

    # ---- one frame -----------------------------------------------------------------------------------
    def _take_frame(self, frame: Frame, raw: bytes, now: int) -> None:
        """Record the raw frame, decode it, record and solve each input it gives; publish findings."""
        node = self.node
        self._last_frame = time.monotonic()
        if self._silent:
            self._silent = False
            node.get_logger().info(f"CAN frames again on {self.source_name}")
        node.recording.input(self.source.raw_topic, FRAME_TYPE, raw, frame.stamp_ns, now)
        decoded = self.decoder.decode(frame, now)
        if decoded.finding is not None:
            node.outputs.publish(Step(frame.stamp_ns, self.source_name, (decoded.finding,)), now)
        for event in decoded.events:
            record = input_record(event)
            node.recording.input(event.topic, record.type_name, record.data, event.stamp_ns, now)
            node.outputs.publish(node.monitor.step(event), now)

    def _check_silence(self) -> None:
        silent_for = time.monotonic() - self._last_frame
        if silent_for > self.silence_s and not self._silent:
            self._silent = True
            now = self.node.now()
            self.node.outputs.publish(Step(now, self.source_name, (Finding(Code.STALE_INPUT, (
                f"no CAN frame on {self.source_name} for {silent_for:.1f} s (silence_timeout {fmt(self.silence_s)} s): "
                "no solve until frames come again; check the bus connection, its bit rate and the tractor's ECUs")),)),
                now)

    def names(self) -> list[str]:
        """The bus (INTERFACE:CHANNEL) or the frames' topic: what the STALE status names."""
        return [self.source_name]

    # ---- frame counts with the heartbeat, at shutdown ----------------------------------------------------
    def on_heartbeat(self) -> None:
        """The frame counts: a status ``<node>: can``."""
        self._publish_counts()

    def _publish_counts(self) -> None:
        counts = self.decoder.counts
        uncounted = self.bus is not None and not self.drops.known   # losses there go unnamed: say so
        self.node.publish_status("can", counts.level, counts.summary() + (
            f"; the frames {self.source_name} drops cannot be counted here" if uncounted else ""), self.node.now())

    def close(self) -> None:
        """What already arrived on the bus worked off, the bus shut down, the frame counts published and logged."""
        try:
            if self.bus is not None:
                self._poll_bus()   # what already arrived is worked off: no frame left behind
                self.bus.shutdown()
            self._publish_counts()
            self.node.get_logger().info(f"CAN {self.source_name}: {self.decoder.counts.summary()}")
        except Exception as exc:  # noqa: BLE001 - the bag is finished whatever happens here
            self.node.get_logger().error(f"final frame count failed: {type(exc).__name__}: {exc}")


class CanBridgeNode(LinkageMonitorNode):
    """The monitor's node with the CAN frames of ``source`` as its input source."""

    def __init__(self, source: CanSource, **kwargs: Any) -> None:
        super().__init__(input_source=CanFrames(source), **kwargs)
