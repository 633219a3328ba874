"""What is in a capture: the per-file summary behind ``mocaplib inspect``.

:func:`inspect_c3d` reads one C3D file and returns a plain, JSON-ready dict (see
:data:`SUMMARY_KEYS`); a file that cannot be read gives ``ok = False`` and the reason in
``error`` instead of an exception. :func:`inspect_trial` does the same for a :class:`Trial`
already in memory. Times are seconds, gaps in percent of the frames and in frames/seconds.
"""

from __future__ import annotations

import os

from ..errors import MocapError, ProtocolError
from ..io import printable
from ..io.c3d import read_c3d
from ..trial import Trial, check_gait_rate, normalise_label, require_markers
from .draft import Draft, draft_protocol
from .matching import match_trial, needs_draft
from .protocols import Protocol, overrides

#: Keys of every summary, in order (failed files have None or empty values).
SUMMARY_KEYS = ("file", "ok", "error", "frames", "rate_hz", "duration_s", "first_frame",
                "units", "vertical_axis", "analog_channels", "force_plates", "labels", "protocol",
                "markers_found", "protocol_markers", "missing_landmarks", "missing_labels",
                "closest_protocol", "draft", "markers", "ignored_points", "unknown_labels",
                "duplicates", "swaps", "events", "warnings")

_EMPTY_LISTS = ("force_plates", "labels", "missing_landmarks", "missing_labels", "markers",
                "ignored_points", "unknown_labels", "duplicates", "swaps", "events", "warnings")


def inspect_c3d(path: str | os.PathLike, /, *, protocol: Protocol | str = "auto") -> dict:
    """Summary of one C3D file; ``protocol`` is ``"auto"``, a shipped name, a path or a
    :class:`Protocol`. Never raises for a bad file, whatever the exception: ``ok`` is False
    and ``error`` says why."""

    try:
        trial = read_c3d(path)
        return inspect_trial(trial, protocol=protocol)
    except (MocapError, OSError) as exc:
        return failed_summary(path, exc)
    except Exception as exc:  # a file no check foresaw must not stop the other files
        return failed_summary(path, f"{os.fspath(path)}: internal error: "
                                    f"{type(exc).__name__}: {exc} (a bug in mocaplib: please "
                                    "report it with this file)")


def failed_summary(path: str | os.PathLike, error: BaseException | str) -> dict:
    """The summary of a file that could not be read: every key, ``ok`` False, the reason."""
    out = {key: None for key in SUMMARY_KEYS}
    out.update({key: [] for key in _EMPTY_LISTS})
    out.update(file=os.fspath(path), ok=False, error=_reason(error))
    return out


def _reason(error: BaseException | str) -> str:
    if isinstance(error, OSError):
        return f"{error.filename or ''}: {error.strerror or error}".lstrip(": ")
    return str(error)


