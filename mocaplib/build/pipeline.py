"""The batch pipeline: from C3D captures to a motion library, in parallel, cached, resumable.

:func:`build_library` runs :func:`mocaplib.build.workflow.process_capture` over many captures — serially, in
worker processes (``jobs``, :mod:`mocaplib.build.workers`: a dead worker fails only its capture) or on
a Dask cluster (``scheduler``) — caches each capture's result (:mod:`mocaplib.build.cache`), and
assembles the :class:`~mocaplib.library.format.Library` and the per-capture diagnostics the HTML report
reads, written as one unit (see ``docs/library-format.md`` and ``docs/reliability.md``).
"""


from __future__ import annotations

import hashlib
import os
import sys
import time
from collections import Counter
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from ..errors import LibraryError, MocapError
from ..io import find_captures, fs_text, printable
from ..io.atomic import atomic_write_files
from ..library.document import DIAGNOSTICS_FORMAT
from ..library.format import Library, assemble_library, diagnostics_path, json_text, to_json_data
from ..library.validation import entry_problems
from ..statics import static_names
from .cache import cache_key, internal_result, read_cache, write_cache
from .dask_batches import run_on_dask
from .drafting import draft_missing_protocols
from .forward import forward_offsets
from .sessions import plan_captures
from .settings import BuildSettings
from .threads import pinned
from .workers import run_tasks
from .workflow import DIAGNOSTICS_DIGITS, CaptureResult, file_sha256, process_capture

DIAGNOSTICS_VERSION = 1


#: Seconds one capture may take in a worker process before the worker is ended and the
#: capture fails alone (``build_library(capture_timeout=...)``, ``--capture-timeout``): a lab walk
#: takes 0.3-1 s, a take of minutes some tens of seconds.
CAPTURE_TIMEOUT_S = 600.0


