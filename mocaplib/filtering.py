"""Marker low-pass filtering before the fit: zero-lag Butterworth, gap-aware, Winter's cutoff.

Marker noise (sub-millimetre white noise, jitter of the reconstruction) passes straight into
the fitted joint angles; gait kinematics hold almost nothing above 6-10 Hz (Winter 2009,
*Biomechanics and Motor Control of Human Movement*, ch. 3). So, as in most gait pipelines, the
markers are low-pass filtered first:

* **Zero lag.** A Butterworth filter of order :data:`ORDER` run forwards and backwards
  (``scipy.signal.sosfiltfilt``): no phase shift, squared magnitude response. Two passes
  lower the -3 dB point, so each pass is designed above the cutoff by Winter's correction
  (2009, §3.4.4.2: ``cutoff / c`` with ``c`` = :func:`pass_correction`, 0.802 for two passes
  of order 2), applied in the bilinear transform's warped frequency so it is exact for the
  digital filter: ``tan(π f_pass / rate) = tan(π cutoff / rate) / c``. The cutoff is then the
  -3 dB point of the whole filter.
* **Gap-aware.** Each marker coordinate is filtered separately over each run of consecutive
  valid (finite) samples; gaps stay NaN and never leak into the valid data. A run shorter
  than :func:`shortest_run` frames (``max(MIN_RUN, rate / cutoff)``: less than one period of
  the cutoff) is left as it is: the filter's edge transients would dominate it.
* **Cutoff.** Given in Hz, or ``"auto"``: Winter's residual analysis per capture
  (:func:`residual_cutoff`), or None for no filtering. The documented default for walking when
  a fixed cutoff is wanted is :data:`WALKING_CUTOFF` (6 Hz). :func:`filter_trial` reports the
  cutoff only when some run was filtered, and refuses a cutoff in Hz whose period is longer
  than the capture (nothing could be filtered).

All arrays have time on axis 0; positions are metres, rates and cutoffs Hz.
"""

from __future__ import annotations

import dataclasses
import functools

import numpy as np
from scipy.signal import butter, sosfiltfilt

from .errors import FitError
from .runs import valid_runs
from .trial import Trial, check_gait_rate

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


def resample(values: np.ndarray, rate: float, times: np.ndarray) -> np.ndarray:
    """``values`` (F, C), frame k at ``k / rate`` s, at ``times`` (n,) s: linear between the
    finite samples of each column, gaps bridged, held flat beyond the first and last. Returns
    (n, C); a column without any finite sample is NaN."""
    values = np.asarray(values, dtype=np.float64)
    frames = np.arange(len(values)) / rate
    out = np.full((len(times), values.shape[1]), np.nan)
    for column in range(values.shape[1]):
        valid = np.isfinite(values[:, column])
        if valid.any():
            out[:, column] = np.interp(times, frames[valid], values[valid, column])
    return out


def longest_run(data: np.ndarray) -> int:
    """Frames in the longest run of finite samples of any column of ``data`` (F, ...)."""
    flat = np.isfinite(np.asarray(data, dtype=np.float64).reshape(len(data), -1))
    return max((stop - start for column in flat.T for start, stop in valid_runs(column)),
               default=0)


def shortest_run(rate: float, cutoff: float) -> int:
    """Frames a run of valid samples needs to be low-passed at ``cutoff`` Hz (``rate`` Hz):
    one period of the cutoff, and at least :data:`MIN_RUN`."""
    return max(MIN_RUN, int(np.ceil(rate / cutoff)))


def _check_cutoff(cutoff: float, rate: float) -> None:
    if not (np.isfinite(cutoff) and 0.0 < cutoff < rate / 2):
        raise FitError(f"low-pass cutoff must be between 0 and {rate / 2:g} Hz (half the "
                       f"frame rate), got {cutoff:g} Hz",
                       hint="give a lower cutoff, 'auto' or 'none'")


def lowpass(data: np.ndarray, rate: float, cutoff: float, /, *, order: int = ORDER
            ) -> np.ndarray:
    """Zero-lag Butterworth low-pass of ``data`` (F, ...) sampled at ``rate`` Hz, gap-aware;
    ``cutoff`` (Hz) is the -3 dB point of the two passes together.

    Every column (trailing index) is filtered over each run of finite samples separately; NaN
    stays NaN; runs shorter than :func:`shortest_run` are returned unchanged.
    Returns a new array of the same shape. Raises :class:`FitError` for a cutoff outside
    (0, rate / 2).
    """
    data = np.asarray(data, dtype=np.float64)
    _check_cutoff(cutoff, rate)
    sos = _design(order, float(cutoff), float(rate)).copy()  # scipy wants it writable
    pad = 3 * (2 * len(sos) + 1)
    shortest = shortest_run(rate, cutoff)
    flat = data.reshape(len(data), -1)
    out = flat.copy()
    finite = np.isfinite(flat)
    complete = finite.all(axis=0)
    if len(flat) >= shortest and complete.any():
        out[:, complete] = sosfiltfilt(sos, flat[:, complete], axis=0,
                                       padlen=min(pad, len(flat) - 1))
    for column in np.flatnonzero(~complete):
        for start, stop in valid_runs(finite[:, column]):
            if stop - start >= shortest:
                out[start:stop, column] = sosfiltfilt(sos, flat[start:stop, column],
                                                      padlen=min(pad, stop - start - 1))
    return out.reshape(data.shape)


