"""Reading and writing files: C3D import, exports, atomic writes."""

from __future__ import annotations

import os
import stat


def unique_paths(paths) -> list[str]:
    """The paths (str or PathLike), each file once in the order given: the same file named
    relative and absolute counts once; empty paths are left out."""
    unique: dict[str, str] = {}
    for path in map(os.fspath, paths):
        if path:
            unique.setdefault(os.path.abspath(path), path)
    return list(unique.values())


def special_file(path: str | os.PathLike) -> bool:
    """True for a path that exists but is neither a regular file nor a folder: a pipe, socket
    or device, which reading could block on forever."""
    try:
        mode = os.stat(path).st_mode
    except OSError:
        return False
    return not (stat.S_ISREG(mode) or stat.S_ISDIR(mode))
