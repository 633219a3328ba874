"""The motion library file: one locomotion cycle per entry, written as deterministic JSON.

A library holds, for every entry, the cycle's average velocities (v̂, ω̂, v̂_l, v̂_f) and the
Fourier coefficients of every degree of freedom of the fixed skeleton
(:data:`mocaplib.skeleton.DOF_NAMES`), with the quality metrics that justify keeping it.
The format is specified in ``docs/library-format.md`` and by the JSON Schema shipped as
``mocaplib/schema/library.schema.json``.

Fourier convention (fixed team-wide), ``t`` in seconds from the cycle start, period ``T`` s::

    q_d(t) = a[d, 0] + sum_{k=1..N} ( a[d, k] cos(2 pi k t / T) + b[d, k] sin(2 pi k t / T) )

``a`` and ``b`` have shape ``(D, N + 1)``, ``b[:, 0] = 0``. Units are those of the DOF: radians,
metres for ``pelvis_t*``. Root channels are stored in the frame moving along the cycle's path;
the per-cycle displacement of that frame is stored apart (``root_drift``).

Files are deterministic: keys sorted, floats written with 10 significant digits, no time stamps,
so the same inputs and settings give byte-identical files. Files are written atomically.
"""

from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass
from functools import cached_property
from importlib import resources
from pathlib import Path

import numpy as np
import pandas as pd

from . import __version__
from .errors import LibraryError
from .io.atomic import atomic_write_text
from .io.jsonvalues import json_values
from .skeleton import DOFS

FORMAT = "mocaplib-library"
FORMAT_VERSION = 1
CONTROL_AXES = ("v", "omega", "v_l")
CONTROL_UNITS = ("m/s", "rad/s", "m/s")
#: Largest |velocity| (m/s, rad/s) and |Fourier coefficient| (rad, or m for pelvis_t*) an entry
#: may have: far beyond any human locomotion, so only corrupt files are refused (and the control
#: space's geometry never overflows).
PLAUSIBLE_SPEED, PLAUSIBLE_COEFFICIENT = 100.0, 1000.0
FOURIER_FORMULA = ("q_d(t) = a[d][0] + sum_{k=1..N} (a[d][k] cos(2 pi k t / T) "
                   "+ b[d][k] sin(2 pi k t / T)), t in s from the cycle start")
ROOT_DRIFT_TEXT = ("displacement of the path frame over one cycle, expressed in the frame at the "
                   "cycle start: dx_m forward, dy_m left, dheading_rad counter-clockwise")

#: QC metric name -> (threshold, "max" if the value must not exceed it, "min" if not fall below).
#: Marker limits are OpenSim's IK best practice. Event quality below 0.5 means most foot samples
#: around a bounding toe-off were gap-filled, not measured. The Fourier limit is twice the encoding
#: target of 0.5 deg (Skejø 2021): the RMS is measured against the fitted angles, whose
#: frame-to-frame noise on poorly observed DOFs (ankle inversion, shoulder rotation) is about
#: 0.5 deg itself, so 1 deg flags cycles that are not periodic or not followed, not fit noise.
#: A threshold of None means the metric is reported, not checked.
QC_LIMITS: dict[str, tuple[float | None, str]] = {
    "marker_rms_m": (0.02, "max"),
    "marker_max_m": (0.04, "max"),
    "gap_fraction": (0.5, "max"),
    "event_quality": (0.5, "min"),   # as mocaplib.cycles.MIN_EVENT_QUALITY
    "fourier_rms_rad": (math.radians(1.0), "max"),  # 2x the encoding tolerance: see docs
    "cycle_closure_rad": (None, "max"),
    "jerk_rms_rad_s3": (None, "max"),
}
QC_NAMES = tuple(QC_LIMITS)
DEFAULT_QC_THRESHOLDS = {name: limit for name, (limit, _) in QC_LIMITS.items()}
_SIGNIFICANT = 10


@dataclass(frozen=True)
class Problem:
    """One reason a library is invalid: ``where`` (a JSON path such as ``entries[3].T``) and why."""

    where: str
    message: str

    def __str__(self) -> str:
        return f"{self.where}: {self.message}"


