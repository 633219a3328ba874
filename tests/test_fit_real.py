"""Calibrate + fit on real captures from ../shared/data/c3d (skipped when absent)."""

from mocaplib.calibration import calibrate
from mocaplib.ik import fit, fit_quality
from mocaplib.io.c3d import read_c3d


def test_plug_in_gait_walk_fits_within_opensim_best_practice(real_c3d):
    trial = read_c3d(real_c3d("btkdata/PiG_Motion-FlatFoot-Full.c3d"))
    model = calibrate(trial)
    quality = fit_quality(fit(trial, model))
    assert model.protocol.name == "plugin_gait"
    # a heel and a toe marker cannot show the foot's inversion: it is held, and said so
    assert sorted(model.locked_dofs) == sorted(model.unobservable) == [
        "ankle_inversion_l", "ankle_inversion_r"]
    # OpenSim's best practice asks marker RMS < 20 mm and max < 40 mm; measured 5.9 / 35.8
    assert quality["marker_rms_mm"] < 10.0
    assert quality["max_marker_error_mm"] < 40.0
    assert quality["failed_frames"] == []


def test_swapped_acromion_labels_are_undone(real_c3d):
    # SOURCES.md: in Walking3 the left acromion is labelled RA and the right one LA
    trial = read_c3d(real_c3d("motonms_unipd/Walking3.c3d"))
    model = calibrate(trial)
    assert model.swapped == [("LA", "RA")]
    assert model.left_out == ["head", "humerus_r", "forearm_r", "humerus_l", "forearm_l"]
    rms = fit(trial, model).marker_rms()
    # once exchanged back both fit like any trunk marker (measured 8.8 and 5.1 mm)
    assert rms[model.labels.index("LA")] < 0.015 and rms[model.labels.index("RA")] < 0.015
