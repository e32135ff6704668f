"""An error budget of a solved pose (``uncertainty.UncertaintyModel`` builds it): the published
outputs and the declared error sources it names, each source's contribution to each output, the
outputs' standard uncertainties, 95 % coverage factors and intervals, and a line per output with
each source's share.
Units SI (m, rad, Pa, N, kg); an output's value and uncertainty in its own unit (N or -).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property
from typing import Callable, Mapping, NamedTuple

import numpy as np

from .coverage_factor import Factors, coverage_factors
from .error_sources import Motion


@dataclass(frozen=True)
class Output:
    """One published number: ``name`` (``P03.fx``, ``lift_cylinder.force``, ``implement_load``,
    ``front_axle_load``, ``steerability_ratio``, ``lift_capacity.hitch_axis``, ``lift_reserve``...),
    ``kind`` (``hinge_fx``, ``hinge_fz``, ``hinge_magnitude``, ``cylinder_force``, ``implement_load``,
    ``axle_load``, ``steerability_ratio``, ``steerability_margin``, ``lift_capacity``,
    ``lift_reserve``) and ``unit`` (``N`` or ``-``)."""

    name: str
    kind: str
    unit: str


class Source(NamedTuple):
    """One declared error source at a pose: ``name`` (``lift_cap_pressure bias``, ``lift_cylinder seal
    friction``, ``implement mass``, ``P03 x position``), the ``input`` it belongs to (a measurement, a
    cylinder, ``implement`` or a point), its ``part`` (``bias``, ``noise``, ``resolution``, ``friction``,
    ``mass``, ``position``), its standard uncertainty ``u`` and ``unit`` (m, rad, Pa, N, kg)."""

    name: str
    input: str
    part: str
    u: float
    unit: str

    @property
    def uniform(self) -> bool:
        """Whether the error is uniform over ±√3·u (a quantization step, a seal's friction band), else
        normal (a bias, noise, the implement's mass, a point's position): the simulator draws them so
        (``sim.sensor_errors``)."""
        return self.part in UNIFORM_PARTS


UNIFORM_PARTS = frozenset({"resolution", "friction"})
# the sign of a seal's friction in the force the pressure carries (+ the cylinder pushes harder) by its
# motion: extending it opposes the motion, so does retracting; standing, either sign (0)
FRICTION_SIGN = {Motion.LIFTING: 1.0, Motion.LOWERING: -1.0, Motion.STANDING: 0.0}


@dataclass(frozen=True)
class OutputUncertainty:
    """One output's line of a budget: its value and standard uncertainty ``u`` (both in the output's
    unit; u NaN where a derivative could not be taken: the interval is unbounded), its 95 % coverage
    factor ``k`` (the 95 % interval is value ± k·u, ``coverage_factor``) and each source's share of u²
    (source name -> 0..1, summing to 1 where u > 0)."""

    output: Output
    value: float
    u: float
    k: float
    shares: Mapping[str, float]

    @property
    def half_width(self) -> float:
        """The 95 % interval's half-width k·u (the output's unit; NaN where unbounded)."""
        return self.k * self.u

    @property
    def dominant(self) -> str:
        """The name of the source with the largest share ("" when u is 0 or NaN)."""
        positive = {name: share for name, share in self.shares.items() if share > 0.0}
        return max(positive, key=positive.__getitem__) if positive else ""


@dataclass(eq=False)
class Budget:
    """The error budget of one pose: ``outputs`` and ``sources`` named, ``values`` (n_out,) and
    ``contributions`` (n_out, n_src) = ∂y/∂s · u_s in the output's unit (signed); ``motions`` the
    motion whose friction band each force-measured cylinder took; ``index`` output name -> its row;
    each source's shape for the coverage factor: ``uniform`` (n_src,) bool (``Source.uniform``) and
    ``sign`` (n_src,) the known sign of a moving seal's friction, else 0 (``FRICTION_SIGN``)."""

    outputs: tuple[Output, ...]
    sources: tuple[Source, ...]
    values: np.ndarray
    contributions: np.ndarray
    motions: Mapping[str, Motion]
    index: Mapping[str, int]
    uniform: np.ndarray
    sign: np.ndarray

    @staticmethod
    def summarised(outputs: tuple[Output, ...], sources: Callable[[], tuple[Source, ...]], values: np.ndarray,
                   contributions: np.ndarray, motions: Mapping[str, Motion], index: Mapping[str, int],
                   uniform: np.ndarray, sign: np.ndarray, u: np.ndarray, k: np.ndarray, tail_k: np.ndarray
                   ) -> "Budget":
        """A budget whose ``u``, ``k`` and ``tail_k`` are computed already (``kernels.tabulated_budget``: as the
        properties below compute them) and whose ``sources`` are built by ``sources()`` when first read
        (a live step reads u and the verdicts' factor alone, the names only where a finding words them)."""
        budget = object.__new__(_SummarisedBudget)   # the fields and the cached properties' values at once
        budget.__dict__ = {"outputs": outputs, "_sources": sources, "values": values, "contributions": contributions,
                           "motions": motions, "index": index, "uniform": uniform, "sign": sign, "u": u, "k": k,
                           "tail_k": tail_k}
        return budget

    @cached_property
    def u(self) -> np.ndarray:
        """Standard uncertainty (n_out,) of every output: NaN (unbounded) where a contribution is NaN or
        infinite (e.g. the lift reserve where a moved pose's lift capacity is infinite)."""
        u = np.sqrt(np.sum(self.contributions**2, axis=1))
        return np.where(np.isfinite(u), u, math.nan)

    @cached_property
    def _factors(self) -> Factors:
        """Both coverage factors of every output (``coverage_factor.coverage_factors``)."""
        return coverage_factors(self.contributions.reshape(len(self.outputs), len(self.sources)), self.uniform,
                                self.sign)

    @cached_property
    def k(self) -> np.ndarray:
        """The 95 % coverage factor (n_out,) of every output from the shape of its budget, 95 % of its
        declared error within ±k·u: 1.96 where the normal sources dominate, down to 1.645 where one
        uniform source does (a quantization step, a seal's friction standing or moving)
        (``coverage_factor.coverage_factors``)."""
        return np.where(np.isfinite(self.u), self._factors.interval, math.nan)

    @cached_property
    def tail_k(self) -> np.ndarray:
        """The factor (n_out,) of a verdict's bound: no tail of the declared error beyond ±k·u above 2.5 %;
        ``k`` where no moving seal's friction enters (else larger: up to 1.69 where it dominates)."""
        return np.where(np.isfinite(self.u), self._factors.tail, math.nan)

    @cached_property
    def half_width(self) -> np.ndarray:
        """The 95 % interval's half-width k·u (n_out,) of every output (its unit; NaN where unbounded)."""
        return self.k * self.u

    def line(self, name: str) -> OutputUncertainty:
        """The budget line of the output called ``name``; unbounded (u NaN) it names no share (all 0)."""
        k = self.index[name]
        u = float(self.u[k])
        squares = self.contributions[k] ** 2
        shares = ({s.name: float(c / u**2) for s, c in zip(self.sources, squares)} if u > 0.0
                  else {s.name: 0.0 for s in self.sources})
        return OutputUncertainty(self.outputs[k], float(self.values[k]), u, float(self.k[k]), shares)

    def lines(self) -> list[OutputUncertainty]:
        """Every output's budget line, in the order of ``outputs``."""
        return [self.line(o.name) for o in self.outputs]

    def u_of(self, name: str) -> float:
        """The standard uncertainty of the output ``name`` (NaN for an output this budget lacks)."""
        k = self.index.get(name)
        return float(self.u[k]) if k is not None else math.nan

    def half_width_of(self, name: str) -> float:
        """The 95 % half-width of the output ``name`` (NaN for an output this budget lacks)."""
        k = self.index.get(name)
        return float(self.half_width[k]) if k is not None else math.nan


class _SummarisedBudget(Budget):
    """A ``Budget.summarised``: its ``sources`` built when first read."""

    _sources: Callable[[], tuple[Source, ...]]

    @cached_property
    def sources(self) -> tuple[Source, ...]:  # type: ignore[override]  # the field, built when first read
        return self._sources()
