"""Tracking markers (clusters): synthetic cluster captures, calibration that measures their
offsets (never from a catalogue), and the whole chain from ``mocaplib synth`` to a library."""

from __future__ import annotations

import json

import numpy as np
import pytest

from mocaplib.model.calibration import calibrate
from mocaplib.cli import main
from mocaplib.model.ik import fit, fit_quality
from mocaplib.markersets.protocols import load_protocol
from mocaplib.markersets.matching import detect_protocol
from mocaplib.skeleton import DOF_NAMES
from mocaplib.synth.capture import synthesize_capture
from mocaplib.library.command import Command

SESSION = 2010
#: The motions compared: a straight walk, a curve and a side-step (speed m/s, radius m).
MOTIONS = {"straight": dict(speed=1.2), "curve": dict(speed=1.0, radius=2.0, side="left"),
           "sidestep": dict(speed=0.45, side="right")}


def _capture(protocol: str, kind: str):
    command = Command.from_kind(kind, **MOTIONS[kind])
    motion = synthesize_capture(command, duration=3.0, seed=7, protocol=protocol,
                                session_seed=SESSION)
    static = synthesize_capture(Command.from_kind("rest"), duration=2.0, seed=8,
                                protocol=protocol, session_seed=SESSION)
    return motion, static


def _angle_errors(motion, model, fitted) -> dict[str, float]:
    """RMS error (degrees) of each fitted rotation DOF against the generator's truth."""
    error = np.degrees(fitted.angles.to_numpy() - motion.truth["angles"]["values"])
    return {name: float(np.sqrt(np.mean(error[:, j] ** 2))) for j, name in enumerate(DOF_NAMES)
            if not name.startswith("pelvis_t") and name not in model.locked_dofs}


@pytest.fixture(scope="module")
def fits():
    """Per motion and static pose, for the anatomical and the cluster set: (marker RMS mm,
    {DOF: angle RMS error, degrees})."""
    out = {}
    for kind in MOTIONS:
        for protocol in ("fullbody38", "cluster_fullbody"):
            motion, static = _capture(protocol, kind)
            for pose in ("neutral", "free"):
                model = calibrate(motion.trial, static=static.trial, static_pose=pose)
                fitted = fit(motion.trial, model)
                out[kind, pose, protocol] = (fit_quality(fitted)["marker_rms_mm"],
                                             _angle_errors(motion, model, fitted))
    return out


def test_a_cluster_capture_has_rigid_plates_and_no_static_only_markers():
    motion, static = _capture("cluster_fullbody", "straight")
    protocol = load_protocol("cluster_fullbody")
    static_only = {m.label for m in protocol.markers if m.static_only}
    assert static_only <= set(static.trial.labels)
    assert static_only.isdisjoint(motion.trial.labels)
    X, labels = motion.trial.markers, motion.trial.labels
    for plate in (("LTH1", "LTH2", "LTH3"), ("RTB1", "RTB2", "RTB3"), ("LUA1", "LUA2", "LUA3")):
        i, j, k = (labels.index(x) for x in plate)
        for a, b in ((i, j), (j, k), (i, k)):
            d = np.linalg.norm(X[:, a] - X[:, b], axis=1)
            # a plate deforms by a fifth of a skin marker's artefact plus 0.7 mm noise
            assert 0.04 < d.mean() < 0.12 and d.std() < 0.003, (plate, d.mean(), d.std())
    # the protocol is recognised on the motion (no knee or ankle marker) and on the static
    assert detect_protocol(motion.trial).protocol.name == "cluster_fullbody"
    assert detect_protocol(static.trial).complete


def test_tracking_offsets_are_measured_on_the_static():
    motion, static = _capture("cluster_fullbody", "straight")
    model = calibrate(motion.trial, static=static.trial, static_pose="neutral")
    tracking = [m.label for m in model.protocol.markers if m.tracking]
    assert set(tracking) <= set(model.labels)
    offsets = dict(zip(model.labels, model.marker_offsets))
    # the thigh plate sits on the lateral thigh, in its middle third (no catalogue says so:
    # it is measured); the right one mirrors the left
    for side, sign in (("L", 1.0), ("R", -1.0)):
        centre = np.mean([offsets[f"{side}TH{k}"] for k in (1, 2, 3)], axis=0)
        assert 0.05 < sign * centre[1] < 0.15 and -0.30 < centre[2] < -0.15, centre