# --------------------------------------------------------------------------- building entries
def make_entry(*, id: str, source_file: str, source_sha256: str, cycle_index: int,
               start_s: float, end_s: float, T: float, pattern: dict, v: float, omega: float,
               v_l: float, v_f: float, a: np.ndarray, b: np.ndarray, root_drift: dict,
               qc: dict, locomotion_class: str | None = None, chosen: bool = True,
               segment_lengths_m: dict | None = None, qc_waived: dict | None = None) -> dict:
    """One library entry as a JSON-ready dict (the structure of ``entries[i]`` in the file).

    ``a``, ``b``: Fourier coefficients, shape (D, N+1), DOF units; ``pattern``: ``type``
    (line/arc/point), ``parameters`` (dict of numbers or number lists), ``residual_m``,
    ``arc_angle_rad``; velocities m/s and rad/s; ``qc``: values keyed by :data:`QC_NAMES`.
    """
    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    if a.ndim != 2 or a.shape != b.shape or a.shape[1] < 1:
        raise LibraryError(f"entry {id}: Fourier a and b must both have shape (D, N+1), "
                           f"got {a.shape} and {b.shape}")
    unknown = set(qc) - set(QC_NAMES) | set(qc_waived or {}) - set(QC_NAMES)
    if unknown:
        raise LibraryError(f"entry {id}: unknown QC metrics {sorted(unknown)}; "
                           f"known are {', '.join(QC_NAMES)}")
    entry = {
        "id": str(id), "locomotion_class": locomotion_class, "source_file": str(source_file),
        "source_sha256": str(source_sha256), "cycle_index": int(cycle_index),
        "chosen": bool(chosen), "start_s": start_s, "end_s": end_s, "T": T,
        "pattern": {"type": pattern["type"], "parameters": dict(pattern.get("parameters", {})),
                    "residual_m": pattern.get("residual_m"),
                    "arc_angle_rad": pattern.get("arc_angle_rad")},
        "v": v, "omega": omega, "v_l": v_l, "v_f": v_f,
        "fourier": {"n": a.shape[1] - 1, "a": a, "b": b},
        "root_drift": dict(root_drift), "qc": dict(qc), "qc_waived": dict(qc_waived or {}),
    }
    if segment_lengths_m is not None:
        entry["segment_lengths_m"] = dict(segment_lengths_m)
    return to_json_data(entry)


def qc_failures(qc: dict, thresholds: dict, waived: dict | None = None) -> list[str]:
    """Human-readable QC metrics outside their threshold and not waived (empty when all pass)."""
    failures = []
    for name, value in qc.items():
        limit = thresholds.get(name)
        if limit is None or (waived and name in waived):
            continue
        if value is None or not math.isfinite(value):
            failures.append(f"{name} is not finite")
            continue
        if QC_LIMITS[name][1] == "max" and value > limit:
            failures.append(f"{name} {value:.4g} > {limit:.4g}")
        elif QC_LIMITS[name][1] == "min" and value < limit:
            failures.append(f"{name} {value:.4g} < {limit:.4g}")
    return failures


def assemble_library(entries: list[dict], *, settings: dict,
                     qc_thresholds: dict | None = None) -> "Library":
    """A library from entries (made by :func:`make_entry`); entries are sorted by id.

    The header's segment lengths are the per-length median over entries (or the nominal
    1.75 m skeleton's when no entry carries lengths); the Fourier order N is the largest
    entry order and smaller orders are zero-padded (exact); control-space scales are
    :func:`control_scale`.
    """
    from .skeleton import Skeleton

    entries = sorted((json.loads(json.dumps(e)) for e in entries), key=lambda e: e["id"])
    n_max = max((e["fourier"]["n"] for e in entries), default=0)
    for entry in entries:
        for key in ("a", "b"):
            rows = entry["fourier"][key]
            entry["fourier"][key] = [row + [0.0] * (n_max + 1 - len(row)) for row in rows]
    lengths = [e["segment_lengths_m"] for e in entries if e.get("segment_lengths_m")]
    if lengths:
        segment_lengths = {k: float(np.median([lens[k] for lens in lengths])) for k in lengths[0]}
    else:
        segment_lengths = Skeleton.from_height(1.75).lengths
    doc = {
        "format": FORMAT, "format_version": FORMAT_VERSION, "tool_version": __version__,
        "settings": settings,
        "skeleton": {
            "dof_names": [d.name for d in DOFS],
            "dof_units": ["m" if d.translation else "rad" for d in DOFS],
            "dof_ranges": [[d.lower, d.upper] for d in DOFS],
            "segment_lengths_m": segment_lengths,
        },
        "fourier": {"formula": FOURIER_FORMULA, "time_origin": "cycle_start",
                    "n_harmonics": n_max, "coefficient_shape": "D x (N+1)",
                    "root_drift": ROOT_DRIFT_TEXT},
        "control_space": {"axes": list(CONTROL_AXES), "units": list(CONTROL_UNITS),
                          "scale": control_scale(), "normalised": "x / scale",
                          "alternative_axes": ["v_f", "omega", "v_l"]},
        "qc_thresholds": dict(DEFAULT_QC_THRESHOLDS if qc_thresholds is None else qc_thresholds),
        "entries": entries,
    }
    return Library(to_json_data(doc))


