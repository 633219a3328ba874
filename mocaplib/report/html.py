"""Assemble the report: numbers from the control space, figures, one self-contained HTML file.

Everything the page needs is inside it: images are base64 ``data:`` URIs, the interactive 3-D
view is a small canvas script with its data inline, there are no external links or fonts, so
the file opens offline and can be mailed. Text from captures (file names, labels, warnings) is
untrusted: the jinja2 environment auto-escapes every value, and the viewer's JSON is written
with ``tojson`` (which escapes ``<``, ``>``, ``&`` and quotes).
"""

from __future__ import annotations

import math
import os
import re
from pathlib import Path

import numpy as np
import orjson

from .. import __version__
from ..build.workers import max_jobs, run_tasks
from ..errors import MocapError
from ..gait.fourier import ANGLE_TOLERANCE, MAX_ANGLE_TOLERANCE, MAX_ORDER
from ..io.atomic import atomic_write_text
from ..io.fastjson import collection_paused
from ..library.controlspace import AXIS_UNITS, ControlSpace
from ..library.document import CHECKSUM_KEY, NO_CHECKSUM_NOTE, version_note
from ..library.format import load_library
from ..library.validation import validate_library
from ..skeleton import DOF_NAMES
from . import figures
from .diagnostics import read_diagnostics
from .figureview import start_planting, viewer_data
from .files import data_uri, report_name
from .plan import planned_status
from .space_sections import AXIS_NAMES, add_control_space, css_colours, resolve_envelope

#: Captures drawn in detail; beyond this the rest are listed without figures (keeps the file
#: small enough to mail; the library's own numbers are still all in the tables).
MAX_CAPTURE_FIGURES = 80
#: Points of each modelled poulaine drawn per capture.
POULAINE_POINTS = 121
#: Entries a report's worker process takes by default (:func:`default_jobs`; on the 2-core
#: machine a worker pays for itself from about 500 entries, 4.5 ms each to plant), and how many
#: entries a capture's figures count for (0.37 s to draw).
ENTRIES_PER_JOB, CAPTURE_ENTRIES = 500, 60


def write_report(library_path: str | os.PathLike, out_dir: str | os.PathLike, *,
                 envelope=None, renderer: str = "auto", jobs: int | None = None) -> Path:
    """Write ``<out_dir>/<library stem>-report.html`` for a library file; returns its path.

    ``envelope``: an :class:`~mocaplib.library.coverage.Envelope`, a TOML file (an ``[envelope]``
    table, or a capture plan), or None for the capture plan shipped with mocaplib (see
    :func:`mocaplib.report.plan.default_envelope`). ``renderer``: ``"auto"`` (pyvista, falling
    back to matplotlib without OpenGL) or ``"matplotlib"``. ``jobs``: processes drawing the
    per-capture figures and planting the figure viewer's cycles (the report's slowest parts;
    None: :func:`default_jobs`). Reads the diagnostics sidecar ``<stem>.diagnostics.json``
    beside the library when it exists and belongs to it.
    """
    library_path = Path(library_path)
    library = load_library(library_path)
    diagnostics, diag_warnings = read_diagnostics(library_path, library)
    if jobs is None:
        jobs = default_jobs(len(library), len((diagnostics or {}).get("captures", [])))
    # the report makes no garbage cycles worth collecting, and every collection would visit
    # the library's millions of lists and dicts again: 7 % of a 5,000-entry report's time
    with collection_paused():
        context = build_context(library, library_path, diagnostics, envelope=envelope,
                                renderer=renderer, jobs=jobs)
        context["warnings"][:0] = diag_warnings
        html = render_html(context)
    return atomic_write_text(Path(out_dir) / report_name(library_path), html)