#: The cluster set's overall RMS on the free-pose straight walk, and its excess over the
#: anatomical set's (degrees), measured: the strict xfail's figures, bounded below.
FREE_STRAIGHT_MEASURED = (3.90, 2.51)


@pytest.mark.parametrize("pose, kind", [
    pytest.param(pose, kind, marks=pytest.mark.xfail(strict=True, reason=(
        "measured RMS over the DOFs 3.90° (cluster) vs 2.51° (anatomical set): the cluster "
        "set's largest errors are its elbows' flexion (10.0°, 7.9°; its epicondyle markers are "
        "on the static only)")) if (pose, kind) == ("free", "straight") else ())
    for pose in ("neutral", "free") for kind in MOTIONS])
def test_a_cluster_capture_fits_as_well_as_the_anatomical_set(fits, kind, pose):
    rms_cluster, _ = fits[kind, pose, "cluster_fullbody"]
    overall = _overall_rms(fits, kind, pose)
    assert rms_cluster <= 10.0, rms_cluster                      # marker RMS target, mm
    # within 1 degree RMS of the anatomical set's angles on the same motion
    assert overall["cluster"] <= overall["anatomical"] + 1.0, overall


def test_the_free_pose_cluster_walk_is_no_worse_than_measured(fits):
    overall = _overall_rms(fits, "straight", "free")
    cluster, anatomical = FREE_STRAIGHT_MEASURED
    assert overall["cluster"] <= cluster + 0.2, overall
    assert overall["cluster"] - overall["anatomical"] <= cluster - anatomical + 0.2, overall


def _overall_rms(fits, kind, pose) -> dict[str, float]:
    """RMS over the DOFs of the angle errors (degrees) of the cluster and anatomical sets."""
    return {name: float(np.sqrt(np.mean(np.square(list(fits[kind, pose, protocol][1].values())))))
            for name, protocol in (("cluster", "cluster_fullbody"), ("anatomical", "fullbody38"))}


def _worse_dofs(fits) -> dict[tuple[str, str, str], float]:
    """(motion, pose, DOF) -> how much worse (degrees) the cluster set fits that DOF than the
    anatomical set, for those more than 1 degree worse."""
    return {(kind, pose, dof): round(err - fits[kind, pose, "fullbody38"][1][dof], 2)
            for (kind, pose, protocol), (_, errors) in fits.items()
            if protocol == "cluster_fullbody" for dof, err in errors.items()
            if dof in fits[kind, pose, "fullbody38"][1]
            and err > fits[kind, pose, "fullbody38"][1][dof] + 1.0}


#: Measured: how many DOF fits of the cluster set (3 motions x 2 static poses) are more than
#: 1 degree worse than the anatomical set's, and the largest excess (degrees).
WORSE_COUNT, WORSE_MAX = 25, 8.93


@pytest.mark.xfail(strict=True, reason=(
    f"measured {WORSE_COUNT} DOF fits more than 1° worse, by {WORSE_MAX}° at most (the "
    "side-step's right elbow flexion, free pose): the arms' and ankles' frames rest on "
    "static-only landmarks"))
def test_every_dof_of_a_cluster_capture_within_1_degree_of_the_anatomical_set(fits):
    worse = _worse_dofs(fits)
    assert not worse, f"{len(worse)} DOF fits more than 1° worse: {worse}"


def test_the_cluster_dofs_worse_than_the_anatomical_set_are_no_more_than_measured(fits):
    worse = _worse_dofs(fits)
    assert len(worse) <= WORSE_COUNT, worse
    assert max(worse.values(), default=0.0) <= WORSE_MAX + 0.3, worse


#: RMS over the DOFs (degrees), cluster vs anatomical set, of the captures fitted without a
#: static: measured, the strict xfail's figures, bounded below.
WITHOUT_STATIC_MEASURED = {"straight": (7.3, 3.1), "curve": (7.0, 3.1),
                           "sidestep": (13.7, 5.0)}


@pytest.fixture(scope="module")
def fits_without_static():
    """Per motion and protocol: (marker RMS mm, RMS over the DOFs of the angle errors, deg,
    the calibrated model), calibrated on the motion itself."""
    out = {}
    for kind in MOTIONS:
        for protocol in ("fullbody38", "cluster_fullbody"):
            motion, _ = _capture(protocol, kind)
            model = calibrate(motion.trial)
            fitted = fit(motion.trial, model)
            errors = _angle_errors(motion, model, fitted)
            out[kind, protocol] = (fit_quality(fitted)["marker_rms_mm"],
                                   float(np.sqrt(np.mean(np.square(list(errors.values()))))),
                                   model)
    return out


