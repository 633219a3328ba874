"""The library file as a JSON document: its format's constants, reading it safely, the shipped
JSON Schema and the content checksum (``docs/library-format.md``, *Integrity*).

The checksum a file carries is the one its ``format_version`` names: from version 3 the SHA-256
of the RFC 8785 (JCS) form of the document without ``content_sha256``, which other languages
recompute; versions 1 and 2 the SHA-256 of its Python-printed canonical JSON.
"""

from __future__ import annotations

import hashlib
import json
import os
from importlib import resources

from ..errors import LibraryError
from ..io import read_regular
from ..io.jsonvalues import canonical_sha256, jcs_sha256, parse_json_finite

FORMAT = "mocaplib-library"
#: The version this mocaplib writes; it reads :data:`READ_VERSIONS` (docs/library-format.md,
#: *Versions*).
FORMAT_VERSION = 5
READ_VERSIONS = (1, 2, 3, 4, 5)
#: The first version whose ``control_space.tetrahedra`` are the gait cells (with each
#: tetrahedron's gait and the hull of all the entries); before it, the Delaunay tetrahedra of
#: all the entries, walks and runs together.
GAIT_CELLS_VERSION = 4
#: The first version whose ``control_space.tetrahedra`` also store each cell's frontal
#: tetrahedra (``frontal_simplices``, ``frontal_gaits``), where a served command's weights are
#: computed; before it, readers weigh commands in the cells' own tetrahedra.
FRONTAL_WEIGHTS_VERSION = 5
#: Versions whose ``content_sha256`` is :func:`mocaplib.io.jsonvalues.canonical_sha256` (numbers
#: as Python prints them); later versions carry :func:`mocaplib.io.jsonvalues.jcs_sha256`.
PYTHON_CHECKSUM_VERSIONS = (1, 2)
#: The ``format`` of a build's diagnostics sidecar (``<stem>.diagnostics.json``), not a library.
DIAGNOSTICS_FORMAT = "mocaplib-diagnostics"
CONTROL_AXES = ("v", "omega", "v_l")
CONTROL_UNITS = ("m/s", "rad/s", "m/s")
#: The top-level key of the content checksum (:func:`content_sha256`).
CHECKSUM_KEY = "content_sha256"
#: Largest library file read (bytes): 68 entries take 1.3 MB, so this is room for about
#: 100,000 entries, and a link to an endless file cannot exhaust the memory.
MAX_LIBRARY_BYTES = 2 << 30


def read_document(path: str | os.PathLike, *,
                  file_sha256: bool = True) -> tuple[object, str | None, bool]:
    """The file's JSON data (:func:`mocaplib.io.jsonvalues.parse_json`: NaN, ±Infinity and
    numbers beyond a double are read as floats, for validation to name where they
    are), the SHA-256 of its bytes (None unless ``file_sha256``: 0.1 s on 71 MB) and whether
    its numbers are finite for certain (:func:`mocaplib.io.jsonvalues.parse_json_finite`:
    validation need not look for NaN and infinities then, 0.5 s on 71 MB)."""
    hint = "a library is a JSON file written by `mocaplib build`"
    try:
        data = read_regular(path, limit=MAX_LIBRARY_BYTES)
    except OSError as exc:
        raise LibraryError(f"cannot read library: {exc.strerror}", path=path,
                           hint="check the path") from exc
    try:
        document, finite = parse_json_finite(data)
    except UnicodeDecodeError as exc:
        raise LibraryError("library is not UTF-8 text", path=path, hint=hint) from exc
    except json.JSONDecodeError as exc:
        raise LibraryError(f"library is not valid JSON: {exc.msg} at line {exc.lineno}",
                           path=path, hint=hint) from exc
    except ValueError as exc:
        raise LibraryError(f"library is not a mocaplib library: {exc}", path=path,
                           hint=hint) from None
    if isinstance(document, dict) and document.get("format") == DIAGNOSTICS_FORMAT:
        library = document.get("library")
        raise LibraryError("this is a build's diagnostics sidecar, not a library", path=path,
                           hint=f"give the library beside it"
                                f"{f', {library}' if isinstance(library, str) else ''}")
    return document, hashlib.sha256(data).hexdigest() if file_sha256 else None, finite


