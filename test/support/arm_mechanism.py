"""The smallest mechanism the failure tests need: one lifting arm and its cylinder, as the dict a
mechanism file holds (`linkage_monitor.mechanics.mechanism_from_dict` reads it)."""

from __future__ import annotations


def arm_mechanism(measure: dict) -> dict:
    """Arm pivoted at O = (0, 0), tip T = (0, 1) in the reference pose; cylinder from E = (−1, 0) to T;
    ``measure`` is its ``measurements`` entry."""
    return {
        "name": "arm",
        "points": {"O": [0.0, 0.0], "T": [0.0, 1.0], "E": [-1.0, 0.0]},
        "bodies": [{"name": "frame", "ground": True, "points": ["O", "E"]},
                   {"name": "arm", "points": ["O", "T"], "mass": 10.0, "cg": "T"}],
        "hinges": [{"name": "O", "bodies": ["frame", "arm"]}],
        "cylinders": [{"name": "cyl", "base": {"point": "E", "body": "frame"},
                       "rod_end": {"point": "T", "body": "arm"}, "bore": 0.1, "rod": 0.05}],
        "measurements": measure,
    }
