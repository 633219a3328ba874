"""Marker low-pass filtering before the fit: zero-lag Butterworth, gap-aware, Winter's cutoff.

Marker noise (sub-millimetre white noise, jitter of the reconstruction) passes straight into
the fitted joint angles; gait kinematics hold almost nothing above 6-10 Hz (Winter 2009,
*Biomechanics and Motor Control of Human Movement*, ch. 3). So, as in most gait pipelines, the
markers are low-pass filtered first:

* **Zero lag.** A Butterworth filter of order :data:`ORDER` run forwards and backwards, as
  ``scipy.signal.sosfiltfilt`` runs it (odd extension of a few samples beyond each end, each
  pass started in the steady state of its first sample): no phase shift, squared magnitude
  response (:func:`zero_lag_gain`). Two passes lower the -3 dB point, so each pass is designed
  above the cutoff by Winter's correction (2009, §3.4.4.2: ``cutoff / c`` with ``c`` =
  :func:`pass_correction`, 0.802 for two passes of order 2), applied in the bilinear
  transform's warped frequency so it is exact for the digital filter:
  ``tan(π f_pass / rate) = tan(π cutoff / rate) / c``. The cutoff is then the -3 dB point of
  the whole filter. Each pass is computed as the convolution with the filter's impulse
  response, by real FFTs long enough for that response to have decayed below rounding: the
  same numbers as ``sosfiltfilt`` to rounding (``tests/test_filtering.py``), numpy only.
* **Gap-aware.** Each marker coordinate is filtered separately over each run of consecutive
  valid (finite) samples; gaps stay NaN and never leak into the valid data. A run shorter
  than :func:`shortest_run` frames (``max(MIN_RUN, rate / cutoff)``: less than one period of
  the cutoff) is left as it is. Runs of the same length, of every coordinate, share one FFT.
* **Spikes.** A sample more than :data:`SPIKE_DISTANCE` from the median of its marker's
  samples within :data:`SPIKE_WINDOW_S` (a ghost) is gapped before anything else
  (:func:`remove_spikes`): filtered, it would spread over its track.
* **Cutoff.** Given in Hz, or ``"auto"``: Winter's residual analysis per capture
  (:func:`residual_cutoff`), or None for no filtering. The analysis takes every candidate's
  residual from one FFT per run (Parseval's theorem) of the run extended by its point
  reflection about both ends, whole: the forward-backward filter in its steady state, which
  differs from the filter applied only within a few samples of a run's ends. It chooses the
  same cutoffs as the residuals of the filter applied within one candidate step (0.5 Hz):
  :func:`residual_curve`, ``tests/test_filtering.py``.
  The documented default for walking when a fixed cutoff is wanted is :data:`WALKING_CUTOFF`
  (6 Hz). :func:`filter_trial` reports the cutoff only when some run was filtered, and refuses
  a cutoff in Hz whose period is longer than the capture (nothing could be filtered).

All arrays have time on axis 0; positions are metres, rates and cutoffs Hz.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterator

import numpy as np

from ..errors import FitError
from ..numeric import distinct, nanmedian
from ..runs import frames_within
from ..trial import Trial, check_gait_rate

#: Butterworth order of each pass (forward and backward: effective order 4).
ORDER = 2


def pass_correction(order: int) -> float:
    """Winter's correction of a pass's design cutoff for two passes of ``order``:
    (2^(1/2) − 1)^(1/(2·order)); 0.802 for order 2."""
    return (2 ** 0.5 - 1) ** (1 / (2 * order))


#: Fixed cutoff commonly used for walking markers, Hz (Winter 2009).
WALKING_CUTOFF = 6.0
#: Runs of valid samples shorter than this many frames are never filtered.
MIN_RUN = 10
#: Residual analysis: candidate cutoffs from 1 Hz in steps of 0.5 Hz up to this fraction of
#: the Nyquist frequency; the straight line through the noise-only residuals is fitted over
#: cutoffs between the two fractions of :data:`NOISE_BAND`.
MAX_CANDIDATE = 0.75
NOISE_BAND = (0.4, 0.75)
#: Bounds of an automatic cutoff, Hz (lower) and fraction of Nyquist (upper).
AUTO_MIN, AUTO_MAX = 2.0, 0.4


def resample(values: np.ndarray, rate: float, times: np.ndarray, /, *,
             jointly: bool = False) -> np.ndarray:
    """``values`` (F, C), frame k at ``k / rate`` s, at ``times`` (n,) s: linear between the
    finite samples of each column, gaps bridged, held flat beyond the first and last. Returns
    (n, C); a column without any finite sample is NaN. ``jointly``: a frame is a sample of
    every column or of none, only where all its columns are finite (a point's x, y and z).

    Reads only the frames from one before the earliest time to one after the latest when a
    column's samples there bracket the times (finite at both ends of that window, or the
    window reaching the capture's end), else the column's every frame: the same numbers, in
    time proportional to the span of ``times`` rather than to F (a cycle of a long take)."""
    values = np.asarray(values, dtype=np.float64)
    times = np.asarray(times, dtype=np.float64)
    n_frames = len(values)
    window = _frames_around(times, rate, n_frames)
    frames = np.arange(window.start, window.stop) / rate
    finite = _finite(values[window], jointly)
    out = np.full((len(times), values.shape[1]), np.nan)
    everywhere = None                                   # every frame's finite samples, if needed
    for column in range(values.shape[1]):
        valid, at, samples = finite[:, column], frames, values[window, column]
        if not (valid.any() and (valid[0] or window.start == 0)
                and (valid[-1] or window.stop == n_frames)):
            if everywhere is None:
                everywhere = _finite(values, jointly)
            valid, at, samples = everywhere[:, column], np.arange(n_frames) / rate, \
                values[:, column]
        if valid.any():
            out[:, column] = np.interp(times, at[valid], samples[valid])
    return out


def _finite(values: np.ndarray, jointly: bool) -> np.ndarray:
    """Where ``values`` (F, C) are finite (F, C) bool; ``jointly``: where the whole row is."""
    finite = np.isfinite(values)
    if jointly:
        finite[:] = finite.all(axis=1, keepdims=True)
    return finite


def _frames_around(times: np.ndarray, rate: float, n_frames: int) -> slice:
    """The frames from the last before the earliest of ``times`` (s) to the first after the
    latest, within [0, n_frames); every frame when a time is not finite."""
    if not times.size or not np.isfinite(times).all():
        return slice(0, n_frames)
    inside = frames_within(float(times.min()), float(times.max()), rate, n_frames)
    return slice(max(inside.start - 1, 0), min(inside.stop + 1, n_frames))


def longest_run(data: np.ndarray) -> int:
    """Frames in the longest run of finite samples of any column of ``data`` (F, ...)."""
    flat = np.isfinite(np.asarray(data, dtype=np.float64).reshape(len(data), -1))
    _, starts, stops = _column_runs(flat)
    return int((stops - starts).max(initial=0))


def shortest_run(rate: float, cutoff: float) -> int:
    """Frames a run of valid samples needs to be low-passed at ``cutoff`` Hz (``rate`` Hz):
    one period of the cutoff, and at least :data:`MIN_RUN`."""
    return max(MIN_RUN, int(np.ceil(rate / cutoff)))


def _check_cutoff(cutoff: float, rate: float) -> None:
    if not (np.isfinite(cutoff) and 0.0 < cutoff < rate / 2):
        raise FitError(f"low-pass cutoff must be between 0 and {rate / 2:g} Hz (half the "
                       f"frame rate), got {cutoff:g} Hz",
                       hint="give a lower cutoff, 'auto' or 'none'")


def zero_lag_gain(frequencies: np.ndarray, rate: float, cutoff: float | np.ndarray, /, *,
                  order: int = ORDER) -> np.ndarray:
    """Gain (``frequencies`` Hz and ``cutoff`` Hz broadcast together) of the forward-backward
    Butterworth low-pass whose two passes have their -3 dB point at ``cutoff`` Hz: one pass's
    squared magnitude,
    ``1 / (1 + (tan(π f / rate) / tan(π f_pass / rate))^(2 order))``; real: no phase."""
    return np.abs(_pass_response(frequencies, rate, cutoff, order)) ** 2


def _pass_response(frequencies: np.ndarray, rate: float, cutoff: float | np.ndarray,
                   order: int) -> np.ndarray:
    """Complex frequency response (``frequencies`` Hz and ``cutoff`` Hz broadcast together)
    of one pass: the analogue Butterworth prototype of ``order`` at the pass's warped cutoff
    (Winter's correction, :func:`pass_correction`), bilinear transform (as
    ``scipy.signal.butter``)."""
    warped = np.tan(np.pi * np.asarray(cutoff) / rate) / pass_correction(order)
    s = (1j * np.tan(np.pi * np.asarray(frequencies, dtype=np.float64) / rate) / warped)[..., None]
    poles = _prototype_poles(order)
    return np.prod(-poles / (s - poles), axis=-1)


def _prototype_poles(order: int) -> np.ndarray:
    """Poles (order,) of the analogue Butterworth low-pass of unit cutoff (left half-plane)."""
    return np.exp(1j * np.pi * (2 * np.arange(1, order + 1) + order - 1) / (2 * order))


def _memory(rate: float, cutoff: float, order: int) -> int:
    """Samples after which one pass's impulse response has decayed below 1e-18 of its start:
    from the largest radius of its digital poles."""
    warped = np.tan(np.pi * cutoff / rate) / pass_correction(order)
    poles = _prototype_poles(order) * warped
    radius = np.abs((1 + poles) / (1 - poles)).max()
    return int(np.ceil(np.log(1e-18) / np.log(radius)))


def _one_pass(series: np.ndarray, rate: float, cutoff: float, order: int) -> np.ndarray:
    """One causal pass of the Butterworth along axis 0 of ``series`` (L, k), started in the
    steady state of its first sample (as ``sosfiltfilt`` starts each pass): that sample plus
    the response from rest to the series minus it, a linear convolution by real FFTs."""
    size = len(series) + _memory(rate, cutoff, order)
    size = 1 << (size - 1).bit_length()
    response = _pass_response(np.fft.rfftfreq(size, 1.0 / rate), rate, cutoff, order)
    moved = np.fft.rfft(series - series[0], size, axis=0) * response[:, None]
    return series[0] + np.fft.irfft(moved, size, axis=0)[:len(series)]


def lowpass(data: np.ndarray, rate: float, cutoff: float, /, *, order: int = ORDER
            ) -> np.ndarray:
    """Zero-lag Butterworth low-pass of ``data`` (F, ...) sampled at ``rate`` Hz, gap-aware;
    ``cutoff`` (Hz) is the -3 dB point of the two passes together.

    Every column (trailing index) is filtered over each run of finite samples separately (as
    ``scipy.signal.sosfiltfilt`` with its default odd padding would); NaN stays NaN; runs
    shorter than :func:`shortest_run` are returned unchanged. Returns a new array of the same
    shape. Raises :class:`FitError` for a cutoff outside (0, rate / 2).
    """
    data = np.asarray(data, dtype=np.float64)
    _check_cutoff(cutoff, rate)
    pad = 3 * (2 * ((order + 1) // 2) + 1)       # sosfiltfilt's default for the sections
    flat = data.reshape(len(data), -1)
    out = flat.copy()
    for n, starts, columns in _run_groups(flat, shortest_run(rate, cutoff)):
        for block in _blocks(n, len(starts)):
            rows_b, columns_b = _runs_of(n, starts[block], columns[block])
            runs = flat[rows_b, columns_b]                    # (n, k): k runs of n samples
            edge = min(pad, len(runs) - 1)
            extended = np.concatenate([2 * runs[:1] - runs[edge:0:-1], runs,
                                       2 * runs[-1:] - runs[-2:-edge - 2:-1]])
            forward = _one_pass(extended, rate, cutoff, order)
            both = _one_pass(forward[::-1], rate, cutoff, order)[::-1]
            out[rows_b, columns_b] = both[edge:len(both) - edge]
    return out.reshape(data.shape)


#: Samples (series × their length) filtered, analysed or searched for spikes at once: a long
#: take's runs (the cutoffs of its residual analysis, its frames) are taken a few at a time,
#: so the work arrays stay near 8-32 MB whatever the capture's length (each run's FFT is the
#: same, to the bit, in any batch).
BLOCK_SAMPLES = 1 << 20


def _blocks(n: int, k: int) -> list[slice]:
    """Slices of ``k`` series (runs, cutoffs) of ``n`` samples each, each slice at most
    :data:`BLOCK_SAMPLES` samples (one series at least)."""
    width = max(1, BLOCK_SAMPLES // max(n, 1))
    return [slice(start, start + width) for start in range(0, k, width)]


def residual_curve(data: np.ndarray, rate: float, cutoffs: np.ndarray) -> np.ndarray:
    """Winter's residual (C,): the RMS difference between ``data`` (F, ...) and its
    forward-backward low-pass at each of ``cutoffs`` (C,) Hz, over every finite sample (a run
    too short to be filtered at a cutoff counts as unchanged there).

    Each run of n samples is extended by its point reflection about both ends: minus the
    straight line through its end samples, it and its reflection are one period (2(n − 1)
    samples) of a smooth periodic signal that holds the run's residual twice, and the filter
    in its steady state multiplies its FFT by :func:`zero_lag_gain` (the line passes
    unchanged). So Parseval's theorem gives every cutoff's residual from one FFT per run.
    Near the ends of a run :func:`lowpass` starts each pass a few samples out instead: the two
    residuals differ there only.
    """
    data = np.asarray(data, dtype=np.float64)
    flat = data.reshape(len(data), -1)
    cutoffs = np.asarray(cutoffs, dtype=np.float64)
    shortest = np.array([shortest_run(rate, fc) for fc in cutoffs])
    energy = np.zeros(len(cutoffs))
    for n, starts, columns in _run_groups(flat, int(shortest.min(initial=MIN_RUN))):
        squared = np.empty((n, len(starts)))               # |FFT|^2 (n, k), a block at a time
        for block in _blocks(n, len(starts)):
            spectra = _odd_spectra(flat[_runs_of(n, starts[block], columns[block])])
            squared[:, block] = spectra.real ** 2 + spectra.imag ** 2
        power = np.sum(squared, axis=1)
        power[1:-1] *= 2                                    # the negative frequencies
        frequencies = np.fft.rfftfreq(2 * (n - 1), 1.0 / rate)
        removed = np.empty((len(cutoffs), len(frequencies)))      # (C, n), a block at a time
        for block in _blocks(len(frequencies), len(cutoffs)):
            removed[block] = 1.0 - zero_lag_gain(frequencies[None, :], rate,
                                                 cutoffs[block, None])
        energy += np.where(n >= shortest, removed ** 2 @ power, 0.0) / (4 * (n - 1))
    count = np.count_nonzero(np.isfinite(flat))
    return np.sqrt(energy / count) if count else np.full(len(cutoffs), np.nan)


def _odd_spectra(runs: np.ndarray) -> np.ndarray:
    """Real FFT (n, k) of one period (2(n − 1) samples) of the odd extension of ``runs``
    (n, k) minus the straight line through their end samples."""
    line = runs[0] + np.linspace(0.0, 1.0, len(runs))[:, None] * (runs[-1] - runs[0])
    detrended = runs - line
    return np.fft.rfft(np.concatenate([detrended, -detrended[-2:0:-1]]), axis=0)


def _column_runs(finite: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Every run of True in ``finite`` (F, C) bool: its column, start and stop (R,) each,
    stop exclusive, ordered by column then start."""
    frames, n_columns = finite.shape
    padded = np.zeros((n_columns, frames + 2), np.int8)
    padded[:, 1:-1] = finite.T
    column, frame = np.divmod(np.flatnonzero(np.diff(padded, axis=1)), frames + 1)
    return column[0::2], frame[0::2], frame[1::2]


def _run_groups(flat: np.ndarray, shortest: int) -> Iterator[tuple[int, np.ndarray, np.ndarray]]:
    """For each length n of the runs of finite samples of ``flat`` (F, C) of ``shortest``
    frames or more: n, and the first frame and the column (k,) each of its k runs
    (:func:`_runs_of`)."""
    column, start, stop = _column_runs(np.isfinite(flat))
    length = stop - start
    for n in distinct(length[length >= max(shortest, 2)]):
        chosen = length == n
        yield int(n), start[chosen], column[chosen]


def _runs_of(n: int, starts: np.ndarray, columns: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Index arrays ``rows`` (n, k) and ``columns`` (1, k) of k runs of n samples starting at
    ``starts`` (k,) in ``columns`` (k,): ``flat[rows, columns]`` is the (n, k) runs."""
    return starts + np.arange(n)[:, None], columns[None, :]


def residual_cutoff(data: np.ndarray, rate: float) -> float:
    """Cutoff (Hz) by Winter's residual analysis of ``data`` (F, ...) sampled at ``rate`` Hz.

    Candidates run from 1 Hz (or from ``rate`` / the longest run of valid samples, below which
    nothing would be filtered) in steps of 0.5 Hz. The residual R(fc) (:func:`residual_curve`) of
    pure white noise falls linearly with fc; at high cutoffs only noise is left, so a straight line
    fitted to R over the noise band (:data:`NOISE_BAND` of the Nyquist frequency) and extended to
    fc = 0 gives the noise's residual ``a``. The cutoff is the lowest candidate whose residual is no
    more than ``a``: signal distortion and passed noise balance there (Winter 2009, §3.4.4.3).
    Clipped to [:data:`AUTO_MIN` Hz, :data:`AUTO_MAX` × Nyquist]. Data too short for the analysis
    (fewer than 4 candidates, or 2 in the noise band) get :data:`WALKING_CUTOFF`.
    """
    nyquist = rate / 2
    data = np.asarray(data, dtype=np.float64)
    default = float(np.clip(WALKING_CUTOFF, AUTO_MIN, AUTO_MAX * nyquist))
    longest = longest_run(data)
    if longest < MIN_RUN:          # nothing long enough to filter, nor to analyse
        return default
    # a cutoff whose period is longer than every run would filter nothing (residual 0)
    lowest = max(1.0, rate / longest)
    cutoffs = np.arange(np.ceil(2 * lowest) / 2, MAX_CANDIDATE * nyquist + 1e-9, 0.5)
    if len(cutoffs) < 4:
        return default
    band = (cutoffs >= NOISE_BAND[0] * nyquist) & (cutoffs <= NOISE_BAND[1] * nyquist)
    resid = residual_curve(data, rate, cutoffs)
    ok = band & np.isfinite(resid)
    if ok.sum() < 2:
        return default
    _, intercept = np.polyfit(cutoffs[ok], resid[ok], 1)
    below = np.flatnonzero(resid <= intercept)
    fc = cutoffs[below[0]] if len(below) else cutoffs[-1]
    return float(np.clip(fc, AUTO_MIN, AUTO_MAX * nyquist))


#: A sample further than this (m) from the median of its marker's samples within
#: :data:`SPIKE_WINDOW_S` on either side is a spike (a ghost, a reflection labelled for a few
#: frames): :func:`remove_spikes`. No labelled marker of the 17 real files comes within 0.18 m
#: of it (brisk walking, jogging; the feet and the hands move fastest).
SPIKE_DISTANCE = 0.5
#: Half the window (s) of :data:`SPIKE_DISTANCE`: spikes of up to about this long are found.
SPIKE_WINDOW_S = 0.05


def remove_spikes(markers: np.ndarray, rate: float, /) -> np.ndarray:
    """``markers`` (F, M, 3) m with each spike made NaN (a copy): a sample further than
    :data:`SPIKE_DISTANCE` from the per-axis median of its marker's valid samples within
    :data:`SPIKE_WINDOW_S` of it (``rate`` Hz). Low-passed, a spike of 2 m over 3 frames
    spreads over a tenth of a second of its track and shifts the cutoff Winter's analysis
    chooses; a calibration on that track is off everywhere (PiG_Motion-FlatFoot-Full: 10 deg
    in every frame). Only markers that jump by half that distance between two frames are
    looked at.
    """
    half = max(1, int(round(SPIKE_WINDOW_S * rate)))
    out = markers.copy()
    jumps = np.zeros(markers.shape[1], dtype=bool)
    stretch = max(2, BLOCK_SAMPLES // max(3 * markers.shape[1], 1))
    for start in range(0, max(len(markers) - 1, 0), stretch):   # frames overlap by one
        with np.errstate(invalid="ignore"):
            steps = np.linalg.norm(np.diff(markers[start:start + stretch + 1], axis=0), axis=2)
            jumps |= (steps > SPIKE_DISTANCE / 2).any(axis=0)
    for m in np.flatnonzero(jumps):
        track = markers[:, m]
        windows = np.lib.stride_tricks.sliding_window_view(
            np.pad(track, ((half, half), (0, 0)), constant_values=np.nan), 2 * half + 1, axis=0)
        median = nanmedian(windows, axis=2)      # a window of gap only: NaN, compared False
        with np.errstate(invalid="ignore"):
            out[np.linalg.norm(track - median, axis=1) > SPIKE_DISTANCE, m] = np.nan
    return out


def filter_trial(trial: Trial, /, *, cutoff: float | str | None = "auto",
                 keep: np.ndarray | None = None) -> tuple[Trial, float | None]:
    """The trial with low-pass filtered markers, and the cutoff used (Hz; None: unfiltered).

    Spikes are gapped first (:func:`remove_spikes`). The input trial is not modified.

    Parameters
    ----------
    trial : Trial
        The capture.
    cutoff : float, "auto", "none" or None
        Hz; ``"auto"``: :func:`residual_cutoff` of the markers kept; None or ``"none"``: no
        filtering (the trial itself is returned).
    keep : ndarray of int, shape (K,), optional
        The marker columns the returned trial holds, in that order (default all). Only those
        are judged and filtered: a file's other points, a model's virtual points or another
        subject's markers neither sway the cutoff nor cost anything.

    Returns
    -------
    trial : Trial
        The filtered trial (the kept markers only).
    cutoff : float or None
        The cutoff used, Hz; None when nothing was filtered, also when no run of valid
        samples was long enough to be filtered (:func:`shortest_run`).

    Raises
    ------
    FitError
        A frame rate no gait capture has (:data:`mocaplib.trial.GAIT_RATES`), a cutoff not in
        (0, rate / 2), or a cutoff in Hz whose period is longer than the whole capture.
    """
    check_gait_rate(trial.rate, trial.source, FitError)
    kept = trial if keep is None else dataclasses.replace(
        trial, markers=trial.markers[:, keep], labels=[trial.labels[i] for i in keep],
        warnings=list(trial.warnings))
    if cutoff is None or cutoff == "none" or trial.n_frames == 0:
        return kept, None
    trial = kept
    given = cutoff != "auto"
    markers = remove_spikes(trial.markers, trial.rate)
    if not given:
        cutoff = residual_cutoff(markers, trial.rate)
    try:
        cutoff = float(cutoff)
        _check_cutoff(cutoff, trial.rate)
    except FitError as exc:
        raise FitError(exc.message, path=trial.source, hint=exc.hint) from None
    except (TypeError, ValueError):
        raise FitError(f"low-pass cutoff must be a number of Hz, 'auto' or 'none', got "
                       f"{cutoff!r}", path=trial.source) from None
    need = shortest_run(trial.rate, cutoff)
    if given and trial.n_frames < need:
        lowest = np.ceil(100 * trial.rate / trial.n_frames) / 100
        raise FitError(
            f"a {cutoff:g} Hz low-pass needs at least {need} frames (one period of the "
            f"cutoff, and {MIN_RUN} at least); the capture has {trial.n_frames}",
            path=trial.source,
            hint=f"give a cutoff of at least {lowest:g} Hz, 'auto' or 'none'"
            if trial.n_frames >= MIN_RUN else "give 'none': the capture is too short to filter")
    if longest_run(markers) < need:   # gaps leave no run long enough: nothing to do
        return trial, None
    markers = lowpass(markers, trial.rate, cutoff)
    return dataclasses.replace(trial, markers=markers, warnings=list(trial.warnings)), cutoff
