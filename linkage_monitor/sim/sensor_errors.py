"""Sensor readings with errors drawn from a mechanism's declared error sources (no rclpy).

The true inputs of a stretch of a simulated stream (``sim.telemetry``: the lengths, angles and the
pressures that carry the true loads, no friction) become what the sensors read, each error drawn from
the declared source (``mechanics.error_sources``, docs/accuracy.md) it stands for:

- a sensor's **bias** once per run (normal, σ = its ``bias``), its **noise** anew per sample (normal,
  σ = its ``noise``), then the reading **quantized** to its resolution step q: rounded to the nearest
  point of its grid z + n·q, the grid's zero z drawn once per run (uniform in ±q/2: where a sensor's
  steps fall against the true length is set by how it is mounted and zeroed, as a CAN signal's DBC
  offset; on the same grid every run, a cylinder standing at the same length would read the same
  error in every run, where the declared source says uniform over ±q/2);
- each force-measured cylinder's **seal friction** F_f, a force the pressure carries on top of the
  load's (F_hyd = F + F_f, + = the cylinder pushes harder), read by the cylinder's cap-chamber sensor
  (else its rod-chamber one) as the pressure F_f / (count·A). The seals' level a in their band is drawn
  once per run (uniform in [0, 1]); while the rod moves (its true length changes from the sample
  before) the friction opposes the motion, F_f = sign(v)·a·band (band = share·|F| + force); standing,
  the seals hold what the last motion left, at the breakaway level: sign(last v)·a·breakaway·band (a
  sign drawn per run before the first motion). Over a run's a and sign this is the declared band:
  moving, within it with the known sign; standing, uniform over ± breakaway band.

The implement-mass tolerance is not drawn (the truth would need another implement): a mechanism that
declares one is refused. Units SI (m, rad, gauge Pa, N).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Mapping

import numpy as np

from linkage_monitor.mechanics.error_sources import ErrorSources
from linkage_monitor.mechanics.inputs import Inputs
from linkage_monitor.mechanics.model import Mechanism
from linkage_monitor.mechanics.output_table import force_per_pressure

KINDS = ("cylinders", "angles", "pressures")   # the measured inputs, as ``Inputs`` names them


@dataclass(frozen=True)
class TrueInputs:
    """The true measured inputs of N samples, by kind (``KINDS``) and name: arrays (N,) in m, rad, gauge Pa
    (the pressures carry the load alone, without seal friction); ``last_motion`` the sign (+1
    extending, −1 retracting, 0 none yet) of each cylinder's last motion before the first sample."""

    values: Mapping[str, Mapping[str, np.ndarray]]
    last_motion: Mapping[str, float]

    def __len__(self) -> int:
        return next((len(v) for group in self.values.values() for v in group.values()), 0)

    def at(self, i: int) -> Inputs:
        """The true inputs of sample ``i``."""
        return Inputs(**{kind: {n: float(v[i]) for n, v in group.items()} for kind, group in self.values.items()})


@dataclass(frozen=True)
class RunErrors:
    """The errors drawn once per run: each sensor's ``bias`` (its unit), each force-measured cylinder's
    seal ``level`` in its band (0..1) and the ``held_sign`` of its friction before its first motion, each
    quantized sensor's ``grid`` zero (its unit, within ±step/2; a sensor not named: 0)."""

    bias: Mapping[str, float]
    level: Mapping[str, float]
    held_sign: Mapping[str, float]
    grid: Mapping[str, float] = field(default_factory=dict)


