"""The CAN bridge's throughput, measured against baselines timed in the same run.

1. Log -> bag (`can-to-bag`'s work: the candump reader, the decoder and the bag writer, on blocks of
   frames) on the shipped lift log repeated to N frames; baseline: python-can's candump reader alone
   (its frames as the bridge's Frames), timed in the same run; beside it the block reader alone and
   reader + decoder without the bag, and with --per-frame python-can's frames through the same blocks
   (the path of .asc and .blf logs) and the conversion one frame at a time as the live bridge records
   a frame (python-can's reader, ``decode``, a bag ``write`` per message). What a process does once (imports, rclpy's
   type support, message layouts) is done before the timing by converting the shipped log. Goal: >= 100k
   frames/s.
2. The live bridge (`linkage-monitor can --bus udp_multicast:...`, its own process, recording) fed
   by another process at a saturated 1 Mbit/s bus's rate (~8k frames/s: 29-bit frames of 8 bytes
   are ~128 bits with stuffing, 1e6 / 128 = 7.8k/s) for S seconds: every frame counted (none lost),
   the bridge's CPU per frame (user + system, /proc) against a process that only receives the same
   frames with python-can (the baseline). Frames: the lift log at its own pace (100 frames/s feed a
   solve), the rest of the bus filled with frames the monitor does not use.

Usage: .venv/bin/python bench/bench_can.py [--frames N] [--seconds S] [--rate FRAMES_PER_S] [--log-only] [--per-frame]
"""

from __future__ import annotations

import argparse
import os
import random
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
LOG = ROOT / "bags" / "can" / "belarus_1221_lift.log"
MAP = ROOT / "config" / "can" / "belarus_1221.yaml"
TICK = os.sysconf("SC_CLK_TCK")
sys.path.insert(0, str(ROOT / "test"))   # test/support: the bridge's recording one frame at a time
HEARTBEAT_S = 1.0   # the bridge repeats its frame counts this often (ros/node.py HEARTBEAT_S)


def _cpu_s(pid: int) -> float:
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / TICK   # utime + stime


def _long_log(path: Path, n: int) -> int:
    """The shipped log repeated (stamps shifted by its length each time) to at least n frames."""
    import can

    from linkage_monitor.can.frames import to_message
    from linkage_monitor.can.sources import read_log

    frames = list(read_log(LOG))
    span = frames[-1].stamp_ns - frames[0].stamp_ns + 20_000_000
    count = 0
    with can.CanutilsLogWriter(str(path), channel="can0") as writer:
        k = 0
        while count < n:
            for f in frames:
                msg = to_message(f)
                msg.timestamp += k * span / 1e9
                writer.on_message_received(msg)
                count += 1
            k += 1
    return count


def bench_log_to_bag(n: int, per_frame: bool = False) -> None:
    from linkage_monitor.can.decoder import CanDecoder, load_databases
    from linkage_monitor.can.mapping import load_mapping
    from linkage_monitor.can.sources import read_log, read_log_blocks
    from linkage_monitor.can.to_bag import blocks_to_bag, can_to_bag
    from linkage_monitor.mechanics import load_description
    from linkage_monitor.monitoring.config import MonitorConfig
    from support.can_per_frame import per_frame_bag

    mapping, mech = load_mapping(MAP), load_description("belarus_1221")
    config = MonitorConfig.default("belarus_1221", mech)
    db = load_databases(mapping.dbc)
    with tempfile.TemporaryDirectory() as tmp:
        log = Path(tmp) / "long.log"
        count = _long_log(log, n)
        # untimed: one conversion of the shipped log and one python-can reading of it, so that imports, rclpy's
        # type support and the message layouts (once per process) are not counted as the frames' time
        sum(1 for _ in read_log(LOG))
        blocks_to_bag(read_log_blocks(LOG, []), CanDecoder(db, mapping, mech, config, "warm"), mech, config,
                      Path(tmp) / "warm")
        timed: dict[str, float] = {}
        t0 = time.perf_counter()
        read = sum(1 for _ in read_log(log))
        timed["python-can candump reader alone (baseline)"] = time.perf_counter() - t0
        t0 = time.perf_counter()
        read_blocks = sum(len(block) for block in read_log_blocks(log, []))
        timed["block reader alone"] = time.perf_counter() - t0
        decoder = CanDecoder(db, mapping, mech, config, "bench")
        t0 = time.perf_counter()
        for block in read_log_blocks(log, []):
            decoder.decode_block(block)
        timed["block reader + decoder"] = time.perf_counter() - t0
        decoder = CanDecoder(db, mapping, mech, config, "bench")
        t0 = time.perf_counter()
        converted = blocks_to_bag(read_log_blocks(log, []), decoder, mech, config, Path(tmp) / "bag")
        timed["log -> bag (can-to-bag)"] = time.perf_counter() - t0
        if per_frame:
            decoder = CanDecoder(db, mapping, mech, config, "bench")
            t0 = time.perf_counter()
            can_to_bag(read_log(log), decoder, mech, config, Path(tmp) / "bag_python_can")
            timed["python-can's frames in blocks (.asc, .blf)"] = time.perf_counter() - t0
            decoder = CanDecoder(db, mapping, mech, config, "bench")
            t0 = time.perf_counter()
            per_frame_bag(read_log(log), decoder, mech, Path(tmp) / "bag_per_frame")
            timed["one frame at a time (decode, write)"] = time.perf_counter() - t0
    assert read == read_blocks == count == converted.counts.received
    print(f"log -> bag, {count} frames ({converted.counts.summary()})")
    t_read = timed["python-can candump reader alone (baseline)"]
    for label, seconds in timed.items():
        print(f"  {label:<44s} {count / seconds:>10,.0f} frames/s  {seconds / t_read:5.2f}x the reader's time")
    t_bag = timed["log -> bag (can-to-bag)"]
    print(f"  goal >= 100,000 frames/s: {'met' if count / t_bag >= 100_000 else 'NOT met'}")


