"""Assemble the report: numbers from the control space, figures, one self-contained HTML file.

Everything the page needs is inside it: images are base64 ``data:`` URIs, the interactive 3-D
view is a small canvas script with its data inline, there are no external links or fonts, so
the file opens offline and can be mailed. Text from captures (file names, labels, warnings) is
untrusted: the jinja2 environment auto-escapes every value, and the viewer's JSON is written
with ``tojson`` (which escapes ``<``, ``>``, ``&`` and quotes).
"""

from __future__ import annotations

import base64
import json
import math
import os
import re
from pathlib import Path

import numpy as np
import pandas as pd

from .. import __version__
from ..errors import MocapError
from ..gait.fourier import ANGLE_TOLERANCE, MAX_ANGLE_TOLERANCE, MAX_ORDER
from ..io import read_regular
from ..io.atomic import atomic_write_text
from ..io.jsonvalues import parse_json
from ..library.controlspace import AXIS_UNITS, CLOSE_DISTANCE, SLIVER_QUALITY, ControlSpace, close_entries, leave_one_out
from ..library.coverage import Envelope, coverage
from ..library.format import (DIAGNOSTICS_FORMAT, NO_CHECKSUM_NOTE, checksum_status, load_library,
                              validate_library)
from . import figures
from .files import report_name
from .plan import default_envelope, planned_status
from .scene3d import render_control_space

#: Captures drawn in detail; beyond this the rest are listed without figures (keeps the file
#: small enough to mail; the library's own numbers are still all in the tables).
MAX_CAPTURE_FIGURES = 80
#: Points of each modelled poulaine drawn per capture.
POULAINE_POINTS = 121
#: Sliver tetrahedra listed one by one (the worst first); the rest are summarised.
MAX_SLIVER_ROWS = 10


def write_report(library_path: str | os.PathLike, out_dir: str | os.PathLike, *,
                 envelope=None, renderer: str = "auto", jobs: int = 1) -> Path:
    """Write ``<out_dir>/<library stem>-report.html`` for a library file; returns its path.

    ``envelope``: an :class:`~mocaplib.library.coverage.Envelope`, a TOML file (an ``[envelope]``
    table, or a capture plan), or None for the capture plan shipped with mocaplib (see
    :func:`mocaplib.report.plan.default_envelope`). ``renderer``: ``"auto"`` (pyvista, falling
    back to matplotlib without OpenGL) or ``"matplotlib"``. ``jobs``: processes drawing the
    per-capture figures (the report's slowest part). Reads the diagnostics sidecar
    ``<stem>.diagnostics.json`` beside the library when it exists and belongs to it.
    """
    library_path = Path(library_path)
    library = load_library(library_path)
    diagnostics, diag_warnings = read_diagnostics(library_path, library)
    context = build_context(library, library_path, diagnostics, envelope=envelope,
                            renderer=renderer, jobs=jobs)
    context["warnings"][:0] = diag_warnings
    html = render_html(context)
    return atomic_write_text(Path(out_dir) / report_name(library_path), html)


def render_html(context: dict) -> str:
    """The report's HTML from a context made by :func:`build_context`."""
    import jinja2

    env = jinja2.Environment(
        loader=jinja2.PackageLoader("mocaplib.report", "templates"),
        autoescape=True, undefined=jinja2.StrictUndefined, trim_blocks=True,
        lstrip_blocks=True)
    env.filters["fmt"] = _fmt
    template = env.get_template("report.html.j2")
    scripts = {f"{name}_js": env.loader.get_source(env, f"{name}.js")[0]
               for name in ("viewer", "motion", "figure")}
    return template.render(**context, **scripts,
                           css=env.loader.get_source(env, "report.css")[0])


def _fmt(value, spec: str = ".3g") -> str:
    """A number for people; '—' for None/NaN."""
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return "—"
    text = format(value, spec)
    return text[1:] if text.startswith("-") and not text.strip("-0.") else text  # no "-0"


def _data_uri(png: bytes) -> str:
    return "data:image/png;base64," + base64.b64encode(png).decode("ascii")


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
    from ..library.format import diagnostics_path

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