# --------------------------------------------------------------------------- many captures
@dataclass
class BuildResult:
    """A finished build: the library, every capture's result (input order) and a summary;
    ``notes`` are the build's own warnings (e.g. a cache it could not write), ``unlisted``
    the input folders it could not list (:func:`mocaplib.io.unlisted_folder`): their captures
    are missing, so the build is not :attr:`ok`."""

    library: Library
    captures: list[CaptureResult]
    settings: BuildSettings
    seconds: float = 0.0
    notes: list = field(default_factory=list)
    unlisted: list = field(default_factory=list)

    @property
    def failures(self) -> list[CaptureResult]:
        return [c for c in self.captures if not c.ok]

    @property
    def ok(self) -> bool:
        return not self.failures and not self.unlisted

    def summary(self) -> dict:
        """Counts, failures (file, stage, reason) and warnings, as JSON data."""
        return {
            "captures": len(self.captures),
            "succeeded": sum(c.ok for c in self.captures),
            "failed": len(self.failures),
            "from_cache": sum(c.from_cache for c in self.captures),
            "cycles": sum(c.n_cycles for c in self.captures),
            "entries": len(self.library),
            "seconds": round(self.seconds, 3),
            "failures": [{"file": c.source, "stage": c.stage, "reason": c.error}
                         for c in self.failures],
            "no_entry": [{"file": c.source, "reason": c.no_entry} for c in self.captures
                         if c.no_entry],
            "warnings": [{"file": c.source, "warning": w} for c in self.captures
                         for w in c.warnings],
            "statics": dict(Counter(c.static for c in self.captures if c.static)),
            "notes": list(self.notes),
            "unlisted": list(self.unlisted),
        }

    def summary_text(self) -> str:
        """The summary as a short table for people, a line per record (file names and
        messages with their control characters, line feeds included, escaped)."""
        s = self.summary()
        lines = [f"captures {s['captures']}  ok {s['succeeded']}  failed {s['failed']}  "
                 f"cached {s['from_cache']}  cycles {s['cycles']}  entries {s['entries']}  "
                 f"({s['seconds']:.1f} s)"]

        names = static_names(self.settings.statics)
        if len(names) > 1:
            lines.append("captures per static: " + ", ".join(
                f"{name} {s['statics'].get(name, 0)}" for name in names))
        if self.settings.forward_reference is not None:
            lines.append("heading turned by the forward reference: " + ", ".join(
                f"{name} {np.rad2deg(offset):+.3f}°"
                for name, offset in zip(names, self.settings.heading_offsets)))
        if s["failures"]:
            lines.append("failures:")
            lines += [f"  {f['file']} [{f['stage']}]: "
                      f"{(f['reason'] or '').removeprefix(f['file'] + ': ')}"
                      for f in s["failures"]]
        if s["no_entry"]:
            lines.append("no entry:")
            lines += [f"  {Path(n['file']).name}: {n['reason']}" for n in s["no_entry"]]
        lines += [f"note: {note}" for note in s["notes"]]
        if s["unlisted"]:
            lines.append(f"folders not searched ({len(s['unlisted'])}):")
            lines += [f"  {folder}" for folder in s["unlisted"]]
        if s["warnings"]:
            lines.append(f"warnings ({len(s['warnings'])}):")
            lines += [f"  {Path(w['file']).name}: {w['warning']}" for w in s["warnings"]]
        return "\n".join(printable(line, keep="") for line in lines)

    def diagnostics(self, library_name: str = "library.json", *,
                    library_sha256: str | None = None) -> dict:
        """The diagnostics sidecar's content (see ``docs/library-format.md``);
        ``library_sha256``: the SHA-256 of the library file's bytes it belongs to."""
        records = []
        for c in self.captures:
            record = {key: None for key in ("rate_hz",)}
            record.update({"time_s": [], "shoulder_mid_xy": [], "frame_rms_m": [],
                           "events": [], "cycles": [], "angles": {}, "poulaine": None})
            record.update(c.diagnostics)
            record.update({"source": c.file, "ok": c.ok, "error": c.error, "stage": c.stage,
                           "static": c.static, "no_entry": c.no_entry,
                           "warnings": list(c.warnings)})
            records.append(record)
        return to_json_data({"format": DIAGNOSTICS_FORMAT, "version": DIAGNOSTICS_VERSION,
                             "library": library_name, "library_sha256": library_sha256,
                             "captures": records}, DIAGNOSTICS_DIGITS)

    def write(self, path: str | os.PathLike) -> tuple[Path, Path]:
        """Write the library and ``<stem>.diagnostics.json`` beside it, as one unit: both are
        written to temporaries first (a full disk or an error leaves both old files as they
        were), then the library is renamed into place and the sidecar last. The sidecar names
        the SHA-256 of the library's bytes, so a reader tells a sidecar left from an earlier
        build (a kill between the two renames) from the library's own and does not use it
        (see ``docs/reliability.md``).

        Raises :class:`LibraryError` and writes nothing when the library has no entry (every
        capture failed, or no cycle was kept): an empty library never replaces one. Entries
        the library's validation refuses are left out when it is assembled
        (:func:`valid_library`).
        """
        path = Path(path)
        if not len(self.library):
            why = ("every capture failed" if not any(c.ok for c in self.captures) else
                   "no capture gave a library entry (see the warnings)")
            raise LibraryError(f"nothing written: {why}", path=path,
                               hint="fix what the summary names and build again; a library "
                                    "already there is left as it was")
        sidecar = diagnostics_path(path)
        library = self.library.to_json().encode("utf-8")
        diagnostics = self.diagnostics(path.name,
                                       library_sha256=hashlib.sha256(library).hexdigest())
        atomic_write_files([(path, library), (sidecar, json_text(diagnostics).encode("utf-8"))])
        return path, sidecar


