"""Weighing the implement while it works: mass, cg and their uncertainty from the monitor's steps (no rclpy).

The monitor solves each step's pose and the lift cylinder's force from its pressure. The
``WeighingEstimator`` takes, per step, the cylinder's length (m) and force (N) (and, with an
IMU, the body's vertical acceleration) and

1. names the step's phase (``WeighingPhase``): only a cylinder that moves with its valve open
   says the load plus a known-signed friction; a standing cylinder holds its load with any
   friction within the breakaway band (unusable); near the working position the implement may
   rest on the ground (its moving steps are binned, and the fit takes the zone's bins only where
   they agree with the rest: ``weighing_fit``); a bouncing body adds inertia (rejected from the IMU's vertical
   acceleration, or without one from the pressure's own variation: the load's relative rate of
   change, smoothed);
2. collects the moving steps of each stroke (a lift or a lower) in bins of the stroke
   (``weighing_fit``); at the end of a stroke it compares the stroke with the earlier ones in the
   same direction (the same friction): a change of the load no uncertainty explains (coupling,
   filling, emptying) is an ``ImplementChange`` and the estimate restarts from that stroke;
3. fits the weight and the cg over the lift/lower pairs (``weighing_fit``) and gives the mass
   (kg) and the cg (m, the implement's reference-pose coordinates, as the mechanism file takes
   them) with standard uncertainties (1 σ widened by Student's factor for the degrees of freedom
   the scatter was estimated from: the 95 % interval is ±1.96 u).

Units SI; frame x forward, z up, origin at the rear wheels' ground contact.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import Enum

import numpy as np

from linkage_monitor.mechanics import Mechanism, Result
from linkage_monitor.mechanics.constants import STANDARD_GRAVITY

from .weighing_fit import N, SUMS, UNITS, Y, Fit, Priors, SensorErrors, Spread, fit, student_factor
from .weighing_model import ForceColumns, WeighingModel


class WeighingPhase(Enum):
    """What a step is to the weighing; only LIFTING and LOWERING steps are used."""

    NOT_SOLVED = "not_solved"          # no pose, no force, or off the tabulated stroke
    GROUND_CONTACT = "ground_contact"  # near the working position: the ground may carry part of the load
    STANDING = "standing"              # the cylinder stands, its valve closed: the friction is indeterminate
    BOUNCING = "bouncing"              # the body bounces: inertia on the load
    LIFTING = "lifting"
    LOWERING = "lowering"


USED = (WeighingPhase.LIFTING, WeighingPhase.LOWERING)


# Settings as fields with defaults, alike in form only to sim.work_cycle.WorkCycle and
# test/support/fuzz_check.FuzzTally: other data.
@dataclass(frozen=True)
class WeighingSettings:
    """How the estimator judges steps. motion_speed: the rod speed (m/s) above which the cylinder
    moves; speed_time: the smoothing of that speed (s); bounce_rate: the load's smoothed relative
    rate of change (1/s) above which the body bounces; bounce_time (s): its averaging;
    imu_bounce: the IMU's RMS vertical acceleration (m/s²) above which it bounces;
    ground_contact: the share of the stroke from the reference (working) length toward lifting
    within which the implement may rest on the ground; bins: of the stroke; min_samples: per bin
    and direction; change: the relative load change that restarts the estimate; pressure_noise,
    pressure_gain, pressure_offset: the pressure sensor's declared errors (Pa, -, Pa; 1 σ)."""

    motion_speed: float = 0.015
    speed_time: float = 0.1
    bounce_rate: float = 0.5
    bounce_time: float = 0.3
    imu_bounce: float = 0.03 * STANDARD_GRAVITY
    ground_contact: float = 0.06
    bins: int = 40
    min_samples: int = 3
    change: float = 0.08
    pressure_noise: float = 2e4
    pressure_gain: float = 0.005
    pressure_offset: float = 2e4
    priors: Priors = Priors()


