"""Atomic writes: the file appears whole or not at all, with the usual permissions."""

import os
import stat

import pytest

from mocaplib.errors import MocapError
from mocaplib.io import atomic
from mocaplib.io.atomic import atomic_write_text


def test_write_replaces_whole_file_and_leaves_no_temporary(tmp_path):
    target = tmp_path / "sub" / "out.txt"
    atomic_write_text(target, "old")
    atomic_write_text(target, "new")
    assert target.read_text() == "new"
    assert sorted(p.name for p in target.parent.iterdir()) == ["out.txt"]


def test_permissions_follow_the_umask_not_mkstemp(tmp_path):
    path = atomic_write_text(tmp_path / "report.html", "x")
    # mkstemp alone would give 0600; other people must be able to read shared reports.
    assert stat.S_IMODE(path.stat().st_mode) == 0o666 & ~atomic.UMASK
    assert atomic.UMASK == atomic._read_umask()   # the process's umask


def test_a_write_leaves_the_process_umask_alone(tmp_path, monkeypatch):
    # setting the umask to read it would give files other threads create meanwhile mode 0666
    def forbidden(mask):
        raise AssertionError("os.umask called during a write")

    monkeypatch.setattr(os, "umask", forbidden)
    assert atomic_write_text(tmp_path / "a.txt", "x").read_text() == "x"


def test_the_folder_entry_is_flushed_after_the_rename(tmp_path, monkeypatch):
    synced, fsync = [], os.fsync

    def record(fd):
        synced.append(stat.S_ISDIR(os.fstat(fd).st_mode))
        fsync(fd)

    monkeypatch.setattr(os, "fsync", record)
    atomic_write_text(tmp_path / "a.txt", "x")
    assert synced == [False, True]   # the file's data, then its folder


def test_unwritable_folder_is_a_clear_error(tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("")
    with pytest.raises(MocapError, match="cannot write here"):
        atomic_write_text(blocker / "out.txt", "x")
