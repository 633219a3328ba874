"""Marker low-pass filter: zero lag, gaps respected, Winter's residual cutoff."""

import numpy as np
import pytest

from mocaplib.errors import FitError
from mocaplib.model.filtering import (MIN_RUN, filter_trial, lowpass, remove_spikes, residual_cutoff,
                                residual_curve)
from mocaplib.runs import valid_runs
from mocaplib.trial import Trial

RATE = 100.0


def _time(n=400):
    return np.arange(n) / RATE


def test_valid_runs():
    mask = np.array([0, 1, 1, 0, 0, 1, 1, 1, 0, 1], bool)
    np.testing.assert_array_equal(valid_runs(mask), [[1, 3], [5, 8], [9, 10]])


def test_no_phase_lag_and_unit_gain_in_the_pass_band():
    t = _time()
    x = 0.05 * np.sin(2 * np.pi * 1.5 * t + 0.3)
    y = lowpass(x, RATE, 6.0)
    lags = np.arange(-5, 6)
    core = slice(50, -50)
    corr = [np.dot(np.roll(y, k)[core], x[core]) for k in lags]
    assert lags[int(np.argmax(corr))] == 0, "the forward-backward filter shifts nothing"
    # 1.5 Hz is a quarter of the cutoff: the 4th-order zero-lag response is 1 - 4e-3 there;
    # odd-extension padding keeps the ends within 1 mm of a 50 mm sine (measured 0.6 mm)
    np.testing.assert_allclose(y[core], x[core], atol=0.05 * 4e-3 + 1e-5)
    np.testing.assert_allclose(y, x, atol=1e-3)


def test_cutoff_is_the_minus_3_db_point_of_both_passes():
    t = _time(2000)
    for fc in (4.0, 6.0, 10.0, 15.0):
        y = lowpass(np.sin(2 * np.pi * fc * t), RATE, fc)[500:-500]
        basis = np.stack([np.sin(2 * np.pi * fc * t), np.cos(2 * np.pi * fc * t)], 1)[500:-500]
        amplitude = np.linalg.norm(np.linalg.lstsq(basis, y, rcond=None)[0])
        # Winter's two-pass correction, in the bilinear transform's warped frequency, puts the
        # half-power point exactly at the cutoff (1e-4: 15 s of a sine, ends cut, by least
        # squares); without it the gain there would be 0.5
        np.testing.assert_allclose(amplitude, 2 ** -0.5, atol=1e-4)


def test_gaps_stay_gaps_and_runs_are_filtered_apart():
    t = _time()
    rng = np.random.default_rng(0)
    x = np.sin(2 * np.pi * t)[:, None] * [1.0, 2.0] + rng.normal(0, 0.01, (len(t), 2))
    x[100:130, 0] = np.nan      # a gap splitting column 0 into two long runs
    x[300:395, 1] = np.nan      # column 1: a long run, then a 5-frame run at the end
    assert 400 - 395 < MIN_RUN
    y = lowpass(x, RATE, 6.0)
    np.testing.assert_array_equal(np.isnan(y), np.isnan(x))
    # each run is filtered on its own: the same as filtering that slice alone, exactly
    np.testing.assert_allclose(y[:100, 0], lowpass(x[:100, 0], RATE, 6.0), atol=1e-12)
    np.testing.assert_allclose(y[130:, 0], lowpass(x[130:, 0], RATE, 6.0), atol=1e-12)
    np.testing.assert_allclose(y[:300, 1], lowpass(x[:300, 1], RATE, 6.0), atol=1e-12)
    # a run shorter than MIN_RUN frames is left as it is
    np.testing.assert_array_equal(y[395:, 1], x[395:, 1])
    # and the long runs are really smoothed: white noise keeps about sqrt(6 / 50) of its sd
    # below 6 Hz (measured 0.35), so it falls at least twofold
    clean = np.sin(2 * np.pi * t)
    assert np.std(y[150:280, 0] - clean[150:280]) < np.std(x[150:280, 0] - clean[150:280]) / 2


