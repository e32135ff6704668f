"""mcap's private names the bag package uses (``bag/mcap_records.py``, the one module that touches them):
each is there in the installed mcap, and one that is gone fails with a sentence naming the mcap version
and the name, not an AttributeError deep in a recording."""

from __future__ import annotations

import importlib.metadata
import io
import re
from pathlib import Path

import mcap.writer
import pytest

import linkage_monitor
from linkage_monitor.bag.mcap_records import MCAP_PRIVATE_NAMES, McapWriter, mcap_internals_missing

MCAP_VERSION = importlib.metadata.version("mcap")


def test_the_installed_mcap_has_every_private_name_the_bag_uses() -> None:
    missing = mcap_internals_missing()
    assert not missing, (f"mcap {MCAP_VERSION} lacks {', '.join(missing)}, private names of mcap 1.x that "
                         "linkage_monitor/bag/mcap_records.py uses: bring it up to this mcap or pin mcap")


def test_a_private_name_gone_is_found_and_named() -> None:
    """An mcap without ``mcap.writer.lz4`` (deleted here) is caught by the check, and a Writer without its
    ``__chunk_builder`` fails with the sentence naming the version and the name."""
    with pytest.MonkeyPatch.context() as patch:
        patch.delattr(mcap.writer, "lz4")
        assert mcap_internals_missing() == ["mcap.writer.lz4"]
    writer = McapWriter(io.BytesIO())
    del writer._Writer__chunk_builder   # type: ignore[attr-defined]  # as an mcap that renamed it
    with pytest.raises(AttributeError, match=rf"mcap {re.escape(MCAP_VERSION)} has no Writer\.__chunk_builder"):
        writer.take_pending_records()


def test_no_other_module_touches_mcaps_private_names() -> None:
    """Outside bag/mcap_records.py the package names none of mcap's private attributes or modules."""
    package = Path(linkage_monitor.__file__).parent
    private = re.compile(r"_Writer__|mcap\._|mcap_writer\.|from mcap\.\w+ import _|_chunk_builder")
    touching = [str(path.relative_to(package)) for path in package.rglob("*.py")
                if path.name != "mcap_records.py" and private.search(path.read_text(encoding="utf-8"))]
    assert touching == [], f"{touching} use mcap's private names: move that use into bag/mcap_records.py"
    assert {"Writer.__chunk_builder", "mcap._message_queue.make_message_queue"} <= set(MCAP_PRIVATE_NAMES)