def control_scale() -> list[float]:
    """Normalisation scales of (v, omega, v_l): :data:`mocaplib.controlspace.DEFAULT_SCALE`.

    Fixed, not derived from the entries, so adding a capture does not re-shape the
    triangulation of the others.
    """
    from .controlspace import DEFAULT_SCALE

    return [float(DEFAULT_SCALE[axis]) for axis in CONTROL_AXES]


def _control_points(entries: list[dict]) -> np.ndarray:
    return np.array([[_float(e[axis]) for axis in CONTROL_AXES] for e in entries],
                    dtype=np.float64).reshape(-1, 3)


def _float(value) -> float:
    return float("nan") if value is None else float(value)


# --------------------------------------------------------------------------- the Library
class Library:
    """A motion library in memory: the JSON document plus array and table views.

    Attributes
    ----------
    document : dict
        The file's content as JSON data (see ``docs/library-format.md``).
    entries : DataFrame
        One row per entry, index ``id``; columns ``locomotion_class, source_file,
        source_sha256, cycle_index, chosen, start_s, end_s, T, pattern_type, pattern_residual_m,
        arc_angle_rad, v, omega, v_l, v_f, fourier_n`` and one ``qc_<metric>`` column per QC
        metric, and ``qc_waived`` (comma-separated metric names).
    """

    def __init__(self, document: dict):
        self.document = document

    # ------------------------------------------------------------------ views
    @property
    def dof_names(self) -> list[str]:
        return list(self.document["skeleton"]["dof_names"])

    @property
    def n_harmonics(self) -> int:
        return int(self.document["fourier"]["n_harmonics"])

    @property
    def settings(self) -> dict:
        return self.document["settings"]

    @property
    def control_scale(self) -> np.ndarray:
        """Normalisation scales of (v, omega, v_l), shape (3,): normalised = value / scale."""
        return np.asarray(self.document["control_space"]["scale"], dtype=np.float64)

    @cached_property
    def entries(self) -> pd.DataFrame:
        rows = []
        for e in self.document["entries"]:
            row = {key: e[key] for key in ("id", "locomotion_class", "source_file",
                                           "source_sha256", "cycle_index")}
            row["chosen"] = bool(e.get("chosen", True))
            row.update({key: _float(e[key]) for key in ("start_s", "end_s", "T")})
            row["pattern_type"] = e["pattern"]["type"]
            row["pattern_residual_m"] = _float(e["pattern"]["residual_m"])
            row["arc_angle_rad"] = _float(e["pattern"]["arc_angle_rad"])
            row.update({key: _float(e[key]) for key in ("v", "omega", "v_l", "v_f")})
            row["fourier_n"] = int(e["fourier"]["n"])
            row.update({f"qc_{name}": _float(e["qc"].get(name)) for name in QC_NAMES})
            row["qc_waived"] = ",".join(sorted(e["qc_waived"]))
            rows.append(row)
        columns = ["id", "locomotion_class", "source_file", "source_sha256", "cycle_index",
                   "chosen", "start_s", "end_s", "T", "pattern_type", "pattern_residual_m",
                   "arc_angle_rad", "v", "omega", "v_l", "v_f", "fourier_n",
                   *(f"qc_{name}" for name in QC_NAMES), "qc_waived"]
        return pd.DataFrame(rows, columns=columns).set_index("id")

    def __len__(self) -> int:
        return len(self.document["entries"])

    def __repr__(self) -> str:
        return (f"<Library {len(self)} entries, {len(self.dof_names)} DOFs, "
                f"N={self.n_harmonics}, mocaplib {self.document['tool_version']}>")

    def entry(self, entry_id: str) -> dict:
        """The JSON data of one entry."""
        for e in self.document["entries"]:
            if e["id"] == entry_id:
                return e
        raise LibraryError(f"no entry {entry_id!r} in the library",
                           hint=f"ids are: {', '.join(self.entries.index[:20])}")

    def coefficients(self, entry_id: str) -> tuple[np.ndarray, np.ndarray]:
        """Fourier ``a`` and ``b`` of one entry, each shape (D, N+1), DOF units."""
        fourier = self.entry(entry_id)["fourier"]
        return _matrix(fourier["a"]), _matrix(fourier["b"])

    def coefficient_arrays(self) -> tuple[np.ndarray, np.ndarray]:
        """Stacked ``a`` and ``b`` of every entry in ``entries`` order, each (E, D, N+1)."""
        shape = (len(self), len(self.dof_names), self.n_harmonics + 1)
        if not len(self):
            return np.zeros(shape), np.zeros(shape)
        a = np.stack([_matrix(e["fourier"]["a"]) for e in self.document["entries"]])
        b = np.stack([_matrix(e["fourier"]["b"]) for e in self.document["entries"]])
        return a, b

    def angles(self, entry_id: str, t: np.ndarray) -> np.ndarray:
        """The entry's joint coordinates at times ``t`` (s from the cycle start), shape (len(t), D).

        Evaluates the library's Fourier formula; ``t`` beyond ``T`` repeats the cycle.
        """
        from .fourier import synthesize

        a, b = self.coefficients(entry_id)
        return synthesize(a, b, _float(self.entry(entry_id)["T"]), np.asarray(t, dtype=float))

    # ------------------------------------------------------------------ output
    def to_json(self) -> str:
        """The file's text: deterministic (sorted keys, 10 significant digits), ends with
        newline."""
        return json_text(self.document)

    def write(self, path: str | os.PathLike) -> Path:
        """Write the library atomically; returns the path."""
        return atomic_write_text(path, self.to_json())