def test_residual_analysis_finds_the_knee_of_signal_plus_noise():
    t = _time(1000)
    rng = np.random.default_rng(1)
    # six coordinates: 1 Hz and 3 Hz sines (100 and 20 mm) of different phases and sizes
    phase = np.arange(6)
    signal = (0.1 * np.sin(2 * np.pi * 1.0 * t[:, None] + phase)
              + 0.02 * np.sin(2 * np.pi * 3.0 * t[:, None] + 2 * phase)) * np.linspace(0.5, 1.5, 6)
    noisy = signal + rng.normal(0, 0.001, signal.shape)
    fc = residual_cutoff(noisy, RATE)
    # the signal ends at 3 Hz and 1 mm noise is flat to 50 Hz: the knee lies a little above 3 Hz
    assert 3.0 <= fc <= 8.0, fc
    # filtering there leaves less error than the noise had (measured 0.62 mm of 1 mm: the
    # residual method balances the noise passed and the 3 Hz signal trimmed)
    error = np.sqrt(np.mean((lowpass(noisy, RATE, fc) - signal) ** 2))
    assert error < 0.75 * 0.001, error
    # the residual falls as the cutoff rises and is noise-sized at high cutoffs
    curve = residual_curve(noisy, RATE, np.array([1.0, 5.0, 20.0, 35.0]))
    assert np.all(np.diff(curve) < 0) and 0.0002 < curve[-1] < 0.001


@pytest.mark.parametrize("signal_hz", [None, 1.0, 4.0, 12.0])
def test_residual_cutoff_is_the_documented_rule_on_the_whole_curve(signal_hz):
    """residual_cutoff picks what the documented rule applied to the whole curve picks, also
    for pure noise, whose residual is at the intercept only inside the band."""
    t = _time(600)
    rng = np.random.default_rng(int(signal_hz or 0))
    data = rng.normal(0, 0.001, (600, 4))
    if signal_hz:
        data += 0.05 * np.sin(2 * np.pi * signal_hz * t[:, None] + np.arange(4))
    nyquist = RATE / 2
    cutoffs = np.arange(np.ceil(2 * max(1.0, RATE / 600)) / 2, 0.75 * nyquist + 1e-9, 0.5)
    curve = residual_curve(data, RATE, cutoffs)
    band = (cutoffs >= 0.4 * nyquist) & (cutoffs <= 0.75 * nyquist)
    _, intercept = np.polyfit(cutoffs[band], curve[band], 1)
    expected = np.clip(cutoffs[np.flatnonzero(curve <= intercept)[0]], 2.0, 0.4 * nyquist)
    assert residual_cutoff(data, RATE) == expected


def test_filter_trial_returns_a_new_trial():
    t = _time(200)
    rng = np.random.default_rng(2)
    markers = np.stack([np.sin(2 * np.pi * t), np.cos(2 * np.pi * t), t], -1)[:, None]
    markers = np.repeat(markers, 3, axis=1) + rng.normal(0, 0.001, (200, 3, 3))
    trial = Trial(markers.copy(), ["A", "B", "C"], RATE, source="walk.c3d")
    filtered, used = filter_trial(trial, cutoff=6.0)
    assert used == 6.0 and filtered is not trial
    np.testing.assert_array_equal(trial.markers, markers)      # the input is untouched
    assert np.abs(filtered.markers - markers).max() > 0
    same, none = filter_trial(trial, cutoff=None)
    assert same is trial and none is None
    auto, fc = filter_trial(trial, cutoff="auto")
    assert 2.0 <= fc <= 20.0


def test_filter_trial_keeps_the_columns_asked_for_and_judges_the_cutoff_on_them():
    t = _time(300)
    rng = np.random.default_rng(6)
    slow = np.stack([np.sin(2 * np.pi * t), np.cos(2 * np.pi * t), t], -1)
    fast = 0.2 * np.stack([np.sin(12 * np.pi * t), np.cos(12 * np.pi * t), t], -1)
    markers = np.stack([slow, fast, slow + 0.1], axis=1) + rng.normal(0, 0.001, (300, 3, 3))
    markers[100:103, 2] += 1.0                                   # a spike on the kept marker
    trial = Trial(markers, ["SLOW", "FAST", "C"], RATE, source="walk.c3d")
    kept, cutoff = filter_trial(trial, cutoff="auto", keep=[2, 0])
    assert kept.labels == ["C", "SLOW"]
    # the 6 Hz marker left out does not sway the cutoff: the kept markers' own is used
    alone = Trial(markers[:, [2, 0]], ["C", "SLOW"], RATE, source="walk.c3d")
    expected, own = filter_trial(alone, cutoff="auto")
    assert cutoff == own != filter_trial(trial, cutoff="auto")[1]
    np.testing.assert_array_equal(kept.markers, expected.markers)
    given, _ = filter_trial(trial, cutoff=6.0, keep=[2])
    np.testing.assert_array_equal(given.markers,
                                  filter_trial(trial, cutoff=6.0)[0].markers[:, [2]])
    assert filter_trial(trial, cutoff=None, keep=[1])[0].labels == ["FAST"]


