"""The live terminal view of a running monitor (``linkage-monitor watch``): a ``WatchRecord`` of the
latest outputs drawn with Rich, and the same record as plain lines for scripts (``--once``).

No rclpy here: ``linkage_monitor.ros.watch`` fills the record from the node's topics. Every figure
carries its unit (kN, deg, msg/s; [-] for a dimensionless ratio). The layout follows the terminal:
boxed panels when they fit, else one line per item without boxes, the hinges in two columns and
the diagnostics cut to the rows left (80x24 holds every part).
"""

from __future__ import annotations

import math
import textwrap
from dataclasses import dataclass

from rich.console import Console, ConsoleOptions, Group, RenderableType, RenderResult
from rich.measure import Measurement
from rich.panel import Panel
from rich.table import Table
from rich.text import Text

BAR_FULL, BAR_EMPTY = "█", "░"
LEVELS = ("OK", "WARN", "ERROR", "STALE")   # diagnostic_msgs/DiagnosticStatus levels 0..3
LEVEL_STYLES = {"OK": "green", "WARN": "yellow", "ERROR": "bold red", "STALE": "bold magenta"}
MIN_COLUMN_WIDTH = 38   # a hinge row (name, force, a short bar, peak) in two columns needs this much


@dataclass(frozen=True)
class HingeLoad:
    """One hinge's reaction: its magnitude in the latest HingeReactions and the largest seen, N."""

    name: str
    force_n: float
    peak_n: float


# Alike in form only to mechanics.model's sensor records and to TopicRate below: fields of other data.
@dataclass(frozen=True)
class StatusLine:
    """The latest DiagnosticStatus of one name on /diagnostics: level name (OK, WARN, ERROR,
    STALE), message, and the findings' codes (``wire.diagnostics.CODES_KEY``; '' if none)."""

    name: str
    level: str
    message: str
    codes: str = ""


@dataclass(frozen=True)
class TopicRate:
    """Messages of one topic the watch received: per second over the last seconds, and in all."""

    topic: str
    rate_hz: float
    received: int


# Alike in form only to HingeLoad and StatusLine above: fields of other data.
@dataclass(frozen=True)
class WatchRecord:
    """What the watch knows of the monitor: the latest value of each output (NaN: not received
    yet), the statuses on /diagnostics, the rates, and how long ago an output last arrived
    (``output_age_s``, s; None: none yet). ``loss`` is the monitor's input-loss status (the node's
    ``<node>: inputs``), None while it reported none; ``ignored`` the statuses of other nodes on
/diagnostics, not shown (by name, with their count). Forces N, angles rad, ratios dimensionless."""

    namespace: str
    topics: tuple[str, ...]
    mechanism: str = ""
    hinges: tuple[HingeLoad, ...] = ()
    ratio: float = math.nan
    ratio_min: float = math.nan
    margin: float = math.nan
    ratio_reference: str = ""
    lift_reserve: float = math.nan
    implement_load_n: float = math.nan
    min_transmission_angle_rad: float = math.nan
    statuses: tuple[StatusLine, ...] = ()
    loss: StatusLine | None = None
    ignored: tuple[tuple[str, int], ...] = ()   # (status name, count): statuses on /diagnostics of other nodes
    rates: tuple[TopicRate, ...] = ()
    output_age_s: float | None = None
    stale_after_s: float = 2.0

    @property
    def stale(self) -> bool:
        """No output received yet, or none for more than ``stale_after_s``."""
        return self.output_age_s is None or self.output_age_s > self.stale_after_s


def kilonewtons(force_n: float) -> str:
    """``12.35 kN`` (n/a for NaN)."""
    return "n/a" if math.isnan(force_n) else f"{force_n / 1e3:.2f} kN"


def ratio(value: float, signed: bool = False) -> str:
    """A dimensionless figure, ``0.312 [-]`` (``+0.112 [-]`` when ``signed``; n/a for NaN)."""
    return "n/a" if math.isnan(value) else f"{value:+.3f} [-]" if signed else f"{value:.3f} [-]"


def degrees(angle_rad: float) -> str:
    """``23.4 deg`` (n/a for NaN: the general path publishes no transmission angle)."""
    return "n/a" if math.isnan(angle_rad) else f"{math.degrees(angle_rad):.1f} deg"


def freshness(record: WatchRecord) -> str:
    """LIVE / STALE / WAITING with the age of the last output."""
    if record.output_age_s is None:
        return "WAITING: no output yet"
    if record.stale:
        return f"STALE: no output for {record.output_age_s:.1f} s"
    return f"LIVE: last output {record.output_age_s:.1f} s ago"


