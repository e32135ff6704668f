"""Replay throughput against the raw decode rate of the same bag (goal: >= 0.5x the decode rate).

Run: .venv/bin/python bench/bench_replay.py [BAG] [--long-inputs N]   (default: the bundled belarus_1221
bag, N = 10^5)
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
Then the replay's memory (goal: flat in the bag's length; a 10^6-input bag under 500 MB): `linkage-monitor
replay --out` (``replay_streaming``) over a long bag of N inputs (bench/long_bag.py: BAG's inputs repeated) in
its own process, its peak RSS (ru_maxrss) and its rate (its summary's, with what a process pays once) against
the replay of BAG writing its output bag above (goal >= 0.5).
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory

from linkage_monitor.offline.replay import mechanism_in_bag, replay

from long_bag import write_long_bag  # noqa: E402  # bench/ is the script's directory

ROOT = Path(__file__).resolve().parent.parent
BAG = ROOT / "bags" / "belarus_1221_lift_transport"
REPEAT = 5   # each row: the fastest of this many runs, the runs of every row interleaved
LONG_INPUTS = 100_000
RSS_GOAL_MB = 500.0   # for 10^6 inputs
MEASURE = """import resource, sys
from pathlib import Path
from linkage_monitor.offline.replay import replay_streaming
summary = replay_streaming(Path(sys.argv[1]), out_dir=Path(sys.argv[2]), progress=None).summary
print(summary.inputs, summary.seconds, resource.getrusage(resource.RUSAGE_SELF).ru_maxrss)"""


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


def long_replay(bag: Path, inputs: int, work: Path) -> tuple[int, float, float]:
    """(inputs, seconds, peak RSS in MB) of a streaming replay, output bag written, of a bag of ``inputs``
    inputs made from ``bag``'s, in its own process."""
    long = work / "long"
    write_long_bag(bag, long, inputs)
    done = subprocess.run([sys.executable, "-c", MEASURE, str(long), str(work / "long_out")], cwd=ROOT,
                          capture_output=True, text=True, check=True)
    n, seconds, rss_kb = done.stdout.split()[-3:]
    return int(n), float(seconds), int(rss_kb) / 1024


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("bag", nargs="?", type=Path, default=BAG)
    parser.add_argument("--long-inputs", type=int, default=LONG_INPUTS, help="inputs of the long bag (0: none)")
    args = parser.parse_args()
    bag = args.bag
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
    if args.long_inputs > 0:
        n_out, t_out = best(out)
        with tempfile.TemporaryDirectory() as tmp:
            n, seconds, rss_mb = long_replay(bag, args.long_inputs, Path(tmp))
        print(f"\nlong bag ({n} inputs, output bag written, own process): {seconds:.1f} s, {n / seconds:,.0f} msg/s = "
              f"{n / seconds / (n_out / t_out):.2f}x the replay of {bag.name} writing its bag (goal >= 0.5); "
              f"peak RSS {rss_mb:.0f} MB (goal: flat in the length, < {RSS_GOAL_MB:.0f} MB at 10^6 inputs)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
