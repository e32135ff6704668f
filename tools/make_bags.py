"""Regenerate the sample bags in bags/: the telemetry simulator through the real node.

`python tools/make_bags.py [--out bags]` runs, for each sample, the live node
(recording on) and one or more `linkage-monitor simulate` runs in separate processes, over
real topics in an isolated ROS domain, and keeps the node's bag. Takes about as long as the
scenarios last (real time).
"""

from __future__ import annotations

import argparse
import os
import random
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

CONFIG = Path(__file__).resolve().parent.parent / "config"
# (bag name, preset, scenarios played one after the other, simulator options); the node runs
# with config/<preset>.yaml (e.g. damping_hitch reads only the lift cylinder's pressure: its
# damping element also pulls, which one cap-side sensor cannot measure).
SAMPLES: list[tuple[str, str, tuple[str, ...], tuple[str, ...]]] = [
    ("belarus_1221_lift_transport", "belarus_1221", ("lift", "transport"), ()),
    ("belarus_1221_overload", "belarus_1221", ("overload",), ()),
    ("damping_hitch_lift", "damping_hitch", ("lift",), ()),
    ("ttz1080_base_change_lift", "ttz1080_base_change", ("lift",), ()),
    ("ksu1_mower_field_copy", "ksu1_mower_adapter", ("field_copy",), ()),
    ("drill_coulter_relief", "drill_coulter", ("relief",), ("--rate", "100")),   # 50 samples per relief wave at 0.4 m/s
]
RATE_HZ = 50.0


def _module(*args: str) -> list[str]:
    return [sys.executable, "-m", *args]


def record(name: str, preset: str, scenarios: tuple[str, ...], options: tuple[str, ...], out: Path) -> Path:
    """Record one sample bag into out/name (replacing it); returns its directory."""
    target = out / name
    with tempfile.TemporaryDirectory() as tmp:
        node = subprocess.Popen(_module("linkage_monitor.ros.node", "--ros-args",
                                        "--params-file", str(CONFIG / f"{preset}.yaml"),
                                        "-p", f"record_dir:={tmp}", "-p", f"record_name:={name}"))
        try:
            time.sleep(3.0)  # node up and subscribed
            for scenario in scenarios:
                subprocess.run(_module("linkage_monitor.cli.main", "simulate", "--preset", preset, "--scenario", scenario,
                                       "--rate", str(RATE_HZ), *options), check=True)
            time.sleep(1.0)
        finally:
            node.send_signal(signal.SIGINT)
            node.wait(timeout=30)
        shutil.rmtree(target, ignore_errors=True)
        shutil.copytree(Path(tmp) / name, target)
    return target


def main(argv: list[str] | None = None) -> int:
    """Record every sample bag; prints each bag's size."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("bags"), help="directory of the sample bags")
    parser.add_argument("--only", metavar="NAME", help="record only this sample")
    args = parser.parse_args(argv)
    os.environ.setdefault("ROS_DOMAIN_ID", str(random.SystemRandom().randint(1, 101)))
    os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    for name, preset, scenarios, options in SAMPLES:
        if args.only and name != args.only:
            continue
        bag = record(name, preset, scenarios, options, args.out)
        size = sum(f.stat().st_size for f in bag.iterdir())
        print(f"{bag}: {size / 1e3:.0f} kB")
    return 0


if __name__ == "__main__":
    sys.exit(main())
