"""The report viewer's poses of library entries, computed by its own JavaScript (node on
templates/motion.js, ``plantedPose``) as the page shows them, for tests and benchmarks to
measure in Python."""

from __future__ import annotations

import json
import shutil
import subprocess
from pathlib import Path

import numpy as np

from mocaplib.gait.fourier import RootDrift
from mocaplib.library.planting import (ContactMeasures, PlantedSeries, contact_measures,
                                       planted_series, stance_frames)
from mocaplib.report.figureview import skeleton_data, viewer_cycles

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
        frames = round(period * rate)
        t = np.arange(-frames, 2 * frames) / rate
        jobs.append({"a": series.a.tolist(), "b": series.b.tolist(), "T": period,
                     "drift": velocities.tolist(), "locks": series.locks.tolist(),
                     "times": np.mod(t, period).tolist()})
        padded.append((e.id, drift, t, (frames, 2 * frames), series))
    out = []
    for (entry, drift, t, window, series), q in zip(padded,
                                                    viewer_poses(library.skeleton, jobs)):
        world = drift.restore(q, t)
        stance = stance_frames(library.skeleton, world, rate)
        out.append((entry, contact_measures(library.skeleton, world, rate, stance,
                                            window=window), series))
    return out