@pytest.mark.parametrize("kind", [
    pytest.param(kind, marks=pytest.mark.xfail(strict=True, reason=(
        f"measured RMS over the DOFs {cluster}° vs {anatomical}° (cluster vs anatomical set) "
        "against the generator's independent body. The legs' flexion is within 2.9° on the "
        "walk and curve, 4.6° on the run (tests/test_cluster_without_static.py); the arms "
        "are not: elbow flexion 9-47° (the elbow turns 14-28°, its SCoRE centre 14-38 mm and SARA axis 15-20° off "
        "the epicondyles' on the walk, run and curve; under 15° no centre at all) and "
        "shoulder flexion and abduction up to 23°")))
    for kind, (cluster, anatomical) in WITHOUT_STATIC_MEASURED.items()])
def test_a_cluster_capture_without_static_fits_as_well_as_the_anatomical_set(
        fits_without_static, kind):
    # the knee centres are functional ones (SCoRE) from the thigh and shank clusters
    for protocol in ("fullbody38", "cluster_fullbody"):
        marker_rms, _, model = fits_without_static[kind, protocol]
        assert marker_rms <= 10.0
        if protocol == "cluster_fullbody":
            assert model.centre_methods["knee_l"].startswith("functional (SCoRE)")
    cluster, anatomical = (fits_without_static[kind, p][1]
                           for p in ("cluster_fullbody", "fullbody38"))
    assert cluster <= anatomical + 1.0, (cluster, anatomical)


@pytest.mark.parametrize("kind", sorted(WITHOUT_STATIC_MEASURED))
def test_a_cluster_capture_without_static_is_no_worse_than_measured(fits_without_static, kind):
    for protocol in ("fullbody38", "cluster_fullbody"):
        marker_rms, _, model = fits_without_static[kind, protocol]
        assert marker_rms <= 10.0, (protocol, marker_rms)
    cluster, anatomical = (fits_without_static[kind, p][1]
                           for p in ("cluster_fullbody", "fullbody38"))
    measured_cluster, measured_anatomical = WITHOUT_STATIC_MEASURED[kind]
    assert cluster <= measured_cluster + 0.5, cluster
    assert anatomical <= measured_anatomical + 0.3, anatomical


#: A small session of cluster captures: four distinct velocities (the least a control space
#: takes) and the static.
CLUSTER_PLAN = """name = "clusters"
[defaults]
protocol = "cluster_fullbody"
session_seed = 3
""" + "".join(f"""
[[capture]]
name = "{name}"
class = "{cls}"
command = {command}
duration = {duration}
seed = {seed}
""" for seed, (name, cls, command, duration) in enumerate([
    ("walk", "nonholonomic", '{ kind = "straight", speed = 1.2 }', 2.7),
    ("curve_left", "nonholonomic", '{ kind = "curve", speed = 1.0, radius = 2.0, side = "left" }',
     3.2),
    ("curve_right", "nonholonomic",
     '{ kind = "curve", speed = 1.0, radius = 2.0, side = "right" }', 3.2),
    ("side_left", "holonomic", '{ kind = "sidestep", speed = 0.45, side = "left" }', 3.6),
    ("rest", "rest", '{ kind = "rest" }', 2.0)], start=1))


def test_synth_to_library_with_clusters(tmp_path, capsys):
    plan = tmp_path / "cluster_plan.toml"
    plan.write_text(CLUSTER_PLAN)
    folder = tmp_path / "captures"
    assert main(["synth", str(plan), "-o", str(folder), "-q"]) == 0
    library = tmp_path / "lib.json"
    captures = [str(folder / f"{name}.c3d") for name in ("walk", "curve_left", "curve_right",
                                                           "side_left")]
    code = main(["build", *captures, "--static", str(folder / "rest.c3d"), "--static-pose",
                 "neutral", "-o", str(library), "--no-cache", "-q"])
    assert code == 0, capsys.readouterr()
    entries = json.loads(library.read_text())["entries"]
    assert len(entries) == 4
    for entry in entries:
        assert entry["qc"]["marker_rms_m"] <= 0.010, entry["qc"]