def inspect_trial(trial: Trial, /, *, protocol: Protocol | str = "auto") -> dict:
    """Summary of a trial in memory (see :data:`SUMMARY_KEYS`).

    With ``protocol="auto"``, ``protocol`` is None when no protocol finds its required
    landmarks in the trial; ``closest_protocol`` then holds the best candidate (``name``,
    ``markers_found``, ``protocol_markers``, ``missing_landmarks``), and the markers' landmark
    column is that candidate's. Where no protocol serves the trial (:func:`needs_draft`: a
    build drafts one), ``warnings`` says so and how to draft it, ``draft`` counts what a
    draft from this trial alone (:func:`~mocaplib.markersets.draft.draft_protocol`) places,
    and each marker's ``drafted`` holds its guess (``landmark``, ``segment``,
    ``confidence``). A protocol or landmark that a user folder redefines is noted in
    ``warnings`` (:func:`mocaplib.markersets.protocols.overrides`). A trial without markers (an
    analog-only file) fails: ``ok`` is False, ``error`` says it holds no marker points (and
    how many analog channels), and the summary keeps what it does hold (frames, rate,
    ``analog_channels``, events, warnings).
    """
    out = failed_summary(trial.source or "", "")
    out.update(ok=True, error=None, frames=trial.n_frames, rate_hz=trial.rate,
               duration_s=trial.duration, first_frame=trial.first_frame, units=trial.units,
               vertical_axis=trial.vertical_axis, analog_channels=trial.analog_channels,
               force_plates=[{"number": p.number, "type": p.kind,
                              "peak_n": float(p.force.max()), "rate_hz": p.rate}
                             for p in trial.force_plates],
               labels=list(trial.labels),
               events=[{"context": e.context, "label": e.label, "time_s": e.time_s}
                       for e in trial.events])
    warnings = list(trial.warnings) + [f"note: {n}" for n in overrides()]
    try:
        check_gait_rate(trial.rate, None)
    except MocapError as exc:  # shown, so the file can still be looked at
        warnings.append(f"{exc.message}; fit, events and build refuse it ({exc.hint})")
    try:
        require_markers(trial)
    except MocapError as exc:        # no protocol to match: what the file holds, and why not
        out.update(ok=False, error=str(exc), warnings=warnings)
        return out
    try:
        match = match_trial(trial, protocol)
    except ProtocolError as exc:
        match = None
        warnings.append(str(exc))
    if protocol == "auto" and needs_draft(match):
        warnings.append(
            "no protocol serves this marker set: `mocaplib build` drafts one from the labels' "
            "names and where the markers sit; `mocaplib protocol draft "
            f"{os.fspath(trial.source or 'FILE')} -o mylab.toml` writes it for you "
            "to check")
        guesses = _draft_preview(trial, out, warnings)
    else:
        guesses = {}
    landmark_of: dict[int, str] = {}
    ignored: set[str] = set()
    if match is not None:
        landmark_of = {i: m.landmark.name for m, i in zip(match.protocol.markers, match.indices)
                       if i >= 0}
        ignored = set(match.ignored)
        out.update(protocol=match.protocol.name, markers_found=match.found,
                   protocol_markers=len(match.indices),
                   missing_landmarks=match.missing_landmarks, missing_labels=list(match.missing),
                   ignored_points=list(match.ignored), unknown_labels=list(match.unknown),
                   duplicates=list(match.duplicates), swaps=list(match.swaps))
        warnings.extend(match.warnings)
        if protocol == "auto" and not match.complete:
            out.update(protocol=None, markers_found=None, protocol_markers=None,
                       missing_landmarks=[], missing_labels=[], closest_protocol={
                           "name": match.protocol.name, "markers_found": match.found,
                           "protocol_markers": len(match.indices),
                           "missing_landmarks": match.missing_landmarks,
                           "missing_labels": list(match.missing)})
    gaps, longest = trial.gap_fraction(), trial.longest_gap()
    out["markers"] = [
        {"label": label, "landmark": landmark_of.get(i), "drafted": guesses.get(trial.names[i]),
         "gap_pct": 100.0 * float(gaps[i]), "longest_gap_frames": int(longest[i]),
         "longest_gap_s": int(longest[i]) / trial.rate}
        for i, label in enumerate(trial.labels) if label not in ignored]
    out["warnings"] = warnings
    return out


def _draft_preview(trial: Trial, out: dict, warnings: list[str]) -> dict[str, dict]:
    """Draft a protocol from ``trial`` alone, as a build does from a session's first capture
    of the marker set: put the counts in ``out["draft"]``, a warning per guess of low
    confidence in ``warnings``, and return ``{normalised label: {"landmark", "segment",
    "confidence"}}`` (labels without a guess left out)."""
    try:
        draft = draft_protocol(trial)
    except ProtocolError as exc:
        warnings.append(f"no draft: {exc}")
        return {}
    out["draft"] = _draft_counts(draft)
    warnings.extend(f"draft: {w}" for w in draft.warnings())
    return {normalise_label(e.label): {"landmark": e.landmark, "segment": e.segment,
                                       "confidence": round(e.confidence, 2)}
            for e in draft.entries if e.landmark or e.segment}


