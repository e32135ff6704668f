"""The monitor's outputs in a bag the replay wrote, read back by mcap's own reader."""

from __future__ import annotations

from pathlib import Path

from mcap.reader import make_reader

OUTPUT_TOPICS = ("/hinge_reactions", "/hitch_state", "/steerability", "/diagnostics")


def output_bytes(bag: Path) -> dict[str, list[bytes]]:
    """The output topics of ``bag`` (a rosbag2 directory of .mcap files, split or not), as CDR bytes
    per topic in the order written."""
    out: dict[str, list[bytes]] = {t: [] for t in OUTPUT_TOPICS}
    for file in sorted(bag.glob("*.mcap")):
        with open(file, "rb") as stream:
            for _, channel, message in make_reader(stream).iter_messages(topics=list(OUTPUT_TOPICS)):
                out[channel.topic].append(message.data)
    return out