@functools.lru_cache(maxsize=1024)
def _design(order: int, cutoff: float, rate: float) -> np.ndarray:
    """Second-order sections of one pass whose two passes have their -3 dB point at ``cutoff``
    (Hz); cached, as the residual analysis designs the same candidates for every capture."""
    design = rate / np.pi * np.arctan(np.tan(np.pi * cutoff / rate) / pass_correction(order))
    sos = butter(order, design, fs=rate, output="sos")
    sos.flags.writeable = False
    return sos


def residual_curve(data: np.ndarray, rate: float, cutoffs: np.ndarray) -> np.ndarray:
    """RMS difference (C,) between ``data`` (F, ...) and its low-pass at each of ``cutoffs``
    (C,) Hz, over the finite samples of the filtered runs (Winter's residual)."""
    data = np.asarray(data, dtype=np.float64)
    out = np.empty(len(cutoffs))
    for i, fc in enumerate(cutoffs):
        diff = lowpass(data, rate, float(fc)) - data
        out[i] = np.sqrt(np.nanmean(diff ** 2))
    return out


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
    longest = longest_run(data)
    if longest < MIN_RUN:          # nothing long enough to filter, nor to analyse
        return float(np.clip(WALKING_CUTOFF, AUTO_MIN, AUTO_MAX * nyquist))
    # a cutoff whose period is longer than every run would filter nothing (residual 0)
    lowest = max(1.0, rate / longest)
    cutoffs = np.arange(np.ceil(2 * lowest) / 2, MAX_CANDIDATE * nyquist + 1e-9, 0.5)
    if len(cutoffs) < 4:
        return float(np.clip(WALKING_CUTOFF, AUTO_MIN, AUTO_MAX * nyquist))
    band = (cutoffs >= NOISE_BAND[0] * nyquist) & (cutoffs <= NOISE_BAND[1] * nyquist)
    resid = np.full(len(cutoffs), np.nan)
    resid[band] = residual_curve(data, rate, cutoffs[band])
    ok = band & np.isfinite(resid)
    if ok.sum() < 2:
        return float(np.clip(WALKING_CUTOFF, AUTO_MIN, AUTO_MAX * nyquist))
    _, intercept = np.polyfit(cutoffs[ok], resid[ok], 1)
    # the lowest candidate at or below the intercept, evaluated upwards from the lowest: the
    # candidates above it are never filtered (the cutoff is usually far below the noise band)
    fc = cutoffs[-1]
    for i, candidate in enumerate(cutoffs):
        if not band[i]:
            resid[i] = residual_curve(data, rate, cutoffs[i:i + 1])[0]
        if resid[i] <= intercept:
            fc = candidate
            break
    return float(np.clip(fc, AUTO_MIN, AUTO_MAX * nyquist))


def filter_trial(trial: Trial, /, *, cutoff: float | str | None = "auto"
                 ) -> tuple[Trial, float | None]:
    """The trial with low-pass filtered markers, and the cutoff used (Hz; None: unfiltered).

    ``cutoff``: Hz, ``"auto"`` (:func:`residual_cutoff` of the trial's markers) or None /
    ``"none"`` (the trial itself is returned). The cutoff is returned only when some run of
    valid samples was long enough to be filtered (:func:`shortest_run`); otherwise the trial
    itself and None. The input trial is not modified. Raises :class:`FitError` for a frame rate
    no gait capture has (:data:`mocaplib.trial.GAIT_RATES`), a cutoff that is not in
    (0, rate / 2), or a cutoff in Hz whose period is longer than the whole capture.
    """
    check_gait_rate(trial.rate, trial.source, FitError)
    if cutoff is None or cutoff == "none" or trial.n_frames == 0:
        return trial, None
    given = cutoff != "auto"
    if not given:
        cutoff = residual_cutoff(trial.markers, trial.rate)
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
    if longest_run(trial.markers) < need:   # gaps leave no run long enough: nothing to do
        return trial, None
    markers = lowpass(trial.markers, trial.rate, cutoff)
    return dataclasses.replace(trial, markers=markers, warnings=list(trial.warnings)), cutoff