def _matrix(rows) -> np.ndarray:
    return np.array([[_float(x) for x in row] for row in rows], dtype=np.float64)


# --------------------------------------------------------------------------- reading
def load_library(path: str | os.PathLike) -> Library:
    """Read a library file. Raises :class:`LibraryError` when it is not a valid library.

    The file is checked against the schema and for what would make its numbers unusable
    (coefficient shapes, non-finite or implausible values, periods), so a table built from it
    can be trusted; a QC metric over its threshold or a degenerate control space does not
    prevent loading — run :func:`validate_library` for those.
    """
    document = _read_document(path)
    problems = _schema_problems(document) or (_skeleton_problems(document)
                                              + _entry_problems(document, qc=False))
    if problems:
        raise LibraryError(f"not a valid mocaplib library: {problems[0]}"
                           + (f" (and {len(problems) - 1} more problems)" if len(problems) > 1
                              else ""), path=path, hint="run `mocaplib validate` on it")
    return Library(document)


def _read_document(path: str | os.PathLike) -> dict:
    try:
        text = Path(path).read_text(encoding="utf-8")
    except OSError as exc:
        raise LibraryError(f"cannot read library: {exc.strerror}", path=path,
                           hint="check the path") from exc
    except UnicodeDecodeError as exc:
        raise LibraryError("library is not UTF-8 text", path=path,
                           hint="a library is a JSON file written by `mocaplib build`") from exc
    try:
        return json.loads(text)
    except json.JSONDecodeError as exc:
        raise LibraryError(f"library is not valid JSON: {exc.msg} at line {exc.lineno}",
                           path=path, hint="a library is a JSON file written by "
                                           "`mocaplib build`") from exc
    except RecursionError:
        raise LibraryError("library is not a mocaplib library: its JSON is nested too deep",
                           path=path, hint="a library is a JSON file written by "
                                           "`mocaplib build`") from None


