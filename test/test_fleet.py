"""Fleet analysis: rainflow spectra against signals whose cycles are known, and `linkage-monitor
fleet` on a real 2-worker Dask LocalCluster against single-bag replays of the same bags."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest

from linkage_monitor.cli.main import main as cli_main
from linkage_monitor.offline.history import LoadHistory
from linkage_monitor.offline.replay import replay
from linkage_monitor.offline.spectra import rainflow_spectrum

BAGS = Path(__file__).resolve().parent.parent / "bags"
SAMPLE_BAGS = sorted(p for p in BAGS.iterdir() if (p / "metadata.yaml").is_file())   # the node's recordings (not bags/can/)


def test_astm_e1049_example():
    """ASTM E1049-85 (2017), Fig. 6 / X1: the load history −2, 1, −3, 5, −1, 3, −4, 4, −2 counts
    (range: cycles) 3: 0.5, 4: 1.5, 6: 0.5, 8: 1.0, 9: 0.5 (the standard's own table)."""
    spectrum = rainflow_spectrum(np.array([-2, 1, -3, 5, -1, 3, -4, 4, -2], dtype=float), duration_s=9.0)
    edges, counts = spectrum.binned(1.0)
    assert dict(zip(edges.tolist(), counts.tolist())) == {3.0: 0.5, 4.0: 1.5, 6.0: 0.5, 8.0: 1.0, 9.0: 0.5}


def _sine_between(reversals: list[float], samples: int = 16) -> np.ndarray:
    """A smooth signal through ``reversals``: half a cosine wave from each to the next."""
    parts = [a + (b - a) * 0.5 * (1.0 - np.cos(np.linspace(0.0, np.pi, samples, endpoint=False)))
             for a, b in zip(reversals[:-1], reversals[1:])]
    return np.concatenate([*parts, [reversals[-1]]])


@pytest.mark.parametrize("slope", [3.0, 5.0, 10.0])
def test_sine_blocks_known_counts_and_del(slope):
    """A lift of A = 40 kN with k1 = 7 sine cycles of range r1 = 6 kN riding on top and k2 = 4 of
    r2 = 10 kN at the bottom: rainflow counts the small ones as k1 and k2 full cycles and the
    lift as one (two halves); DEL = ((k1·r1^m + k2·r2^m + A^m) / (1 Hz · T))^(1/m)."""
    lift, r1, k1, r2, k2, duration = 40e3, 6e3, 7, 10e3, 4, 120.0
    reversals = [0.0, lift, *[lift - r1, lift] * k1, 0.0, *[r2, 0.0] * k2]
    spectrum = rainflow_spectrum(_sine_between(reversals), duration_s=duration)
    edges, counts = spectrum.binned(1e3)
    assert dict(zip(edges.tolist(), counts.tolist())) == {r1: k1, r2: k2, lift: 1.0}
    expected = ((k1 * r1**slope + k2 * r2**slope + lift**slope) / duration) ** (1.0 / slope)
    assert spectrum.damage_equivalent(slope) == pytest.approx(expected, rel=1e-12)


def test_constant_signal_has_no_cycles():
    assert rainflow_spectrum(np.full(50, 3e3), duration_s=5.0).damage_equivalent(3.0) == 0.0


@pytest.fixture(scope="module")
def fleet_run(tmp_path_factory) -> tuple[Path, Path, int]:
    """The sample bags plus a corrupt one (a bag cut after 3 kB) through `fleet` on 2 workers."""
    root = tmp_path_factory.mktemp("fleet")
    for bag in SAMPLE_BAGS:
        shutil.copytree(bag, root / "bags" / bag.name)
    first = next(iter(sorted(BAGS.glob("*/*.mcap"))))
    (root / "bags" / "corrupt.mcap").write_bytes(first.read_bytes()[:3000])
    code = cli_main(["fleet", str(root / "bags"), "--out", str(root / "out"), "--workers", "2", "--quiet"])
    return root / "bags", root / "out", code


@pytest.mark.slow
def test_fleet_rows_equal_single_bag_replays(fleet_run):
    bags, out, code = fleet_run
    assert code == 0
    rows = {Path(r["bag"]).name: r for r in pq.read_table(out / "bags.parquet").to_pylist()}
    assert set(rows) == {p.name for p in bags.iterdir()}
    assert "incomplete" in rows["corrupt.mcap"]["error"] or "mechanism" in rows["corrupt.mcap"]["error"]
    assert "corrupt.mcap is cut off at byte" in rows["corrupt.mcap"]["warning"]   # where the reader stopped
    spectra = pq.read_table(out / "spectra.parquet").to_pylist()
    for bag in SAMPLE_BAGS:
        row = rows[bag.name]
        assert row["error"] is None
        single = replay(bags / bag.name, progress=None)   # this process, no Dask
        history = LoadHistory.from_run(single.run)
        assert (row["inputs"], row["solved"]) == (single.summary.inputs, single.summary.solved)
        for hinge, (peak, at) in single.summary.peak_hinge.items():
            assert row[f"{hinge}_peak_N"] == pytest.approx(peak, rel=1e-9)
            assert row[f"{hinge}_peak_at_s"] == pytest.approx(at, abs=1e-9)
            spectrum = history.spectra()[hinge]
            assert row[f"{hinge}_del_N"] == pytest.approx(spectrum.damage_equivalent(3.0), rel=1e-9)
            cycles = sum(s["cycles"] for s in spectra if s["bag"] == row["bag"] and s["hinge"] == hinge)
            assert cycles == pytest.approx(spectrum.counts.sum(), rel=1e-12)
        if single.summary.min_margin is not None:
            assert row["min_margin"] == pytest.approx(single.summary.min_margin[0], rel=1e-9)
            assert row["below_margin_s"] == pytest.approx(history.time_below(history.margin, 0.0), abs=1e-9)
        shares = sum(v for k, v in row.items() if k.startswith("share_"))
        assert shares == pytest.approx(sum(single.summary.kinds.values()) / len(single.steps), rel=1e-12)


@pytest.mark.slow
def test_overload_bag_spends_time_below_the_margin(fleet_run):
    """belarus_1221_overload is simulated past the steerability limit (tools/make_bags.py): the
    fleet row says for how long; the lift/transport bag never goes below it."""
    _, out, _ = fleet_run
    rows = {Path(r["bag"]).name: r for r in pq.read_table(out / "bags.parquet").to_pylist()}
    assert rows["belarus_1221_overload"]["min_margin"] < 0.0 < rows["belarus_1221_overload"]["below_margin_s"]
    assert rows["belarus_1221_lift_transport"]["below_margin_s"] == 0.0


@pytest.mark.slow
def test_fleet_png_written(fleet_run):
    _, out, _ = fleet_run
    assert (out / "fleet.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


@pytest.mark.slow
def test_replay_spectra_prints_each_hinge(capsys):
    bag = BAGS / "belarus_1221_lift_transport"
    assert cli_main(["replay", str(bag), "--spectra", "--quiet"]) == 0
    text = capsys.readouterr().out
    history = LoadHistory.from_run(replay(bag, progress=None).run)
    for hinge, spectrum in history.spectra().items():
        assert f"hinge {hinge}: {spectrum.counts.sum():g} cycles, damage-equivalent load " \
               f"{spectrum.damage_equivalent(3.0) / 1e3:.3f} kN" in text


def test_fleet_without_bags_is_one_line(tmp_path, capsys):
    (tmp_path / "empty").mkdir()
    assert cli_main(["fleet", str(tmp_path / "empty"), "--out", str(tmp_path / "out")]) == 2
    assert capsys.readouterr().err.count("\n") == 1