def build_library(inputs: Iterable[str | os.PathLike], settings: BuildSettings | None = None, *,
          jobs: int = 1, scheduler: str | None = None, cache_dir: str | os.PathLike | None = None,
          progress: bool = True,
          process: Callable[[str, BuildSettings], CaptureResult] | None = None,
          capture_timeout: float | None = CAPTURE_TIMEOUT_S,
          drafts_dir: str | os.PathLike | None = None,
          batch_size: int | None = None) -> BuildResult:
    """Process every capture and assemble the library.

    Parameters
    ----------
    inputs
        C3D files and folders (searched recursively for ``*.c3d``).
    settings
        :class:`BuildSettings` (defaults when None). Each capture is processed with the
        settings :func:`mocaplib.build.sessions.plan_captures` gives it: a ``session.toml``'s beside
        it, or these with the standing files among the captures added to the statics.
        Forward references are measured first (:func:`forward_offsets`; its CalibrationError
        is raised, nothing is processed).
    jobs
        Worker processes (1 = in this process).
    scheduler
        Address of a Dask distributed scheduler (``tcp://host:8786``); needs the optional
        extra ``mocaplib[dask]``. Overrides ``jobs``. The captures go in batches, several
        to a task (:mod:`mocaplib.build.dask_batches`).
    cache_dir
        Folder of cached per-capture results (JSON); None disables the cache.
    progress
        Show a progress bar with ETA on stderr.
    process
        The per-capture function, :func:`process_capture` by default (any pure, picklable
        function of ``(path, settings)`` returning a :class:`CaptureResult`).
    capture_timeout
        Seconds a capture may run in a worker process (``jobs`` > 1) before the worker is
        ended and the capture fails alone (stage ``worker``); None: no limit. Captures run in
        this process (``jobs=1``) or on a Dask cluster have no limit.
    drafts_dir
        Folder to draft protocols into for the captures no protocol serves
        (:mod:`mocaplib.build.drafting`; the library's settings list them as
        ``drafted_protocols``); None: such captures fail at their protocol.
    batch_size
        Captures per Dask task (``scheduler`` only); None: chosen from the captures' frame
        counts, about :data:`mocaplib.build.dask_batches.TASK_FRAMES` frames a task.

    Returns
    -------
    BuildResult
        Captures that failed are in it, not raised, and so are the folders that could not be
        listed (``unlisted``; the others are searched). A capture whose worker process dies is
        run once more in a new worker, then fails alone (stage ``worker``); no worker outlives
        the build (:mod:`mocaplib.build.workers`). At most :func:`mocaplib.build.workers.max_jobs` worker
        processes are started.
    """
    from tqdm import tqdm

    settings = settings or BuildSettings()
    process = process or process_capture
    if jobs < 1:
        raise MocapError(f"jobs must be >= 1, got {jobs}")
    started = time.perf_counter()
    unlisted: list[MocapError] = []
    paths = find_captures(inputs, unlisted=unlisted)
    if not paths:
        raise MocapError("no C3D captures found in the inputs" + "".join(
                         f"; {folder}" for folder in unlisted),
                         hint="give .c3d files or folders that contain some")
    pool, planned = plan_captures(paths, settings)
    if settings.require_static and not any(p.statics for p in planned):
        raise MocapError("the build requires a static (require_static) but none is given or "
                         "found among the captures",
                         hint="give the statics with --static or a session.toml beside the "
                              "captures, or leave --require-static out")
    if pool.forward_reference is not None and pool.heading_offsets is None:
        offsets = pinned(forward_offsets, pool)
        planned = [replace(p, heading_offsets=offsets) if p is pool else p for p in planned]
        pool = replace(pool, heading_offsets=offsets)
    notes: list[str] = []
    drafted: dict[str, str] = {}
    if drafts_dir is not None:
        planned, notes, drafted = draft_missing_protocols(paths, planned, drafts_dir)
    results: dict[int, CaptureResult] = {}
    cache = None if cache_dir is None else Path(cache_dir)
    for i, path in enumerate(paths):
        if cache is not None:
            try:
                sha256 = file_sha256(path)
            except OSError:
                continue  # unreadable: its processing fails and says why
            cached, why = read_cache(cache, cache_key(path, sha256, planned[i]), sha256)
            if cached is not None:
                cached.source = os.fspath(path)
                results[i] = cached
            elif why is not None:
                notes.append(f"{fs_text(path.name)}: its cached result was not used ({why}): "
                             "processed again")
    todo = [i for i in range(len(paths)) if i not in results]
    cache_failed = False
    with tqdm(total=len(paths), initial=len(results), desc="build", unit="capture",
              disable=not progress, file=sys.stderr, dynamic_ncols=True) as bar:
        for i, result in _run(process, [(i, paths[i], planned[i]) for i in todo], jobs,
                              scheduler, capture_timeout, batch_size):
            results[i] = result
            if cache is not None and result.sha256 and not internal_result(result) \
                    and not cache_failed:
                try:  # keyed by the content the worker read (a file changed meanwhile: its own)
                    write_cache(cache, cache_key(paths[i], result.sha256, planned[i]), result)
                except MocapError as exc:  # the build goes on, uncached
                    notes.append(f"results not cached: {exc}")
                    cache_failed = True
            bar.update(1)
    captures = [results[i] for i in range(len(paths))]
    _unique_entry_ids(captures)
    library = valid_library(captures, settings={**pool.to_dict(), **(
        {"drafted_protocols": drafted} if drafted else {}), "captures": [
            {"file": c.file, **c.provenance} for c in captures if c.provenance]},
        qc_thresholds=pool.qc_thresholds)
    return BuildResult(library, captures, pool, time.perf_counter() - started, notes,
                       [str(folder) for folder in unlisted])


