"""TOML files (protocols, capture plans, envelopes) read with errors that name the file."""

from __future__ import annotations

import os
import tomllib

from ..errors import MocapError
from . import read_regular


#: The largest TOML file read (bytes): protocols, plans and sessions take a few kB (the
#: largest shipped, paper_plan.toml, 13 kB).
MAX_TOML_BYTES = 4 << 20


def read_toml(path: str | os.PathLike, /, *, error: type[MocapError] = MocapError,
              what: str = "TOML file", hint: str | None = None) -> dict:
    """The parsed document of ``path``.

    Raises ``error`` naming the file, with ``hint``, when it is missing, cannot be read (a
    folder, a pipe or device, a link loop, no permission: :func:`mocaplib.io.read_regular`),
    holds more than :data:`MAX_TOML_BYTES`, is not UTF-8 text, is not valid TOML or nests
    tables or arrays deeper than the parser can follow; ``what`` names the kind of file in
    the message (``"protocol"``, ``"capture plan"``).
    """
    try:
        return tomllib.loads(read_regular(path, limit=MAX_TOML_BYTES).decode("utf-8"))
    except FileNotFoundError:
        raise error(f"{what} not found", path=path, hint=hint) from None
    except OSError as exc:
        raise error(f"cannot read the {what}: {exc.strerror or exc}", path=path,
                    hint=hint) from None
    except UnicodeDecodeError:
        raise error(f"the {what} is not UTF-8 text", path=path, hint=hint) from None
    except tomllib.TOMLDecodeError as exc:
        raise error(f"not valid TOML: {exc}", path=path, hint=hint) from None
    except RecursionError:
        raise error(f"the {what} nests arrays or tables too deep to read", path=path,
                    hint=hint) from None
