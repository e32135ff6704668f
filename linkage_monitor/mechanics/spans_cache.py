"""The swept spans of a mechanism's inputs (``limits``) kept on disk, so that a process started
again (a node, a replay, a fleet worker) reads them instead of sweeping the linkage again: the
sweeps build a solver per driving input and run batch kernels nothing else at start-up needs.

Where: ``$LINKAGE_MONITOR_CACHE_DIR``, else ``$XDG_CACHE_HOME/linkage_monitor``, else
``~/.cache/linkage_monitor``; in its ``input_spans`` directory, one JSON file per entry (never a
pickle: a file there is data, not code). A cache that cannot be read, holds a malformed entry or
cannot be written is passed over: the spans are swept as without it.

Key: SHA-256 of the description (canonical JSON), the sweep's parameters, and the physics code —
every source file of this package, the numpy, numba and Python versions and the CPU numba
compiles for. A change to any of them gives another key, so an entry is never read for anything
but what computed it; the oldest entries beyond KEPT are removed when one is written.
"""

from __future__ import annotations

import functools
import hashlib
import json
import math
import os
import sys
import tempfile
from pathlib import Path
from typing import Collection, Mapping

import numba
import numpy as np
from llvmlite import binding as llvm

CACHE_ENV = "LINKAGE_MONITOR_CACHE_DIR"
PACKAGE = Path(__file__).parent   # the physics code the spans come from
KEPT = 256   # entries kept (each a few hundred bytes)

Spans = dict[str, tuple[float, float]]   # input name -> (lo, hi), m or rad


def cache_dir() -> Path:
    """The directory of the entries (see the module's docstring)."""
    user_cache = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache")
    return Path(os.environ.get(CACHE_ENV) or user_cache / "linkage_monitor") / "input_spans"


@functools.lru_cache(maxsize=4)
def code_fingerprint(package: Path = PACKAGE) -> str:
    """SHA-256 of every ``*.py`` of ``package`` (by path inside it), the numpy, numba and Python
    versions and the host CPU (name and features) numba compiles the kernels for."""
    digest = hashlib.sha256()
    for path in sorted(package.rglob("*.py")):
        digest.update(path.relative_to(package).as_posix().encode() + b"\0" + path.read_bytes() + b"\0")
    digest.update("\0".join([np.__version__, numba.__version__, sys.version, llvm.get_host_cpu_name(),
                             llvm.get_host_cpu_features().flatten()]).encode())
    return digest.hexdigest()


def entry_key(description_key: str, parameters: Mapping[str, float]) -> str:
    """The key of a description's spans swept with these parameters by this code."""
    digest = hashlib.sha256(code_fingerprint().encode())
    digest.update(json.dumps(dict(parameters), sort_keys=True).encode() + b"\0" + description_key.encode())
    return digest.hexdigest()


def load(key: str, names: Collection[str]) -> Spans | None:
    """The spans kept under ``key``, or None when there are none or the entry is not spans of
    inputs among ``names`` (each a finite lo <= hi)."""
    try:
        data = json.loads((cache_dir() / f"{key}.json").read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    if not isinstance(data, dict) or not set(data) <= set(names):
        return None
    spans: Spans = {}
    for name, value in data.items():
        if not (isinstance(value, list) and len(value) == 2
                and all(type(v) is float and math.isfinite(v) for v in value) and value[0] <= value[1]):
            return None
        spans[name] = (value[0], value[1])
    return spans


def store(key: str, spans: Mapping[str, tuple[float, float]]) -> None:
    """Keep ``spans`` under ``key`` (written whole or not at all); nothing when the directory
    cannot be written."""
    directory = cache_dir()
    try:
        directory.mkdir(parents=True, exist_ok=True)
        with tempfile.NamedTemporaryFile("w", dir=directory, suffix=".tmp", delete=False, encoding="utf-8") as file:
            json.dump({name: [float(lo), float(hi)] for name, (lo, hi) in spans.items()}, file)
        os.replace(file.name, directory / f"{key}.json")
        _prune(directory)
    except OSError:
        return


def _prune(directory: Path) -> None:
    """Remove the least recently written entries beyond KEPT."""
    entries = sorted(directory.glob("*.json"), key=lambda path: path.stat().st_mtime)
    for path in entries[:-KEPT]:
        path.unlink(missing_ok=True)