def library_document(library):
    """The JSON data of a library given as a path (read: :func:`read_document`), as JSON data
    (a dict) or as a :class:`mocaplib.library.format.Library` (its ``document``)."""
    if isinstance(library, dict):
        return library
    if isinstance(library, (str, os.PathLike)):
        return read_document(library, file_sha256=False)[0]
    return library.document


def schema() -> dict:
    """The JSON Schema (draft 2020-12) of library files, as shipped in the package."""

    text = resources.files("mocaplib").joinpath("schema/library.schema.json").read_text("utf-8")
    return json.loads(text)


def content_sha256(document: dict, *, finite: bool = False) -> str:
    """The library's content checksum, the one its ``format_version`` carries: SHA-256 of the
    RFC 8785 (JCS) form of the document without ``content_sha256``
    (:func:`mocaplib.io.jsonvalues.jcs_sha256`), or for versions
    :data:`PYTHON_CHECKSUM_VERSIONS` of its Python-printed canonical JSON
    (:func:`mocaplib.io.jsonvalues.canonical_sha256`). Reformatting a file keeps it; changing
    a value, a key or an entry changes it. Raises ValueError for content JCS cannot hold
    (NaN, ±inf); ``finite``: the caller has checked there are none."""
    content = {k: v for k, v in document.items() if k != CHECKSUM_KEY}
    if document.get("format_version") in PYTHON_CHECKSUM_VERSIONS:
        return canonical_sha256(content)
    return jcs_sha256(content, finite=finite)


def checksum_status(library) -> str | None:
    """Whether a library (path, JSON dict or
    :class:`~mocaplib.library.format.Library`) is the content it was written
    with: ``"verified"`` (its stored :func:`content_sha256` matches), ``"mismatch"`` (it was
    changed after it was written), ``"absent"`` (no checksum: written by a mocaplib that did
    not store one, or built in memory by another tool); None when it is no library document
    (not an object of format ``mocaplib-library``). Raises :class:`LibraryError` for a file
    that cannot be read as JSON."""
    document = library_document(library)
    if not isinstance(document, dict) or document.get("format") != FORMAT:
        return None
    stored = document.get(CHECKSUM_KEY)
    if stored is None:
        return "absent"
    try:
        computed = content_sha256(document)
    except ValueError:              # NaN or infinity: never in a file mocaplib wrote
        return "mismatch"
    return "verified" if stored == computed else "mismatch"


def version_note(document: dict) -> str | None:
    """What a person reading a library of an earlier version needs to know about its control
    space (``mocaplib validate``, the report), or None for a file of the current version."""
    version = document.get("format_version")
    if not isinstance(version, int) or version >= FRONTAL_WEIGHTS_VERSION:
        return None
    if version >= GAIT_CELLS_VERSION:
        return (f"format_version {version}: the control space's stored tetrahedra are the gait "
                f"cells without their frontal tetrahedra; mocaplib weighs commands in the "
                f"frontal tetrahedra it computes from the entries, but a reader in another "
                f"language needs format_version {FRONTAL_WEIGHTS_VERSION}: build the library "
                f"again with mocaplib build")
    return (f"format_version {version}: the control space's stored tetrahedra (if any) are "
            f"those of all the entries, walks and runs together; mocaplib blends in the gait "
            f"cells it computes from the entries, but a reader in another language needs "
            f"format_version {FRONTAL_WEIGHTS_VERSION}: build the library again with mocaplib "
            f"build")


#: What a library without a checksum is told (``mocaplib validate``, the report).
NO_CHECKSUM_NOTE = ("no content checksum (written by a mocaplib that did not store one): its "
                    "integrity cannot be checked; build it again to add one")