# --------------------------------------------------------------------------- context
def build_context(library, library_path: Path, diagnostics: dict | None, *, envelope=None,
                  renderer: str = "auto", jobs: int = 1) -> dict:
    """Every number, table and figure of the report (values still unescaped).

    ``diagnostics``: the sidecar as :func:`read_diagnostics` returns it (records checked)."""
    entries = library.entries
    warnings = [f"library check: {p}" for p in validate_library(library)]
    if checksum_status(library.document) == "absent":
        warnings.append(f"library check: {NO_CHECKSUM_NOTE}")
    env, env_note = _resolve_envelope(envelope)
    label = _class_labeller(library, env_note["plan"])
    classes_all = [label(e.id) for e in entries]
    cs, cs_error = None, None
    try:
        cs = ControlSpace.from_library(library, source=library_path.name)
        cs.classes = [label(i) for i in cs.ids]
    except MocapError as exc:
        cs_error = str(exc)
        warnings.append(f"control space: {exc}")
    context = {
        "title": library_path.name, "version": __version__,
        "summary": _summary(library, diagnostics, cs),
        "warnings": warnings, "cs_error": cs_error, "envelope_note": env_note,
        "axes": [{"name": n, "unit": AXIS_UNITS[n], "label": AXIS_NAMES[n]} for n in
                 (cs.axes if cs else ("v", "omega", "v_l"))],
        "entries": _entry_rows(entries, label),
        "coverage": None, "loo": None, "three_d": None, "viewer": None, "projections": None,
        "planned": planned_status(env_note["plan"], env_note["plan_name"], entries,
                                  diagnostics),
        "captures": _captures(diagnostics, library, jobs=jobs),
    }
    for capture in context["captures"]:
        warnings.extend(f"{capture['source']}: {w}" for w in capture["warnings"])
    _add_control_space(context, cs, env, library, label, classes_all, renderer)
    context["motion"] = _motion(library, cs, classes_all, warnings)
    _shorten_paths(context)
    return context


def _add_control_space(context, cs, env, library, label, classes_all, renderer) -> None:
    """Coverage, blending error and the control-space figures into ``context``."""
    warnings = context["warnings"]
    if cs is None:
        velocities = np.array([e.velocity for e in library.entries],
                              dtype=np.float64).reshape(-1, 3)
        finite = np.isfinite(velocities).all(axis=1)
        if finite.any():
            context["projections"] = _data_uri(figures.projections(
                velocities[finite],
                [c for c, ok in zip(classes_all, finite) if ok], ("v", "omega", "v_l"),
                envelope=env.vertices))
        return
    cov = coverage(cs, env)
    context["projections"] = _data_uri(figures.projections(
        cs.points, cs.classes, cs.axes, envelope=env.vertices, hull_points=cs.points,
        holes=cov.samples[~cov.samples_inside],
        suggestions=cov.capture_next[list(cs.axes)].to_numpy()))
    context["coverage"] = _coverage_context(cov, cs, library, label)
    if any(e.mirrored for e in library.entries):
        context["coverage"]["without_mirrors"] = _coverage_without_mirrors(library, env)
    if context["coverage"]["close"]:
        warnings.append(_close_warning(context["coverage"]["close"]))
    context["loo"] = _loo_context(leave_one_out(cs))
    context["three_d"], context["viewer"] = _three_d(cs, env, renderer)
    if context["three_d"]["fallback_reason"]:
        warnings.append("3-D view drawn with matplotlib: "
                        + context["three_d"]["fallback_reason"])


#: An absolute path's folders (POSIX or Windows), up to its last separator.
_ABSOLUTE_FOLDERS = re.compile(r"(?<![\w.~/\\])(?:/|[A-Za-z]:[\\/])[^\s:;,'\"()<>]*[\\/]")


def _shorten_paths(context: dict) -> None:
    """Show the absolute paths in the report's texts (errors and warnings carry the paths given
    to the build) relative to the folder holding all of them: names alone when they share one
    folder. The report may be mailed; the build machine's folders are of no use there."""
    texts = [*context["warnings"], *context["summary"]["built_with"]]
    for c in context["captures"]:
        texts += [c["error"] or "", *c["warnings"]]
    folders = [m.group(0) for t in texts for m in _ABSOLUTE_FOLDERS.finditer(t)]
    if not folders:
        return
    common = os.path.commonpath(folders) if len(set(map(_drive, folders))) == 1 else ""
    if not common:
        return

    def short(text):
        return _ABSOLUTE_FOLDERS.sub(lambda m: m.group(0)[len(common):].lstrip("/\\"),
                                     text) if isinstance(text, str) else text

    context["warnings"][:] = map(short, context["warnings"])
    context["summary"]["built_with"][:] = map(short, context["summary"]["built_with"])
    if context["cs_error"]:
        context["cs_error"] = short(context["cs_error"])
    for c in context["captures"]:
        c["error"], c["warnings"][:] = short(c["error"]), map(short, c["warnings"])
    for f in (context["planned"] or {}).get("failed", []):
        f["reason"] = short(f["reason"])


