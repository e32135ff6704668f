"""The bundled bags are what today's code records: each bag's recorded outputs equal a replay of
its recorded inputs by this checkout to 1e-9 relative (the tolerance `make demo` holds the live
node to its replay with). A change of the physics, the checks or their wording makes this fail
until the bags are regenerated with `python tools/make_bags.py`."""

from __future__ import annotations

from pathlib import Path

import pytest

from linkage_monitor.offline.compare import compare_bags
from linkage_monitor.offline.replay import mechanism_in_bag, replay

ROOT = Path(__file__).resolve().parent.parent / "bags"
BAGS = sorted(p for p in ROOT.iterdir() if (p / "metadata.yaml").is_file())   # the node's recordings


def test_every_bundled_bag_is_checked():
    assert len(BAGS) >= 6, BAGS   # the six simulator samples of tools/make_bags.py


@pytest.mark.slow
@pytest.mark.parametrize("bag", BAGS, ids=[b.name for b in BAGS])
def test_bundled_bag_outputs_equal_todays_replay(bag, tmp_path):
    out = tmp_path / "replayed"
    replay(bag, out_dir=out, progress=None)
    comparison = compare_bags(bag, out, f"linkage_monitor: {mechanism_in_bag(bag).name}", rel=1e-9)
    assert comparison.counts["/hinge_reactions"] > 0
    assert comparison.equal, (f"{bag.name} was recorded by other code (largest relative difference "
                              f"{comparison.worst:.1e}); regenerate with `python tools/make_bags.py`",
                              comparison.differences[:5])
