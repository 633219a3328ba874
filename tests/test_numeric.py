"""The shared reductions equal numpy's own to the bit."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from mocaplib.numeric import nanmedian


@pytest.mark.parametrize("shape", [(7,), (8,), (1, 5), (60, 3), (59, 4, 3), (700, 3)])
def test_nanmedian_is_numpys_to_the_bit(shape):
    # short and long axes (numpy takes its masked-array path below 600), odd and even counts,
    # missing samples, infinities, whole slices missing
    rng = np.random.default_rng(len(shape) * 100 + shape[0])
    values = rng.normal(size=shape) * np.exp(rng.uniform(-10.0, 5.0, size=shape))
    values[rng.random(shape) < 0.3] = np.nan
    values.flat[::11] = np.inf
    if values.ndim > 1:
        values[..., 0] = np.nan
    for axis in [None, *range(values.ndim), -1]:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)          # numpy's all-NaN slices
            expected = np.nanmedian(values, axis=axis)
        got = nanmedian(values, axis=axis)
        assert np.shape(got) == np.shape(expected)
        assert np.asarray(got).tobytes() == np.asarray(expected).tobytes(), axis


def test_nanmedian_of_nothing_seen_is_nan_without_a_warning():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert np.isnan(nanmedian(np.full(4, np.nan)))
        assert np.isnan(nanmedian(np.zeros((0, 3)), axis=0)).all()
        assert nanmedian(np.array([[1.0, np.nan], [3.0, np.nan]]), axis=0).tobytes() == \
            np.array([2.0, np.nan]).tobytes()
