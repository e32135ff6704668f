"""Replay throughput against the raw decode rate of the same bag (goal: >= 0.5x the decode rate).

Run: .venv/bin/python bench/bench_replay.py [BAG]   (default: the bundled belarus_1221 bag)
Prints messages per second (each the fastest of REPEAT runs, the rows' runs interleaved) of
- raw decode: mcap + mcap-ros2-support decoding every message of the bag (the floor of any
  reader in Python, measured in the same run),
- replay: `linkage_monitor.offline.replay.replay` over the same bag (read, solve batched, machine-level
  results, output messages), without and with writing the output bag, after a first replay of the
  process (its own row) has paid what a process pays once: the compiled kernels loaded from
  numba's cache, the output messages' layouts parsed from their .msg definitions, and once per
  mechanism description the input limits' sweeps and the MarkerArray layouts (the next bag of the
  same mechanism, as a fleet worker replays them, skips them),
and the ratios to the raw decode (goal >= 0.5): of every message of the bag (the bundled bag is a
node recording: its outputs are 3/4 of it, and a reader decompresses their chunks too), and of
the input messages the replay reads (topic filter: the same messages).
"""

from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path

from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory

from linkage_monitor.mechanics import kernels  # noqa: E402
from linkage_monitor.offline.replay import mechanism_in_bag, replay

BAG = Path(__file__).resolve().parent.parent / "bags" / "belarus_1221_lift_transport"
REPEAT = 5   # each row: the fastest of this many runs, the runs of every row interleaved


def raw_decode(bag: Path, topics: list[str] | None = None) -> tuple[int, float]:
    """(messages, seconds) to decode every message of the bag (or of ``topics``) with mcap-ros2-support."""
    start, count = time.perf_counter(), 0
    for path in sorted(bag.glob("*.mcap")):
        with open(path, "rb") as f:
            for _ in make_reader(f, decoder_factories=[DecoderFactory()]).iter_decoded_messages(topics=topics):
                count += 1
    return count, time.perf_counter() - start


def best(runs: list[tuple[int, float]]) -> tuple[int, float]:
    """The (messages, seconds) of the fastest of ``runs``."""
    return min(runs, key=lambda run: run[1])


def main() -> int:
    kernels.allow_threads()   # as `linkage-monitor replay` does
    bag = Path(sys.argv[1]) if len(sys.argv) > 1 else BAG
    mech = mechanism_in_bag(bag)
    with tempfile.TemporaryDirectory() as tmp:
        # once per process: the compiled kernels loaded from numba's cache, the output messages'
        # layouts parsed from their .msg definitions
        replayed = replay(bag, mech, out_dir=Path(tmp) / "first", progress=None)
        config, first = replayed.config, replayed.summary
        inputs = [config.topics.joint_states, *config.pressure_topics]
        raw, raw_in, out, plain = [], [], [], []
        for k in range(REPEAT):   # interleaved: a slow phase of the machine slows every row alike
            raw.append(raw_decode(bag))
            raw_in.append(raw_decode(bag, inputs))
            summary = replay(bag, mech, out_dir=Path(tmp) / f"out{k}", progress=None).summary
            out.append((summary.inputs, summary.seconds))
            summary = replay(bag, mech, progress=None).summary
            plain.append((summary.inputs, summary.seconds))
    (n_raw, t_raw), (n_in, t_in) = best(raw), best(raw_in)
    raw_rate, in_rate = n_raw / t_raw, n_in / t_in
    rows = [("raw decode (mcap-ros2-support), all messages", n_raw, t_raw),
            ("raw decode, the input messages only", n_in, t_in),
            ("first replay of the process, output bag written (+ once per process)", first.inputs, first.seconds),
            ("replay, input messages, no output files", *best(plain)),
            ("replay, input messages, writing the output bag", *best(out))]
    print(f"bag: {bag} ({mech.name})")
    print(f"{'':70} {'messages':>9} {'seconds':>8} {'msg/s':>9} {'ratio':>6} {'ratio to the same messages':>27}")
    for name, n, t in rows:
        print(f"{name:70} {n:9d} {t:8.3f} {n / t:9.0f} {n / t / raw_rate:6.2f} {n / t / in_rate:27.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
