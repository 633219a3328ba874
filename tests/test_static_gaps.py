"""A static that does not show a marker the capture has (hidden, or put on after it): the
marker is placed on its segment from the capture's own frames
(:func:`mocaplib.model.fitting.with_motion_markers`), so the fit follows it and the feet keep
their toe."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest
from conftest import SAMPLES

from mocaplib.cli import main
from mocaplib.gait.events import capture_events
from mocaplib.io.c3d import read_c3d
from mocaplib.markersets.matching import detect_protocol
from mocaplib.model.calibration import calibrate
from mocaplib.model.fitting import fit_capture

HIDDEN = "RTOE"


def _hidden(static, label=HIDDEN, seen=0.05):
    """``static`` with ``label`` measured in only the first ``seen`` share of its frames."""
    markers = static.markers.copy()
    markers[int(seen * static.n_frames) + 1:, static.labels.index(label)] = np.nan
    return dataclasses.replace(static, markers=markers)


@pytest.mark.usefixtures("sample_dir")
def test_a_marker_the_static_hides_is_placed_from_the_capture():
    # the static shows RTOE in 5 % of its frames, the walk loses it over the right foot's
    # first stance: the model places it from the walk's frames, fills the gap, and the
    # stance and its toe-off are found (markers alone: not placed)
    motion = read_c3d(SAMPLES / "walk_straight_normal.c3d")
    rest = _hidden(read_c3d(SAMPLES / "rest.c3d"))
    truth = json.loads((SAMPLES / "walk_straight_normal.truth.json").read_text())["events"]
    strike = min(e["time_s"] for e in truth if e["side"] == "right"
                 and e["kind"] == "heel_strike")
    off = min(e["time_s"] for e in truth if e["side"] == "right" and e["kind"] == "toe_off"
              and e["time_s"] > strike)
    markers = motion.markers.copy()
    markers[int((strike - 0.1) * motion.rate):int((off - 0.05) * motion.rate),
            motion.labels.index(HIDDEN)] = np.nan
    gappy = dataclasses.replace(motion, markers=markers)
    assert HIDDEN not in calibrate(gappy, static=rest).labels
    fit = fit_capture(gappy, static=[rest])
    assert HIDDEN in fit.model.labels
    assert [w for w in fit.warnings if "does not show" in w] == [
        "static rest.c3d does not show RTOE (seen in under 10% of its frames): placed on its "
        "segment from the capture's own frames"]
    residuals = fit.motion.residuals[:, fit.motion.marker_labels.index(HIDDEN)]
    assert np.nanmedian(np.abs(residuals)) < 0.008                    # measured 5.5 mm
    match = detect_protocol(gappy)
    fitted, _ = capture_events(gappy, match, motion=fit.motion)
    alone, _ = capture_events(gappy, match)
    found = [min((e for e in events if e.side == "right" and e.kind == "toe_off"),
                 key=lambda e: abs(e.time_s - off)) for events in (fitted, alone)]
    assert found[0].placed and abs(found[0].time_s - off) < 1.0 / motion.rate, found[0]
    assert not found[1].placed


@pytest.mark.usefixtures("sample_dir")
def test_a_static_that_shows_every_marker_changes_nothing():
    motion = read_c3d(SAMPLES / "walk_straight_normal.c3d")
    rest = read_c3d(SAMPLES / "rest.c3d")
    fit = fit_capture(motion, static=[rest])
    assert not [w for w in fit.warnings if "does not show" in w]
    assert fit.model.labels == calibrate(motion, static=rest).labels


def test_the_motonms_walks_keep_their_right_toe_and_its_plate(real_c3d):
    # Static1 shows RIMH (the right foot's toe) in 1 of its 107 frames, the walk in 16 % of
    # its own: a model without it would leave the right foot, which stands on plate 1 with its
    # toe marker hidden, without a stance and its toe-off not placed; placed from the walk,
    # the fitted toe shows the stance and the plate times its toe-off
    motion = read_c3d(real_c3d("motonms_unipd/Walking1.c3d"))
    static = read_c3d(real_c3d("motonms_unipd/Static1.c3d"))
    fit = fit_capture(motion, static=[static])
    assert "RIMH" in fit.model.labels
    assert any("does not show RIMH" in w for w in fit.warnings)
    events, _ = capture_events(motion, detect_protocol(motion), motion=fit.motion)
    right_offs = [e for e in events if e.side == "right" and e.kind == "toe_off"]
    assert [(e.placed, e.plate) for e in right_offs] == [(True, 1)]
    assert right_offs[0].time_s == pytest.approx(3.135, abs=0.001)
    # the markers' toe-off the plate replaced lay on the fitted toe, not a measured one
    # (quality 0): it tells nothing of how late the markers place the others
    assert not any(e.plate_shift_s for e in events)


def test_the_events_command_says_fit_places_what_a_gap_hides(real_c3d, capsys):
    # without --fit the right stance hidden by RIMH's gap leaves its toe-off not placed, and
    # the command says --fit can place it; with --fit it is placed and timed by plate 1
    path = str(real_c3d("motonms_unipd/Walking1.c3d"))
    assert main(["events", path]) == 0
    err = capsys.readouterr().err
    assert "1 event(s) not placed where foot markers are missing: `mocaplib events --fit`" in err
    assert main(["events", path, "--fit"]) == 0
    out, err = capsys.readouterr()
    assert "not placed" not in out + err
    assert "right  toe_off      quality 1.00  force plate 1" in out