def _stream(rate: float, seconds: float) -> list:
    """A saturated bus's frames (python-can messages, in send order, with their send offsets in s): the
    lift log's frames at their own pace (the hitch status and the pressure at 50 Hz each, the wheel speed
    and EEC1 at 10 Hz), the rest of the ``rate`` filled with frames the monitor does not use (auxiliary
    valve 0 measured flow, known to the DBC; a proprietary frame no DBC knows)."""
    import can

    from linkage_monitor.can.frames import to_message
    from linkage_monitor.can.sources import read_log

    log = list(read_log(LOG))
    t0 = log[0].stamp_ns
    span = (log[-1].stamp_ns - t0) / 1e9 + 0.02
    fillers = [can.Message(arbitration_id=0x0CFE20F0, data=bytes([125, 125, 0xA0, 0x0F, 0x64, 0, 10, 0])),
               can.Message(arbitration_id=0x18FF5533, data=bytes(8))]
    out, k, cycle = [], 0, 0
    for i in range(int(rate * seconds)):
        t = i / rate
        frame = log[k]
        if (frame.stamp_ns - t0) / 1e9 + cycle * span <= t:
            out.append((t, to_message(frame)))
            k += 1
            if k == len(log):
                k, cycle = 0, cycle + 1
        else:
            out.append((t, fillers[i % 2]))
    return out


def _send(spec: str, rate: float, seconds: float) -> None:
    """Sender process: ``_stream`` onto the bus, paced; prints the count, the rate achieved and the
    frames that feed the monitor."""
    from linkage_monitor.can.sources import open_bus

    stream = _stream(rate, seconds)
    bus = open_bus(spec)
    time.sleep(0.5)
    start = time.monotonic()
    for offset, msg in stream:
        delay = start + offset - time.monotonic()
        if delay > 0:
            time.sleep(delay)
        bus.send(msg)
    mapped = sum(1 for _, m in stream if m.arbitration_id in (0x0CFE45F0, 0x18FF2021))
    print(len(stream), f"{len(stream) / (time.monotonic() - start):.0f}", mapped)
    bus.shutdown()


def _receive(spec: str, total: int) -> None:
    """Baseline process: receive ``total`` frames with python-can and nothing else; prints the count."""
    from linkage_monitor.can.sources import open_bus

    bus = open_bus(spec)
    print("ready", flush=True)
    n = 0
    last = time.monotonic()
    while n < total and time.monotonic() - last < 5.0:
        if bus.recv(0.5) is not None:
            n += 1
            last = time.monotonic()
    print(n, flush=True)
    bus.shutdown()


def _counted(total: int, timeout: float) -> tuple[str, float]:
    """Wait (rclpy) for the bridge's frame-count status to reach ``total``; (status, when)."""
    import rclpy
    from diagnostic_msgs.msg import DiagnosticArray
    from rclpy.qos import QoSProfile, ReliabilityPolicy

    node = rclpy.create_node("bench_can")
    seen: list[str] = []
    node.create_subscription(DiagnosticArray, "/diagnostics",
                             lambda m: seen.extend(s.message for s in m.status if s.name.endswith(": can")),
                             QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE))
    end = time.monotonic() + timeout
    last, changed = "", time.monotonic()
    while time.monotonic() < end:
        rclpy.spin_once(node, timeout_sec=0.1)
        if seen and seen[-1] != last:
            last, changed = seen[-1], time.monotonic()
            if int(last.split()[0]) >= total:
                break
        elif last and time.monotonic() - changed > 3 * HEARTBEAT_S:   # no progress: the rest was lost
            break
    node.destroy_node()
    return (last or "no status"), changed


