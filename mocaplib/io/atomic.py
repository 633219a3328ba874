"""Atomic file output: write to a temporary file in the target folder, then rename.

A reader never sees a half-written file, and an interrupted write leaves the old file intact.
The file's data and, where the system allows it, the folder's new entry are flushed to disk
before returning. :func:`atomic_write_files` writes several files as far as POSIX allows as
one: every temporary is written and flushed before the first rename, so a full disk or an
error leaves every old file as it was; only a kill between the renames (which need no space)
can leave some files new and the rest old, and the last file renamed is the one that tells a
reader the set is complete (the library's diagnostics sidecar names the library's hash).

Temporaries are named ``.<name>.<pid>.<random>.tmp``; one left behind by a process that no
longer runs (killed in the middle of a write) is removed by the next write of the same file.
"""

from __future__ import annotations

import os
import re
import tempfile
from pathlib import Path

from ..errors import MocapError


def atomic_write_bytes(path: str | os.PathLike, data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically (parent folders are created). Returns the path."""
    return atomic_write_files([(path, data)])[0]


def atomic_write_files(files: list[tuple[str | os.PathLike, bytes]]) -> list[Path]:
    """Write each ``(path, data)`` atomically, all temporaries first, then rename them in the
    order given (parent folders are created). Returns the paths.

    Raises :class:`MocapError` naming the file when a temporary cannot be written: then no
    file was replaced and no temporary is left.
    """
    written: list[tuple[Path, str]] = []
    try:
        for path, data in files:
            written.append((Path(path), _temporary(Path(path), data)))
        for path, tmp in written:
            try:
                os.replace(tmp, path)
            except OSError as exc:
                raise MocapError(f"cannot write file: {exc.strerror}", path=path,
                                 hint="check free disk space and permissions") from exc
            _fsync_folder(path.parent)
    finally:
        for _, tmp in written:
            Path(tmp).unlink(missing_ok=True)
    return [path for path, _ in written]


def _temporary(path: Path, data: bytes) -> str:
    """A temporary file beside ``path`` holding ``data``, flushed to disk; its name."""
    blocking = next((p for p in path.parents if p.exists() and not p.is_dir()), None)
    if blocking is not None:
        raise MocapError(f"cannot write here: {blocking} is a file, not a folder", path=path,
                         hint="choose another output path")
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        _remove_stale_temporaries(path)
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.{os.getpid()}.", suffix=".tmp",
                                   dir=path.parent)
    except OSError as exc:
        raise MocapError(f"cannot write here: {exc.strerror}", path=path,
                         hint="choose a folder you can write to") from exc
    try:
        os.chmod(tmp, 0o666 & ~UMASK)  # mkstemp makes 0600; give the usual permissions
        with os.fdopen(fd, "wb") as handle:
            handle.write(data)
            handle.flush()
            os.fsync(handle.fileno())
    except OSError as exc:
        Path(tmp).unlink(missing_ok=True)
        raise MocapError(f"cannot write file: {exc.strerror}", path=path,
                         hint="check free disk space and permissions") from exc
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return tmp


def _remove_stale_temporaries(path: Path) -> None:
    """Remove the temporaries of ``path`` whose writing process no longer runs (POSIX only:
    elsewhere a process cannot be asked whether it runs without side effects)."""
    if os.name != "posix":
        return
    pattern = re.compile(rf"\.{re.escape(path.name)}\.(\d+)\.[^.]+\.tmp")
    for entry in os.scandir(path.parent):
        found = pattern.fullmatch(entry.name)
        if found and not _running(int(found.group(1))):
            Path(entry.path).unlink(missing_ok=True)


def _running(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except (PermissionError, OverflowError):
        return True  # another user's process (or no pid at all: leave the file alone)
    return True


def _read_umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


#: The process's umask, read once at import: reading it means setting it, which would give
#: files another thread creates meanwhile the wrong permissions.
UMASK = _read_umask()


def _fsync_folder(folder: Path) -> None:
    """Flush ``folder``'s entries (the rename) to disk; skipped where folders cannot be opened
    or synced (Windows, some network file systems)."""
    try:
        fd = os.open(folder, os.O_RDONLY | getattr(os, "O_DIRECTORY", 0))
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


def atomic_write_text(path: str | os.PathLike, text: str) -> Path:
    """Write UTF-8 ``text`` to ``path`` atomically. Returns the path."""
    return atomic_write_bytes(path, text.encode("utf-8"))
