"""Reading and writing files: C3D import and writing, atomic writes, JSON and TOML.

Helpers every reader shares: :func:`find_captures` lists the captures a command is given;
:func:`open_regular` / :func:`read_regular` refuse what is not a regular file (a pipe, socket
or device could block forever or never end) before reading from it; :func:`fs_text` turns a file name the system could not decode into text any file can hold;
:func:`printable` escapes control characters before text reaches a terminal.
"""

from __future__ import annotations

import errno
import os
import re
import stat
from collections.abc import Iterable
from pathlib import Path

from ..errors import MocapError


def unique_paths(paths) -> list[str]:
    """The paths (str or PathLike), each file once in the order given: the same file named
    relative and absolute counts once; empty paths are left out."""
    unique: dict[str, str] = {}
    for path in map(os.fspath, paths):
        if path:
            unique.setdefault(os.path.abspath(path), path)
    return list(unique.values())


def _not_regular(mode: int, path) -> OSError:
    if stat.S_ISDIR(mode):
        return IsADirectoryError(errno.EISDIR, "is a folder, not a file", os.fspath(path))
    if stat.S_ISLNK(mode):
        return OSError(errno.ELOOP, "is a symbolic link, not a regular file", os.fspath(path))
    return OSError(errno.EINVAL, "not a regular file (a pipe, socket or device)",
                   os.fspath(path))


def open_regular(path: str | os.PathLike, /, *, follow_links: bool = True):
    """``path`` opened for binary reading, when it is a regular file.

    Anything else raises OSError before a byte is read: a folder (IsADirectoryError), a pipe,
    socket or device (EINVAL, "not a regular file"), and with ``follow_links=False`` a
    symbolic link (ELOOP). The type is checked with ``stat`` before opening, and again on the
    open descriptor, which is opened without blocking, so a pipe put in the file's place
    meanwhile cannot hang the reader.
    """
    mode = os.stat(path, follow_symlinks=follow_links).st_mode
    if not stat.S_ISREG(mode):
        raise _not_regular(mode, path)
    flags = os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_BINARY", 0)
    if not follow_links:
        flags |= getattr(os, "O_NOFOLLOW", 0)
    fd = os.open(path, flags)
    try:
        mode = os.fstat(fd).st_mode
        if not stat.S_ISREG(mode):
            raise _not_regular(mode, path)
        if hasattr(os, "set_blocking"):
            os.set_blocking(fd, True)
        return os.fdopen(fd, "rb")
    except BaseException:
        os.close(fd)
        raise


def read_regular(path: str | os.PathLike, /, *, limit: int | None = None,
                 follow_links: bool = True) -> bytes:
    """The bytes of the regular file ``path`` (:func:`open_regular`); OSError (EFBIG) when it
    holds more than ``limit`` bytes (None: no limit)."""
    with open_regular(path, follow_links=follow_links) as handle:
        data = handle.read() if limit is None else handle.read(limit + 1)
    if limit is not None and len(data) > limit:
        raise OSError(errno.EFBIG, f"larger than {limit} bytes", os.fspath(path))
    return data


_ESCAPED_BYTES = re.compile("[\udc80-\udcff]")
_LONE_SURROGATES = re.compile("[\ud800-\udfff]")


def fs_text(text: str, /) -> str:
    """``text`` that UTF-8 can encode: file-name bytes the system could not decode (Python
    keeps them as lone surrogates, U+DC80-U+DCFF) read as Latin-1, e.g. the Latin-1 name
    ``gehen_\\xe4.c3d`` becomes ``gehen_ä.c3d``; any other lone surrogate becomes U+FFFD."""
    if text.isascii():
        return text
    text = _ESCAPED_BYTES.sub(lambda found: chr(ord(found.group()) - 0xDC00), text)
    return _LONE_SURROGATES.sub("\ufffd", text)


_CONTROL = re.compile("[\x00-\x1f\x7f-\x9f]")


def printable(text: str, /, *, keep: str = "\n\t") -> str:
    """``text`` with control characters (C0 but those in ``keep``, DEL, C1) written as
    ``\\xNN``: text from files (C3D labels, file names) cannot then move the cursor, change
    colours or retitle the terminal it is printed on; with ``keep=""`` a line feed is escaped
    too, so one record (a label, a file name, a message) prints as one line."""
    return _CONTROL.sub(lambda found: found.group() if found.group() in keep
                        else f"\\x{ord(found.group()):02x}", text)


def find_captures(inputs: Iterable[str | os.PathLike], /, *,
                  unlisted: list[MocapError] | None = None) -> list[Path]:
    """C3D files named directly, plus the ``*.c3d`` entries found recursively (sorted) in
    folders.

    In a folder, every entry named ``*.c3d`` that is not a folder is a capture: a pipe, a
    device, a dangling link or a link loop too, which then fails alone, saying why, when it is
    read. Links to folders are not followed (a link loop cannot trap the search). The same file
    named twice is processed once. A folder that cannot be listed (no read permission, an I/O
    error) is skipped and the search goes on; ``unlisted``: a list each such folder is appended
    to, as an error naming it and why (:func:`unlisted_folder`). Raises :class:`MocapError`
    for a path that does not exist.
    """
    found: dict[str, Path] = {}
    for item in inputs:
        path = Path(item)
        if path.is_dir():  # a folder or pipe named like a capture is not one
            candidates = _c3d_entries(path, [] if unlisted is None else unlisted)
        elif os.path.lexists(path):  # reading a pipe or a broken link fails and says why
            candidates = [path]
        else:
            raise MocapError("no such file or folder", path=path,
                             hint="check the path; folders are searched for *.c3d")
        for candidate in candidates:
            found.setdefault(os.path.realpath(candidate), candidate)
    return list(found.values())


def unlisted_folder(error: OSError, /) -> MocapError:
    """What a user is told of a folder the capture search could not list (``error``, from
    listing it): its path, why, and what to do."""
    return MocapError(
        f"cannot list this folder ({error.strerror or error}): the captures in it are left out",
        path=fs_text(os.fspath(error.filename)),
        hint="give the folder read and execute permission (chmod u+rx), or leave it out of "
             "the inputs")


def _c3d_entries(folder: Path, unlisted: list[MocapError]) -> list[Path]:
    """Entries named ``*.c3d`` (any case) in ``folder`` and its subfolders that are not
    folders, sorted; links to folders are neither taken nor followed. Each folder that cannot
    be listed is appended to ``unlisted`` (:func:`unlisted_folder`)."""
    entries = []
    for root, _, names in os.walk(folder, onerror=lambda e: unlisted.append(unlisted_folder(e))):
        entries += [Path(root, name) for name in names if Path(name).suffix.lower() == ".c3d"]
    return sorted(entries)
