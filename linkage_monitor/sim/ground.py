"""Ground-driven scenarios: linkages that the ground moves, not a cylinder (no rclpy).

Some linkages follow the field: the mower header rides on its shoes (Kotov & Krol, field-copying
mode: both cylinders locked, one degree of freedom measured as the float lever's angle), the
drill coulter's support wheel rolls over the relief (Naumenko et al. 2021). Their scenarios prescribe the
height of the ground contact over time; the kinematics turns it into the one angle reading
(a monotonic map solved once on a grid, then interpolated), measured cylinders stay at their
reference lengths, pressures (if the mechanism has sensors) follow from the statics.

``field_copy`` the shoes follow a field whose height under them is
               h(t) = 0.125 m·(0.6 sin(2π·0.15 t + φ1) + 0.3 sin(2π·0.41 t + φ2) + 0.1 sin(2π·0.93 t + φ3))
               (Kotov & Krol's copying range ±125 mm about the reference line; phases from the seed).
               Default 30 s. Phase ``field_copy``. The shoe drag f is the mechanism's (contacts.friction).
``relief``     the wheel rolls over Naumenko et al. 2021's relief y(x) = A·(1 − cos(2π·x/l)), l = 0.2 m,
               A = 0.049 m, at v = 0.2 m/s for the first half, then 0.4 m/s (x continuous): the
               inertia loads of the second half are 4× those of the first at the same x (they
               scale with v²). The crests decelerate the wheel by A·(2πv/l)²: 0.78 g at 0.4 m/s;
               above v = (l/2π)·√(g/A) = 0.45 m/s it would leave the ground (the monitor says
               lift_off). Angle rates (rad/s) go into JointState.velocity, exact (chain rule
               through the kinematic map), for the monitor's kinetostatics. Default 8 s. Phases
               ``v=0.2 m/s``, ``v=0.4 m/s``.

Frame: x forward, z up, origin at the rear wheels' / wheel's ground contact; SI units.
"""

from __future__ import annotations

import math

import numpy as np

from linkage_monitor.mechanics import Mechanism, Solver
from linkage_monitor.mechanics.capacity import reference_length
from linkage_monitor.mechanics.results import Status

COPY_RANGE_M = 0.125              # Kotov & Krol: the header copies the ground ±125 mm
RELIEF_WAVELENGTH_M = 0.2         # Naumenko et al. 2021: l
RELIEF_AMPLITUDE_M = 0.049        # Naumenko et al. 2021: A
RELIEF_SPEEDS_M_S = (0.2, 0.4)    # m/s, first half, second half of the run (below lift-off, ~0.45 m/s)
GROUND_SCENARIOS = {"field_copy": 30.0, "relief": 8.0}   # name -> default duration, s
_GRID = 4001                      # angle grid of the kinematic map


class GroundDrive:
    """The kinematic map of a ground-driven mechanism: its one angle sensor -> height (m) of its
    first contact point, cylinders held at their reference lengths."""

    def __init__(self, mech: Mechanism) -> None:
        meas = mech.measurements
        if len(meas.angles) != 1 or not mech.contacts:
            raise ValueError(f"{mech.file}: a ground-driven scenario needs one angle sensor (the degree of freedom) "
                             f"and a ground contact; this mechanism has {len(meas.angles)} angle sensor(s) and "
                             f"{len(mech.contacts)} contact(s)")
        self.mech, self.sensor, self.contact = mech, meas.angles[0], mech.contacts[0]
        given = mech.reference_inputs.get("cylinders", {})
        self.lengths = {c: float(given.get(c, reference_length(mech, c))) for c in meas.cylinders}
        self.solver = Solver(mech)
        angles = self.sensor.reference + np.linspace(-0.8, 0.8, _GRID)
        batch = self._solve(angles)
        ok = batch.status == Status.OK
        height = batch.points[self.contact.point][:, 1]
        centre = _GRID // 2
        lo, hi = centre, centre                 # the assemblable, monotonic stretch around the reference
        slope = np.sign(height[centre + 1] - height[centre - 1])
        while lo > 0 and ok[lo - 1] and np.sign(height[lo] - height[lo - 1]) == slope:
            lo -= 1
        while hi < _GRID - 1 and ok[hi + 1] and np.sign(height[hi + 1] - height[hi]) == slope:
            hi += 1
        order = slice(lo, hi + 1) if slope > 0 else slice(hi, lo - 1 if lo > 0 else None, -1)
        self.heights, self.angles = height[order], angles[order]   # heights increasing
        self.reference_height = float(height[centre])

    def _solve(self, angles: np.ndarray):
        n = angles.size
        return self.solver.solve_batch(cylinders={c: np.full(n, v) for c, v in self.lengths.items()},
                                       angles={self.sensor.name: angles})

    def angle(self, height: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Angle readings (rad) that put the contact at ``height`` (m, absolute), and dθ/dh (rad/m)."""
        if height.min() < self.heights[0] or height.max() > self.heights[-1]:
            raise ValueError(f"{self.mech.file}: the ground moves the contact '{self.contact.name}' to "
                             f"{height.min():.3f}..{height.max():.3f} m, outside what the linkage reaches "
                             f"({self.heights[0]:.3f}..{self.heights[-1]:.3f} m)")
        slope = np.gradient(self.angles, self.heights)
        return np.interp(height, self.heights, self.angles), np.interp(height, self.heights, slope)

    def cylinder_forces(self, angles: np.ndarray) -> dict[str, np.ndarray]:
        """Cylinder forces (N, + pushing) at these angle readings (statics with the file's loads)."""
        batch = self._solve(angles)
        return {c: batch.cylinder_force[c] for c in self.lengths}


def ground_profile(scenario: str, t: np.ndarray, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(height change of the ground contact from its reference, m; its rate, m/s; phase) per sample."""
    if scenario == "field_copy":
        amplitudes, freqs = (0.6, 0.3, 0.1), (0.15, 0.41, 0.93)
        phases = rng.uniform(0.0, 2.0 * np.pi, 3)
        h = sum(a * np.sin(2 * np.pi * f * t + p) for a, f, p in zip(amplitudes, freqs, phases))
        rate = sum(a * 2 * np.pi * f * np.cos(2 * np.pi * f * t + p) for a, f, p in zip(amplitudes, freqs, phases))
        return COPY_RANGE_M * h, COPY_RANGE_M * rate, np.full(t.shape, "field_copy")
    half = (t[-1] + (t[1] - t[0] if t.size > 1 else 0.0)) / 2.0 if t.size else 0.0   # duration / 2: at a trough
    v_slow, v_fast = RELIEF_SPEEDS_M_S
    v = np.where(t <= half, v_slow, v_fast)
    x = np.where(t <= half, v_slow * t, v_slow * half + v_fast * (t - half))
    k = 2.0 * np.pi / RELIEF_WAVELENGTH_M
    height = RELIEF_AMPLITUDE_M * (1.0 - np.cos(k * x))     # Naumenko et al. 2021: y = (h/2)(1 − cos 2πx/l)
    rate = RELIEF_AMPLITUDE_M * k * np.sin(k * x) * v
    phase = np.where(t <= half, f"v={v_slow:.1f} m/s", f"v={v_fast:.1f} m/s")
    return height, rate, phase