def _drive(path: str) -> str:
    return path[:2] if path[1:2] == ":" else "/"


def _class_labeller(library, plan):
    """Entry id -> its locomotion class; entries without one take their capture's class in the
    plan (matched by file stem), else "unknown"."""
    from_plan = {} if plan is None else dict(zip(plan["name"], plan["class"]))

    def label(entry_id):
        entry = library.entry(entry_id)
        if isinstance(entry.locomotion_class, str):
            return entry.locomotion_class
        return from_plan.get(Path(entry.source_file).stem, figures.UNKNOWN_CLASS)
    return label


def _resolve_envelope(envelope) -> tuple[Envelope, dict]:
    if isinstance(envelope, Envelope):
        return envelope, {"text": f"given by the caller ({envelope.source})", "plan": None,
                          "plan_name": None, "default": False}
    return default_envelope(None if envelope is None else Path(envelope))


def _summary(library, diagnostics, cs) -> dict:
    captures = (diagnostics or {}).get("captures") or []
    failed = [c for c in captures if not c.get("ok", True)]
    return {
        "entries": len(library), "in_control_space": len(cs.points) if cs else 0,
        "captures": len(captures) if captures else len({e.source_file for e in library.entries}),
        "failed": len(failed), "fourier_n": library.n_harmonics,
        "fourier_cap": MAX_ORDER, "fourier_tolerance_deg": math.degrees(ANGLE_TOLERANCE),
        "fourier_noisy_tolerance_deg": math.degrees(MAX_ANGLE_TOLERANCE),
        "at_cap": [e.id for e in library.entries if e.fourier.n >= MAX_ORDER],
        "built_with": _built_with(library.settings),
        "scale": [] if cs is None else [
            {"axis": a, "scale": s, "unit": AXIS_UNITS[a]} for a, s in zip(cs.axes, cs.scale)],
        "tetrahedra": 0 if cs is None else len(cs.tri.simplices),
    }


def _built_with(settings: dict) -> list[str]:
    """The build settings the library records (``settings``, see ``docs/library-format.md``),
    as short phrases for the summary; a setting the library lacks is left out."""
    def names(key: str) -> list:
        """A setting that is one file name, a list of them or null, as a list."""
        value = settings.get(key)
        return value if isinstance(value, list) else [value] if value else []

    phrases = []
    if "protocol" in settings:
        phrases.append(f"protocol {settings['protocol']}")
    statics = names("static")
    if "static" in settings:
        phrases.append(f"static {', '.join(map(str, statics))} "
                       f"({settings.get('static_pose', 'free')} pose)" if statics else
                       "each capture calibrated from itself")
    references = names("forward_reference")
    if references:
        offsets = settings.get("heading_offsets") or []
        turned = [f"{name} {math.degrees(o):+.3f}°" for name, o in zip(statics, offsets)
                  if isinstance(o, (int, float))] if len(offsets) == len(statics) else []
        phrases.append(f"heading set by the forward reference {', '.join(map(str, references))}"
                       + (f" ({'; '.join(turned)})" if turned else ""))
    if "cutoff" in settings:
        cutoff = settings["cutoff"]
        phrases.append("markers unfiltered" if cutoff is None else
                       "marker low-pass by Winter's residual analysis" if cutoff == "auto" else
                       f"marker low-pass {cutoff} Hz")
    if "toe_off" in settings:
        phrases.append(f"cycles cut at {settings['toe_off']} toe-offs")
    if "all_cycles" in settings:
        phrases.append("every complete cycle" if settings["all_cycles"] else
                       "one cycle per capture")
    if settings.get("mirror"):
        phrases.append("each capture's mirror image added")
    if "qc_policy" in settings:
        phrases.append(f"QC failures {'waived' if settings['qc_policy'] == 'waive' else 'dropped'}")
    return phrases


