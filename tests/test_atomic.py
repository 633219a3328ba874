"""Atomic writes: the file appears whole or not at all, with the usual permissions."""

import os
import stat

import pytest

from mocaplib.errors import MocapError
from mocaplib.io.atomic import atomic_write_text


def test_write_replaces_whole_file_and_leaves_no_temporary(tmp_path):
    target = tmp_path / "sub" / "out.txt"
    atomic_write_text(target, "old")
    atomic_write_text(target, "new")
    assert target.read_text() == "new"
    assert sorted(p.name for p in target.parent.iterdir()) == ["out.txt"]


def test_permissions_follow_the_umask_not_mkstemp(tmp_path):
    old = os.umask(0o022)
    try:
        path = atomic_write_text(tmp_path / "report.html", "x")
    finally:
        os.umask(old)
    # mkstemp alone would give 0600; other people must be able to read shared reports.
    assert stat.S_IMODE(path.stat().st_mode) == 0o644


def test_unwritable_folder_is_a_clear_error(tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("")
    with pytest.raises(MocapError, match="cannot write here"):
        atomic_write_text(blocker / "out.txt", "x")
