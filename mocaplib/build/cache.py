"""The build's per-capture cache: one JSON file per capture result, keyed by the SHA-256 of the
file, the settings, the tool version and the code, verified by the hash of its content when
read (anything that does not verify is recomputed; see ``docs/reliability.md``)."""


from __future__ import annotations

import functools
import hashlib
import json
import os
from dataclasses import fields
from pathlib import Path

from .. import __version__
from ..errors import LibraryError
from ..io import read_regular
from ..io.atomic import atomic_write_text
from ..io.jsonvalues import canonical_sha256, parse_json
from ..library.format import json_text, to_json_data
from ..markersets.protocols import user_fingerprint
from .settings import BuildSettings
from .workflow import CHANGED_WHILE_READ, CaptureResult, static_sha256


@functools.lru_cache(maxsize=1)
def code_fingerprint() -> str:
    """SHA-256 of mocaplib's own code and data (``*.py``, protocols, schema), read once.

    Part of every cache key: a result cached by different code (a development checkout, a
    patched install) is never reused, even when the version number did not change.
    """
    root = Path(__file__).resolve().parents[1]
    files = [Path(folder, name) for folder, _, names in os.walk(root, followlinks=True)
             for name in names if name.endswith((".py", ".toml", ".json"))]
    digest = hashlib.sha256()
    for path in sorted(files):
        digest.update(path.relative_to(root).as_posix().encode() + b"\0" + path.read_bytes())
    return digest.hexdigest()


def cache_key(path: Path, sha256: str, settings: BuildSettings) -> str:
    """Hex key of a capture's cached result: file name and content, settings, tool version.

    The static trial's content, :func:`code_fingerprint` and the users' protocol folders
    (:func:`mocaplib.markersets.protocols.user_fingerprint`) are part of the key, so editing any of them
    invalidates the cache.
    """

    parts = {"file": path.name, "sha256": sha256, "settings": settings.to_dict(),
             "tool": __version__, "code": code_fingerprint(), "protocols": user_fingerprint()}
    if settings.statics:
        shas = [static_sha256(static) for static in settings.statics]
        parts["static_sha256"] = shas if len(shas) > 1 else shas[0]
    return hashlib.sha256(json.dumps(parts, sort_keys=True).encode()).hexdigest()


def internal_result(result: CaptureResult) -> bool:
    """An unexpected exception or a dead worker is not cached (it may be a fixed bug), also
    when it stopped a static (which then gives no entry, saying why), nor a capture whose
    file changed while it was processed (:data:`CHANGED_WHILE_READ`)."""
    said = f"{result.error or ''} {result.no_entry or ''}"
    return result.stage == "worker" or any(why in said for why in ("internal error",
                                                                   CHANGED_WHILE_READ))


#: ``format`` and ``version`` of a cache entry.
CACHE_FORMAT, CACHE_VERSION = "mocaplib-cache", 1
#: Largest cache entry read (bytes): a capture's result takes tens of kB.
MAX_CACHE_BYTES = 64 << 20


#: Types of the fields a cached :class:`CaptureResult` must have to be trusted.
_CACHED_TYPES = {"source": str, "sha256": str, "ok": bool, "entries": list, "diagnostics": dict,
                 "warnings": list, "stage_times": dict, "n_frames": int, "n_cycles": int}


def write_cache(cache: Path, key: str, result: CaptureResult) -> None:
    """Store ``result`` under ``key`` (:func:`cache_key`: the hash of the capture's inputs
    and of the code), with the hash of its content (see :func:`read_cache`)."""
    data = to_json_data(result.to_dict())
    atomic_write_text(cache / f"{key}.json", json_text({
        "format": CACHE_FORMAT, "version": CACHE_VERSION, "key": key,
        "content_sha256": canonical_sha256(data), "result": data}))


def read_cache(cache: Path, key: str, sha256: str) -> tuple[CaptureResult | None, str | None]:
    """The cached result under ``key`` (:func:`cache_key` of a capture whose bytes have the
    SHA-256 ``sha256``) and None; ``(None, None)`` when there is none; and ``(None, why)``
    when the entry does not verify: not a regular file (a pipe, device or link is refused
    before it is opened), too large, unreadable, not an entry as :func:`write_cache` writes
    it, stored under another key, with content that does not match its hash (a truncated or
    hand-edited file), or the result of other bytes than ``sha256``'s."""
    path = cache / f"{key}.json"
    try:
        entry = parse_json(read_regular(path, limit=MAX_CACHE_BYTES, follow_links=False)
                           .decode("utf-8"))
    except FileNotFoundError:
        return None, None
    except OSError as exc:
        return None, f"{path.name}: {exc.strerror}"
    except ValueError:  # also UnicodeDecodeError
        return None, f"{path.name}: not JSON text"
    if not (isinstance(entry, dict) and entry.get("format") == CACHE_FORMAT
            and entry.get("version") == CACHE_VERSION):
        return None, f"{path.name}: not a mocaplib cache entry of version {CACHE_VERSION}"
    if entry.get("key") != key:
        return None, f"{path.name}: stored for other inputs or code"
    data = entry.get("result")
    if entry.get("content_sha256") != canonical_sha256(data):
        return None, f"{path.name}: its content does not match its hash (changed after it " \
                     "was written)"
    if not (isinstance(data, dict) and set(data) == {f.name for f in fields(CaptureResult)}
            and all(isinstance(data[name], kind) for name, kind in _CACHED_TYPES.items())
            and all(isinstance(e, dict) for e in data["entries"])):
        return None, f"{path.name}: not a capture's result"
    try:
        result = CaptureResult.from_dict(data)
    except LibraryError as exc:
        return None, f"{path.name}: not a capture's result ({exc.message})"
    if result.sha256 != sha256:
        return None, f"{path.name}: the result of other content than the file's"
    result.from_cache = True
    return result, None
