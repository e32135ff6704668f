"""``linkage-monitor capacity`` (capacity_cli + capacity_plot): the PNG and the JSON of the curve."""

from __future__ import annotations

import argparse
import json

import matplotlib.image
import numpy as np

from linkage_monitor.cli.capacity import add_capacity_parser, run_capacity

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"  # PNG spec, section 5.2


def _args(*argv: str) -> argparse.Namespace:
    parser = argparse.ArgumentParser()
    add_capacity_parser(parser.add_subparsers(dest="command"))
    return parser.parse_args(["capacity", *argv])


def test_capacity_png_is_a_real_image(tmp_path, capsys):
    png = tmp_path / "capacity.png"
    assert run_capacity(_args("--preset", "belarus_1221", "--stroke", "0.515", "0.715", "--points", "41",
                              "--plot", str(png), "--json")) == 0
    assert png.read_bytes()[:8] == PNG_SIGNATURE
    image = matplotlib.image.imread(png)
    assert image.ndim == 3 and image.shape[0] > 300 and image.shape[1] > 500
    assert image[..., :3].std() > 0.05  # not a blank canvas
    curve = json.loads(capsys.readouterr().out)
    assert len(curve["length"]) == 41 and curve["length"][0] == 0.515 and curve["length"][-1] == 0.715
    # ends of the curve, at the header cg: S = 0.515 m: 165 kN / Table 1's I_S 8.695 = 18.98 kN;
    # S = 0.715 m: Table 2's G_s = 26.83 kN
    np.testing.assert_allclose(np.array(curve["lift_capacity"]["implement_cg"])[[0, -1]] / 1e3,
                               [18.98, 26.83], atol=0.05)
    # docs/belarus-1221-geometry.md: the steerable header weight at k = 0.2 is about 20.5 kN over the working range
    assert 19.5 < min(curve["max_implement_weight"]) / 1e3 < 21.5


def test_default_stroke_stops_where_the_implement_stops_rising(capsys):
    assert run_capacity(_args("--preset", "belarus_1221", "--points", "11", "--json")) == 0
    curve = json.loads(capsys.readouterr().out)
    assert all(s == 0 for s in curve["status"])
    assert all(c > 0.0 for c in curve["lift_capacity"]["implement_cg"])  # I_S > 0 all along
    # Table 1's stroke 0.515-0.715 m lies inside the default range
    assert curve["length"][0] <= 0.515 and curve["length"][-1] >= 0.715
