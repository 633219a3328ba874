"""The build's diagnostics sidecar as the report reads it: each capture's series and cycles,
checked field by field (a bad record is reported, not fatal), and whether the sidecar belongs to
the library it sits beside."""

from __future__ import annotations

import json
import math
import os
from pathlib import Path

from ..io import read_regular
from ..io.jsonvalues import parse_json
from ..library.document import DIAGNOSTICS_FORMAT
from ..library.format import diagnostics_path


# --------------------------------------------------------------------------- sidecar
def read_diagnostics(library_path: Path, library) -> tuple[dict | None, list[str]]:
    """The diagnostics sidecar of ``library`` (None when missing, unreadable or another
    build's) and the report warnings about it.

    A sidecar belongs to the library whose bytes have the SHA-256 it names
    (``library_sha256``, compared with :attr:`mocaplib.library.format.Library.file_sha256`): one that
    names another was left by another build (a build killed between writing the library and
    its sidecar, or a library moved beside another one's sidecar) and is not used, since its
    counts and plots would contradict the library. A sidecar without the hash (written before
    it was stored) must name exactly the library's entry ids instead.

    Capture records are checked once here, so the rest of the report can rely on their shape:
    a record that is not an object, or whose ``cycles`` or ``warnings`` are malformed, is left
    out with a warning naming it (:func:`_record_problem`)."""

    path = diagnostics_path(library_path)
    if not os.path.lexists(path):
        return None, [f"no diagnostics sidecar {path.name}: per-capture plots are not shown "
                      f"(`mocaplib build` writes it beside the library)"]
    try:
        data = parse_json(read_regular(path, limit=MAX_SIDECAR_BYTES).decode("utf-8"))
        if not isinstance(data, dict) or data.get("format") != DIAGNOSTICS_FORMAT \
                or not isinstance(data.get("captures"), list):
            raise ValueError(f"not a {DIAGNOSTICS_FORMAT} file")
    except OSError as exc:
        return None, [f"diagnostics sidecar {path.name} unreadable ({exc.strerror}); "
                      "per-capture plots skipped"]
    except ValueError as exc:
        return None, [f"diagnostics sidecar {path.name} unreadable ({exc}); "
                      "per-capture plots skipped"]
    warnings, records = [], []
    for k, record in enumerate(data["captures"]):
        problem = _record_problem(record)
        if problem is None:
            records.append(record)
            continue
        name = f" ({record['source']})" if isinstance(record, dict) and isinstance(
            record.get("source"), str) else ""
        warnings.append(f"diagnostics sidecar {path.name}: capture record {k}{name} left out "
                        f"of the report: {problem}")
    other = _other_build(data, records, library)
    if other:
        return None, [f"diagnostics sidecar {path.name} does not belong to this library "
                      f"({other}): it was written by another build, so its captures, counts "
                      "and plots are not shown (keep each library with the sidecar its build "
                      "wrote, or rebuild)"]
    return {**data, "captures": records}, warnings


#: Largest diagnostics sidecar read (bytes): 68 captures take about 1 MB.
MAX_SIDECAR_BYTES = 1 << 30


def _other_build(sidecar: dict, records: list[dict], library) -> str | None:
    """Why the sidecar (its well-formed capture ``records``) is not ``library``'s, or None:
    it names another library's SHA-256; or, when there is no hash to compare (a sidecar
    written before it was stored, a library built in memory), its entry ids are not the
    library's (:func:`_sidecar_mismatch`)."""
    named = sidecar.get("library_sha256")
    if named is not None and library.file_sha256 is not None:
        return None if named == library.file_sha256 else (
            f"it names the library whose SHA-256 is {str(named)[:12]}…, this file's is "
            f"{library.file_sha256[:12]}…")
    return _sidecar_mismatch(records, {e.id for e in library.entries} - _series_images(library),
                             complete=len(records) == len(sidecar["captures"]))


def _series_images(library) -> set[str]:
    """Ids of the mirror images made from a stored series (``mocaplib mirror``), which no
    capture record of the sidecar names (those of ``build --mirror`` it does)."""
    return {e.id for e in library.entries if e.mirror_method == "series"}


def _record_problem(record) -> str | None:
    """What makes a capture record of the sidecar unusable (None when its shape is right).

    Checked: the record is an object; ``source``, ``error``, ``stage``, ``static``,
    ``no_entry`` texts (or null); ``ok`` true or false; ``cycles`` (and ``mirror_cycles``, ``build --mirror``'s) a
    list of objects whose ``start_s``/``end_s`` are finite numbers (or null), ``index`` a whole number, ``entry_id`` a string (or null) and
    ``pattern`` an object (or null); ``warnings`` a list. Series drawn in the capture's figure
    (``time_s``, ``angles`` ...) are not: a bad one costs that figure only."""
    if not isinstance(record, dict):
        return f"a {type(record).__name__}, not an object"
    for key in ("source", "error", "stage", "static", "no_entry"):
        if record.get(key) is not None and not isinstance(record[key], str):
            return f"{key} = {json.dumps(record[key])[:40]} is not a text"
    if not isinstance(record.get("ok", True), bool):
        return f"ok = {json.dumps(record['ok'])[:40]} is not true or false"
    if not isinstance(record.get("warnings") or [], list):
        return "its warnings are not a list"
    for field, what in (("cycles", "cycle"), ("mirror_cycles", "mirror image cycle")):
        cycles = record.get(field) or []
        if not isinstance(cycles, list):
            return f"its {field} are not a list"
        for n, cycle in enumerate(cycles):
            if not isinstance(cycle, dict):
                return f"{what} {n} is a {type(cycle).__name__}, not an object"
            for key, ok in _CYCLE_FIELDS.items():
                if cycle.get(key) is not None and not ok(cycle[key]):
                    return (f"{what} {n}: {key} = {json.dumps(cycle[key])[:40]} has the "
                            "wrong type")
    return None


#: Fields of a sidecar cycle the report reads outside its figures, and their type check.
_CYCLE_FIELDS = {
    "start_s": lambda x: _finite_number(x),
    "end_s": lambda x: _finite_number(x),
    "index": lambda x: isinstance(x, int) and not isinstance(x, bool),
    "entry_id": lambda x: isinstance(x, str),
    "pattern": lambda x: isinstance(x, dict),
}


def _finite_number(value) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool) \
        and math.isfinite(value)


def _sidecar_mismatch(records: list[dict], library_ids: set[str], *,
                      complete: bool) -> str | None:
    """Why the sidecar's ``records`` are not the library's build, or None: the entry ids they
    name must all be in the library and, when no record was left out (``complete``), name
    every library entry."""
    named = {c["entry_id"] for r in records
             for c in (r.get("cycles") or []) + (r.get("mirror_cycles") or [])
             if c.get("entry_id") is not None}
    unknown, unnamed = sorted(named - library_ids), sorted(library_ids - named)
    reasons = []
    if unknown:
        reasons.append(f"it names {len(unknown)} entr{'y' if len(unknown) == 1 else 'ies'} "
                       f"the library lacks, e.g. {unknown[0]}")
    if unnamed and complete:
        reasons.append(f"{len(unnamed)} of the library's {len(library_ids)} entries are not "
                       f"in it, e.g. {unnamed[0]}")
    return "; ".join(reasons) or None
