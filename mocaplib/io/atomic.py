"""Atomic file output: write to a temporary file in the target folder, then rename.

A reader never sees a half-written file, and an interrupted write leaves the old file intact.
The file's data and, where the system allows it, the folder's new entry are flushed to disk
before returning. :func:`atomic_write_files` writes several files as far as POSIX allows as
one: every temporary is written and flushed before the first rename, so a full disk or an
error leaves every old file as it was; only a kill between the renames (which need no space)
can leave some files new and the rest old, and the last file renamed is the one that tells a
reader the set is complete (the library's diagnostics sidecar names the library's hash).

Where a file is written (:func:`destination`): a symbolic link is followed and the file it
points to is replaced, never the link; a path in a system folder (:data:`SYSTEM_FOLDERS`:
``/dev``, ``/proc``, ``/sys`` ...), or that is or points to something other than a regular file
(a device, a pipe, a folder, a link loop), is refused before anything is written.

Temporaries are named ``.<name>.<pid>.<random>.tmp``; one left behind by a process that no
longer runs (killed in the middle of a write) is removed by the next write of the same file.
"""

from __future__ import annotations

import os
import re
import tempfile
from pathlib import Path

from ..errors import MocapError

#: Folders of the operating system that no output of mocaplib may be written into (nor a link
#: pointing into them followed): devices, kernel interfaces, programs and their settings.
SYSTEM_FOLDERS = ("/dev", "/proc", "/sys", "/run", "/boot", "/etc", "/bin", "/sbin", "/lib",
                  "/lib32", "/lib64", "/usr/bin", "/usr/lib", "/usr/sbin", "/usr/share")


def system_folder(path: str | os.PathLike) -> str | None:
    """The :data:`SYSTEM_FOLDERS` entry ``path`` (made absolute, not resolved) lies in, or
    None; always None outside POSIX systems."""
    if os.name != "posix":
        return None
    absolute = os.path.normpath(os.path.abspath(path))
    return next((folder for folder in SYSTEM_FOLDERS
                 if absolute == folder or absolute.startswith(folder + "/")), None)


def destination(path: str | os.PathLike) -> Path:
    """Where writing ``path`` puts the file: ``path`` itself, or for a symbolic link the file
    it points to (followed to the end), so that the link stays a link.

    Raises :class:`MocapError` naming ``path`` when it lies, or its link points, in a
    :data:`SYSTEM_FOLDERS` folder, when the links loop, or when what is there is not a
    regular file (a folder, a device, a pipe, a socket): it would be replaced by a file.
    """
    hint = "choose a file name in one of your folders"
    path = Path(path)
    target = Path(os.path.realpath(path)) if path.is_symlink() else path
    for where in dict.fromkeys((path, target)):
        if (folder := system_folder(where)) is not None:
            raise MocapError(f"will not write into the system folder {folder}"
                             + ("" if where == path else f" (the link points to {target})"),
                             path=path, hint=hint)
    if target.is_symlink():
        raise MocapError("its symbolic links form a loop", path=path, hint=hint)
    if os.path.lexists(target) and not target.is_file():
        what = "a folder" if target.is_dir() else "not a regular file (a device or a pipe)"
        raise MocapError(f"is {what}" + ("" if target == path else f" (the link points to "
                                          f"{target})") + ": it would be replaced by a file",
                         path=path, hint=hint)
    return target


def atomic_write_bytes(path: str | os.PathLike, data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically (parent folders are created). Returns the path."""
    return atomic_write_files([(path, data)])[0]


def atomic_write_files(files: list[tuple[str | os.PathLike, bytes]]) -> list[Path]:
    """Write each ``(path, data)`` atomically, all temporaries first, then rename them in the
    order given (parent folders are created; a link's file is written, :func:`destination`).
    Returns the paths as given.

    Raises :class:`MocapError` naming the file when a path is refused (:func:`destination`)
    or a temporary cannot be written: then no file was replaced and no temporary is left.
    """
    targets = [(destination(path), data) for path, data in files]
    written: list[tuple[Path, str]] = []
    try:
        for path, data in targets:
            written.append((path, _temporary(path, data)))
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
    return [Path(path) for path, _ in files]


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