def valid_library(captures: list[CaptureResult], /, *, settings: dict,
                  qc_thresholds: dict) -> Library:
    """The library of the captures' entries (:func:`~mocaplib.library.format.assemble_library`)
    that its own validation accepts: an entry :func:`mocaplib.library.validation.validate_library`
    refuses (with ``--all-cycles --qc waive``, a cycle whose mean angle leaves its range) is
    left out, with a warning on its capture naming the cycle and why, and the library is
    assembled again without it (its header depends on the entries)."""
    while True:
        library = assemble_library([e for c in captures for e in c.entries], settings=settings,
                                   qc_thresholds=qc_thresholds)
        refused = entry_problems(library)
        if not refused:
            return library
        for c in captures:
            for e in (e for e in c.entries if e.id in refused):
                c.warnings.append(f"cycle {e.cycle_index} ({e.start_s:.2f}-{e.end_s:.2f} s) "
                                  f"left out: the library's validation refuses it: " + "; ".join(
                                      f"{p.where}: {p.message}" for p in refused[e.id]))
            c.entries = [e for e in c.entries if e.id not in refused]
            for cycle in c.diagnostics.get("cycles", []) + c.diagnostics.get("mirror_cycles", []):
                if cycle.get("entry_id") in refused:
                    cycle["entry_id"] = None


def build_inputs(captures: Iterable[str | os.PathLike], settings: BuildSettings) -> list[Path]:
    """Every file a build of ``captures`` reads, and the files beside them an output must not
    replace: the captures, their truth sidecars (``<stem>.truth.json``, written by ``mocaplib
    synth`` beside its captures) that exist, the statics and the forward references."""
    files = [Path(c) for c in captures]
    files += [t for c in files if (t := c.with_name(f"{c.stem}.truth.json")).is_file()]
    return files + [Path(f) for f in (*settings.statics, *settings.forward_references)]


def _run(process, work: list[tuple[int, Path, BuildSettings]], jobs: int,
         scheduler: str | None, timeout: float | None, batch_size: int | None):
    """Yield ``(index, CaptureResult)`` as captures finish (in any order), each work item
    ``(index, path, its settings)`` run by :func:`mocaplib.build.workers.run_tasks` (at most
    ``timeout`` s in a worker) or on a Dask cluster, in batches
    (:func:`mocaplib.build.dask_batches.run_on_dask`)."""
    if not work:
        return
    if scheduler is not None:
        outcomes = run_on_dask(process, work, scheduler, batch_size=batch_size)
    else:
        tasks = [(os.fspath(path), settings) for _, path, settings in work]
        outcomes = ((work[k][0], result, error) for k, result, error
                    in run_tasks(process, tasks, jobs=jobs, timeout=timeout))
    paths = {index: path for index, path, _ in work}
    for index, result, error in outcomes:
        yield index, result if error is None else _worker_failure(paths[index], error)


def _worker_failure(path, error: BaseException) -> CaptureResult:
    """The result of a capture whose processing raised or whose worker died: it fails alone."""
    source = os.fspath(path)
    return CaptureResult(source=source, ok=False, stage="worker",
                         error=f"{source}: worker failed: {type(error).__name__}: {error}")


def _unique_entry_ids(captures: list[CaptureResult]) -> None:
    """Make entry ids unique when captures share a file name (append the SHA-256 prefix).

    A byte-identical copy of an earlier capture adds nothing: its entries are dropped with a
    warning.
    """
    first_with_content: dict[str, str] = {}
    names: dict[str, set[str]] = {}
    for c in captures:
        if c.entries and c.sha256 in first_with_content:
            c.warnings.append(f"same content as {first_with_content[c.sha256]}: "
                              "its cycles are not added twice")
            c.entries = []
            for cycle in c.diagnostics.get("cycles", []) + c.diagnostics.get("mirror_cycles", []):
                cycle["entry_id"] = None
        elif c.entries:
            first_with_content[c.sha256] = c.source
        for e in c.entries:
            names.setdefault(e.id, set()).add(c.sha256)
    for c in captures:
        renamed = {e.id: f"{e.id}@{c.sha256[:8]}" for e in c.entries if len(names[e.id]) > 1}
        c.entries = [replace(e, id=renamed.get(e.id, e.id),
                             mirror_of=renamed.get(e.mirror_of, e.mirror_of))
                     for e in c.entries]
        for cycle in c.diagnostics.get("cycles", []) + c.diagnostics.get("mirror_cycles", []):
            cycle["entry_id"] = renamed.get(cycle.get("entry_id"), cycle.get("entry_id"))
