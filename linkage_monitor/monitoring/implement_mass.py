"""Which implement mass and cg the machine-level results use, and the weighing inside the monitor (no rclpy).

``MonitorConfig.implement_mass_source`` chooses (docs/implements.md):

- ``file`` (default): the mechanism file's, or the implement file's (``MonitorConfig.implement``);
  the weighing estimator does not run;
- ``estimate``: the ``WeighingEstimator``'s (``monitoring.weighing``) as soon as it has one;
- ``estimate_when_confident``: the estimate once it is confident (``confident``), the file's before.

The estimator sees every solved step, live or batched, in the order of the inputs. When it finds
an implement change (coupling, filling, emptying), the mass the results use is stale: every step
carries an ``implement_changed`` WARN until a confident estimate is in use again (the monitor
rebuilds its mechanism with it: ``ImplementMass.pending``). Units SI (kg, m); the cg in the
mechanism's reference pose, frame x forward, z up, origin at the rear wheels' ground contact.
"""

from __future__ import annotations

from dataclasses import replace
from typing import NamedTuple, Sequence

import numpy as np

from linkage_monitor.mechanics import Mechanism, MechanismFileError, Result, apply_overrides
from linkage_monitor.mechanics.implements import ImplementFile, Tolerances, load_implement, with_implement

from .config import IMPLEMENT_MASS_SOURCES, MonitorConfig
from .findings import Code, Finding, fmt
from .weighing import WeighingEstimate, WeighingEstimator, WeighingPhase, WeighingSettings
from .weighing_fit import Priors

CONFIDENT_SHARE = 0.05   # confident: the mass's 95 % half-interval within this share of the mass (-)
CONFIDENT_PAIRS = 5      # ... from at least this many lift/lower pairs of stroke bins
MOVED = 0.5              # a new estimate is put in use when it moved by more than this many of its u


def confident(estimate: WeighingEstimate | None) -> bool:
    """The estimate is trusted for the verdicts: its 95 % mass interval within ±CONFIDENT_SHARE of the
    mass, from CONFIDENT_PAIRS pairs or more."""
    return (estimate is not None and estimate.pairs >= CONFIDENT_PAIRS
            and 1.96 * estimate.mass_u <= CONFIDENT_SHARE * estimate.mass)


class WeighingState(NamedTuple):
    """The weighing as one step left it (published with the step: HitchState, /diagnostics, Rerun):
    the step's ``phase``, the ``estimate`` after it (None before the first lift/lower pair), whether
    that is ``confident``, and whether the machine-level results of the step used an estimate
    (``estimate_in_use``; else the file's mass and cg). Units SI (kg, m)."""

    phase: WeighingPhase
    estimate: WeighingEstimate | None
    confident: bool
    estimate_in_use: bool


class WeighingSeries(NamedTuple):
    """The weighing's estimate after each of N steps as arrays (NaN where a step has none): ``mass`` and
    ``mass_u`` (N,) kg, ``cg`` and ``cg_u`` (N, 2) m (x, z in the mechanism's reference pose; a coordinate
    the strokes do not identify: the file's value with its prior's uncertainty); the ``u``: standard
    uncertainties (1 sigma)."""

    mass: np.ndarray
    mass_u: np.ndarray
    cg: np.ndarray
    cg_u: np.ndarray


def weighing_series(states: Sequence[WeighingState | None]) -> WeighingSeries:
    """The estimates of ``states`` (a step's each, None for a step without) as a ``WeighingSeries``."""
    rows = np.full((len(states), 6), np.nan)
    for k, state in enumerate(states):
        e = state.estimate if state is not None else None
        if e is not None:
            rows[k] = (e.mass, e.mass_u, e.cg_x, e.cg_z, e.cg_x_u, e.cg_z_u)
    return WeighingSeries(rows[:, 0], rows[:, 1], rows[:, 2:4], rows[:, 4:6])


def with_estimate(mechanism: Mechanism, estimate: WeighingEstimate) -> Mechanism:
    """A copy of ``mechanism`` whose implement has the estimate's mass and cg, the mass's standard
    uncertainty as its declared error source (``error_sources.implement.mass``)."""
    implement = ImplementFile(name="estimate", description="", mechanism=mechanism.name, mass=estimate.mass,
                              cg=(estimate.cg_x, estimate.cg_z), hitch_point=None, mast_point=None,
                              tolerances=Tolerances(mass=estimate.mass_u), file=f"{mechanism.file} (weighed)")
    return with_implement(mechanism, implement)


