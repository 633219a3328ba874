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


def test_temporaries_of_writers_that_no_longer_run_are_removed(tmp_path):
    # a writer killed between creating its temporary and renaming it leaves it behind
    dead = tmp_path / ".out.txt.4194305.abc123.tmp"   # above Linux's largest pid
    alive = tmp_path / f".out.txt.{os.getpid()}.def456.tmp"   # a write going on
    other = tmp_path / ".notes.txt.4194305.abc123.tmp"   # another file's
    for path in (dead, alive, other):
        path.write_text("partial")
    atomic_write_text(tmp_path / "out.txt", "whole")
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted([alive.name, other.name,
                                                                 "out.txt"])


def test_several_files_are_all_written_or_none_replaced(tmp_path, monkeypatch):
    first, second = tmp_path / "a.json", tmp_path / "b.json"
    atomic.atomic_write_files([(first, b"old a"), (second, b"old b")])
    written, real = [], os.fdopen

    def full_on_second(fd, mode):
        handle = real(fd, mode)
        written.append(fd)
        if len(written) == 2:
            handle.close()
            raise OSError(28, "No space left on device")
        return handle

    monkeypatch.setattr(os, "fdopen", full_on_second)
    with pytest.raises(MocapError, match=f"{second}: cannot write file: No space left"):
        atomic.atomic_write_files([(first, b"new a"), (second, b"new b")])
    assert (first.read_bytes(), second.read_bytes()) == (b"old a", b"old b")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.json", "b.json"]
