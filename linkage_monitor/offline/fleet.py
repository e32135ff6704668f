"""Fleet analysis: many bags replayed as Dask tasks, one row per bag and a load spectrum per hinge.

Each bag is one task (``analyse_bag``) on a dask.distributed cluster — a LocalCluster on this
machine, or an existing scheduler: the same code either way. A task replays its bag with the
same stages as ``linkage-monitor replay`` (offline.replay) and reduces it to a row of
``bags.parquet`` and rows of ``spectra.parquet``; a bag that cannot be read or solved gives a
row with its error text, never a failed run. Columns carry their units (``peak_N``, ``del_N``,
``below_margin_s``); docs/fleet.md says what each one means.
"""

from __future__ import annotations

import math
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Iterable, TextIO

from linkage_monitor.bag.faults import ReadFault, read_faults
from linkage_monitor.bag.storage import STORAGE_SUFFIXES, is_split_bag
from linkage_monitor.mechanics import Mechanism, kernels
from linkage_monitor.monitoring.findings import Code

from .history import LoadHistory
from .replay import replay

DEFAULT_SLOPE = 3.0        # Wöhler exponent m (welded steel details; pins and bushings vary: the user's)
DEFAULT_BIN_N = 1000.0     # width of a range bin of the spectra, N
MARGIN_LIMIT = 0.0         # steerability margin below this: too little weight on the steered axle
RESERVE_LIMIT = 1.0        # lift reserve below this: the hitch cannot lift the implement


@dataclass
class BagAnalysis:
    """One bag reduced: ``row`` for bags.parquet, ``spectra`` rows for spectra.parquet."""

    row: dict[str, Any]
    spectra: list[dict[str, Any]] = field(default_factory=list)


def find_bags(paths: Iterable[Path]) -> list[Path]:
    """The bags under ``paths``: a file is a bag (.mcap or .db3), a directory with metadata.yaml is
    a bag (one storage file or a split bag), so is a directory whose storage files are the files of
    one split bag without it (``is_split_bag``: `<stem>_<N>.mcap`, one stem); any other directory is
    searched (sorted) for bags."""
    found: list[Path] = []
    for path in paths:
        if path.is_dir() and not is_split_bag(path):
            found += find_bags(sorted(p for p in path.iterdir() if p.is_dir() or p.suffix in STORAGE_SUFFIXES))
        else:
            found.append(path)
    return found


def analyse_bag(bag: Path, mech: Mechanism | None = None, slope: float = DEFAULT_SLOPE,
                bin_width: float = DEFAULT_BIN_N, uncertainty: bool = False) -> BagAnalysis:
    """Replay ``bag`` and reduce it (one Dask task). Never raises: an error becomes the row's ``error``;
    what of the bag could not be read (a cut-off file, a skipped chunk, a file metadata.yaml does not
    list: the reader's ``ReadFault``s) the row's ``warning``, its messages counted there.
    uncertainty: replayed with the error budget (``replay``'s), the row also gives the time the
    margin and the reserve were uncertain (``uncertain_margin_s``, ``uncertain_reserve_s``)."""
    with read_faults() as faults:
        try:
            replayed = replay(bag, mech, progress=None, uncertainty=uncertainty)
        except Exception as exc:  # noqa: BLE001 - a task boundary: the bag's own row says what failed
            text = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
            return BagAnalysis({"bag": str(bag), "error": text, "warning": _warning(faults)})
    summary, history = replayed.summary, LoadHistory.from_run(replayed.run)
    steps = max(len(replayed.steps), 1)
    row: dict[str, Any] = {
        "bag": str(bag), "error": None, "warning": _warning(faults),
        "mechanism": replayed.run.segments[0].mechanism.name
        if replayed.run.segments else None,
        "duration_s": history.duration_s, "inputs": summary.inputs, "solved": summary.solved,
        "min_margin": summary.min_margin[0] if summary.min_margin else math.nan,
        "min_margin_at_s": summary.min_margin[1] if summary.min_margin else math.nan,
        "below_margin_s": history.time_below(history.margin, MARGIN_LIMIT),
        "min_reserve": summary.min_reserve[0] if summary.min_reserve else math.nan,
        "min_reserve_at_s": summary.min_reserve[1] if summary.min_reserve else math.nan,
        "below_reserve_s": history.time_below(history.reserve, RESERVE_LIMIT),
    }
    if history.margin_half_width is not None and history.reserve_half_width is not None:
        row["uncertain_margin_s"] = history.time_uncertain(history.margin, history.margin_half_width, MARGIN_LIMIT)
        row["uncertain_reserve_s"] = history.time_uncertain(history.reserve, history.reserve_half_width,
                                                            RESERVE_LIMIT)
    counts = {code.ident: 0 for code in Code}
    for (_, ident), count in summary.kinds.items():
        counts[ident] += count
    row.update({f"share_{ident}": count / steps for ident, count in counts.items()})
    spectra = []
    for name, spectrum in history.spectra().items():
        peak, at = summary.peak_hinge[name]
        row[f"{name}_peak_N"], row[f"{name}_peak_at_s"] = peak, at
        row[f"{name}_del_N"] = spectrum.damage_equivalent(slope)
        row[f"{name}_cycles"] = float(spectrum.counts.sum())
        for lower, count in zip(*spectrum.binned(bin_width)):
            spectra.append({"bag": str(bag), "hinge": name, "range_lo_N": float(lower),
                            "range_hi_N": float(lower + bin_width), "cycles": float(count)})
    return BagAnalysis(row, spectra)