def _entry_rows(entries, label) -> list[dict]:
    """The entries table: one row per :class:`~mocaplib.library.entry.LibraryEntry`, in degrees and
    millimetres where a person reads; a value not computed is NaN (None for the degrees)."""
    def number(value) -> float:
        return math.nan if value is None else float(value)

    def degrees(value) -> float | None:
        return None if value is None or math.isnan(value) else math.degrees(value)

    return [{"id": e.id, "class": label(e.id), "source": e.source_file, "chosen": e.chosen,
             "mirror_of": e.mirror_of, "v": number(e.v), "omega_deg": degrees(e.omega),
             "v_l": number(e.v_l), "v_f": number(e.v_f), "T": number(e.T),
             "pattern": e.pattern.type, "rms_mm": number(e.qc.get("marker_rms_m")) * 1000,
             "fourier_n": e.fourier.n, "at_cap": e.fourier.n >= MAX_ORDER,
             "fourier_deg": degrees(e.qc.get("fourier_rms_rad"))} for e in entries]


def _coverage_context(cov, cs, library, label) -> dict:
    next_rows = []
    for n, row in enumerate(cov.capture_next.itertuples(index=False), 1):
        values = dict(zip(cs.axes, row[:3]))
        next_rows.append({"n": n, "values": values, "omega_deg": math.degrees(values["omega"]),
                          "gap": row[3], "describe": describe_command(values)})
    hole = dict(zip(cs.axes, cov.largest_hole))
    return {
        "fraction": cov.fraction_inside, "n_samples": cov.n_samples,
        "hole": hole, "hole_omega_deg": math.degrees(hole["omega"]),
        "hole_distance": cov.largest_hole_distance,
        "per_class": cov.entries_per_class,
        "slivers": _sliver_context(cov.slivers),
        "n_tetra": len(cs.tri.simplices), "next": next_rows,
        "close": _close_rows(cs), "other_axes": _other_axes(cs, library, label),
        "without_mirrors": None,
    }


def _coverage_without_mirrors(library, env: Envelope) -> dict:
    """Coverage of ``env`` by the chosen entries that are not mirror images: ``fraction``
    (None when they have no control space, ``reason`` then says why), ``n_entries`` and
    ``n_mirrored`` (the chosen mirror images left out)."""
    chosen = [e for e in library.entries if e.chosen]
    out = {"n_mirrored": sum(e.mirrored for e in chosen),
           "n_entries": sum(not e.mirrored for e in chosen),
           "fraction": None, "reason": None}
    try:
        own = ControlSpace.from_library(library, mirrored=False)
    except MocapError as exc:
        out["reason"] = exc.message
        return out
    out["fraction"] = coverage(own, env).fraction_inside
    return out


def _sliver_context(slivers) -> dict:
    """Sliver count by radius-ratio band, the entries most often in one, the worst few."""
    worst = slivers.sort_values("quality", kind="stable")
    counts = pd.Series([e for entries in slivers["entries"] for e in entries]).value_counts()
    edges = [0.0, 1e-3, 1e-2, SLIVER_QUALITY]
    bands = [{"label": f"{lo:g} – {hi:g}", "count": int(((slivers["quality"] >= lo)
                                                         & (slivers["quality"] < hi)).sum())}
             for lo, hi in zip(edges[:-1], edges[1:])]
    return {"count": len(slivers), "threshold": SLIVER_QUALITY, "bands": bands,
            "frequent": [{"id": k, "count": int(v)} for k, v in counts.head(6).items()],
            "worst": [{"entries": ", ".join(r.entries), "quality": r.quality}
                      for r in worst.head(MAX_SLIVER_ROWS).itertuples(index=False)],
            "not_listed": max(0, len(slivers) - MAX_SLIVER_ROWS)}


def _close_rows(cs) -> list[dict]:
    """Pairs of entries too close to tell apart (:func:`close_entries`), with their gap in SI."""
    rows = []
    index = {k: i for i, k in enumerate(cs.ids)}
    for r in close_entries(cs).itertuples(index=False):
        gap = cs.points[index[r.a]] - cs.points[index[r.b]]
        gap[cs.axes.index("omega")] = math.degrees(gap[cs.axes.index("omega")])
        rows.append({"a": r.a, "b": r.b, "distance": r.distance, "within": CLOSE_DISTANCE,
                     "gap": ", ".join(f"{abs(g):.3f}" for g in gap)})
    return rows


