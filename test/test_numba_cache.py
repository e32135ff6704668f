"""numba's cache directory when the install and the home directory cannot be written.

numba refuses to define a ``cache=True`` kernel when none of its cache directories is writable
(as `runuser -u nobody` with HOME=/nonexistent on a root-owned checkout shows: "RuntimeError:
cannot cache function 'lu_factor': no locator available").
As root every real directory is writable, so "unwritable" here is a path below a regular file
(no one can create a directory there).
"""

from __future__ import annotations

import tempfile
from pathlib import Path

import pytest
from numba.core import config

from linkage_monitor.mechanics.numba_cache import ensure_writable, package_stamp, writable


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
    monkeypatch.setattr(tempfile, "tempdir", str(blocked / "tmp"))   # the system's temporary directory too
    with pytest.raises(RuntimeError, match="set NUMBA_CACHE_DIR"):
        ensure_writable(in_tree=blocked / "a", user_cache=blocked / "b", temporary=blocked / "c")


def test_a_fallback_directory_others_can_write_is_not_used(tmp_path, blocked, monkeypatch):
    """numba loads its cache files with pickle: a directory another user could write (here one
    made group- and world-writable) is passed over for a new private temporary directory."""
    monkeypatch.setattr(config, "CACHE_DIR", "")
    shared = tmp_path / "shared"
    shared.mkdir()
    shared.chmod(0o777)
    chosen = ensure_writable(in_tree=blocked / "pycache", user_cache=blocked / "user", temporary=shared)
    assert chosen is not None and chosen != shared and chosen.name.startswith("linkage_monitor-numba-")
    assert chosen.stat().st_mode & 0o077 == 0 and config.CACHE_DIR == str(chosen)
    chosen.rmdir()


def test_a_change_to_any_module_of_the_package_changes_the_stamp(tmp_path):
    """A cached kernel holds the machine code of the kernels it calls from the package's other
    modules: the stamp numba keeps with it is the whole package's, and a change to any module changes it."""
    package = tmp_path / "kernels"
    package.mkdir()
    (package / "a.py").write_text("x = 1\n")
    (package / "b.py").write_text("y = 2\n")
    before = package_stamp(package)
    assert package_stamp(package) == before
    (package / "b.py").write_text("y = 3\n")
    assert package_stamp(package) != before


def test_every_kernel_is_stamped_with_its_package():
    from linkage_monitor.mechanics import kernels
    for kernel in (kernels.linalg.lu_factor, kernels.live.live_series):
        assert kernel._cache._impl.locator.get_source_stamp() == package_stamp()   # numba's locator of the kernel