def machine_figures(record: WatchRecord) -> list[tuple[str, str]]:
    """The machine-level figures as (label, value with its unit)."""
    reference = f" ({record.ratio_reference})" if record.ratio_reference else ""
    return [("steerability ratio", ratio(record.ratio) + reference), ("ratio min", ratio(record.ratio_min)),
            ("steerability margin", ratio(record.margin, signed=True)), ("lift reserve", ratio(record.lift_reserve)),
            ("implement load", kilonewtons(record.implement_load_n)),
            ("min transmission angle", degrees(record.min_transmission_angle_rad))]


def rate_figures(record: WatchRecord) -> list[tuple[str, str]]:
    """Each watched topic with the messages per second the watch receives of it."""
    return [(r.topic, f"{r.rate_hz:.1f} msg/s") for r in record.rates]


def loss_lines(record: WatchRecord) -> list[str]:
    """The monitor's input losses as it reported them on /diagnostics (``<node>: inputs``): its
    level and sentence, then its per-topic counts (the part after ``): ``, one topic a line); then
    the statuses of other nodes the watch left out, if any."""
    ignored = ([f"/diagnostics of other nodes, not shown: {sum(n for _, n in record.ignored)} statuses ("
                + ", ".join(name for name, _ in record.ignored) + ")"] if record.ignored else [])
    if record.loss is None:
        return ["input losses: none reported", *ignored]
    sentence, _, counts = record.loss.message.partition("): ")
    if not counts:
        return [f"input losses: {record.loss.level} {record.loss.message}", *ignored]
    return [f"input losses: {record.loss.level} {sentence.partition(' (')[0]}", *(f"  {c}" for c in counts.split("; ")),
            *ignored]


def snapshot_lines(record: WatchRecord) -> list[str]:
    """The record as plain text, one figure per line (``watch --once``: for scripts)."""
    lines = [f"monitor {record.namespace} {record.mechanism}: {freshness(record)}"]
    lines += [f"hinge {h.name} |F| {kilonewtons(h.force_n)} (peak {kilonewtons(h.peak_n)})" for h in record.hinges]
    lines += [f"{label} {value}" for label, value in machine_figures(record)]
    lines += [f"diagnostics {_status_text(s)}" for s in record.statuses]
    lines += [f"received {topic} {value}" for topic, value in rate_figures(record)]
    return [*lines, *loss_lines(record)]


class _Bar:
    """A hinge's force against its peak: a bar that fills the cell Rich gives it, its filled share
    ``force / peak`` (clipped to [0, 1]) at any width."""

    def __init__(self, force_n: float, peak_n: float) -> None:
        self.share = 0.0 if not peak_n > 0.0 or math.isnan(force_n) else min(1.0, max(0.0, force_n / peak_n))

    def __rich_console__(self, console: Console, options: ConsoleOptions) -> RenderResult:
        width = max(1, options.max_width)
        filled = round(self.share * width)
        yield Text(BAR_FULL * filled, style="cyan") + Text(BAR_EMPTY * (width - filled), style="grey35")

    def __rich_measure__(self, console: Console, options: ConsoleOptions) -> Measurement:
        return Measurement(4, options.max_width)


def _hinge_table(hinges: tuple[HingeLoad, ...]) -> Table:
    table = Table.grid(padding=(0, 1), expand=True)
    table.add_column("hinge", no_wrap=True)
    table.add_column("|F|", justify="right", no_wrap=True)
    table.add_column("bar", ratio=1, no_wrap=True)
    table.add_column("peak", justify="right", no_wrap=True)
    for h in hinges:
        table.add_row(h.name, kilonewtons(h.force_n), _Bar(h.force_n, h.peak_n), f"peak {kilonewtons(h.peak_n)}")
    return table


def _hinge_rows(count: int, rows: int, width: int) -> int:
    """Rows the hinges take: one column when they fit in ``rows`` (or the width allows no second)."""
    return count if count <= rows or width < 2 * MIN_COLUMN_WIDTH else (count + 1) // 2


def _hinges(record: WatchRecord, rows: int, width: int) -> RenderableType:
    """The hinges in one column, or two when they do not fit in ``rows`` (and the width allows)."""
    if not record.hinges:
        return Text(f"waiting for {', '.join(record.topics)}", overflow="fold")
    half = _hinge_rows(len(record.hinges), rows, width)
    if half == len(record.hinges):
        return _hinge_table(record.hinges)
    columns = Table.grid(padding=(0, 2), expand=True)
    columns.add_column(ratio=1)
    columns.add_column(ratio=1)
    columns.add_row(_hinge_table(record.hinges[:half]), _hinge_table(record.hinges[half:]))
    return columns