def _close_warning(close: list[dict]) -> str:
    """The report's warning about the pairs of :func:`_close_rows` (not empty)."""
    return (f"{len(close)} pair(s) of entries nearly coincide in the control space (closer "
            f"than {close[0]['within']:.2f} normalised), e.g. {close[0]['a']} and "
            f"{close[0]['b']}: blending switches between them over a tiny change of velocity; "
            "see Coverage")


def _other_axes(cs, library, label) -> dict | None:
    """Slivers, close pairs and blending error of the other axes variant, to compare (None if
    it cannot be triangulated)."""
    other = "frontal" if cs.variant == "tangential" else "tangential"
    try:
        alt = ControlSpace.from_library(library, axes=other)
    except MocapError:
        return None
    alt.classes = [label(i) for i in alt.ids]
    loo = _loo_context(leave_one_out(alt))
    return {"variant": other, "axes": ", ".join(AXIS_NAMES[a] for a in alt.axes),
            "n_tetra": len(alt.tri.simplices),
            "slivers": int((alt.tetra_quality() < SLIVER_QUALITY).sum()),
            "close": len(close_entries(alt)), "n_tested": loo["n_headline"],
            "median_rms": loo["median"]["rms_deg"],
            "median_stride": loo["median"]["stride_error_mm"]}


def describe_command(values: dict) -> str:
    """A velocity triple in words, for the "capture next" list: below 0.05 m/s (or rad/s) a
    velocity counts as none."""
    v = values.get("v", values.get("v_f", 0.0))
    w, vl = values["omega"], values["v_l"]
    parts = []
    if abs(v) < 0.05 and abs(w) >= 0.05:
        return (f"turn on the spot to the {'left' if w > 0 else 'right'} at "
                f"{abs(math.degrees(w)):.0f}°/s")
    if abs(v) < 0.05:
        return "stand still"
    if abs(vl) >= 0.05:
        direction = math.degrees(math.asin(max(-1.0, min(1.0, vl / v)))) if v else 0.0
        side = "left" if vl > 0 else "right"
        parts.append(f"walk at {v:.2f} m/s heading {abs(direction):.0f}° to the {side} of "
                     f"the body")
    else:
        parts.append(f"walk forward at {v:.2f} m/s")
    if abs(w) >= 0.05:
        parts.append(f"turning {'left' if w > 0 else 'right'} (radius {abs(v / w):.1f} m)")
    return ", ".join(parts)


#: Gait mode of each locomotion class (:func:`_gait_mode`): walking in any direction (the plan's
#: nonholonomic, holonomic and mixed classes and any other named class), running, rest.
GAIT_MODES = {"running": "running", "rest": "rest", figures.UNKNOWN_CLASS: None}
#: A leave-one-out row is flagged when at least this share of its blend weight comes from
#: entries of another gait mode (walking rebuilt mostly from running, ...).
CROSS_MODE_SHARE = 0.5


def _gait_mode(cls: str | None) -> str | None:
    """"walking", "running" or "rest" for a locomotion class; None when unknown."""
    if cls is None or cls != cls:
        return None
    return GAIT_MODES.get(cls, "walking")


def _loo_context(df) -> dict:
    """The leave-one-out table and its medians.

    The headline medians leave out rest entries: a standing pose rebuilt from other standing
    poses (other subjects' statics, at the same point (0, 0, 0)) measures how the poses differ,
    not blending; they get their own median. Rows whose blend takes at least
    :data:`CROSS_MODE_SHARE` of its weight from another gait mode are flagged (``cross``) and a
    median without them is given too."""
    mode_of = dict(zip(df["id"], (_gait_mode(c) for c in df["class"])))
    rows = []
    for _, r in df.sort_values("rms_deg", ascending=False, kind="stable").iterrows():
        rows.append({"id": r["id"], "class": r["class"] or figures.UNKNOWN_CLASS,
                     "inside": bool(r["inside"]), "rest": mode_of[r["id"]] == "rest",
                     "cross": _cross_mode(mode_of[r["id"]], r["neighbours"], r["weights"],
                                          mode_of),
                     "rebuilt_from": ", ".join(f"{n} ({w:.2f})" for n, w in
                                               zip(r["neighbours"], r["weights"])),
                     **{k: r[k] for k in LOO_COLUMNS}, "worst_dof": r["worst_dof"]})
    tested = [r for r in rows if r["inside"]]
    headline = [r for r in tested if not r["rest"]]
    same_mode = [r for r in headline if not r["cross"]]
    rest = [r for r in tested if r["rest"]]
    median = _medians(headline)
    return {"rows": rows, "n_inside": len(tested), "n": len(rows), "median": median,
            "n_headline": len(headline), "median_rms": median["rms_deg"],
            "max_rms": max((r["rms_deg"] for r in headline), default=None),
            "n_rest": len(rest), "rest_median_rms": _medians(rest)["rms_deg"],
            "n_cross": len(headline) - len(same_mode), "cross_share": CROSS_MODE_SHARE,
            "same_mode_median_rms": _medians(same_mode)["rms_deg"]}