@dataclass(frozen=True)
class WeighingEstimate:
    """The implement's mass (kg) and cg (m, the mechanism's reference pose, the implement's frame)
    with their standard uncertainties (1 σ, Student-widened: ±1.96 u is 95 %); ``cg_x_identified`` /
    ``cg_z_identified``: the data narrowed the coordinate to less than half its prior (otherwise it is the file's value and the
    prior's uncertainty); ``pairs``: lift/lower pairs of stroke bins used; ``friction_share``: the
    seal friction found, as a share of the load's force (-)."""

    mass: float
    mass_u: float
    cg_x: float
    cg_x_u: float
    cg_z: float
    cg_z_u: float
    cg_x_identified: bool
    cg_z_identified: bool
    pairs: int
    friction_share: float

    def interval(self, value: float, u: float) -> tuple[float, float]:
        """The 95 % interval value ± 1.96·u."""
        return value - 1.96 * u, value + 1.96 * u


@dataclass(frozen=True)
class ImplementChange:
    """A load change no uncertainty explains, found at the end of a stroke: when (ns), by how much (-)."""

    stamp_ns: int
    relative_change: float


class WeighingEstimator:
    """The live weighing of ``mechanism``'s implement (module docstring); ``step`` once per solved step."""

    def __init__(self, mechanism: Mechanism, settings: WeighingSettings = WeighingSettings(),
                 model: WeighingModel | None = None) -> None:
        self.model = model if model is not None else WeighingModel(mechanism)
        self.settings = settings
        cylinder = mechanism.cylinder(self.model.cylinder)
        area = cylinder.count * cylinder.cap_area
        self.errors = SensorErrors(noise=settings.pressure_noise * area, gain=settings.pressure_gain,
                                   offset=settings.pressure_offset * area)
        m = self.model
        span = m.high - m.low
        self._contact_edge = m.contact_edge(settings.ground_contact)
        self._bin_width = span / settings.bins
        # the bins reaching into the contact zone, from its edge toward the working position
        touched = [k for k in range(settings.bins)
                   if m.grounded(m.low + (k + (0.0 if m.lifting_sign > 0 else 1.0)) * self._bin_width, self._contact_edge)]
        self._contact = np.array(sorted(touched, reverse=m.lifting_sign > 0), dtype=int)
        self._sums = np.zeros((settings.bins, 2, len(SUMS)))
        self._units = np.zeros((UNITS, settings.bins, 2, len(SUMS)))   # the strokes in groups, a direction each
        self._strokes = [0, 0]   # strokes so far per direction (lifting, lowering): the next one's group
        self._stroke: dict[tuple[int, int], list[float]] = {}
        self._stroke_direction = 0
        self._last_stamp: int | None = None
        self._last_length = math.nan
        self._speed = 0.0
        self._smooth_load = math.nan
        self._bounce = 0.0
        self._fit: Fit | None = None
        self._columns: ForceColumns | None = None
        self.changes: list[ImplementChange] = []
        self.fits = 0   # fits made so far: the estimate changes only when this grows
        self.phase_steps = {phase: 0 for phase in WeighingPhase}
        self.phase = WeighingPhase.NOT_SOLVED
        self._motion = 0   # the step's direction of motion, +1 lifting, -1 lowering, 0 standing or bouncing

    # ---- per step -----------------------------------------------------------------------------
    def step(self, stamp_ns: int, length: float, force: float, vertical_acceleration: float | None = None
             ) -> WeighingPhase:
        """One solved step: the lift cylinder's length (m) and force from its pressure (N, + pushing),
        the body's vertical acceleration (m/s², gravity excluded; None without an IMU). Returns the
        step's phase."""
        phase = self._phase(stamp_ns, length, force, vertical_acceleration)
        direction = self._motion
        if phase is not WeighingPhase.BOUNCING and direction != self._stroke_direction:
            self._close_stroke(stamp_ns)
            self._stroke_direction = direction
        if direction:
            self._collect(length, force, direction, self._columns)
        self.phase = phase
        self.phase_steps[phase] += 1
        return phase

    def step_result(self, stamp_ns: int, result: Result, vertical_acceleration: float | None = None
                    ) -> WeighingPhase:
        """``step`` with the lift cylinder's length and force taken from the monitor's solved pose."""
        row = result.cylinder_values[result.names.cylinders.index(self.model.cylinder)]
        return self.step(stamp_ns, float(row[0]), float(row[1]), vertical_acceleration)

    def run(self, stamps_ns: np.ndarray, lengths: np.ndarray, forces: np.ndarray,
            vertical_accelerations: np.ndarray | None = None) -> list[WeighingPhase]:
        """``step`` over arrays of steps (ns, m, N, m/s² or None), then ``finish``; the phases."""
        accelerations = [None] * len(lengths) if vertical_accelerations is None else vertical_accelerations.tolist()
        phases = [self.step(stamp, length, force, acceleration) for stamp, length, force, acceleration
                  in zip(stamps_ns.tolist(), lengths.tolist(), forces.tolist(), accelerations)]
        if len(stamps_ns):
            self.finish(int(stamps_ns[-1]))
        return phases

    def _phase(self, stamp_ns: int, length: float, force: float, acceleration: float | None) -> WeighingPhase:
        settings, m = self.settings, self.model
        last_stamp, last_length = self._last_stamp, self._last_length
        if last_stamp is None or stamp_ns > last_stamp:   # a second step of one stamp (another input) keeps the first
            self._last_stamp, self._last_length = stamp_ns, length
        columns = self._columns = m.at(length) if math.isfinite(force) else None
        self._motion = 0
        if columns is None:
            self._smooth_load = math.nan
            return WeighingPhase.NOT_SOLVED
        if last_stamp is not None and stamp_ns > last_stamp and math.isfinite(last_length):
            dt = (stamp_ns - last_stamp) * 1e-9
            keep = math.exp(-dt / settings.speed_time)
            self._speed = keep * self._speed + (1.0 - keep) * (length - last_length) / dt
            load = (force - columns.link) / columns.u0
            smooth = self._smooth_load
            self._smooth_load = load if math.isnan(smooth) else keep * smooth + (1.0 - keep) * load
            if acceleration is not None:
                signal = acceleration * acceleration
            elif not math.isnan(smooth) and load != 0.0:
                rate = (self._smooth_load - smooth) / (dt * abs(self._smooth_load))
                signal = rate * rate
            else:
                signal = 0.0
            fade = math.exp(-dt / settings.bounce_time)
            self._bounce = fade * self._bounce + (1.0 - fade) * signal
        self._motion = 0
        grounded = m.grounded(length, self._contact_edge)
        if abs(self._speed) < settings.motion_speed:
            self._bounce = 0.0 if acceleration is None else self._bounce   # a stroke's start judges itself
            return WeighingPhase.GROUND_CONTACT if grounded else WeighingPhase.STANDING
        limit = settings.imu_bounce if acceleration is not None else settings.bounce_rate
        now = acceleration * acceleration if acceleration is not None else 0.0
        if self._bounce > limit * limit or now > limit * limit:
            return WeighingPhase.GROUND_CONTACT if grounded else WeighingPhase.BOUNCING
        self._motion = 1 if self._speed * m.lifting_sign > 0.0 else -1
        # a moving step within the contact zone is collected in its bin all the same: the fit takes
        # the zone's bins only while the ground carries none of the load they show (weighing_fit)
        if grounded:
            return WeighingPhase.GROUND_CONTACT
        return WeighingPhase.LIFTING if self._motion > 0 else WeighingPhase.LOWERING

    def _collect(self, length: float, force: float, direction: int, columns: ForceColumns | None) -> None:
        assert columns is not None   # _phase names a step off the table NOT_SOLVED
        k = min(int((length - self.model.low) / self._bin_width), self.settings.bins - 1)
        y = force - columns.link
        sums = self._stroke.get((k, direction))
        if sums is None:
            self._stroke[(k, direction)] = [1.0, columns.u0, columns.ux, columns.uz, y, y * y, force]
        else:
            sums[0] += 1.0
            sums[1] += columns.u0
            sums[2] += columns.ux
            sums[3] += columns.uz
            sums[4] += y
            sums[5] += y * y
            sums[6] += force

    # ---- per stroke ---------------------------------------------------------------------------
    def _close_stroke(self, stamp_ns: int) -> None:
        """Compare the stroke with the earlier ones of its direction, restart on a change, refit."""
        if not self._stroke:
            return
        stroke = np.zeros_like(self._sums)
        for (k, direction), sums in self._stroke.items():
            stroke[k, 0 if direction > 0 else 1] = sums
        self._stroke = {}
        change = self._relative_change(stroke)
        if change is not None and abs(change) > self.settings.change:
            self.changes.append(ImplementChange(stamp_ns, change))
            self._sums = stroke
            self._units[:] = 0.0
            self._strokes = [0, 0]
        else:
            self._sums += stroke
        side = 0 if self._stroke_direction > 0 else 1
        self._units[self._strokes[side] % UNITS, :, side] += stroke[:, side]
        self._strokes[side] += 1
        # the contact zone's bins are judged against the rest once each direction has two strokes: from
        # one lift and one lower (a start, a change) the rest's fit is too loose to tell the ground's share
        self._fit = fit(self._sums, self.errors, self.settings.priors, self.settings.min_samples, self._units,
                        self._contact, judge_contact=min(self._strokes) >= 2)
        self.fits += 1

    def _relative_change(self, stroke: np.ndarray) -> float | None:
        """The stroke's load against the earlier strokes' in the same bins and direction (median
        relative difference of the bins' mean y); None where they share no bin."""
        minimum = self.settings.min_samples
        both = (stroke[:, :, N] >= minimum) & (self._sums[:, :, N] >= minimum)
        both[self._contact] = False   # the ground's share may differ from stroke to stroke
        if not both.any():
            return None
        new = stroke[both][:, Y] / stroke[both][:, N]
        old = self._sums[both][:, Y] / self._sums[both][:, N]
        return float(np.median((new - old) / np.abs(old)))

    def finish(self, stamp_ns: int) -> None:
        """End of the data: the stroke under way is closed (its steps counted in the estimate)."""
        self._close_stroke(stamp_ns)
        self._stroke_direction = 0

    # ---- the estimate -------------------------------------------------------------------------
    @property
    def estimate(self) -> WeighingEstimate | None:
        """The present estimate (None before the first lift/lower pair)."""
        result = self._fit
        if result is None or result.theta[0] <= 0.0:
            return None
        g = self.model.gravity
        weight, wx, wz = (float(v) for v in result.theta)
        mass = result.spread(np.array([1.0, 0.0, 0.0]))
        offsets = []
        for j in (1, 2):   # d = θj/θ0: first-order propagation of θ's covariance, with its own degrees of freedom
            jac = np.zeros(3)
            jac[0], jac[j] = -result.theta[j] / weight**2, 1.0 / weight
            offsets.append(_widened(result.spread(jac)))
        priors = self.settings.priors
        ref = self.model.reference_cg
        return WeighingEstimate(mass=weight / g, mass_u=_widened(mass) / g,
                                cg_x=float(ref[0]) + wx / weight, cg_x_u=offsets[0],
                                cg_z=float(ref[1]) + wz / weight, cg_z_u=offsets[1],
                                cg_x_identified=offsets[0] < 0.5 * priors.x,
                                cg_z_identified=offsets[1] < 0.5 * priors.z,
                                pairs=result.pairs, friction_share=result.friction_share)


