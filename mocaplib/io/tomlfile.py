"""TOML files (protocols, capture plans, envelopes) read with errors that name the file."""

from __future__ import annotations

import os
import tomllib

from ..errors import MocapError
from . import open_regular


def read_toml(path: str | os.PathLike, /, *, error: type[MocapError] = MocapError,
              what: str = "TOML file", hint: str | None = None) -> dict:
    """The parsed document of ``path``.

    Raises ``error`` naming the file, with ``hint``, when it is missing, cannot be read (a
    folder, a pipe or device, no permission: :func:`mocaplib.io.open_regular`), is not UTF-8
    text or is not valid TOML; ``what`` names the kind of
    file in the message (``"protocol"``, ``"capture plan"``).
    """
    try:
        with open_regular(path) as handle:
            return tomllib.load(handle)
    except FileNotFoundError:
        raise error(f"{what} not found", path=path, hint=hint) from None
    except OSError as exc:
        raise error(f"cannot read the {what}: {exc.strerror or exc}", path=path,
                    hint=hint) from None
    except UnicodeDecodeError:
        raise error(f"the {what} is not UTF-8 text", path=path, hint=hint) from None
    except tomllib.TOMLDecodeError as exc:
        raise error(f"not valid TOML: {exc}", path=path, hint=hint) from None
