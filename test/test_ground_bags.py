"""The two ground-driven sample bags (tools/make_bags.py: the simulator's field_copy and relief
scenarios recorded through the real node), replayed, show their seed's result.

- Kotov & Krol (ksu1_mower_field_copy): the shoe drag T70 = f·N70 loads the tilt cylinder HI more
  as f grows (0, 0.5, 0.8: the paper's range), while the lift cylinder AC carries the same force
  (it depends only on the spring block): the bag replayed with the mechanism at each f.
- Naumenko et al. 2021 (drill_coulter_relief): the inertia loads (kinetostatics on minus off, the same bag)
  at 0.4 m/s are 4× those at 0.2 m/s over the same relief: they scale with v².
"""

from __future__ import annotations

import copy
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from linkage_monitor.mechanics import load_preset, mechanism_from_dict
from linkage_monitor.offline.replay import recording_in_bag, replay
from linkage_monitor.sim.ground import COPY_RANGE_M, RELIEF_SPEEDS_M_S

BAGS = Path(__file__).resolve().parent.parent / "bags"


def _with_friction(f: float):
    mech = load_preset("ksu1_mower_adapter")
    raw = copy.deepcopy(dict(mech.raw))
    raw["contacts"][0]["friction"] = f
    return mechanism_from_dict(raw, file=f"{mech.file} (friction {f})")


def test_mower_tilt_cylinder_grows_with_shoe_drag_lift_cylinder_does_not():
    bag = BAGS / "ksu1_mower_field_copy"
    forces = {}
    for f in (0.0, 0.5, 0.8):
        run = replay(bag, mech=_with_friction(f), progress=None).run
        poses = [s.pose.result for s in run.steps if s.pose is not None]
        assert len(poses) == len(run.steps) > 1000     # every input solved
        forces[f] = (np.array([p.cylinders["lift_cylinder"].force for p in poses]),
                     np.array([p.cylinders["tilt_cylinder"].force for p in poses]))
        shoe = np.array([p.points["R"][1] for p in poses])
        assert shoe.max() - shoe.min() > 1.6 * COPY_RANGE_M   # the header copied most of ±125 mm
    for f in (0.5, 0.8):
        np.testing.assert_allclose(forces[f][0], forces[0.0][0], rtol=1e-9)   # AC: only the springs
    tilt = {f: np.abs(v[1]) for f, v in forces.items()}
    assert np.all(tilt[0.5] > tilt[0.0]) and np.all(tilt[0.8] > tilt[0.5])     # HI: grows with f, every pose


def test_coulter_inertia_loads_scale_with_speed_squared():
    bag = BAGS / "drill_coulter_relief"
    recorded = recording_in_bag(bag).config
    assert recorded is not None and recorded.kinetostatics
    dynamic = replay(bag, progress=None).run.steps
    static = replay(bag, config=replace(recorded, kinetostatics=False), progress=None).run.steps
    start = dynamic[0].stamp_ns
    t, inertia = [], []
    for d, s in zip(dynamic, static):
        assert d.pose is not None and s.pose is not None and d.stamp_ns == s.stamp_ns
        gap = [np.hypot(d.pose.result.hinges[h].fx - s.pose.result.hinges[h].fx,
                        d.pose.result.hinges[h].fz - s.pose.result.hinges[h].fz) for h in d.pose.result.hinges]
        t.append((d.stamp_ns - start) * 1e-9)
        inertia.append(max(gap))
    t, inertia = np.array(t), np.array(inertia)
    half = t[-1] / 2.0
    slow, fast = inertia[t < half - 0.1].max(), inertia[t > half + 0.1].max()
    assert slow > 1.0                                   # N: the kinetostatics is doing something
    expected = (RELIEF_SPEEDS_M_S[1] / RELIEF_SPEEDS_M_S[0]) ** 2
    assert fast / slow == pytest.approx(expected, rel=0.05)