@pytest.mark.parametrize("frames", [1, 5, MIN_RUN - 1])
def test_auto_cutoff_of_a_capture_too_short_to_filter(frames):
    # a one-frame static (btkdata's PiG_Calibration-FlatFoot-One) has no residual curve: it
    # gets the walking default, nothing is filtered and no cutoff is reported
    markers = np.random.default_rng(3).normal(0, 0.1, (frames, 4, 3))
    trial = Trial(markers.copy(), ["A", "B", "C", "D"], RATE, source="static.c3d")
    assert 0 < residual_cutoff(markers, RATE) < RATE / 2
    filtered, used = filter_trial(trial, cutoff="auto")
    assert used is None and filtered is trial
    np.testing.assert_array_equal(filtered.markers, markers)


@pytest.mark.parametrize("frames, cutoff, hint", [
    (266, 0.001, "give a cutoff of at least 0.38 Hz"),     # 100 Hz / 266 frames = 0.376 Hz
    (266, 0.3, "give a cutoff of at least 0.38 Hz"),
    (5, 6.0, "give 'none': the capture is too short"),
])
def test_a_cutoff_whose_period_is_longer_than_the_capture_is_refused(frames, cutoff, hint):
    markers = np.random.default_rng(4).normal(0, 0.1, (frames, 2, 3))
    trial = Trial(markers, ["A", "B"], RATE, source="walk.c3d")
    with pytest.raises(FitError, match=f"walk.c3d: a {cutoff:g} Hz low-pass needs at least "
                                       f"{max(MIN_RUN, int(np.ceil(RATE / cutoff)))} frames"
                                       f".*the capture has {frames} .*{hint}"):
        filter_trial(trial, cutoff=cutoff)
    if frames >= MIN_RUN:   # the lowest cutoff the hint names does filter
        _, used = filter_trial(trial, cutoff=0.38)
        assert used == 0.38


def test_a_cutoff_no_run_between_gaps_is_long_enough_for_is_not_reported():
    markers = np.random.default_rng(5).normal(0, 0.1, (300, 2, 3))
    markers[::50] = np.nan                     # runs of 49 frames
    trial = Trial(markers, ["A", "B"], RATE, source="walk.c3d")
    same, used = filter_trial(trial, cutoff=1.5)     # needs 67 frames
    assert used is None and same is trial
    filtered, used = filter_trial(trial, cutoff=2.5)  # needs 40 frames
    assert used == 2.5 and np.nanmax(np.abs(filtered.markers - markers)) > 0


@pytest.mark.parametrize("cutoff", [0.0, 50.0, "fast"])
def test_bad_cutoff_names_the_file(cutoff):
    trial = Trial(np.zeros((50, 1, 3)), ["A"], RATE, source="walk.c3d")
    with pytest.raises(FitError, match="walk.c3d: low-pass cutoff must be"):
        filter_trial(trial, cutoff=cutoff)