def default_jobs(entries: int, captures: int) -> int:
    """Worker processes for a report of ``entries`` entries and ``captures`` captures in its
    diagnostics: one per :data:`ENTRIES_PER_JOB` entries, a capture counting as
    :data:`CAPTURE_ENTRIES`, at most :func:`~mocaplib.build.workers.max_jobs` (a smaller
    library is done before a worker would have started)."""
    work = entries + CAPTURE_ENTRIES * captures
    return max(1, min(max_jobs(), -(-work // ENTRIES_PER_JOB)))


def render_html(context: dict) -> str:
    """The report's HTML from a context made by :func:`build_context`."""
    import jinja2

    env = jinja2.Environment(
        loader=jinja2.PackageLoader("mocaplib.report", "templates"),
        autoescape=True, undefined=jinja2.StrictUndefined, trim_blocks=True,
        lstrip_blocks=True)
    env.filters["fmt"] = _fmt
    # the page's JSON data (the figure viewer's), compact, by orjson (a 5,000-entry library's
    # 40 MB in a tenth of the standard library's time); ``tojson`` escapes it for HTML
    env.policies["json.dumps_function"] = _page_json
    env.policies["json.dumps_kwargs"] = {}
    template = env.get_template("report.html.j2")
    scripts = {f"{name}_js": env.loader.get_source(env, f"{name}.js")[0]
               for name in ("viewer", "motion", "figure")}
    return template.render(**context, **scripts,
                           css=env.loader.get_source(env, "report.css")[0])


def _page_json(data) -> str:
    """Compact JSON text of the page's ``data``, keys sorted (integer keys as strings, as
    :func:`json.dumps` writes them; numpy numbers as numbers)."""
    return orjson.dumps(data, option=orjson.OPT_SORT_KEYS | orjson.OPT_NON_STR_KEYS
                        | orjson.OPT_SERIALIZE_NUMPY).decode()


def _fmt(value, spec: str = ".3g") -> str:
    """A number for people; '—' for None/NaN."""
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return "—"
    text = format(value, spec)
    return text[1:] if text.startswith("-") and not text.strip("-0.") else text  # no "-0"


# --------------------------------------------------------------------------- context
def build_context(library, library_path: Path, diagnostics: dict | None, *, envelope=None,
                  renderer: str = "auto", jobs: int = 1) -> dict:
    """Every number, table and figure of the report (values still unescaped).

    ``diagnostics``: the sidecar as :func:`read_diagnostics` returns it (records checked)."""
    entries = library.entries
    planted = start_planting(library, jobs=jobs) if _motion_shown(library) is None else None
    warnings = [f"library check: {p}" for p in validate_library(library)]
    if library.document.get(CHECKSUM_KEY) is None:      # a stored one is checked above
        warnings.append(f"library check: {NO_CHECKSUM_NOTE}")
    if version_note(library.document):
        warnings.append(f"library check: {version_note(library.document)}")
    env, env_note = resolve_envelope(envelope)
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
    add_control_space(context, cs, env, library, label, classes_all, renderer)
    context["motion"] = _motion(library, cs, classes_all, warnings, planted)
    _shorten_paths(context)
    return context


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
    statics = names("static")
    captures = settings.get("captures")
    if isinstance(captures, list) and captures:
        phrases += _provenance(captures, settings.get("static_pose", "free"))
    else:
        if "protocol" in settings:
            phrases.append(f"protocol {settings['protocol']}")
        if "static" in settings:
            phrases.append(f"static {', '.join(map(str, statics))} "
                           f"({settings.get('static_pose', 'free')} pose)" if statics else
                           "each capture calibrated from itself")
    if settings.get("keep_non_level"):
        phrases.append("cycles on stairs or slopes kept, flagged")
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
                       "one cycle per activity segment of each capture")
    if settings.get("mirror"):
        phrases.append("each capture's mirror image added")
    if "qc_policy" in settings:
        phrases.append(f"QC failures {'waived' if settings['qc_policy'] == 'waive' else 'dropped'}")
    return phrases


def _provenance(captures: list, static_pose: str) -> list[str]:
    """What the library's captures were calibrated from and their marker-set protocols, as
    phrases (``settings.captures``, see ``docs/library-format.md``): one per static and where
    it came from, naming the captures; one per protocol and its origin."""
    def listed(files: list) -> str:
        return ", ".join(map(str, files[:4])) + (f" and {len(files) - 4} more"
                                                 if len(files) > 4 else "")

    calibrations: dict[tuple, list] = {}
    protocols: dict[tuple, list] = {}
    for c in (c for c in captures if isinstance(c, dict)):
        calibrations.setdefault((c.get("static"), c.get("calibrated_from"),
                                 c.get("static_pose", static_pose)), []).append(c.get("file"))
        protocols.setdefault((c.get("protocol"), c.get("protocol_origin")), []).append(
            c.get("file"))
    said = {"command line": "named on the command line", "session.toml": "named by a "
            "session.toml", "found among the inputs": "found among the inputs"}
    phrases = [f"{listed(files)} calibrated from {'itself' if len(files) == 1 else 'themselves'}"
               if static is None else f"{listed(files)} calibrated from the static {static} "
               f"({pose} pose, {said.get(source, source)})"
               for (static, source, pose), files in calibrations.items()]
    return phrases + [f"protocol {name} ({origin}) for {listed(files)}"
                      for (name, origin), files in protocols.items()]


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


def _motion_shown(library) -> str | None:
    """Why the report has no figure viewer for ``library``, or None when it has one."""
    if not len(library):
        return "motion viewer left out: the library has no entry"
    if library.dof_names != list(DOF_NAMES):
        return ("motion viewer left out: the library's DOFs are not this mocaplib's skeleton's "
                "(report it with the mocaplib version that wrote it)")
    return None


def _motion(library, cs, classes: list[str], warnings: list[str], planted) -> dict | None:
    """The figure viewer's data (:func:`mocaplib.report.figureview.viewer_data`, its cycles
    from ``planted``, what :func:`~mocaplib.report.figureview.start_planting` returned); None,
    with a warning, when :func:`_motion_shown` says why there is none."""
    reason = _motion_shown(library)
    if reason:
        warnings.append(reason)
        return None
    colours = css_colours(figures.class_colours(classes))
    return viewer_data(library, cs, classes, colours, planted=planted)


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
                   "plates": list(c.get("bound_plates") or (None, None))[:2],
                   "shifts_ms": [1000 * (x or 0.0) for x in
                                 (c.get("bound_plate_shifts_s") or (0.0, 0.0))[:2]],
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
        item["figure"] = None if png is None else data_uri(png)
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