def _status_text(s: StatusLine) -> str:
    return f"{s.level} {s.name}: {s.message}" + (f" [{s.codes}]" if s.codes else "")


def _status_lines(statuses: tuple[StatusLine, ...], width: int, rows: int) -> list[Text]:
    """The statuses, worst level first, each wrapped to ``width``, cut to ``rows`` (at least one;
    a cut line ends in an ellipsis)."""
    if not statuses:
        return [Text("no status on /diagnostics yet", no_wrap=True, overflow="ellipsis")]
    order = sorted(statuses, key=lambda s: -LEVELS.index(s.level) if s.level in LEVELS else 0)
    lines: list[Text] = []
    for s in order:
        for k, chunk in enumerate(textwrap.wrap(_status_text(s), width, subsequent_indent="      ")):
            lines.append(Text(chunk, style=LEVEL_STYLES.get(s.level, "") if k == 0 else "", no_wrap=True,
                              overflow="ellipsis"))
    if len(lines) > max(1, rows):
        lines = lines[:max(1, rows)]
        lines[-1] = Text(lines[-1].plain[:width - 1] + "…", style=lines[-1].style, no_wrap=True)
    return lines


def _pairs(figures: list[tuple[str, str]], columns: int) -> Table:
    """(label, value) figures in ``columns`` pairs of columns, filled row by row."""
    grid = Table.grid(padding=(0, 1), expand=True)
    for _ in range(columns):
        grid.add_column(no_wrap=True, style="dim")
        grid.add_column(no_wrap=True, ratio=1)
    for k in range(0, len(figures), columns):
        row = [cell for figure in figures[k:k + columns] for cell in figure]
        grid.add_row(*row, *[""] * (2 * columns - len(row)))
    return grid


def _wrapped(lines: list[str], width: int) -> list[Text]:
    """Each of ``lines`` wrapped to ``width``, its continuation indented 4 cells."""
    return [Text(chunk, no_wrap=True, overflow="ellipsis") for line in lines
            for chunk in textwrap.wrap(line, width, subsequent_indent="    ")]


def _header(record: WatchRecord) -> Text:
    title = Text(no_wrap=True, overflow="ellipsis")
    title.append("linkage-monitor watch ", style="bold")
    title.append(f"{record.mechanism or '(mechanism not known yet)'} in {record.namespace}  ")
    title.append(freshness(record), style="bold reverse red" if record.stale else "bold green")
    return title


def view(record: WatchRecord, width: int, height: int) -> RenderableType:
    """The whole screen for a terminal of ``width`` x ``height`` cells: boxed panels when they fit,
    else plain rows; the figures in two columns when the width allows; the statuses take the rows
    left (at least one)."""
    boxed = width >= 2 * MIN_COLUMN_WIDTH + 4
    inner = width - 4 if boxed else width
    columns = 2 if inner >= 2 * MIN_COLUMN_WIDTH else 1
    machine, rates = machine_figures(record), rate_figures(record)
    losses = _wrapped(loss_lines(record), inner)
    machine_rows, rate_rows = -(-len(machine) // columns), -(-len(rates) // columns)
    hinge_rows = max(1, len(record.hinges))
    status_rows = height - (1 + hinge_rows + machine_rows + rate_rows + len(losses) + 8)   # 4 boxes, 2 rows each
    if boxed and status_rows >= min(2, len(record.statuses)):
        return Group(_header(record),
                     Panel(_hinges(record, hinge_rows, inner), title="hinge reactions |F| against the peak seen",
                           title_align="left"),
                     Panel(_pairs(machine, columns), title="machine", title_align="left"),
                     Panel(Group(*_status_lines(record.statuses, inner, status_rows)), title="/diagnostics",
                           title_align="left"),
                     Panel(Group(_pairs(rates, columns), *losses), title="inputs: received by this watch, lost by "
                           "the monitor", title_align="left"))
    columns = 2 if width >= 2 * MIN_COLUMN_WIDTH else 1
    losses = _wrapped(loss_lines(record), width)
    machine_rows, rate_rows = -(-len(machine) // columns), -(-len(rates) // columns)
    fixed = 1 + machine_rows + rate_rows + len(losses)
    hinge_rows = _hinge_rows(len(record.hinges), height - fixed - 1, width)
    return Group(_header(record), _hinges(record, height - fixed - 1, width), _pairs(machine, columns),
                 *_status_lines(record.statuses, width, height - fixed - hinge_rows), _pairs(rates, columns), *losses)
