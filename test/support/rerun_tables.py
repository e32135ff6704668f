"""Reading back a Rerun .rrd in tests: its chunks' record batches by entity path (rerun.chunk.RrdReader)."""

from __future__ import annotations

from pathlib import Path

from rerun.chunk import RrdReader


def temporal_tables(path: Path) -> dict[str, list]:
    """Entity path (no leading slash) -> record batches of its chunks on the ros_time timeline."""
    tables: dict[str, list] = {}
    for chunk in RrdReader(path).stream().to_chunks():
        rb = chunk.to_record_batch()
        if "ros_time" in rb.schema.names:
            tables.setdefault(chunk.entity_path.lstrip("/"), []).append(rb)
    return tables


def column(tables: dict[str, list], entity: str, name: str) -> list:
    """All rows (each a list of instances) of one component column of ``entity``, in time order."""
    rows = [(t, v) for rb in tables[entity]
            for t, v in zip(rb.column("ros_time").to_pylist(), rb.column(name).to_pylist())]
    return [v for _, v in sorted(rows, key=lambda r: r[0])]
