"""Fourier encoding (paper eq. (3), 2πkt/T convention), order by tolerance, root drift."""

from __future__ import annotations

import numpy as np
import pytest

from mocaplib.errors import FitError
from mocaplib.gait.fourier import encode, encode_cycle, fit_series, root_drift, synthesize
from mocaplib.skeleton import ROOT_X, ROOT_Y
from mocaplib.skeleton import ROOT_HEADING
from mocaplib.skeleton import DOF_NAMES, TRANSLATION

T = 1.1
D = len(DOF_NAMES)


def known(order=3, channels=4, seed=1):
    rng = np.random.default_rng(seed)
    a = rng.normal(0, 0.3, (channels, order + 1))
    b = rng.normal(0, 0.3, (channels, order + 1))
    b[:, 0] = 0
    return a, b


def test_synthesize_matches_the_formula_and_is_periodic():
    a, b = known()
    t = np.array([[0.0, 0.2], [0.7, 1.05]])
    got = synthesize(a, b, T, t)
    assert got.shape == (2, 2, 4)
    k = np.arange(4)
    expected = (a[1] * np.cos(2 * np.pi * k * 0.7 / T)
                + b[1] * np.sin(2 * np.pi * k * 0.7 / T)).sum()
    np.testing.assert_allclose(got[1, 0, 1], expected, atol=1e-12)  # same formula, rounding only
    np.testing.assert_allclose(synthesize(a, b, T, t + T), got, atol=1e-12)  # base period is T


def test_fit_recovers_known_coefficients_from_frames():
    a, b = known()
    time = np.arange(0, T, 0.01)  # 100 Hz samples of one period
    series = fit_series(synthesize(a, b, T, time), time, T, 3)
    np.testing.assert_allclose(series.a, a, atol=1e-10)  # exact data, least squares is exact
    np.testing.assert_allclose(series.b, b, atol=1e-10)
    assert series.rms.max() < 1e-10


def test_order_chosen_by_tolerance():
    a, b = known(order=5)
    a[:, 4:] = b[:, 4:] = 0.0
    a[0, 4] = np.deg2rad(2.0)  # a 4th harmonic of 2 degrees on channel 0 only
    time = np.arange(0, T, 0.01)
    values = synthesize(a, b, T, time)
    series = encode(values, time, T, tolerance=np.deg2rad(0.5))
    assert series.order == 4
    assert np.rad2deg(series.rms.max()) <= 0.5
    # order 3 would leave the 2-degree harmonic: RMS 2/sqrt(2) degrees on channel 0
    np.testing.assert_allclose(np.rad2deg(fit_series(values, time, T, 3).rms[0]), np.sqrt(2),
                               atol=0.02)


def test_bad_input_raises():
    with pytest.raises(FitError, match="NaN"):
        encode(np.full((10, 2), np.nan), np.arange(10) / 10, 1.0, tolerance=0.01)
    with pytest.raises(FitError, match="period"):
        synthesize(np.zeros((2, 3)), np.zeros((2, 3)), 0.0, [0.1])


def walking_q(time, *, v=1.2, omega=0.5, heading0=2.9):
    """Joint coordinates of a periodic gait drifting along an arc (heading crosses ±π)."""
    q = np.zeros((len(time), D))
    phase = 2 * np.pi * time / T
    for d in range(D):
        q[:, d] = 0.2 * np.sin(phase + d) + 0.05 * np.cos(2 * phase + 0.3 * d)
    psi = heading0 + omega * time
    radius = v / omega
    # wrapped, as a fit gives
    q[:, ROOT_HEADING] = np.angle(np.exp(1j * (psi + q[:, ROOT_HEADING])))
    q[:, ROOT_X] = radius * np.sin(psi) + 0.02 * np.sin(phase)
    q[:, ROOT_Y] = -radius * np.cos(psi) + 0.03 * np.cos(phase)
    return q


def test_cycle_encoding_is_periodic_and_restores_the_drift():
    time = np.arange(0, T, 0.01)
    q = walking_q(time)
    q_end = walking_q(np.array([T]))[0]
    enc = encode_cycle(q, time, T, q_end)
    # every channel, root included, is periodic: 0.5 deg / 2 mm tolerance met at a low order
    assert enc.order <= 3
    assert enc.rms_deg <= 0.5
    np.testing.assert_allclose(enc.drift.omega, 0.5, atol=1e-9)  # exact heading change / T
    world = enc.synthesize_world(time)
    # restoring the drift gives back the world coordinates (heading unwrapped)
    np.testing.assert_allclose(world[:, TRANSLATION], q[:, TRANSLATION], atol=0.002)
    np.testing.assert_allclose(np.angle(np.exp(1j * (world - q)))[:, ~TRANSLATION], 0,
                               atol=np.deg2rad(0.5))