def _warning(faults: list[ReadFault]) -> str | None:
    """The row's ``warning``: every part of the bag that could not be read, one sentence each; None when all could."""
    return "; ".join(fault.text for fault in faults) or None


@dataclass
class Fleet:
    """All bags' rows (in the order of the bags) and spectra rows."""

    rows: list[dict[str, Any]]
    spectra: list[dict[str, Any]]


def run_fleet(bags: list[Path], mech: Mechanism | None = None, slope: float = DEFAULT_SLOPE,
              bin_width: float = DEFAULT_BIN_N, scheduler: str | None = None, workers: int | None = None,
              progress: TextIO | None = sys.stderr, uncertainty: bool = False) -> Fleet:
    """Analyse ``bags`` as one Dask task each: on the cluster at ``scheduler`` (tcp://host:port), or
    on a LocalCluster of ``workers`` processes (default: one per core) started and stopped here;
    ``uncertainty`` as ``analyse_bag``'s."""
    from dask.distributed import Client, LocalCluster, as_completed
    from tqdm import tqdm

    cluster = None
    if scheduler is None:
        cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=None)
    client = Client(scheduler or cluster)
    client.run(kernels.allow_threads, False)   # a worker is one process per core already: no thread pool in it
    try:
        futures = client.map(analyse_bag, bags, mech=mech, slope=slope, bin_width=bin_width, uncertainty=uncertainty,
                             pure=False)
        order = {f.key: i for i, f in enumerate(futures)}
        done: list[BagAnalysis | None] = [None] * len(bags)
        for future in tqdm(as_completed(futures), total=len(futures), desc="fleet", unit="bag", file=progress,
                           disable=progress is None):
            i = order[future.key]
            try:
                done[i] = future.result()
            except Exception as exc:  # noqa: BLE001 - the worker itself failed (e.g. killed): the row says so
                done[i] = BagAnalysis({"bag": str(bags[i]), "error": f"task failed: {exc}"})
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
    analyses = [a for a in done if a is not None]
    return Fleet([a.row for a in analyses], [s for a in analyses for s in a.spectra])


def write_parquet(fleet: Fleet, out_dir: Path) -> tuple[Path, Path]:
    """bags.parquet (one row per bag, the union of all bags' columns) and spectra.parquet."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    columns: dict[str, None] = {}
    for row in fleet.rows:
        columns.update(dict.fromkeys(row))
    bags = pa.Table.from_pylist([{c: row.get(c) for c in columns} for row in fleet.rows])
    spectra = pa.Table.from_pylist(fleet.spectra, schema=pa.schema(
        [("bag", pa.string()), ("hinge", pa.string()), ("range_lo_N", pa.float64()), ("range_hi_N", pa.float64()),
         ("cycles", pa.float64())]))
    out_dir.mkdir(parents=True, exist_ok=True)
    pq.write_table(bags, out_dir / "bags.parquet")
    pq.write_table(spectra, out_dir / "spectra.parquet")
    return out_dir / "bags.parquet", out_dir / "spectra.parquet"


def hinge_columns(rows: list[dict[str, Any]], suffix: str) -> list[str]:
    """Hinge names having a ``<hinge><suffix>`` column in any row, in first-seen order."""
    names: dict[str, None] = {}
    for row in rows:
        names.update(dict.fromkeys(k[: -len(suffix)] for k in row if k.endswith(suffix)))
    return list(names)


def worst_table(fleet: Fleet, count: int = 10) -> str:
    """The bags with the lowest steerability margin (then the failed ones) as a plain-text table."""
    ok = sorted((r for r in fleet.rows if r["error"] is None),
                key=lambda r: (math.inf if math.isnan(r["min_margin"]) else r["min_margin"]))
    lines = [f"{'bag':<44} {'inputs':>7} {'solved':>7} {'min margin':>10} {'below [s]':>9} "
             f"{'min reserve':>11} {'largest DEL':>20}"]
    for r in ok[:count]:
        dels = {h: r[f"{h}_del_N"] for h in hinge_columns([r], "_del_N")}
        worst = max(dels, key=lambda h: dels[h]) if dels else ""
        largest = f"{worst} {dels[worst] / 1e3:.2f} kN" if worst else "-"
        lines.append(f"{_short(r['bag'], 44):<44} {r['inputs']:7d} {r['solved']:7d} {r['min_margin']:+10.3f} "
                     f"{r['below_margin_s']:9.2f} {r['min_reserve']:11.2f} {largest:>20}")
    for r in fleet.rows:
        if r["error"] is not None:
            lines.append(f"{_short(r['bag'], 44):<44} failed: {r['error']}")
    for r in fleet.rows:
        if r.get("warning") is not None:
            lines.append(f"{_short(r['bag'], 44):<44} read in part: {r['warning']}")
    return "\n".join(lines)


def _short(text: str, width: int) -> str:
    return text if len(text) <= width else "…" + text[-(width - 1):]