def bench_live(rate: float, seconds: float) -> None:
    import rclpy

    os.environ.setdefault("ROS_DOMAIN_ID", str(random.SystemRandom().randint(1, 101)))
    os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    total = int(rate * seconds)
    me = [sys.executable, str(Path(__file__).resolve())]
    with tempfile.TemporaryDirectory() as tmp:
        # baseline: python-can receiving the same stream
        spec = f"udp_multicast:239.75.{random.randint(0, 255)}.{random.randint(1, 254)}"
        receiver = subprocess.Popen([*me, "--receive", spec, str(total)], stdout=subprocess.PIPE, text=True)
        assert receiver.stdout is not None and receiver.stdout.readline().strip() == "ready"
        cpu0 = _cpu_s(receiver.pid)
        sent = subprocess.run([*me, "--send", spec, str(rate), str(seconds)], capture_output=True, text=True, check=True)
        cpu_base = _cpu_s(receiver.pid) - cpu0
        got = int(receiver.stdout.readline())
        receiver.wait()
        n_sent, achieved, mapped = sent.stdout.split()
        print(f"live, {n_sent} frames sent at {float(achieved):,.0f} frames/s (asked {rate:,.0f}) over udp_multicast, "
              f"{mapped} of them feed the monitor ({float(mapped) / seconds:.0f}/s)")
        print(f"  python-can receiver alone (baseline): {got} received, CPU {cpu_base / got * 1e6:6.1f} us/frame")
        # the bridge
        spec = f"udp_multicast:239.75.{random.randint(0, 255)}.{random.randint(1, 254)}"
        log = Path(tmp) / "bridge.log"
        bridge = subprocess.Popen([sys.executable, "-m", "linkage_monitor.cli.main", "can", "--map", str(MAP), "--bus",
                                   spec, "--ros-args", "-p", f"record_dir:={tmp}"], stdout=log.open("w"),
                                  stderr=subprocess.STDOUT)
        end = time.monotonic() + 60
        while "CAN frames from" not in log.read_text() and time.monotonic() < end:
            time.sleep(0.2)
        rclpy.init()
        try:
            cpu0 = _cpu_s(bridge.pid)
            t0 = time.monotonic()
            sent = subprocess.run([*me, "--send", spec, str(rate), str(seconds)], capture_output=True, text=True,
                                  check=True)
            t_sent = time.monotonic()
            status, t_done = _counted(total, timeout=10 * seconds + 60)
            cpu = _cpu_s(bridge.pid) - cpu0
        finally:
            rclpy.shutdown()
            bridge.send_signal(2)
            bridge.wait(timeout=60)
        received = int(status.split()[0]) if status[0].isdigit() else 0
        print(f"  bridge: {status}")
        print(f"  bridge: {'no frame lost' if received == total else f'{total - received} frames LOST'}; worked off "
              f"{t_done - t_sent:.1f} s after the last was sent (sending took {t_sent - t0:.1f} s); CPU "
              f"{cpu / max(received, 1) * 1e6:6.1f} us/frame = {cpu / max(received, 1) / (cpu_base / got):.1f}x the "
              f"receiver; {received / (t_done - t0):,.0f} frames/s end to end")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=200_000, help="frames of the log -> bag run")
    parser.add_argument("--seconds", type=float, default=5.0, help="seconds of the live run")
    parser.add_argument("--rate", type=float, default=8000.0, help="frames/s of the live run")
    parser.add_argument("--log-only", action="store_true", help="only the log -> bag part (no live bridge)")
    parser.add_argument("--per-frame", action="store_true",
                        help="also time python-can's frames through the blocks and the conversion one frame at a time")
    parser.add_argument("--send", nargs=3, metavar=("SPEC", "RATE", "SECONDS"), help=argparse.SUPPRESS)
    parser.add_argument("--receive", nargs=2, metavar=("SPEC", "TOTAL"), help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.send:
        _send(args.send[0], float(args.send[1]), float(args.send[2]))
        return 0
    if args.receive:
        _receive(args.receive[0], int(args.receive[1]))
        return 0
    bench_log_to_bag(args.frames, args.per_frame)
    if not args.log_only:
        bench_live(args.rate, args.seconds)
    return 0


if __name__ == "__main__":
    sys.exit(main())