def test_cycle_end_pose_may_be_a_list():
    time = np.arange(0, T, 0.01)
    q = walking_q(time)
    q_end = walking_q(np.array([T]))[0]
    from_list = encode_cycle(q.tolist(), time, T, q_end.tolist())
    from_array = encode_cycle(q, time, T, q_end)
    np.testing.assert_array_equal(from_list.series.a, from_array.series.a)
    assert from_list.drift == from_array.drift


def test_drift_frame_reaches_the_end_pose():
    start = np.zeros(D)
    end = np.zeros(D)
    start[[ROOT_X, ROOT_Y, ROOT_HEADING]] = [1.0, 2.0, 0.3]
    end[[ROOT_X, ROOT_Y, ROOT_HEADING]] = [1.5, 3.1, 1.1]
    drift = root_drift(start, end, T)
    x, y, psi = drift.frame(np.array([0.0, T]))
    np.testing.assert_allclose([x[1], y[1], psi[1]], [1.5, 3.1, 1.1], atol=1e-12)
    np.testing.assert_allclose([x[0], y[0], psi[0]], [1.0, 2.0, 0.3], atol=1e-12)
    straight = root_drift(start, start + np.eye(D)[ROOT_X], T)  # 1 m along +X, no turn
    np.testing.assert_allclose(straight.u_f, np.cos(0.3) / T, atol=1e-12)
    np.testing.assert_allclose(straight.u_l, -np.sin(0.3) / T, atol=1e-12)


@pytest.mark.real
def test_real_chosen_cycles_encode_with_few_harmonics():
    # the target: order <= 12 for >= 90 % of the real chosen cycles (every one hit the
    # cap of 20 at a flat 0.5 deg tolerance, forced through each cycle's start-to-end step);
    # measured 5-10 on the 10 real walks (docs/guide/fourier.md)
    from walking_library import real_walks

    _, records = real_walks()
    orders = np.array([c["fourier_n"] for record in records.values()
                       for c in record["cycles"] if c["chosen"]])
    assert len(orders) == 10 and np.mean(orders <= 12) >= 0.9, orders


def test_a_cycle_that_does_not_close_keeps_a_low_order_and_its_ramp():
    # a real cycle ends a few degrees from where it started: forced through that step, the
    # series needed every harmonic; taken out as a ramp, the periodic part is encoded as usual
    from mocaplib.gait.fourier import MAX_ANGLE_TOLERANCE, channel_tolerance

    time = np.arange(0, T, 0.01)
    q = walking_q(time)
    q_end = walking_q(np.array([T]))[0]
    knee = DOF_NAMES.index("knee_flexion_l")
    step = np.deg2rad(12.0)
    q[:, knee] += step * time / T
    q_end[knee] += step
    enc = encode_cycle(q, time, T, q_end)
    assert enc.order <= 3 and enc.rms_deg <= 0.5
    np.testing.assert_allclose(enc.ramp[knee], step, atol=1e-9)
    assert enc.ramp[ROOT_X] == enc.ramp[ROOT_Y] == enc.ramp[ROOT_HEADING] == 0.0
    # series + ramp·t/T is the captured cycle (root in the moving frame), to the tolerance
    captured = enc.drift.remove(np.unwrap(q, axis=0), time)
    np.testing.assert_allclose(enc.synthesize_cycle(time)[:, knee], captured[:, knee],
                               atol=np.deg2rad(0.5))
    # without the ramp the same cycle needs many more harmonics
    flat = encode(captured, time, T, tolerance=channel_tolerance())
    assert flat.order >= 3 * enc.order
    # the tolerance follows each angle's noise floor, from 0.5 deg up to 1 deg
    noise = np.zeros(D)
    noise[knee], noise[0] = np.deg2rad(0.7), np.deg2rad(5.0)
    tolerance = channel_tolerance(noise)
    assert tolerance[knee] == pytest.approx(np.deg2rad(0.7))
    assert tolerance[DOF_NAMES.index("hip_flexion_l")] == pytest.approx(np.deg2rad(0.5))
    assert tolerance[0] == 0.002 and MAX_ANGLE_TOLERANCE == pytest.approx(np.deg2rad(1.0))
    assert channel_tolerance(np.full(D, 1.0))[knee] == MAX_ANGLE_TOLERANCE
