"""Builds without a protocol written by hand: a protocol drafted for the captures whose labels
no shipped or user protocol matches.

A capture built with ``protocol = "auto"`` is matched against every protocol
(:func:`mocaplib.markersets.matching.detect_protocol`). When the best match misses a required
landmark, or leaves more of the capture's labels unknown than it finds
(:func:`~mocaplib.markersets.matching.needs_draft`),
a protocol is drafted from the first such capture of each label set (and the first static of
its settings that holds the same markers) by :func:`mocaplib.markersets.draft.draft_protocol`, written atomically as
``<folder>/drafted_<label-set hash>.toml`` and used for every capture of that label set. The
drafted file says ``drafted = true``
(:attr:`mocaplib.markersets.protocols.Protocol.origin` is then ``"drafted"``).

The folder is added to the protocol folders first, so a draft written by an earlier build —
kept as it is or edited by the technician — is matched like any user protocol and not drafted
again.
"""

from __future__ import annotations

import hashlib
import os
from dataclasses import replace
from pathlib import Path

from ..errors import MocapError
from ..io import fs_text
from ..io.atomic import atomic_write_text
from ..io.c3d import read_c3d
from ..markersets.draft import draft_protocol, marker_labels
from ..markersets.matching import detect_protocol, match_protocol, needs_draft
from ..markersets.protocols import load_protocol, toml_files, use_protocol_folders
from ..trial import normalise_label
from .settings import BuildSettings

#: The folder beside the library that drafted protocols are written into.
DRAFTS_FOLDER = "drafted_protocols"


def draft_missing_protocols(paths: list[Path], planned: list[BuildSettings],
                            folder: str | os.PathLike) -> tuple[list[BuildSettings], list[str],
                                                                 dict[str, str]]:
    """Draft a protocol for every label set of ``paths`` (captures) whose ``planned``
    settings say ``protocol = "auto"`` and that no protocol serves
    (:func:`~mocaplib.markersets.matching.needs_draft`), as
    the module describes.

    Returns the settings with each such capture's protocol set to its drafted file, one note
    per drafted protocol for the build's summary, and ``{protocol name: file}``. A capture
    that cannot be read is left as it is (its processing fails and says why).
    """
    folder = Path(folder)
    if folder.is_dir() and toml_files(folder):
        use_protocol_folders([folder])
    planned = list(planned)
    drafted: dict[frozenset, Path | None] = {}
    notes: list[str] = []
    names: dict[str, str] = {}
    for i, (path, settings) in enumerate(zip(paths, planned)):
        if settings.protocol != "auto":
            continue
        try:
            trial = read_c3d(path)
            labels = frozenset(trial.names)
            if labels not in drafted:
                drafted[labels] = _draft_if_needed(trial, settings, folder, labels, notes)
        except MocapError:
            continue
        if drafted[labels] is not None:
            planned[i] = replace(settings, protocol=os.fspath(drafted[labels]))
            names[drafted[labels].stem] = os.fspath(drafted[labels])
    return planned, notes, names


#: A static serves a draft when it holds at least this share of the capture's marker labels.
STATIC_SHARE = 0.8


def _session_static(trial, settings: BuildSettings):
    """The first static of ``settings`` that holds :data:`STATIC_SHARE` of ``trial``'s marker
    labels (a static of another marker set would add its labels to the draft), or None."""
    labels = {normalise_label(x) for x in marker_labels(trial)}
    for path in settings.statics:
        try:
            static = read_c3d(path)
        except MocapError:
            continue
        shared = labels & {normalise_label(x) for x in marker_labels(static)}
        if len(shared) >= STATIC_SHARE * len(labels):
            return static
    return None


def _draft_if_needed(trial, settings: BuildSettings, folder: Path, labels: frozenset,
                     notes: list[str]) -> Path | None:
    """The drafted protocol file for ``trial``'s label set, written into ``folder``, or None
    when a protocol serves it. A note for the summary says what was drafted."""
    try:
        match = detect_protocol(trial)
    except MocapError:
        match = None
    if not needs_draft(match):
        return None
    static = _session_static(trial, settings)
    digest = hashlib.sha256("\n".join(sorted(labels)).encode()).hexdigest()[:8]
    name = f"drafted_{digest}"
    draft = draft_protocol(trial, static=static, name=name)
    path = folder / f"{name}.toml"
    atomic_write_text(path, draft.to_toml())
    drafted = match_protocol(trial, load_protocol(path), check_swaps=False)
    source = fs_text(Path(trial.source or "capture").name)
    why = ("no protocol matches its labels" if match is None else
           f"the closest protocol, {match.protocol.name}, "
           + (f"misses {', '.join(match.missing_landmarks)}" if not match.complete else
              f"knows {match.found} of its labels and not {len(match.unknown)}"))
    lacks = "" if drafted.complete else (
        f"; it lacks required landmarks ({', '.join(drafted.missing_landmarks)}): edit it")
    notes.append(f"{source}: {why}: drafted protocol {name} from it and used it for its marker "
                 f"set ({len(draft.warnings())} guesses of low confidence){lacks}; check it, "
                 f"then keep it with --protocols {fs_text(os.fspath(folder))}: {fs_text(os.fspath(path))}")
    return path
