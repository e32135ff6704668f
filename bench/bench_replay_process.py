"""A long replay as the user runs it, a whole process, against an independent decode of the same bag.

Run: .venv/bin/python bench/bench_replay_process.py [--inputs N] [--repeat R]   (defaults 100,000 and 3)
Two bags of N input messages made from the bundled belarus_1221 bag (bench/long_bag.py):
- a node's recording: the inputs, every output and /diagnostics, as the node records them (written
  by `linkage-monitor replay --out`, which records what the node records);
- the inputs alone (the mechanism description, the configuration and the JointState + FluidPressure
  messages).
For each, the wall time of two processes started from the shell, their runs interleaved (a slow phase
of the machine slows both alike), the fastest of R:
- `linkage-monitor replay BAG --out DIR --quiet` (imports, kernels loaded from numba's cache, the
  limits' sweep, read, solve, write the output bag);
- an independent decode: a Python process that imports mcap + mcap-ros2-support and decodes every
  message of the bag.
The ratio is the replay's rate over the decode's rate of the same bag (goal >= 0.5).
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from long_bag import BAG, write_long_bag  # noqa: E402  # bench/ is the script's directory

ROOT = Path(__file__).resolve().parent.parent
CLI = Path(sys.executable).with_name("linkage-monitor")
DECODE = """import sys
from pathlib import Path
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
count = 0
for path in sorted(Path(sys.argv[1]).glob("*.mcap")):
    with open(path, "rb") as f:
        for _ in make_reader(f, decoder_factories=[DecoderFactory()]).iter_decoded_messages():
            count += 1
print(count)"""


def wall(argv: list[str]) -> float:
    """Seconds of wall time of the process ``argv`` (which must succeed)."""
    start = time.perf_counter()
    subprocess.run(argv, cwd=ROOT, check=True, stdout=subprocess.DEVNULL)
    return time.perf_counter() - start


def compare(bag: Path, work: Path, repeat: int) -> tuple[float, float]:
    """(replay seconds, decode seconds) of ``bag``, each the fastest of ``repeat`` interleaved runs."""
    work.mkdir()
    replays, decodes = [], []
    for k in range(repeat):
        replays.append(wall([str(CLI), "replay", str(bag), "--out", str(work / f"out{k}"), "--quiet"]))
        decodes.append(wall([sys.executable, "-c", DECODE, str(bag)]))
    return min(replays), min(decodes)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--inputs", type=int, default=100_000, help="input messages of the long bags")
    parser.add_argument("--repeat", type=int, default=3, help="runs of each process (the fastest counts)")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        inputs_only = work / "inputs_only"
        write_long_bag(BAG, inputs_only, args.inputs)
        recording = work / "recording"
        subprocess.run([str(CLI), "replay", str(inputs_only), "--out", str(recording), "--quiet"], cwd=ROOT,
                       check=True, stdout=subprocess.DEVNULL)
        print(f"{args.inputs:,} inputs from {BAG.name}; wall seconds, the fastest of {args.repeat}")
        print(f"{'bag':40} {'replay --out':>13} {'decode':>8} {'ratio':>6}  (goal >= 0.5)")
        for name, bag in (("a node's recording (inputs + outputs)", recording), ("the inputs alone", inputs_only)):
            t_replay, t_decode = compare(bag, work / f"{bag.name}_replayed", args.repeat)
            print(f"{name:40} {t_replay:13.2f} {t_decode:8.2f} {t_decode / t_replay:6.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
