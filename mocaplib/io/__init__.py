"""Reading and writing files: C3D import, exports, atomic writes."""

from __future__ import annotations

import os
import stat


def special_file(path: str | os.PathLike) -> bool:
    """True for a path that exists but is neither a regular file nor a folder: a pipe, socket
    or device, which reading could block on forever."""
    try:
        mode = os.stat(path).st_mode
    except OSError:
        return False
    return not (stat.S_ISREG(mode) or stat.S_ISDIR(mode))