@pytest.mark.usefixtures("sample_dir")
def test_fit_reports_no_cutoff_for_a_capture_too_short_to_filter(tmp_path, capsys):
    import json

    from conftest import SAMPLES
    from mocaplib.cli import main
    from mocaplib.io.c3d import read_c3d
    from mocaplib.io.c3d_write import write_c3d

    walk = read_c3d(SAMPLES / "walk_straight_normal.c3d")
    short = write_c3d(tmp_path / "short.c3d", walk.markers[:5], walk.labels, walk.rate)
    assert main(["fit", str(short), "-o", str(tmp_path / "a.csv"), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["cutoff_hz"] is None
    assert main(["fit", str(short), "-o", str(tmp_path / "b.csv"), "--cutoff", "6"]) == 1
    assert "a 6 Hz low-pass needs at least 17 frames" in capsys.readouterr().err
    assert not (tmp_path / "b.csv").exists()


def test_resample_bridges_gaps_per_column_and_keeps_empty_columns_nan():
    from mocaplib.model.filtering import resample

    values = np.array([[0.0, np.nan, np.nan], [1.0, 10.0, np.nan], [np.nan, 20.0, np.nan],
                       [3.0, np.nan, np.nan]])
    got = resample(values, 2.0, np.array([0.0, 0.25, 1.0, 2.0]))   # frames at 0, 0.5, 1, 1.5 s
    np.testing.assert_allclose(got[:, 0], [0.0, 0.5, 2.0, 3.0])       # the gap at 1 s bridged
    np.testing.assert_allclose(got[:, 1], [10.0, 10.0, 20.0, 20.0])   # held beyond the ends
    assert np.isnan(got[:, 2]).all()


def _sosfiltfilt_lowpass(data, rate, cutoff):
    """The reference: scipy's Butterworth design and ``sosfiltfilt`` over each run of finite
    samples of each column (runs shorter than shortest_run left as they are)."""
    from scipy.signal import butter, sosfiltfilt

    from mocaplib.model.filtering import pass_correction, shortest_run

    design = rate / np.pi * np.arctan(np.tan(np.pi * cutoff / rate) / pass_correction(2))
    sos = butter(2, design, fs=rate, output="sos")
    flat = np.asarray(data, dtype=np.float64).reshape(len(data), -1)
    out = flat.copy()
    for column in range(flat.shape[1]):
        for start, stop in valid_runs(np.isfinite(flat[:, column])):
            if stop - start >= shortest_run(rate, cutoff):
                out[start:stop, column] = sosfiltfilt(sos, flat[start:stop, column],
                                                      padlen=min(9, stop - start - 1))
    return out.reshape(np.shape(data))


def _capture_markers(relative, real_c3d, sample_dir):
    from mocaplib.io.c3d import read_c3d

    path = sample_dir / relative if relative.startswith("walk_") else real_c3d(relative)
    return read_c3d(path)


#: Real captures with gaps of every kind (BTS: 31 run lengths, Walking3: 26), Y-up, 60-200 Hz,
#: and two samples.
CAPTURES = ["ezc3d_testfiles/BTS.c3d", "motonms_unipd/Walking3.c3d", "btkdata/Gait.c3d",
            "ezc3d_testfiles/Qualisys.c3d", "biomechzoo/HC030A05.c3d", "cmu/07_12.c3d",
            "walk_straight_normal.c3d", "walk_curve_r2_left_slow.c3d"]


@pytest.mark.parametrize("relative", CAPTURES)
def test_lowpass_is_scipys_sosfiltfilt_run_by_run(relative, real_c3d, sample_dir):
    trial = _capture_markers(relative, real_c3d, sample_dir)
    for cutoff in (2.0, 6.0, 0.3 * trial.rate):
        got = lowpass(trial.markers, trial.rate, cutoff)
        expected = _sosfiltfilt_lowpass(trial.markers, trial.rate, cutoff)
        np.testing.assert_array_equal(np.isnan(got), np.isnan(trial.markers))
        # the same filter computed by FFT convolution: rounding only (measured below 1e-13 m
        # on metre-sized coordinates)
        np.testing.assert_allclose(got, expected, rtol=0, atol=1e-11, err_msg=f"{cutoff} Hz")


def test_residual_curve_is_parsevals_residual_of_the_whole_odd_extension():
    """The spectral residual of a run equals the time-domain residual of the filter applied to
    the run's odd extension repeated (so that the filter is in its steady state), measured on
    the middle period."""
    rng = np.random.default_rng(7)
    n = 150
    run = np.cumsum(rng.normal(0, 0.01, n)) + 0.3 * np.sin(np.arange(n) / 9)
    line = run[0] + np.linspace(0, 1, n) * (run[-1] - run[0])
    detrended = run - line
    period = np.concatenate([detrended, -detrended[-2:0:-1]])       # 2 (n - 1) samples
    repeated = np.tile(period, 9)
    for cutoff in (2.0, 6.0, 20.0):
        middle = 4 * len(period)
        filtered = lowpass(repeated, RATE, cutoff)[middle:middle + n]
        expected = np.sqrt(np.mean((filtered - detrended) ** 2))
        got = residual_curve(run, RATE, np.array([cutoff]))[0]
        # four periods either side make the ends' start-up negligible (< 1e-12 at 2 Hz)
        np.testing.assert_allclose(got, expected, rtol=1e-9, err_msg=f"{cutoff} Hz")


def _time_domain_residual(data, rate, cutoffs):
    """Winter's residual of the filter applied (lowpass), candidate by candidate."""
    return np.array([np.sqrt(np.nanmean((lowpass(data, rate, fc) - data) ** 2))
                     for fc in cutoffs])


def _compare_cutoffs(paths, monkeypatch):
    import mocaplib.model.filtering as filtering
    from mocaplib.io.c3d import read_c3d

    steps = []
    for path in paths:
        trial = read_c3d(path)
        spectral = filtering.residual_cutoff(trial.markers, trial.rate)
        with monkeypatch.context() as patch:
            patch.setattr(filtering, "residual_curve", _time_domain_residual)
            applied = filtering.residual_cutoff(trial.markers, trial.rate)
        steps.append((spectral - applied) / 0.5)
    return np.array(steps)


def test_automatic_cutoffs_of_the_real_files_are_those_of_the_filter_applied(shared_c3d,
                                                                             monkeypatch):
    from conftest import real_files

    steps = _compare_cutoffs(real_files(), monkeypatch)
    # the spectral residual leaves out the passes' start-up a few samples beyond each end of a
    # run, which adds residual at low cutoffs: the cutoff is at most one candidate (0.5 Hz)
    # away, lower more often than higher (measured: 3 of 17 files one step lower)
    assert np.all(np.abs(steps) <= 1), steps
    assert np.count_nonzero(steps) <= 4, steps


def test_automatic_cutoffs_of_the_samples_are_those_of_the_filter_applied(sample_dir,
                                                                          monkeypatch):
    steps = _compare_cutoffs(sorted(sample_dir.glob("*.c3d")), monkeypatch)
    # measured: 61 of 68 the same, 6 one step lower, 1 one step higher
    assert np.all(np.abs(steps) <= 1), steps
    assert np.count_nonzero(steps) <= 10, steps


def test_remove_spikes_gaps_a_ghost_and_nothing_of_fast_smooth_motion():
    """A foot swinging at 10 m/s peak keeps every sample but a ghost 2 m away for 3 frames;
    a lone sample 1 m away is gapped too."""
    rate = 100.0
    t = np.arange(200) / rate
    swing = np.stack([0.5 * np.sin(2 * np.pi * 3.2 * t), 0.1 * np.cos(2 * np.pi * 3.2 * t),
                      0.1 + 0.1 * np.sin(2 * np.pi * 6.4 * t)], axis=1)      # 10 m/s peak
    markers = np.stack([swing, swing + 0.3], axis=1)
    markers[40:60, 1] = np.nan                                               # a gap stays
    spiky = markers.copy()
    spiky[100:103, 0] += [2.0, 1.0, 0.0]
    spiky[150, 1] += [0.0, 1.0, 0.0]
    cleaned = remove_spikes(spiky, rate)
    expected = markers.copy()
    expected[100:103, 0] = np.nan
    expected[150, 1] = np.nan
    np.testing.assert_array_equal(cleaned, expected)
    assert np.linalg.norm(np.diff(swing, axis=0), axis=1).max() * rate > 9.9   # m/s


def test_a_ghost_of_three_frames_fits_as_a_gap_would(real_c3d):
    """LKNE of PiG_Motion-FlatFoot-Full 2 m away for 3 frames (a reflection labelled LKNE):
    low-passed with the track, it moved the automatic cutoff and the calibration, every
    frame's angles 10 deg off; gapped first, the fit is that of the same 3 frames missing."""
    from dataclasses import replace

    from mocaplib.io.c3d import read_c3d
    from mocaplib.model.fitting import fit_capture

    trial = read_c3d(real_c3d("btkdata/PiG_Motion-FlatFoot-Full.c3d"))
    knee = trial.labels.index("LKNE")
    ghost, gap = trial.markers.copy(), trial.markers.copy()
    ghost[100:103, knee] += [2.0, 1.0, 0.0]
    gap[100:103, knee] = np.nan
    angles = [fit_capture(replace(trial, markers=m)).motion.q for m in (ghost, gap)]
    # the raw fit's outlier pass sees the ghost and the gap differently: measured 0.011 deg
    np.testing.assert_allclose(*angles, atol=np.radians(0.05))
