"""The report viewer's poses of library entries, computed by its own JavaScript (node on
templates/motion.js, ``plantedPose``) as the page shows them, for tests and benchmarks to
measure in Python."""

from __future__ import annotations

import json
import shutil
import subprocess
from pathlib import Path

import numpy as np

from mocaplib.gait.fourier import RootDrift, synthesize
from mocaplib.library.controlspace import ControlSpace
from mocaplib.library.planting import (ContactMeasures, PlantedSeries, contact_measures,
                                       planted_series, stance_frames)
from mocaplib.report.figureview import skeleton_data, viewer_cycles, viewer_data

NODE = shutil.which("node")
MOTION_JS = Path(__file__).parents[1] / "mocaplib" / "report" / "templates" / "motion.js"
_SCRIPT = ("const M = require(process.argv[1]);"
           "const job = JSON.parse(require('fs').readFileSync(0, 'utf8'));"
           "process.stdout.write(JSON.stringify(job.entries.map((e) => "
           "e.times.map((t) => M.plantedPose(job.skeleton, e, t)))));")


def viewer_poses(skeleton, entries: list[dict]) -> list[np.ndarray]:
    """Poses (F, D) the viewer shows for each entry ``{a, b, T, drift, locks, times}`` (the
    page's data, times in [0, T) s) on ``skeleton``, computed by node."""
    job = {"skeleton": skeleton_data(skeleton), "entries": entries}
    done = subprocess.run([NODE, "-e", _SCRIPT, str(MOTION_JS)], input=json.dumps(job),
                          capture_output=True, text=True, timeout=600, check=True)
    return [np.array(q) for q in json.loads(done.stdout)]


#: node: the page's blend at each command (figure.js ``pick``: ``weigh``, ``blend``, its locks
#: by ``findLocks``), null where no gait cell holds it.
_BLEND_SCRIPT = (
    "const M = require(process.argv[1]);"
    "const job = JSON.parse(require('fs').readFileSync(0, 'utf8'));"
    "process.stdout.write(JSON.stringify(job.commands.map((c) => {"
    "  const found = M.weigh(job.space, c); if (found.simplex < 0) { return null; }"
    "  const b = M.blend(found.corners.map((i) => job.entries[job.space.entries[i]]),"
    "                    found.weights);"
    "  b.locks = M.findLocks(job.skeleton, b);"
    "  return b; })));")


def cell_centroids(library, every: int = 2) -> np.ndarray:
    """The centroids (C, 3), SI, of every ``every``-th tetrahedron of each gait cell of the
    library's control space: commands spread over where the viewer blends."""
    cs = ControlSpace.from_library(library)
    return np.array([cs.points[simplex].mean(axis=0) for cell in cs.cells.values()
                     for simplex in cell.tri.simplices[::every]])


def viewer_blends(library, commands, rate: float = 100.0) -> list[dict | None]:
    """The report viewer's blend at each SI command (v̂, ω̂, v̂_l) of the library's control
    space, as the page picks it, computed by node: ``a``, ``b`` (D, N+1), ``T`` (s), ``drift``,
    ``locks`` (L, 6) found on it in JavaScript, ``times`` (3F,) s from one cycle before to
    one after and ``world`` (3F, D) its poses there in the world (:func:`viewer_poses`),
    ``contact`` (:class:`ContactMeasures` over its middle cycle, its stances whole) and
    ``alone`` (the same of its series posed without locks); None where no gait cell holds the
    command."""
    cs = ControlSpace.from_library(library)
    classes = [e.locomotion_class or "unknown" for e in library.entries]
    page = viewer_data(library, cs, classes, {})
    job = {"skeleton": page["skeleton"], "entries": page["entries"], "space": page["space"],
           "commands": np.asarray(commands, dtype=float).tolist()}
    done = subprocess.run([NODE, "-e", _BLEND_SCRIPT, str(MOTION_JS)], input=json.dumps(job),
                          capture_output=True, text=True, timeout=600, check=True)
    blends = json.loads(done.stdout)
    found = [b for b in blends if b is not None]
    for b in found:
        b["times"] = _three_cycles(b["T"], rate)
    posed = iter(viewer_poses(library.skeleton, [
        {**b, "times": np.mod(b["times"], b["T"]).tolist()} for b in found]))
    out = []
    for b in blends:
        if b is None:
            out.append(None)
            continue
        blend = {"a": np.array(b["a"]), "b": np.array(b["b"]), "T": b["T"],
                 "drift": np.array(b["drift"]), "times": b["times"],
                 "locks": np.array(b["locks"], dtype=float).reshape(-1, 6)}
        drift, t = RootDrift(0.0, 0.0, 0.0, *blend["drift"]), blend["times"]
        blend["world"], blend["contact"] = _contact(library.skeleton, drift, next(posed), t, rate)
        series = synthesize(blend["a"], blend["b"], blend["T"], np.mod(t, blend["T"]))
        blend["alone"] = _contact(library.skeleton, drift, series, t, rate)[1]
        out.append(blend)
    return out


def _three_cycles(period: float, rate: float) -> np.ndarray:
    """Times (3F,) s at ``rate`` Hz from one cycle of ``period`` s before the cycle (F whole
    samples) to one after it."""
    frames = round(period * rate)
    return np.arange(-frames, 2 * frames) / rate


def _contact(skeleton, drift: RootDrift, q: np.ndarray, t: np.ndarray, rate: float
             ) -> tuple[np.ndarray, ContactMeasures]:
    """Poses ``q`` (3F, D) in the path frame at times ``t`` (3F,) s, from one cycle before to
    one after, moved along ``drift`` into the world, and their :class:`ContactMeasures` over
    the middle cycle at ``rate`` Hz (its stances whole)."""
    world = drift.restore(q, t)
    frames = len(t) // 3
    return world, contact_measures(skeleton, world, rate, stance_frames(skeleton, world, rate),
                                   window=(frames, 2 * frames))


def viewer_contact(library, rate: float = 100.0
                   ) -> list[tuple[str, ContactMeasures, PlantedSeries]]:
    """Each entry with a finite drift and its feet as the viewer poses its planted series (its
    cycle on the library's body, :func:`~mocaplib.report.figureview.viewer_cycles`, planted:
    :func:`~mocaplib.library.planting.planted_series`) at ``rate`` Hz, over one cycle, its
    stances whole (one cycle more on each side): ``(id, ContactMeasures, the series)``."""
    jobs, padded = [], []
    for e, (a, b, period, velocities) in zip(library.entries, viewer_cycles(library)):
        if not np.isfinite(velocities).all():
            continue
        drift = RootDrift(0.0, 0.0, 0.0, *velocities)
        series = planted_series(library.skeleton, a, b, period, drift)
        t = _three_cycles(period, rate)
        jobs.append({"a": series.a.tolist(), "b": series.b.tolist(), "T": period,
                     "drift": velocities.tolist(), "locks": series.locks.tolist(),
                     "times": np.mod(t, period).tolist()})
        padded.append((e.id, drift, t, series))
    return [(entry, _contact(library.skeleton, drift, q, t, rate)[1], series)
            for (entry, drift, t, series), q in zip(padded, viewer_poses(library.skeleton, jobs))]