def _medians(rows: list[dict]) -> dict:
    """Median of |value| of each :data:`LOO_COLUMNS` over ``rows``, NaN left out (None when
    there is no value)."""
    values = {k: [abs(r[k]) for r in rows if r[k] == r[k]] for k in LOO_COLUMNS}
    return {k: float(np.median(v)) if v else None for k, v in values.items()}


def _cross_mode(mode: str | None, neighbours, weights, mode_of: dict) -> dict | None:
    """The other gait mode giving a blend at least :data:`CROSS_MODE_SHARE` of its weight
    (``{"mode", "share"}``), or None (also when a mode is unknown)."""
    if mode is None:
        return None
    shares: dict[str, float] = {}
    for n, w in zip(neighbours, weights):
        if mode_of.get(n) is not None and mode_of[n] != mode:
            shares[mode_of[n]] = shares.get(mode_of[n], 0.0) + w
    other = max(shares, key=shares.get, default=None)
    if other is None or shares[other] < CROSS_MODE_SHARE:
        return None
    return {"mode": other, "share": shares[other]}


#: Numeric columns of :func:`mocaplib.library.controlspace.leave_one_out` shown in the report.
LOO_COLUMNS = ("rms_deg", "max_deg", "heading_rms_deg", "root_rms_mm", "stride_error_mm",
               "turn_error_deg", "T_error_s")
#: Axis names as the report's tables show them.
AXIS_NAMES = {"v": "v̂", "v_f": "v̂_f", "omega": "ω̂", "v_l": "v̂_l"}


def _three_d(cs: ControlSpace, env: Envelope, renderer: str) -> tuple[dict, dict]:
    """The static 3-D picture (pyvista or matplotlib) and the interactive viewer's data."""
    from scipy.spatial import ConvexHull, QhullError

    classes = cs.classes
    colours = figures.class_colours(classes)
    x = cs.normalise(cs.points)
    edges = _unique_edges(cs.tri.simplices)
    env_x = cs.normalise(env.vertices)
    try:
        env_tris = ConvexHull(env_x).simplices
    except QhullError:  # a flat envelope: drawn as its vertices only
        env_tris = np.zeros((0, 3), int)
    # Axes labelled for people: round SI values (ω in °/s) around everything drawn.
    titles = [VTK_AXIS_TITLES[a] for a in cs.axes]
    everything = np.vstack([x, env_x])
    to_people = cs.scale * np.where(np.asarray(cs.axes) == "omega", 180 / np.pi, 1.0)
    ticks = [nice_range(lo, hi) for lo, hi in zip(everything.min(axis=0) * to_people,
                                                  everything.max(axis=0) * to_people)]
    ranges = np.array([t[:2] for t in ticks])
    rendered = render_control_space(
        x, [colours[c] for c in classes], classes, titles, edges=edges,
        hull_triangles=cs.hull_facets, envelope_points=env_x, envelope_triangles=env_tris,
        axes_bounds=(ranges / to_people[:, None]).ravel(), axes_ranges=ranges.ravel(),
        axes_intervals=[t[2] for t in ticks], renderer=renderer,
        fallback=lambda: figures.control_space_3d(cs.points, classes, cs.axes, edges=edges,
                                                  envelope=env.vertices))
    png = rendered.png if rendered.renderer == "matplotlib" else figures.compress_png(rendered.png)
    viewer = {"points": np.round(x, 5).tolist(), "ids": cs.ids, "classes": classes,
              "colours": _css_colours(colours),
              "edges": edges.tolist(),
              "axes": [f"{figures.axis_label(a)}: {lo:.2f} to {hi:.2f}" if a != "omega" else
                       f"{figures.axis_label(a)}: {lo:.0f} to {hi:.0f}"
                       for a, (lo, hi) in zip(cs.axes, ranges)],
              "velocities": [_velocity_text(p, cs.axes) for p in cs.points],
              "envelope": {"points": np.round(env_x, 5).tolist(),
                           "edges": _unique_edges(env_tris).tolist()}}
    return ({"png": _data_uri(png), "renderer": rendered.renderer,
             "fallback_reason": rendered.fallback_reason}, viewer)