def schema() -> dict:
    """The JSON Schema (draft 2020-12) of library files, as shipped in the package."""
    text = resources.files("mocaplib").joinpath("schema/library.schema.json").read_text("utf-8")
    return json.loads(text)


# --------------------------------------------------------------------------- validation
def validate_library(library) -> list[Problem]:
    """Schema and semantic problems of a library (path, JSON dict or :class:`Library`).

    Checks, after the schema: DOF names unique and units/ranges one per DOF; every entry's
    coefficients of shape (D, N+1) with N the header's, finite, ``b[:, 0] = 0``; ``T > 0`` and
    ``end_s - start_s = T`` (1 ms); velocities finite; ids unique; control-space scales finite
    and > 0 and the entries' normalised (v, omega, v_l) points of affine rank 3 (a 3-D
    triangulation needs them); every QC metric within ``qc_thresholds`` or listed in the
    entry's ``qc_waived`` with a reason. Returns an empty list for a valid library.
    """
    if isinstance(library, Library):
        document = library.document
    elif isinstance(library, dict):
        document = library
    else:
        try:
            document = _read_document(library)
        except LibraryError as exc:
            return [Problem("file", exc.message)]
    problems = _schema_problems(document)
    if problems:
        return problems
    return (_skeleton_problems(document) + _entry_problems(document)
            + _control_space_problems(document))


def _schema_problems(document) -> list[Problem]:
    from jsonschema import Draft202012Validator

    validator = Draft202012Validator(schema())
    errors = sorted(validator.iter_errors(document), key=lambda e: list(map(str, e.path)))
    return [Problem(_json_path(error.path), f"schema: {error.message[:300]}") for error in errors]


def _json_path(parts) -> str:
    text = ""
    for part in parts:
        text += f"[{part}]" if isinstance(part, int) else (f".{part}" if text else str(part))
    return text or "(document)"


def _skeleton_problems(doc: dict) -> list[Problem]:
    skel = doc["skeleton"]
    names = skel["dof_names"]
    problems = []
    if len(set(names)) != len(names):
        dupes = sorted({n for n in names if names.count(n) > 1})
        problems.append(Problem("skeleton.dof_names", f"duplicate DOF names: {dupes}"))
    for key in ("dof_units", "dof_ranges"):
        if len(skel[key]) != len(names):
            problems.append(Problem(f"skeleton.{key}",
                                    f"{len(skel[key])} items for {len(names)} DOFs"))
    return problems


def _entry_problems(doc: dict, *, qc: bool = True) -> list[Problem]:
    """Problems of the entries: ids, coefficients, periods, velocities and (``qc``) QC."""
    n_dof = len(doc["skeleton"]["dof_names"])
    n_harm = doc["fourier"]["n_harmonics"]
    thresholds = doc["qc_thresholds"]
    problems = []
    seen: set[str] = set()
    for i, e in enumerate(doc["entries"]):
        where = f"entries[{i}]"
        if e["id"] in seen:
            problems.append(Problem(f"{where}.id", f"duplicate id {e['id']!r}"))
        seen.add(e["id"])
        problems += _fourier_problems(e["fourier"], f"{where}.fourier", n_dof, n_harm)
        period = _float(e["T"])
        if not (math.isfinite(period) and period > 0):
            problems.append(Problem(f"{where}.T", f"period must be finite and > 0, got {period}"))
        elif abs((e["end_s"] - e["start_s"]) - period) > 1e-3:
            problems.append(Problem(f"{where}.T", f"T = {period} s but end_s - start_s = "
                                                  f"{e['end_s'] - e['start_s']} s"))
        for key in ("v", "omega", "v_l", "v_f"):
            if not math.isfinite(_float(e[key])):
                problems.append(Problem(f"{where}.{key}", "velocity is missing or not finite"))
            elif abs(_float(e[key])) > PLAUSIBLE_SPEED:
                problems.append(Problem(f"{where}.{key}", f"velocity {e[key]} is not a "
                                                          f"locomotion's (|value| > "
                                                          f"{PLAUSIBLE_SPEED:g})"))
        for failure in qc_failures(e["qc"], thresholds, e["qc_waived"]) if qc else ():
            problems.append(Problem(f"{where}.qc", f"{failure} (fix the capture, or waive it "
                                                   f"with a reason in qc_waived)"))
    return problems


