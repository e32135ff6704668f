"""numba's cache directory when the install and the home directory cannot be written.

numba refuses to define a ``cache=True`` kernel when none of its cache directories is writable
(checked by hand in round 2, eighth session: `runuser -u nobody` with HOME=/nonexistent on the
root-owned checkout: "RuntimeError: cannot cache function 'lu_factor': no locator available").
As root every real directory is writable, so "unwritable" here is a path below a regular file
(no one can create a directory there).
"""

from __future__ import annotations

from pathlib import Path

import pytest
from numba.core import config

from linkage_monitor.mechanics.numba_cache import ensure_writable, writable


@pytest.fixture
def blocked(tmp_path: Path) -> Path:
    """A regular file: every path below it is unwritable."""
    path = tmp_path / "a_file"
    path.write_text("not a directory")
    return path


def test_writable_means_a_file_can_be_made_there(tmp_path, blocked):
    assert writable(tmp_path / "new" / "cache")
    assert (tmp_path / "new" / "cache").is_dir()
    assert not writable(blocked / "cache")


def test_numba_keeps_its_own_choice_while_one_of_its_directories_is_writable(tmp_path, blocked, monkeypatch):
    monkeypatch.setattr(config, "CACHE_DIR", "")
    assert ensure_writable(in_tree=blocked / "pycache", user_cache=tmp_path / "user",
                           temporary=tmp_path / "tmp") is None
    assert ensure_writable(in_tree=tmp_path / "pycache", user_cache=blocked / "user",
                           temporary=tmp_path / "tmp") is None
    assert config.CACHE_DIR == ""   # untouched
    assert not (tmp_path / "tmp").exists()


def test_without_a_writable_directory_numba_is_pointed_at_a_temporary_one(tmp_path, blocked, monkeypatch):
    monkeypatch.setattr(config, "CACHE_DIR", "")
    chosen = ensure_writable(in_tree=blocked / "pycache", user_cache=blocked / "user", temporary=tmp_path / "tmp")
    assert chosen == tmp_path / "tmp" and chosen.is_dir()
    assert config.CACHE_DIR == str(tmp_path / "tmp")


def test_an_unwritable_numba_cache_dir_setting_is_passed_over_too(tmp_path, blocked, monkeypatch):
    monkeypatch.setattr(config, "CACHE_DIR", str(blocked / "configured"))
    chosen = ensure_writable(in_tree=blocked / "pycache", user_cache=blocked / "user", temporary=tmp_path / "tmp")
    assert chosen == tmp_path / "tmp"


def test_no_writable_directory_at_all_says_what_to_set(blocked, monkeypatch):
    monkeypatch.setattr(config, "CACHE_DIR", "")
    with pytest.raises(RuntimeError, match="set NUMBA_CACHE_DIR"):
        ensure_writable(in_tree=blocked / "a", user_cache=blocked / "b", temporary=blocked / "c")
