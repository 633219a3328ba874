"""OpenSim 4.6's tools as the benchmarks run them: ScaleTool, InverseKinematicsTool, .mot files.

Imported by ``ik_vs_opensim.py`` and ``end_to_end.py``; run as a script it does one job in a
fresh process, as a user would: ``python benchmarks/opensim_tools.py JOB.json`` scales the
generic model to a static trial (when the job names one) and solves the motion's inverse
kinematics (:func:`run_job`). Needs the bench extra (``pip install ".[bench]"``: opensim).
"""

from __future__ import annotations

import contextlib
import json
import os
import sys
import time
from pathlib import Path

import numpy as np

#: OpenSim's IK stops when its optimizer's relative tolerance reaches this (its default).
ACCURACY = 1e-5


def _opensim():
    import opensim

    opensim.Logger.setLevelString("error")
    opensim.Logger.removeFileSink()              # no opensim.log in the working folder
    return opensim


@contextlib.contextmanager
def quiet_stdout():
    """Silence writes to file descriptor 1 (OpenSim's C++ side prints there)."""
    sys.stdout.flush()
    saved = os.dup(1)
    with open(os.devnull, "w") as null:
        os.dup2(null.fileno(), 1)
        try:
            yield
        finally:
            os.dup2(saved, 1)
            os.close(saved)


def _add_marker_tasks(task_set, labels, weights) -> None:
    opensim = _opensim()
    for label, weight in zip(labels, weights):
        task = opensim.IKMarkerTask()
        task.setName(label)
        task.setWeight(float(weight))
        task.setApply(True)
        task_set.cloneAndAppend(task)


def inverse_kinematics(osim_path: Path, trc_path: Path, labels, weights, t_end: float,
                       out: Path, *, accuracy: float = ACCURACY) -> None:
    """OpenSim's InverseKinematicsTool on the model and markers: one task per marker with its
    weight, coordinates clamped to their ranges, from 0 to ``t_end`` s; writes ``out`` (.mot)."""
    opensim = _opensim()
    model = opensim.Model(str(osim_path))        # referenced here while the tool runs
    tool = opensim.InverseKinematicsTool()
    tool.setModel(model)
    tool.setMarkerDataFileName(str(trc_path))
    tool.setStartTime(0.0)
    tool.setEndTime(t_end)
    tool.set_accuracy(accuracy)
    tool.set_report_errors(False)
    tool.setOutputMotionFileName(str(out))
    _add_marker_tasks(tool.getIKTaskSet(), labels, weights)
    with quiet_stdout():                         # the tool prints the whole model summary
        tool.run()


def scale_model(generic: Path, static_trc: Path, labels, weights, pairs: dict, segments,
                t_end: float, height: float, out: Path) -> None:
    """OpenSim's ScaleTool: each body scaled by the distances of the marker ``pairs`` on it in
    the static trial against the generic model ({body: [(label, label), ...]}; bodies without
    pairs by all the pairs), then the markers placed on the static pose (MarkerPlacer, its IK
    weighted as the fit is); writes the scaled model with its markers to ``out``."""
    opensim = _opensim()
    tool = opensim.ScaleTool()
    tool.setSubjectMass(70.0)
    tool.setSubjectHeight(1000.0 * height)
    tool.getGenericModelMaker().setModelFileName(str(generic))
    scaler = tool.getModelScaler()
    scaler.setApply(True)
    scaler.setScalingOrder(_strings(["measurements"]))
    scaler.setMarkerFileName(str(static_trc))
    scaler.setTimeRange(_doubles([0.0, t_end]))
    scaler.setPreserveMassDist(False)
    measurements = scaler.getMeasurementSet()
    every = [pair for body_pairs in pairs.values() for pair in body_pairs]
    rest = [name for name in segments if name not in pairs]
    for name, body_pairs, bodies in [*((n, p, [n]) for n, p in pairs.items()),
                                     *([("others", every, rest)] if rest and every else [])]:
        measurement = opensim.Measurement()
        measurement.setName(name)
        measurement.setApply(True)
        for a, b in body_pairs:
            measurement.getMarkerPairSet().cloneAndAppend(opensim.MarkerPair(a, b))
        for body in bodies:
            scale = opensim.BodyScale()
            scale.setName(body)
            scale.setAxisNames(_strings(["X", "Y", "Z"]))
            measurement.getBodyScaleSet().cloneAndAppend(scale)
        measurements.cloneAndAppend(measurement)
    placer = tool.getMarkerPlacer()
    placer.setApply(True)
    placer.setStaticPoseFileName(str(static_trc))
    placer.setTimeRange(_doubles([0.0, t_end]))
    placer.setMoveModelMarkers(True)
    _add_marker_tasks(placer.getIKTaskSet(), labels, weights)
    placer.setOutputModelFileName(str(out))
    with quiet_stdout():
        if not tool.run():
            raise RuntimeError(f"OpenSim's ScaleTool failed on {static_trc}")


def _strings(items):
    array = _opensim().ArrayStr()
    for item in items:
        array.append(item)
    return array


def _doubles(items):
    array = _opensim().ArrayDouble()
    for item in items:
        array.append(float(item))
    return array


def read_mot(path: Path, names: list[str], rotations: list[int]) -> np.ndarray:
    """Coordinates (F, len(names)) in radians/metres from an OpenSim .mot, columns ``names``
    (degrees of the ``rotations`` columns converted)."""
    lines = Path(path).read_text().splitlines()
    end = next(i for i, line in enumerate(lines) if line.strip().lower() == "endheader")
    degrees = any(line.strip().lower() == "indegrees=yes" for line in lines[:end])
    header = lines[end + 1].split("\t")
    data = np.array([[float(v) for v in line.split("\t")] for line in lines[end + 2:] if line])
    q = np.column_stack([data[:, header.index(name)] for name in names])
    if degrees:
        q[:, rotations] = np.radians(q[:, rotations])
    return q


def run_job(job: dict) -> dict:
    """One capture the way OpenSim users process it: ScaleTool on the static (when ``job``
    names one: ``generic``, ``static``, ``static_end``, ``pairs``, ``segments``, ``height``),
    else the given ``model``; then IK on ``motion`` up to ``motion_end`` s with the markers
    ``labels`` weighted by ``weights``, written to ``mot``. Returns the seconds of each step."""
    seconds = {}
    model = job.get("model")
    if job.get("static"):
        model = str(Path(job["mot"]).with_name("scaled.osim"))
        start = time.perf_counter()
        scale_model(job["generic"], job["static"], job["labels"], job["weights"], job["pairs"],
                    job["segments"], job["static_end"], job["height"], model)
        seconds["scale"] = time.perf_counter() - start
    start = time.perf_counter()
    inverse_kinematics(model, job["motion"], job["labels"], job["weights"], job["motion_end"],
                       job["mot"])
    seconds["ik"] = time.perf_counter() - start
    return seconds


if __name__ == "__main__":
    print(json.dumps(run_job(json.loads(Path(sys.argv[1]).read_text()))))