def _fourier_problems(fourier: dict, where: str, n_dof: int, n_harm: int) -> list[Problem]:
    problems = []
    a, b = fourier["a"], fourier["b"]
    for key, rows in (("a", a), ("b", b)):
        if len(rows) != n_dof or any(len(row) != n_harm + 1 for row in rows):
            shape = (len(rows), sorted({len(row) for row in rows}))
            problems.append(Problem(f"{where}.{key}", f"coefficients must be {n_dof} rows of "
                                                      f"{n_harm + 1}, got {shape}"))
            return problems
        values = _matrix(rows)
        if not np.isfinite(values).all():
            problems.append(Problem(f"{where}.{key}", "coefficients contain null or non-finite "
                                                      "values"))
        elif np.abs(values).max(initial=0.0) > PLAUSIBLE_COEFFICIENT:
            problems.append(Problem(f"{where}.{key}", f"coefficients beyond "
                                                      f"±{PLAUSIBLE_COEFFICIENT:g} (rad or m) "
                                                      "are not a joint's"))
    if any(row[0] not in (0, 0.0) for row in b):
        problems.append(Problem(f"{where}.b", "b[:, 0] must be 0 (there is no sin(0) term)"))
    if fourier["n"] > n_harm:
        problems.append(Problem(f"{where}.n", f"fitted order {fourier['n']} exceeds the "
                                              f"library's n_harmonics {n_harm}"))
    return problems


def _control_space_problems(doc: dict) -> list[Problem]:
    scale = np.asarray(doc["control_space"]["scale"], dtype=np.float64)
    points = _control_points(doc["entries"])
    points = points[np.isfinite(points).all(axis=1)] / scale
    if len(points) < 4:
        return [Problem("control_space", f"{len(points)} entries with finite velocities; a 3-D "
                                         "control space needs at least 4")]
    centred = points - points.mean(axis=0)
    singular = np.linalg.svd(centred, compute_uv=False)
    # Normalised axes span about 1; a singular value below 1e-6 of the largest means the
    # points lie on a plane or a line (e.g. all v_l = 0) and Delaunay would be degenerate.
    rank = int((singular > 1e-6 * singular[0]).sum()) if singular[0] > 0 else 0
    if rank < 3:
        return [Problem("control_space", f"entries span only {rank} dimension(s) of "
                                         "(v, omega, v_l); add captures off that "
                                         f"{'plane' if rank == 2 else 'subspace'} "
                                         "(e.g. side-steps or turns)")]
    return []


# --------------------------------------------------------------------------- JSON text
def to_json_data(obj, digits: int = _SIGNIFICANT):
    """``obj`` as plain JSON values (:func:`mocaplib.io.jsonvalues.json_values`) with floats
    rounded to ``digits`` significant digits (10 by default); LibraryError for a value JSON
    cannot hold.
    """
    try:
        return json_values(obj, significant=digits)
    except TypeError as exc:
        raise LibraryError(f"cannot store in a library file: {exc}") from None


def json_text(obj) -> str:
    """Deterministic JSON text of ``obj`` (see :func:`to_json_data`), ending with a newline."""
    return _dump(to_json_data(obj)) + "\n"


def _dump(obj, level: int = 0) -> str:
    """JSON text with sorted keys; lists of scalars on one line, everything else indented."""
    pad, inner = "  " * level, "  " * (level + 1)
    if isinstance(obj, dict):
        if not obj:
            return "{}"
        items = [f"{inner}{json.dumps(k, ensure_ascii=False)}: {_dump(obj[k], level + 1)}"
                 for k in sorted(obj)]
        return "{\n" + ",\n".join(items) + "\n" + pad + "}"
    if isinstance(obj, list):
        if all(not isinstance(v, (dict, list)) for v in obj):
            return "[" + ", ".join(_dump(v) for v in obj) + "]"
        return "[\n" + ",\n".join(inner + _dump(v, level + 1) for v in obj) + "\n" + pad + "]"
    if isinstance(obj, float):
        return repr(obj)
    return json.dumps(obj, ensure_ascii=False)