class ImplementMass:
    """The weighing of ``mechanism``'s implement (the file's values, before any estimate) for a monitor
    whose configuration takes its mass from ``source`` (not ``file``); ``tolerances``: the implement
    file's, its cg's the estimator's priors when it declares them; ``key``: the configuration's
    (implement, implement_mass_source) it weighs for. MechanismFileError when the mechanism cannot be
    weighed (no implement, no measured lift cylinder with a pressure sensor)."""

    def __init__(self, mechanism: Mechanism, source: str, tolerances: Tolerances | None = None,
                 key: tuple[str, str] = ("", "")) -> None:
        if source not in IMPLEMENT_MASS_SOURCES[1:]:
            raise ValueError(f"implement_mass_source '{source}' does not weigh "
                             f"(one of {', '.join(IMPLEMENT_MASS_SOURCES[1:])})")
        settings = WeighingSettings()
        if tolerances is not None and tolerances.cg_x is not None and tolerances.cg_z is not None:
            settings = replace(settings, priors=Priors(x=tolerances.cg_x, z=tolerances.cg_z))
        try:
            self.estimator = WeighingEstimator(mechanism, settings)
        except ValueError as exc:   # no implement, no measured lift cylinder with a pressure
            raise MechanismFileError(mechanism.file, "", f"implement_mass_source '{source}' cannot weigh: "
                                     + str(exc).removeprefix(f"{mechanism.file}: ")) from exc
        self.source = source
        self.in_use: WeighingEstimate | None = None   # the estimate the monitor's mechanism carries
        self.stale = False                            # a change found since the last confident estimate in use
        self.key = key
        self.last_stamp_ns = 0   # of the last step observed
        self._changes = 0
        self._fits = 0
        self._state_fit = 0   # the fit ``state``'s estimate is of (none before the first)
        self._state_estimate: tuple[WeighingEstimate | None, bool] = (None, False)

    def observe(self, stamp_ns: int, result: Result, vertical_acceleration: float | None = None) -> None:
        """One solved step, in input order; the body's vertical acceleration at the implement (m/s², gravity
        excluded; None without an IMU reading)."""
        self.estimator.step_result(stamp_ns, result, vertical_acceleration)
        self.last_stamp_ns = stamp_ns
        if len(self.estimator.changes) != self._changes:
            self._changes = len(self.estimator.changes)
            self.stale, self.in_use = True, None

    def state(self) -> WeighingState:
        """The weighing after the last step observed, that step's results computed with ``in_use``."""
        estimator = self.estimator
        if self._state_fit != estimator.fits:   # the estimate changes only with a new fit
            estimate = estimator.estimate
            self._state_fit, self._state_estimate = estimator.fits, (estimate, confident(estimate))
        estimate, sure = self._state_estimate
        return WeighingState(estimator.phase, estimate, sure, self.in_use is not None)

    def final_estimate(self) -> WeighingEstimate | None:
        """The estimate at the end of the data (the stroke under way closed)."""
        self.estimator.finish(self.last_stamp_ns)
        return self.estimator.estimate

    def pending(self) -> WeighingEstimate | None:
        """The estimate the monitor should put in use now (None: keep what it has): the first usable
        one, or one that moved by more than MOVED of its uncertainty."""
        if self.estimator.fits == self._fits:   # no new fit since the last look
            return None
        self._fits = self.estimator.fits
        estimate = self.estimator.estimate
        usable = confident(estimate) if self.source == "estimate_when_confident" or self.stale else estimate is not None
        if estimate is None or not usable:
            return None
        used = self.in_use
        if used is not None and (abs(estimate.mass - used.mass) <= MOVED * used.mass_u
                                 and abs(estimate.cg_x - used.cg_x) <= MOVED * used.cg_x_u):
            return None
        return estimate

    def put_in_use(self, estimate: WeighingEstimate) -> None:
        """The monitor's mechanism now carries ``estimate``; a confident one ends the stale mass."""
        self.in_use = estimate
        if confident(estimate):
            self.stale = False

    def finding(self) -> Finding | None:
        """The ``implement_changed`` WARN while the mass in use is stale, else None."""
        if not self.stale:
            return None
        change = self.estimator.changes[-1]
        return Finding(Code.IMPLEMENT_CHANGED, (
            f"implement changed: its load moved {change.relative_change * 100:+.1f} % at "
            f"{fmt(change.stamp_ns * 1e-9)} s; the machine-level results use the mass from before until the "
            "weighing is confident again (a lift and a lower)"))


def weighing_values(state: WeighingState) -> dict[str, str]:
    """The diagnostic's key-values of a step's weighing (kg, m; the cg in the mechanism's reference pose,
    x forward, z up): its phase, the estimate with its standard uncertainties (1 sigma), whether it is
    confident, and which mass the step's machine-level results use."""
    values = {"weighing phase": state.phase.value,
              "implement mass in use": "weighing estimate" if state.estimate_in_use else "file"}
    e = state.estimate
    if e is None:
        values["implement mass estimate"] = "none yet (no lift/lower pair over the same poses)"
        return values
    values["implement mass estimate [kg]"] = fmt(e.mass)
    values["implement mass standard uncertainty [kg]"] = fmt(e.mass_u)
    for axis, value, u, found in (("x", e.cg_x, e.cg_x_u, e.cg_x_identified), ("z", e.cg_z, e.cg_z_u, e.cg_z_identified)):
        if found:
            values[f"implement cg {axis} estimate [m]"] = fmt(value)
            values[f"implement cg {axis} standard uncertainty [m]"] = fmt(u)
        else:
            values[f"implement cg {axis} estimate"] = "not identified by these strokes"
    values["weighing confident"] = ("yes" if state.confident else
                                    f"no (the 95 % mass interval within {CONFIDENT_SHARE:.0%} of the mass from "
                                    f"{CONFIDENT_PAIRS} lift/lower pairs or more: not yet)")
    return values


def effective_mechanism(description: Mechanism, config: MonitorConfig, running: ImplementMass | None
                        ) -> tuple[Mechanism, ImplementMass | None]:
    """The mechanism a monitor of ``config`` solves: ``description`` with the configured implement hung
    on, the configuration's overrides, and the estimate in use; and its weighing (``running`` kept
    while the implement and the source stay the same; None for the source ``file``)."""
    implement = load_implement(config.implement) if config.implement else None
    hung = with_implement(description, implement) if implement is not None else description
    mech = apply_overrides(hung, dict(config.overrides)) if config.overrides else hung
    key = (config.implement, config.implement_mass_source)
    if config.implement_mass_source == "file":
        return mech, None
    weighing = (running if running is not None and running.key == key else
                ImplementMass(mech, config.implement_mass_source, implement.tolerances if implement else None, key))
    return (with_estimate(mech, weighing.in_use) if weighing.in_use is not None else mech), weighing