def _widened(spread: Spread) -> float:
    """The standard uncertainty widened by Student's factor for its degrees of freedom: ±1.96 u is 95 %."""
    return math.sqrt(max(spread.variance, 0.0)) * student_factor(spread.dof)


def estimate_text(estimate: WeighingEstimate | None, file_mass: float | None) -> str:
    """The estimate with its 95 % intervals as lines of text (kg, m; ``file_mass`` kg the file's, if any)."""
    if estimate is None:
        return "no estimate (no lift/lower pair over the same poses)"
    low, high = estimate.interval(estimate.mass, estimate.mass_u)
    lines = [f"implement mass {estimate.mass:.1f} kg, 95 % interval {low:.1f} .. {high:.1f} kg"
             + (f" (the mechanism file says {file_mass:.1f} kg)" if file_mass is not None else "")]
    for axis, value, u, found in (("x", estimate.cg_x, estimate.cg_x_u, estimate.cg_x_identified),
                                  ("z", estimate.cg_z, estimate.cg_z_u, estimate.cg_z_identified)):
        lo, hi = estimate.interval(value, u)
        lines.append(f"cg {axis} {value:+.3f} m, 95 % interval {lo:+.3f} .. {hi:+.3f} m (reference pose)"
                     + ("" if found else ": not identified by these strokes, the file's value"))
    lines.append(f"from {estimate.pairs} lift/lower pairs of stroke bins; seal friction "
                 f"{estimate.friction_share * 100:.1f} % of the force")
    return "\n".join(lines)