def _css_colours(colours: dict) -> dict[str, str]:
    """Class -> CSS colour ``#rrggbb`` of :func:`mocaplib.report.figures.class_colours`."""
    return {k: "#%02x%02x%02x" % tuple(int(255 * c) for c in v) for k, v in colours.items()}


def _motion(library, cs, classes: list[str], warnings: list[str]) -> dict | None:
    """The figure viewer's data (:func:`mocaplib.report.figureview.viewer_data`); None, with a
    warning, when the library has no entry or its DOFs are not this mocaplib's skeleton's."""
    from ..skeleton import DOF_NAMES
    from .figureview import viewer_data

    if not len(library):
        warnings.append("motion viewer left out: the library has no entry")
        return None
    if library.dof_names != list(DOF_NAMES):
        warnings.append("motion viewer left out: the library's DOFs are not this mocaplib's "
                        "skeleton's (report it with the mocaplib version that wrote it)")
        return None
    colours = _css_colours(figures.class_colours(classes))
    return viewer_data(library, cs, classes, colours)


def nice_range(lo: float, hi: float) -> tuple[float, float, int]:
    """The tightest range containing [lo, hi] split into 3 to 7 equal steps of 1, 2, 2.5, 3 or
    5 × 10^k: (start, stop, number of steps)."""
    span = max(hi - lo, 1e-9)
    best = None
    for k in range(int(np.floor(np.log10(span / 7))), int(np.ceil(np.log10(span))) + 1):
        for step in (m * 10.0 ** k for m in (1.0, 2.0, 2.5, 3.0, 5.0)):
            start = np.floor(lo / step + 1e-9) * step
            n = int(np.ceil((hi - start) / step - 1e-9))
            if 3 <= n <= 7 and (best is None or n * step < best[1] - best[0] - 1e-12):
                best = (float(start), float(start + n * step), n)
    return best


#: Axis titles of the pyvista picture (ASCII: VTK's fonts may lack ω and the hats).
VTK_AXIS_TITLES = {"v": "v (m/s)", "v_f": "v_f (m/s)", "omega": "omega (deg/s, > 0 left)",
                   "v_l": "v_l (m/s, > 0 left)"}


def _velocity_text(point, axes) -> str:
    """One entry's velocities for people, e.g. 'v̂ 1.20 m/s, ω̂ -30 °/s, v̂_l 0.00 m/s'."""
    return ", ".join(f"{AXIS_NAMES[a]} {math.degrees(p):.0f} °/s" if a == "omega"
                     else f"{AXIS_NAMES[a]} {p:.2f} m/s" for a, p in zip(axes, point))


def _unique_edges(cells: np.ndarray) -> np.ndarray:
    """Distinct vertex pairs (K, 2) of cells (n, k) (tetrahedra or triangles)."""
    k = cells.shape[1]
    pairs = [cells[:, [i, j]] for i in range(k) for j in range(i + 1, k)]
    return np.unique(np.sort(np.vstack(pairs), axis=1), axis=0).reshape(-1, 2)


