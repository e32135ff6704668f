"""A bag's storage files: which they are and in which order (a rosbag2 directory, split or not, or one
file), the storage of each from its first bytes (MCAP, sqlite3; a ROS 1 bag refused with the command
that converts it), and the records of each file by its storage."""

from __future__ import annotations

import os
import re
from collections.abc import Collection, Iterator
from pathlib import Path
from typing import Any

import yaml

from linkage_monitor.bag.errors import BagError
from linkage_monitor.bag.faults import ReadFault, report
from linkage_monitor.bag.mcap_file import mcap_first_log_time, mcap_messages
from linkage_monitor.bag.mcap_records import MCAP_MAGIC
from linkage_monitor.bag.sqlite3_file import sqlite3_first_log_time, sqlite3_messages

_SQLITE_MAGIC = b"SQLite format 3\x00"
_ROS1_MAGIC = b"#ROSBAG V"
STORAGE_SUFFIXES = (".mcap", ".db3")
# libyaml's safe loader where PyYAML was built with it (4x faster on a rosbag2 metadata.yaml), else PyYAML's
_SAFE_LOADER = getattr(yaml, "CSafeLoader", yaml.SafeLoader)


def storage_files(path: str | os.PathLike[str]) -> list[Path]:
    """Return the storage files of a bag, in reading order: a rosbag2 directory or a single `.mcap` /
    `.db3` file. A directory's files in metadata.yaml's order; without metadata.yaml, or with storage
    files it does not list, every storage file by its first message's log time (ties and files without
    messages by the split index `_N` of their names, numerically: `_2` before `_10`). Raises BagError
    saying what is wrong (a ROS 1 bag: the command that converts it)."""
    path = Path(path)
    if not path.exists():
        raise BagError(f"bag {path} does not exist: give a bag directory, an .mcap or a .db3 file")
    if not path.is_dir():
        storage_of(path)
        return [path]
    listed = _files_from_metadata(path)
    for file in listed or []:
        if not file.is_file():
            raise BagError(f"bag file {file} listed in {path / 'metadata.yaml'} is missing")
    on_disk = [f for f in path.iterdir() if f.suffix in STORAGE_SUFFIXES and f.is_file()]
    for file in on_disk if listed is None else listed:
        storage_of(file)
    files = _directory_order(path, listed, on_disk)
    if not files:
        ros1 = sorted(path.glob("*.bag"))
        raise BagError(_ros1_advice(ros1[0]) if ros1 else
                       f"bag directory {path} holds no .mcap or .db3 file: give a rosbag2 bag")
    return files


def _directory_order(directory: Path, listed: list[Path] | None, on_disk: list[Path]) -> list[Path]:
    """The reading order of a bag directory's storage files (``storage_files``).

    A storage file metadata.yaml does not list is read, not skipped: rosbag2 rewrites metadata.yaml
    only when a file is closed, so such a file is most often the last one of a recorder that was
    killed, or one copied in afterwards; its messages are the recording's and leaving them out would
    lose them without a word. It is read in the order of its messages' log times, with every other
    file, and named in a ``ReadFault`` (a file of another recording shows up there: remove it)."""
    if listed is not None:
        unlisted = [file for file in sorted(set(on_disk) - set(listed), key=_split_order)
                    if _unlisted_is_read(directory, file)]
        if not unlisted:
            return listed
        on_disk = listed + unlisted
    starts = {file: _first_log_time(file) for file in on_disk}
    return sorted(on_disk, key=lambda f: (starts[f] is None, starts[f] or 0, _split_order(f)))


def _unlisted_is_read(directory: Path, file: Path) -> bool:
    """Whether the storage file ``file`` that bag ``directory``'s metadata.yaml does not list is read (it
    is an MCAP or sqlite3 file) or left out (it is not); named in a ``ReadFault`` either way."""
    try:
        storage_of(file)
    except BagError as exc:
        report(ReadFault(str(file), "unlisted_file", None, None,
                         f"{file} is in bag {directory} but not listed in its metadata.yaml, and not read: {exc}"))
        return False
    report(ReadFault(str(file), "unlisted_file", None, None,
                     f"{file} is in bag {directory} but not listed in its metadata.yaml: read in the order of its "
                     "log times with the listed files (remove it if it is not this recording's)"))
    return True


_SPLIT_NAME = re.compile(r"^(?P<stem>.+)_(?P<index>[0-9]+)$")   # rosbag2's `<bag>_<N>.<storage>`


def _split_order(file: Path) -> tuple[str, int, str]:
    """A storage file's place by its name: the stem, then rosbag2's split index `_N` as a number."""
    match = _SPLIT_NAME.match(file.stem)
    return (match["stem"], int(match["index"]), file.name) if match else (file.stem, -1, file.name)


def is_split_bag(directory: Path) -> bool:
    """Whether ``directory`` is one bag: it has metadata.yaml, or it holds no directory and its storage
    files are named as the files of one rosbag2 bag, `<stem>_<N>.mcap` / `.db3` with one stem (a split
    bag without metadata)."""
    if (directory / "metadata.yaml").is_file():
        return True
    entries = list(directory.iterdir())
    names = [_SPLIT_NAME.match(f.stem) for f in entries if f.suffix in STORAGE_SUFFIXES]
    return (bool(names) and all(names) and len({m["stem"] for m in names if m}) == 1
            and not any(f.is_dir() for f in entries))


def _first_log_time(file: Path) -> int | None:
    """The log time (ns since the epoch) of a storage file's first message; None when it holds none or
    that cannot be read."""
    if storage_of(file) == "sqlite3":
        return sqlite3_first_log_time(file)
    return mcap_first_log_time(file)


def storage_of(file: Path) -> str:
    """'mcap' or 'sqlite3', from the file's first bytes; BagError for anything else."""
    with open(file, "rb") as stream:
        head = stream.read(len(_SQLITE_MAGIC))
    if head.startswith(MCAP_MAGIC):
        return "mcap"
    if head.startswith(_SQLITE_MAGIC):
        return "sqlite3"
    if head.startswith(_ROS1_MAGIC):
        raise BagError(_ros1_advice(file))
    raise BagError(f"{file} is neither an MCAP nor a sqlite3 rosbag2 file (starts with {head[:8]!r}): "
                   "give a rosbag2 bag")


def _ros1_advice(file: Path) -> str:
    return (f"{file} is a ROS 1 bag: convert it to a rosbag2 bag with `rosbags-convert --src {file} "
            f"--dst {file.with_suffix('')}` (rosbags, installed with linkage_monitor), then give that directory")


def _files_from_metadata(directory: Path) -> list[Path] | None:
    """The files metadata.yaml lists, in its order; None when the directory has no metadata.yaml."""
    metadata = directory / "metadata.yaml"
    if not metadata.is_file():
        return None
    try:
        info = yaml.load(metadata.read_text(encoding="utf-8"), Loader=_SAFE_LOADER)["rosbag2_bagfile_information"]
        return [directory / Path(p).name for p in info["relative_file_paths"]]
    except (yaml.YAMLError, KeyError, TypeError, UnicodeDecodeError) as exc:
        raise BagError(f"{metadata} is not a rosbag2 metadata file ({type(exc).__name__}): fix or remove it"
                       ) from exc


def raw_messages(file: Path, topics: Collection[str] | None) -> Iterator[tuple[Any, Any, Any]]:
    """(schema, channel, message) records of one storage file, in log-time order."""
    if storage_of(file) == "sqlite3":
        return sqlite3_messages(file, topics)
    return mcap_messages(file, topics)
