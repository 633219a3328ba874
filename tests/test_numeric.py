"""The shared reductions equal numpy's own to the bit."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from mocaplib.numeric import distinct, median, nanmedian, nanpercentile, percentile


SHAPES = [(7,), (8,), (1, 5), (60, 3), (59, 4, 3), (700, 3)]


def _values(shape, *, missing=0.3):
    """Values spread over 15 orders of magnitude, some infinite and some NaN (a whole slice
    of the last axis too)."""
    rng = np.random.default_rng(len(shape) * 100 + shape[0])
    values = rng.normal(size=shape) * np.exp(rng.uniform(-10.0, 5.0, size=shape))
    values[rng.random(shape) < missing] = np.nan
    values.flat[::11] = np.inf
    if values.ndim > 1 and missing:
        values[..., 0] = np.nan
    return values


def _same(got, expected):
    return np.shape(got) == np.shape(expected) and \
        np.asarray(got).tobytes() == np.asarray(expected).tobytes()


@pytest.mark.parametrize("shape", SHAPES)
def test_nanmedian_and_median_are_numpys_to_the_bit(shape):
    # short and long axes (numpy takes its masked-array path below 600), odd and even counts,
    # missing samples, infinities, whole slices missing
    for missing in (0.3, 0.0):
        values = _values(shape, missing=missing)
        for axis in [None, *range(values.ndim), -1]:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", RuntimeWarning)      # numpy's all-NaN slices
                assert _same(nanmedian(values, axis=axis), np.nanmedian(values, axis=axis))
                assert _same(median(values, axis=axis), np.median(values, axis=axis))


@pytest.mark.parametrize("shape", SHAPES)
def test_percentile_is_numpys_to_the_bit(shape):
    for missing in (0.3, 0.0):
        values = _values(shape, missing=missing)
        for axis in range(values.ndim):
            for q in ([10, 90], [0.0, 33.3, 50.0, 99.9, 100.0], 25):
                with np.errstate(invalid="ignore"):                  # inf - inf, in both
                    assert _same(percentile(values, q, axis=axis),
                                 np.percentile(values, q, axis=axis)), (axis, q)


@pytest.mark.parametrize("shape", SHAPES)
def test_nanpercentile_is_numpys_to_the_bit(shape):
    # the floor under the feet (model.floor) takes its heights' low percentiles, on the fit's
    # path, where np.nanpercentile would import numpy.ma
    for missing in (0.3, 0.0):
        values = _values(shape, missing=missing)
        for axis in range(values.ndim):
            for q in ([10, 90], [0.0, 33.3, 50.0, 99.9, 100.0], 5):
                with warnings.catch_warnings(), np.errstate(invalid="ignore"):
                    warnings.simplefilter("ignore", RuntimeWarning)  # numpy's all-NaN slices
                    assert _same(nanpercentile(values, q, axis=axis),
                                 np.nanpercentile(values, q, axis=axis)), (axis, q)


def test_distinct_is_numpys_unique():
    rng = np.random.default_rng(0)
    for size in (0, 1, 5, 40):
        values = rng.integers(-3, 9, size=size)
        assert _same(distinct(values), np.unique(values))


def test_nanmedian_of_nothing_seen_is_nan_without_a_warning():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert np.isnan(nanmedian(np.full(4, np.nan)))
        assert np.isnan(nanmedian(np.zeros((0, 3)), axis=0)).all()
        assert nanmedian(np.array([[1.0, np.nan], [3.0, np.nan]]), axis=0).tobytes() == \
            np.array([2.0, np.nan]).tobytes()
