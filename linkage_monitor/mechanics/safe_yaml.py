"""A mechanism file's YAML, read safely: only a regular file of at most MAX_FILE_BYTES (a FIFO or a
device would block), UTF-8, no aliases (no expansion bombs), nesting no deeper than MAX_DEPTH, no
duplicate keys, no absurdly long integers. Every problem raises :class:`MechanismFileError` naming
the file and the line and column.
"""

from __future__ import annotations

import stat
from pathlib import Path
from typing import Any

import yaml

from .errors import MechanismFileError

MAX_FILE_BYTES = 1 << 20     # a mechanism description is a few kB; more is not a mechanism
MAX_DEPTH = 32               # nesting of mappings/lists (the schema needs 5)


def read_file(path: Path) -> bytes:
    """The bytes of the regular file ``path`` of at most MAX_FILE_BYTES (a FIFO or a device would block)."""
    try:
        info = path.stat()
    except OSError as exc:
        raise MechanismFileError(str(path), "", f"cannot read the file ({exc.strerror})") from exc
    if not stat.S_ISREG(info.st_mode):
        raise MechanismFileError(str(path), "", "not a regular file (a directory, FIFO or device): give a YAML file")
    if info.st_size > MAX_FILE_BYTES:
        raise MechanismFileError(str(path), "", f"{info.st_size} bytes: larger than the {MAX_FILE_BYTES} bytes a "
                                 "mechanism description may have")
    try:
        with open(path, "rb") as stream:
            data = stream.read(MAX_FILE_BYTES + 1)
    except OSError as exc:
        raise MechanismFileError(str(path), "", f"cannot read the file ({exc.strerror})") from exc
    return data


# libyaml's safe loader where built: ~9x faster than PyYAML's own parser (the same safe constructors)
LIBYAML_LOADER = getattr(yaml, "CSafeLoader", yaml.SafeLoader)
_OPENS, _CLOSES = (yaml.MappingStartEvent, yaml.SequenceStartEvent), (yaml.MappingEndEvent, yaml.SequenceEndEvent)


def _refuse_aliases_and_depth(text: str) -> None:
    """Raise a YAML error at the first alias (``*name``: no expansion bombs) or at nesting deeper than
    MAX_DEPTH, from the parser's events, before anything is composed."""
    depth = 0
    try:
        for event in yaml.parse(text, Loader=LIBYAML_LOADER):
            if isinstance(event, yaml.AliasEvent):
                raise yaml.constructor.ConstructorError(None, None, "aliases (*name) are not allowed in a mechanism "
                                                        "description: write the value out", event.start_mark)
            depth += isinstance(event, _OPENS) - isinstance(event, _CLOSES)
            if depth > MAX_DEPTH:
                raise yaml.constructor.ConstructorError(None, None, f"nesting deeper than {MAX_DEPTH} levels",
                                                        event.start_mark)
    except yaml.scanner.ScannerError as exc:   # libyaml stops at 1000 open brackets itself, scanning ahead
        if "maximum nesting depth" not in str(exc.problem):
            raise
        raise yaml.constructor.ConstructorError(None, None, f"nesting deeper than {MAX_DEPTH} levels",
                                                exc.problem_mark) from None


class _StrictLoader(LIBYAML_LOADER):   # type: ignore[misc,valid-type]  # CSafeLoader or SafeLoader
    """Safe loader that refuses duplicate keys and absurdly long integers (aliases and deep nesting:
    ``_refuse_aliases_and_depth``, first)."""

    def construct_mapping(self, node, deep=False):
        seen = set()
        for key_node, _ in node.value:
            key = self.construct_object(key_node, deep=deep)
            if key in seen:
                raise yaml.constructor.ConstructorError(None, None, f"duplicate key {key!r}", key_node.start_mark)
            seen.add(key)
        return super().construct_mapping(node, deep=deep)

    def construct_yaml_int(self, node):
        if len(str(node.value)) > 30:
            raise yaml.constructor.ConstructorError(None, None, f"integer of {len(str(node.value))} digits: "
                                                    "not a quantity of a linkage", node.start_mark)
        return super().construct_yaml_int(node)


_StrictLoader.add_constructor("tag:yaml.org,2002:int", _StrictLoader.construct_yaml_int)
_StrictLoader.add_constructor("tag:yaml.org,2002:map", _StrictLoader.construct_yaml_map)


def parse_yaml(text: bytes | str, file: str) -> Any:
    """The YAML ``text`` (bytes: UTF-8) parsed, hostile text refused; ``file`` names it in errors."""
    if isinstance(text, bytes):
        if len(text) > MAX_FILE_BYTES:
            raise MechanismFileError(file, "", f"larger than the {MAX_FILE_BYTES} bytes a mechanism description "
                                     "may have")
        try:
            text = text.decode("utf-8")
        except UnicodeDecodeError as exc:
            raise MechanismFileError(file, "", f"not UTF-8 text (byte {exc.start}: {exc.reason}); save the file "
                                     "as UTF-8") from exc
    try:
        _refuse_aliases_and_depth(text)
        data = yaml.load(text, Loader=_StrictLoader)  # noqa: S506 - a safe loader's subclass
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f"line {mark.line + 1}, column {mark.column + 1}" if mark is not None else "YAML"
        problem = getattr(exc, "problem", None) or str(exc).splitlines()[0]
        raise MechanismFileError(file, where, f"malformed YAML: {problem}") from exc
    except RecursionError as exc:
        raise MechanismFileError(file, "YAML", f"nesting deeper than {MAX_DEPTH} levels") from exc
    return data
