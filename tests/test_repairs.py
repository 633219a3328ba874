"""Labelling errors the fit undoes: two labels exchanged for the whole capture or a stretch of
it (any two markers: left/right, front/back, neighbours on one segment), a marker far from its
place; on synthetic and real captures, each repair reported."""

from __future__ import annotations

import json
from dataclasses import replace

import pytest

from mocaplib.cli import main
from mocaplib.model.ik import fit_quality
from mocaplib.model.fitting import fit_capture
from mocaplib.io.c3d import read_c3d
from mocaplib.io.c3d_write import write_c3d
from mocaplib.synth.capture import synthesize_capture
from mocaplib.library.command import Command


def swapped(trial, a: str, b: str, frames: slice = slice(None)):
    """``trial`` with the data of labels ``a`` and ``b`` exchanged in ``frames``."""
    markers = trial.markers.copy()
    i, j = trial.labels.index(a), trial.labels.index(b)
    markers[frames, [i, j]] = trial.markers[frames, [j, i]]
    return replace(trial, markers=markers, warnings=list(trial.warnings))


def _rms_and_repairs(trial, **options):
    motion = fit_capture(trial, **options).motion
    quality = fit_quality(motion)
    return quality["marker_rms_mm"], quality["repairs"]


@pytest.fixture(scope="module")
def cluster_session():
    walk = synthesize_capture(Command.from_kind("straight", speed=1.2), duration=3.0, seed=4,
                              protocol="cluster_fullbody", session_seed=9)
    rest = synthesize_capture(Command.from_kind("rest"), duration=2.0, seed=5,
                              protocol="cluster_fullbody", session_seed=9)
    return walk.trial, rest.trial


@pytest.mark.parametrize("a, b, frames", [
    ("LTH1", "LTH2", slice(None)),               # neighbours on one cluster, whole capture
    ("RFHD", "LBHD", slice(100, 200)),           # front and back of the head, 1 s
    ("LHEE", "RHEE", slice(150, 250)),           # left and right heels, 1 s
    ("LUA3", "LFA1", slice(None)),               # two segments' clusters, whole capture
])
def test_synthetic_swaps_are_undone(cluster_session, a, b, frames):
    walk, rest = cluster_session
    reference, none = _rms_and_repairs(walk, static=rest, static_pose="neutral")
    assert none == []                              # nothing to repair in a clean capture
    rms, repairs = _rms_and_repairs(swapped(walk, a, b, frames), static=rest,
                                    static_pose="neutral")
    assert abs(rms - reference) <= 1.0, (rms, reference)           # the target
    (repair,) = repairs
    first, last = frames.indices(walk.n_frames)[:2]
    assert repair["kind"] == "swap" and set(repair["markers"]) == {a, b}
    # the stretch found is the one exchanged (its first and last frame within 2 frames)
    assert abs(repair["frames"][0] - first) <= 2 and abs(repair["frames"][1] - (last - 1)) <= 2
    assert "mm from its model place" in repair["evidence"]


def test_a_swap_in_the_calibration_trial_itself_is_undone(cluster_session):
    walk, _ = cluster_session
    reference, _ = _rms_and_repairs(walk)
    rms, repairs = _rms_and_repairs(swapped(walk, "LASI", "RPSI"))
    assert abs(rms - reference) <= 1.0 and [set(r["markers"]) for r in repairs] == [
        {"LASI", "RPSI"}]


@pytest.mark.parametrize("name, a, b, frames", [
    ("btkdata/PiG_Motion-FlatFoot-Full.c3d", "RFHD", "LBHD", slice(100, 200)),
    ("ezc3d_testfiles/Qualisys.c3d", "L_FLE", "L_FAX", slice(None)),
    ("cmu/07_01.c3d", "LKNE", "RKNE", slice(120, 240)),
])
def test_real_captures_with_swapped_labels_are_repaired(real_c3d, name, a, b, frames):
    trial = read_c3d(real_c3d(name))
    spelt = {label: trial.labels[i] for i, label in enumerate(trial.names)}   # liu:LKNE
    reference, before = _rms_and_repairs(trial)
    rms, repairs = _rms_and_repairs(swapped(trial, spelt.get(a, a), spelt.get(b, b), frames))
    assert abs(rms - reference) <= 1.0, (rms, reference)
    found = [r for r in repairs if r not in before]
    assert [set(r["markers"]) for r in found] == [{a, b}], repairs     # protocol labels


def test_walking3_swapped_acromions_are_undone_with_its_static(real_c3d):
    # SOURCES.md: Walking3 labels its left acromion RA and its right one LA, for the whole walk
    trial = read_c3d(real_c3d("motonms_unipd/Walking3.c3d"))
    static = read_c3d(real_c3d("motonms_unipd/Static1.c3d"))
    fixed = swapped(trial, "LA", "RA")
    for pose in ("free", "neutral"):
        reference, clean = _rms_and_repairs(fixed, static=static, static_pose=pose)
        rms, repairs = _rms_and_repairs(trial, static=static, static_pose=pose)
        assert clean == [] and [r["markers"] for r in repairs] == [["LA", "RA"]]
        assert abs(rms - reference) <= 1.0, (pose, rms, reference)


def test_fit_json_and_build_diagnostics_report_the_repair(cluster_session, tmp_path, capsys):
    walk, rest = cluster_session
    bad = swapped(walk, "RFHD", "LBHD", slice(100, 200))
    capture = write_c3d(tmp_path / "walk.c3d", bad.markers, bad.labels, bad.rate)
    static = write_c3d(tmp_path / "rest.c3d", rest.markers, rest.labels, rest.rate)
    assert main(["fit", str(capture), "--static", str(static), "-o", str(tmp_path / "a.csv"),
                 "--json"]) == 0
    captured = capsys.readouterr()
    (repair,) = json.loads(captured.out)["repairs"]
    assert repair["markers"] == ["RFHD", "LBHD"] and repair["kind"] == "swap"
    assert "labels RFHD and LBHD look exchanged in frames" in captured.err
    from mocaplib.build.settings import BuildSettings
    from mocaplib.build.workflow import process_capture

    result = process_capture(capture, BuildSettings(static=str(static)))
    assert result.ok, result.error
    assert [r["markers"] for r in result.diagnostics["repairs"]] == [["RFHD", "LBHD"]]
    assert any(w.startswith("labels RFHD and LBHD look exchanged") for w in result.warnings)