def _draft_counts(draft: Draft) -> dict[str, int]:
    """How many labels ``draft`` puts on a landmark, in a segment's cluster, nowhere, and how
    many of its guesses are of low confidence (:meth:`Draft.warnings`, one each)."""
    entries = draft.entries
    return {"landmarks": sum(e.landmark is not None for e in entries),
            "cluster_markers": sum(e.landmark is None and e.segment is not None
                                   for e in entries),
            "without_guess": sum(e.landmark is None and e.segment is None for e in entries),
            "low_confidence": len(draft.warnings())}


def _landmark_cell(marker: dict) -> str:
    """The table's landmark column: the protocol's landmark, else the draft's guess."""
    guess = marker.get("drafted")
    if guess:
        where = guess["landmark"] or f"{guess['segment']} cluster"
        return f"{where} (drafted, {guess['confidence']:.0%})"
    return marker["landmark"] or "(not in protocol)"


def format_summary(summary: dict) -> str:
    """A summary as the readable text block ``mocaplib inspect`` prints (degrees-free, SI),
    a line per row (file name, labels and messages with control characters escaped)."""
    lines = [summary["file"]]
    if not summary["ok"]:
        return "\n".join(printable(line, keep="")
                         for line in lines + [f"  FAILED: {summary['error']}"])
    rotated = "" if summary["vertical_axis"] == "Z" else " (rotated to Z up)"
    first = summary["first_frame"]
    lines.append(f"  {summary['frames']} frames at {summary['rate_hz']:g} Hz "
                 f"({summary['duration_s']:.2f} s)"
                 + (f" from C3D frame {first}" if first != 1 else "")
                 + f", units {summary['units']}, vertical axis {summary['vertical_axis']}"
                 f"{rotated}")
    closest = summary.get("closest_protocol")
    if summary["protocol"] is None and closest:
        lines.append(f"  protocol: none has its required landmarks; closest {closest['name']} "
                     f"({closest['markers_found']}/{closest['protocol_markers']} markers) lacks "
                     f"{', '.join(closest['missing_landmarks'])}")
    elif summary["protocol"] is None:
        lines.append("  protocol: none matched")
    else:
        missing = ", ".join(summary["missing_landmarks"]) or "none"
        lines.append(f"  protocol {summary['protocol']}: {summary['markers_found']}/"
                     f"{summary['protocol_markers']} markers; missing required landmarks: "
                     f"{missing}")
        if summary["missing_labels"]:
            lines.append(f"  not found: {', '.join(summary['missing_labels'])}")
    draft = summary.get("draft")
    if draft:
        lines.append(f"  drafted from this file alone (as a build drafts from a session's first "
                     f"capture of this marker set): {draft['landmarks']} labels on a landmark, "
                     f"{draft['cluster_markers']} in a segment's cluster, "
                     f"{draft['without_guess']} without a guess; "
                     f"{draft['low_confidence']} of low confidence")
    plates = summary.get("force_plates") or []
    if plates:
        lines.append("  force plates: " + ", ".join(
            f"{p['number']} (type {p['type']}, peak {p['peak_n']:.0f} N)" for p in plates))
    events = summary["events"]
    clock = (f" (lab clock: the file starts at {(first - 1) / summary['rate_hz']:.3f} s)"
             if first != 1 and events else "")
    lines.append(f"  events{clock}: " + (", ".join(
        f"{e['context']} {e['label']} {e['time_s']:.3f} s".strip() for e in events) or "none"))
    rows = [(m["label"], _landmark_cell(m), f"{m['gap_pct']:.1f}",
             f"{m['longest_gap_s']:.2f} s ({m['longest_gap_frames']} frames)"
             if m["longest_gap_frames"] else "-") for m in summary["markers"]]
    widths = [max(len(r[k]) for r in rows + [("marker", "landmark", "gap %", "")])
              for k in range(3)]
    for label, landmark, gap, longest in [("marker", "landmark", "gap %", "longest gap")] + rows:
        lines.append(f"  {label:<{widths[0]}}  {landmark:<{widths[1]}}  {gap:>{widths[2]}}  "
                     f"{longest}")
    if summary["warnings"]:
        lines.append("  warnings:")
        lines.extend(f"    - {w}" for w in summary["warnings"])
    return "\n".join(printable(line, keep="") for line in lines)
