"""Where numba keeps the compiled physics kernels (the ``kernels`` package, ``@njit(cache=True)``),
and when it compiles them again.

numba looks for a writable directory, in this order: ``NUMBA_CACHE_DIR``, ``__pycache__`` in the
``kernels`` package (where ``make`` and a colcon install put the warm cache), the user's cache
directory (``~/.cache/numba``). When none is writable — a read-only install run by a user without
a writable home: a container, a service account — numba refuses to define the kernels at all
(``RuntimeError: cannot cache function ... no locator available``) and the node could not start.
``ensure_writable`` is called before the kernels are defined and then points numba at a per-user
directory under the system's temporary directory (compiled at the first start, and again whenever
that directory is cleared; the node's log says when it compiled).

A cached kernel holds the machine code of every kernel it calls, from the package's other modules
too, while numba keeps with it the content of its own module only: it would load a kernel built
from an older version of a module it calls. ``stamp_by_package`` has numba stamp every kernel with
the content of the whole package instead: a change to any of its modules compiles them all again.
"""

from __future__ import annotations

import functools
import hashlib
import logging
import os
import stat
import tempfile
from pathlib import Path
from typing import Any

from numba.core import caching, config

try:
    from numba.misc.appdirs import AppDirs   # the helper numba's own user-wide cache locator uses
    USER_CACHE = Path(AppDirs(appname="numba", appauthor=False).user_cache_dir)
except ImportError:   # pragma: no cover - a numba without it: its documented default on Linux
    USER_CACHE = Path.home() / ".cache" / "numba"

KERNELS = Path(__file__).with_name("kernels")   # the package of compiled kernels
IN_TREE = KERNELS / "__pycache__"   # numba's cache in the package
_log = logging.getLogger(__name__)


def writable(directory: Path) -> bool:
    """True when ``directory`` exists or can be made, and a file can be created in it (numba's own test)."""
    try:
        directory.mkdir(parents=True, exist_ok=True)
        tempfile.TemporaryFile(dir=directory).close()
        return True
    except OSError:
        return False


def private(directory: Path) -> bool:
    """True when ``directory`` is (or is made) a real directory of this user that no one else may
    write to: numba's cache files are pickles, and a shared temporary directory is open to others."""
    try:
        directory.mkdir(mode=0o700, exist_ok=True)
        info = directory.lstat()
    except OSError:
        return False
    return stat.S_ISDIR(info.st_mode) and info.st_uid == os.getuid() and not info.st_mode & 0o022


def ensure_writable(configured: str | None = None, in_tree: Path = IN_TREE, user_cache: Path = USER_CACHE,
                    temporary: Path | None = None) -> Path | None:
    """Leave numba's choice alone when one of its cache directories is writable (returns None);
    otherwise set its cache directory to ``temporary`` (default: ``<tmp>/linkage_monitor-numba-<uid>``;
    a new private temporary directory instead when that one is not this user's alone) and return it. ``configured``: NUMBA_CACHE_DIR (default: numba's configuration).
    Raises RuntimeError, saying what to do, when no directory at all can be written."""
    # numba's config module sets CACHE_DIR from the environment at import (mypy does not see it)
    configured = config.CACHE_DIR if configured is None else configured   # type: ignore[attr-defined]
    candidates = ([Path(configured)] if configured else []) + [in_tree, user_cache]
    if any(writable(directory) for directory in candidates):
        return None
    fallback = temporary or Path(tempfile.gettempdir()) / f"linkage_monitor-numba-{os.getuid()}"
    if not (private(fallback) and writable(fallback)):
        try:   # numba loads its cache files with pickle: never from a directory someone else can write
            fallback = Path(tempfile.mkdtemp(prefix="linkage_monitor-numba-"))
        except OSError as exc:
            raise RuntimeError(f"no writable directory for the compiled physics kernels: not "
                               f"{', '.join(str(d) for d in [*candidates, fallback])} ({exc.strerror}); set "
                               "NUMBA_CACHE_DIR to a directory this user can write") from exc
    config.CACHE_DIR = str(fallback)   # type: ignore[attr-defined]  # read when a cached kernel is defined
    _log.warning("numba cannot write its cache beside %s nor in %s: the physics kernels are cached in %s "
                 "(compiled again whenever that directory is cleared; set NUMBA_CACHE_DIR to keep them)",
                 in_tree.parent, user_cache, fallback)
    return fallback


@functools.lru_cache(maxsize=None)
def _package_hash(sources: tuple[tuple[str, int, int], ...]) -> bytes:
    """The hash of the package's modules' contents, by (path, mtime ns, size) of each (read again
    when one changes while the process runs)."""
    digest = hashlib.sha256()
    for path, _, _ in sources:
        digest.update(Path(path).name.encode())
        digest.update(Path(path).read_bytes())
    return digest.digest()


def package_stamp(package: Path = KERNELS) -> bytes:
    """The source stamp of every kernel of ``package``: a hash of all its modules' contents."""
    sources = []
    for path in sorted(package.glob("*.py")):
        info = path.stat()
        sources.append((str(path), info.st_mtime_ns, info.st_size))
    return _package_hash(tuple(sources))


class _PackageStamped:
    """A numba cache locator for the kernels package's functions only, stamped with ``package_stamp``."""

    def get_source_stamp(self) -> bytes:
        return package_stamp()

    @classmethod
    def from_function(cls, py_func: Any, py_file: str) -> Any:
        if not _in_package(py_file):
            return None
        return super().from_function(py_func, py_file)   # type: ignore[misc]


@functools.lru_cache(maxsize=None)
def _in_package(py_file: str) -> bool:
    """Whether ``py_file`` is a module of the kernels package (asked for each kernel by each locator: its
    paths resolved once per file)."""
    return Path(py_file).resolve().parent == KERNELS.resolve()


def stamp_by_package() -> None:
    """Have numba stamp the kernels package's cached functions with ``package_stamp``, in each of its
    cache directories (``NUMBA_CACHE_DIR``, in the package, the user's): before they are defined."""
    impl = caching.CacheImpl
    if any(issubclass(locator, _PackageStamped) for locator in impl._locator_classes):
        return
    stamped: list[Any] = [type(f"Package{base.__name__}", (_PackageStamped, base), {"__module__": __name__})
                           for base in (caching.UserProvidedCacheLocator, caching.InTreeCacheLocator,
                                        caching.UserWideCacheLocator)]
    impl._locator_classes[:0] = stamped