class SensorErrorSimulator:
    """Draws the declared errors of ``mech``'s sensors and cylinder seals (``sources``: default the
    mechanism's own) and applies them to true inputs."""

    def __init__(self, mech: Mechanism, sources: ErrorSources | None = None) -> None:
        self.mech = mech
        self.sources = sources if sources is not None else mech.error_sources
        if self.sources.implement_mass > 0.0:
            raise ValueError(f"{mech.name}: the simulator does not draw the implement-mass tolerance")
        self.kind_of = {**{c: "cylinders" for c in mech.measurements.cylinders},
                        **{a.name: "angles" for a in mech.measurements.angles},
                        **{p.name: "pressures" for p in mech.measurements.pressures}}

    def draw(self, rng: np.random.Generator) -> RunErrors:
        """The once-per-run errors of one run."""
        bias = {name: float(self.sources.sensor(name, kind).bias * rng.standard_normal())
                for name, kind in self.kind_of.items()}
        cylinders = [c.name for c in self.mech.cylinders]
        level = {c: float(rng.uniform(0.0, 1.0)) for c in cylinders}
        held = {c: float(rng.choice((-1.0, 1.0))) for c in cylinders}
        steps = {name: self.sources.sensor(name, kind).resolution for name, kind in self.kind_of.items()}
        grid = {name: float(rng.uniform(-0.5, 0.5) * step) for name, step in steps.items() if step > 0.0}
        return RunErrors(bias, level, held, grid)

    def readings(self, truth: TrueInputs, run: RunErrors, rng: np.random.Generator) -> dict[str, dict[str, np.ndarray]]:
        """What the sensors read of ``truth`` in the run ``run``: by kind and name, arrays (N,) (m, rad,
        gauge Pa); the noise drawn from ``rng``."""
        n = len(truth)
        out: dict[str, dict[str, np.ndarray]] = {kind: {} for kind in KINDS}
        friction = self.friction_pressures(truth, run)
        for kind in KINDS:
            for name, true in truth.values.get(kind, {}).items():
                error = self.sources.sensor(name, kind)
                read = np.asarray(true, dtype=float) + run.bias[name] + friction.get(name, 0.0)
                if error.noise > 0.0:
                    read = read + error.noise * rng.standard_normal(n)
                if error.resolution > 0.0:
                    zero = run.grid.get(name, 0.0)
                    read = np.round((read - zero) / error.resolution) * error.resolution + zero
                out[kind][name] = read
        return out

    def friction_pressures(self, truth: TrueInputs, run: RunErrors) -> dict[str, np.ndarray]:
        """The pressure (Pa, arrays (N,)) each force-measured cylinder's seal friction adds to the sensor
        that reads it (its cap chamber's when given, else its rod chamber's)."""
        pressures = truth.values.get("pressures", {})
        lengths = truth.values.get("cylinders", {})
        out = {}
        for cyl in self.mech.cylinders:
            sensors = sorted((ps.chamber != "cap", ps.name) for ps in self.mech.measurements.pressures
                             if ps.cylinder == cyl.name and ps.name in pressures)
            if not sensors:
                continue
            force = sum(pressures[name] * force_per_pressure(self.mech, name) for _, name in sensors)
            seal = self.sources.seal_friction(cyl.name)
            band = seal.share * np.abs(force) + seal.force
            direction = motion_signs(lengths.get(cyl.name), len(truth),
                                     truth.last_motion.get(cyl.name, 0.0) or run.held_sign[cyl.name])
            moving = direction.moving
            friction = run.level[cyl.name] * band * direction.sign * np.where(moving, 1.0, seal.breakaway)
            reader = sensors[0][1]
            out[reader] = friction / force_per_pressure(self.mech, reader)
        return out


@dataclass(frozen=True)
class MotionSigns:
    """Per sample: ``moving`` (the true length changed from the sample before) and ``sign`` of the
    friction (+1: the rod extends or last extended)."""

    moving: np.ndarray
    sign: np.ndarray


def motion_signs(lengths: np.ndarray | None, n: int, before: float) -> MotionSigns:
    """The motion of a cylinder of true ``lengths`` (N,) (None: not measured, standing), its last motion
    before the first sample ``before`` (±1); the first sample's change is taken as 0 (standing)."""
    if lengths is None:
        return MotionSigns(np.zeros(n, dtype=bool), np.full(n, before))
    change = np.diff(np.asarray(lengths, dtype=float), prepend=lengths[0])
    moving = change != 0.0
    step = np.where(moving, np.sign(change), 0.0)
    last = np.maximum.accumulate(np.where(moving, np.arange(n), -1))
    return MotionSigns(moving, np.where(last >= 0, step[np.maximum(last, 0)], before))
