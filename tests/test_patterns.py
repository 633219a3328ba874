"""Line/arc/point patterns and the cycle velocities v̂, ω̂, v̂_l, v̂_f on exact analytic paths."""

from __future__ import annotations

import numpy as np
import pytest

from mocaplib.errors import EventError
from mocaplib.gait.patterns import cycle_velocities, fit_circle, fit_line, fit_pattern

from gait_model import shoulders

RATE = 100.0


def arc_points(radius, angle, n=100, noise=0.0, seed=0, centre=(1.0, -2.0)):
    phi = np.linspace(0.3, 0.3 + angle, n)
    xy = np.column_stack([centre[0] + radius * np.cos(phi), centre[1] + radius * np.sin(phi)])
    return xy + np.random.default_rng(seed).normal(0, noise, xy.shape)


def kasa(xy):
    """Kåsa's algebraic circle fit (the biased reference): radius."""
    x, y = xy.T
    a = np.column_stack([x, y, np.ones_like(x)])
    c = np.linalg.lstsq(a, x * x + y * y, rcond=None)[0]
    return np.sqrt(c[2] + (c[0] ** 2 + c[1] ** 2) / 4)


def test_line_fit_is_total_least_squares_and_oriented():
    t = np.linspace(0, 1, 50)
    xy = np.column_stack([3 - 2 * t, 1 - 2 * t])  # moving towards -x, -y
    line = fit_line(xy)
    # exact data: direction and length are exact up to rounding
    np.testing.assert_allclose(line.params["direction"], -np.ones(2) / np.sqrt(2), atol=1e-12)
    np.testing.assert_allclose(line.length, np.hypot(2, 2), atol=1e-12)
    assert line.residual < 1e-12


def test_circle_fit_recovers_exact_arc():
    arc = fit_circle(arc_points(2.5, 1.0))
    # noise-free points lie on the circle: centre, radius exact to solver precision
    np.testing.assert_allclose(arc.params["centre"], [1.0, -2.0], atol=1e-9)
    np.testing.assert_allclose(arc.params["radius"], 2.5, atol=1e-9)
    np.testing.assert_allclose(arc.arc_angle, 1.0, atol=1e-9)
    assert arc.params["turn"] == 1.0
    clockwise = fit_circle(arc_points(2.5, 1.0)[::-1])
    assert clockwise.params["turn"] == -1.0 and clockwise.arc_angle < 0


def test_short_noisy_arc_radius_is_less_biased_than_kasa():
    # 25 degree arc of radius 3 m with 1 cm noise: Kåsa shrinks the radius (known bias)
    ours, theirs = [], []
    for seed in range(40):
        xy = arc_points(3.0, np.deg2rad(25), n=110, noise=0.01, seed=seed)
        ours.append(fit_circle(xy).params["radius"])
        theirs.append(kasa(xy))
    bias_ours = abs(np.mean(ours) - 3.0)
    bias_kasa = abs(np.mean(theirs) - 3.0)
    assert bias_ours < 0.5 * bias_kasa, (bias_ours, bias_kasa)
    # mean over 40 trials: the Hyper+LM radius is within 5 % of the truth
    np.testing.assert_allclose(np.mean(ours), 3.0, rtol=0.05)


def test_choice_line_for_straight_with_sway_arc_for_curve_point_on_the_spot():
    t = np.arange(0, 1.1, 0.01)
    straight = np.column_stack([1.2 * t, 0.02 * np.sin(2 * np.pi * t / 1.1)])
    assert fit_pattern(straight).kind == "line"
    curve = arc_points(2.0, 0.6, noise=0.002)
    chosen = fit_pattern(curve)
    assert chosen.kind == "arc"
    np.testing.assert_allclose(chosen.arc_angle, 0.6, atol=0.02)  # 2 mm noise on a 1.2 m arc
    spot = np.column_stack([0.02 * np.cos(4 * np.pi * t), 0.02 * np.sin(2 * np.pi * t)])
    assert fit_pattern(spot).kind == "point"


def cycle(*, v_f=1.2, v_l=0.0, omega=0.0, period=1.1, noise=0.001):
    t = np.arange(0, 3.0, 1 / RATE)
    left, right = shoulders(t, v_f=v_f, v_l=v_l, omega=omega, period=period, noise=noise)
    return cycle_velocities(left, right, RATE, 0.403, 0.403 + period)


@pytest.mark.parametrize("v_f, v_l, omega", [
    (1.2, 0.0, 0.0),      # straight
    (1.2, 0.0, 0.6),      # left curve, radius 2 m
    (1.2, 0.0, -0.4),     # right curve, radius 3 m
    (0.6, 0.0, 0.6),      # slow, radius 1 m
    (0.0, 0.5, 0.0),      # side-step to the left
    (0.0, -0.5, 0.0),     # side-step to the right
    (0.5, 0.5, 0.0),      # diagonal forward-left
    (-0.4, -0.3, 0.0),    # diagonal backward-right
    (0.0, 0.0, 1.2),      # on the spot, turning left
    (0.0, 0.0, -1.2),     # on the spot, turning right
])
def test_velocities_and_signs(v_f, v_l, omega):
    got = cycle(v_f=v_f, v_l=v_l, omega=omega)
    speed = np.hypot(v_f, v_l)
    # truth of model (2); tolerances are the targets (2 % or 0.02 m/s, 0.02 rad/s)
    np.testing.assert_allclose(got.v, speed, atol=max(0.02 * speed, 0.02))
    np.testing.assert_allclose(got.omega, omega, atol=0.02)
    np.testing.assert_allclose(got.v_l, v_l, atol=0.02)
    np.testing.assert_allclose(got.v_f, v_f, atol=0.02)
    assert got.pattern.kind == ("point" if speed == 0 else "arc" if omega else "line")


def test_missing_shoulders_named():
    t = np.arange(0, 3.0, 1 / RATE)
    left, right = shoulders(t)
    left[30:120] = np.nan
    with pytest.raises(EventError, match="left shoulder missing"):
        cycle_velocities(left, right, RATE, 0.4, 1.5, source="walk.c3d")
    with pytest.raises(EventError, match="not after its start"):
        cycle_velocities(left, right, RATE, 1.5, 1.5)