def _captures(diagnostics: dict | None, library, *, jobs: int = 1) -> list[dict]:
    """Per-capture sections: status, warnings, cycles and the quality figure (drawn by
    ``jobs`` processes).

    ``diagnostics``: as :func:`read_diagnostics` returns it (its records' shape checked).
    Cycles are numbered by their ``index`` in the capture, from 0, as in the entry ids
    (``<stem>_c<index>``) and the warnings."""
    if not diagnostics:
        return []
    out, drawn = [], []
    known = {e.id for e in library.entries}
    for k, record in enumerate(diagnostics.get("captures") or []):
        cycles = [{"index": c.get("index", n), "start": c.get("start_s"),
                   "end": c.get("end_s"), "chosen": bool(c.get("chosen")),
                   "start_event": None if c.get("start_event", "left_toe_off") == "left_toe_off"
                   else str(c["start_event"]).replace("_", " "),
                   "entry": c.get("entry_id"), "pattern": (c.get("pattern") or {}).get("type")}
                  for n, c in enumerate(record.get("cycles") or [])]
        item = {"source": str(record.get("source", f"capture {k}")),
                "ok": record.get("ok", True), "error": record.get("error"),
                "stage": record.get("stage"), "static": record.get("static"),
                "no_entry": record.get("no_entry"),
                "warnings": [str(w) for w in record.get("warnings") or []],
                "cycles": cycles, "n_entries": sum(c["entry"] is not None for c in cycles),
                "figure": None, "figure_error": None, "anchor": f"capture-{k}"}
        if (record.get("time_s") or record.get("angles")) and k < MAX_CAPTURE_FIGURES:
            drawn.append((item, (record, _reconstructions(record, library, known),
                                 _poulaine(record, library, known))))
        out.append(item)
    results = _in_processes(_capture_figure, [arguments for _, arguments in drawn], jobs)
    for (item, _), (png, error) in zip(drawn, results):
        item["figure"] = None if png is None else _data_uri(png)
        item["figure_error"] = error
    return out


def _capture_figure(record: dict, reconstructions: dict, poulaine: dict | None
                    ) -> tuple[bytes | None, str | None]:
    """A capture's quality figure (PNG), or why its sidecar record could not be drawn."""
    try:
        return figures.capture_figure(record, reconstructions, poulaine), None
    except (ValueError, TypeError, KeyError, IndexError, AttributeError) as exc:
        # a hand-edited or foreign sidecar: this capture's plots only are lost
        return None, (f"its record in the diagnostics sidecar is malformed "
                      f"({type(exc).__name__}: {str(exc)[:200]})")


def _in_processes(function, arguments: list[tuple], jobs: int) -> list:
    """``[function(*a) for a in arguments]`` by ``jobs`` worker processes
    (:func:`mocaplib.build.workers.run_tasks`, as the build's); ``function`` returns ``(value,
    error)``, and a call that raised or whose worker died gives ``(None, reason)``."""
    from ..build.workers import run_tasks

    results: list = [None] * len(arguments)
    for i, value, error in run_tasks(function, arguments, jobs=jobs):
        results[i] = value if error is None else (
            None, f"it could not be drawn ({type(error).__name__}: {str(error)[:200]})")
    return results


def _poulaine(record: dict, library, known: set) -> dict | None:
    """The model of the poulaines of the capture's chosen cycle, if it is an entry with one:
    ``path`` (n, 2, 3) m over the cycle and the characteristic ``points`` (2, 4, 3) m."""
    chosen = [c.get("entry_id") for c in record.get("cycles") or [] if c.get("chosen")]
    model = library.poulaine(chosen[0]) if chosen and chosen[0] in known else None
    if model is None:
        return None
    return {"path": model(np.linspace(0.0, 1.0, POULAINE_POINTS)),
            "points": np.stack([model.left.points, model.right.points])}


def _reconstructions(record: dict, library, known: set) -> dict:
    """Fourier series of the capture's cycles that became entries, on the capture's time axis.

    Root channels are stored in the path frame, so only the joint DOFs drawn are rebuilt."""
    out: dict[str, list] = {}
    for cycle in record.get("cycles") or []:
        entry_id = cycle.get("entry_id")
        if entry_id not in known:
            continue
        T = library.entry(entry_id).T
        t = np.linspace(0.0, T, 120)
        q = library.angles(entry_id, t)
        for dof in figures.CAPTURE_DOFS:
            j = library.dof_names.index(dof)
            out.setdefault(dof, []).append((t + cycle["start_s"], q[:, j]))
    # Several cycles: joined with NaN gaps so each DOF is one dashed line.
    return {dof: (np.concatenate([np.append(t, np.nan) for t, _ in parts]),
                  np.concatenate([np.append(q, np.nan) for _, q in parts]))
            for dof, parts in out.items()}
