"""Array reductions equal to numpy's own to the bit, without numpy.ma: ``np.nanmedian`` along
an axis shorter than 600 goes through a masked array (~0.1 ms a call), and ``np.median``,
``np.percentile``, ``np.nanpercentile`` and ``np.unique`` (numpy 2) look numpy.ma up, which imports it (~7 ms of a
command's start-up). The stages of ``mocaplib fit`` use these instead."""

from __future__ import annotations

import numpy as np


def nanmedian(values: np.ndarray, /, *, axis: int | None = None) -> np.ndarray | np.float64:
    """Median of ``values`` over its non-NaN entries along ``axis`` (all entries when None):
    the array without that axis, or a scalar; NaN where no entry is seen (without
    ``np.nanmedian``'s warning). The middle value, or the mean of the two middle values, of
    the sorted entries, as ``np.nanmedian`` computes it."""
    values = np.asarray(values, dtype=np.float64)
    if axis is None:
        values, axis = values.ravel(), 0
    if values.shape[axis] == 0:
        return np.full(np.delete(values.shape, axis), np.nan)[()]
    ordered = np.sort(values, axis=axis)                                   # NaN sort last
    count = np.expand_dims((~np.isnan(values)).sum(axis=axis), axis)
    low = np.take_along_axis(ordered, np.maximum(count - 1, 0) // 2, axis=axis)
    high = np.take_along_axis(ordered, count // 2, axis=axis)
    return np.where(count > 0, 0.5 * (low + high), np.nan).squeeze(axis)[()]


def median(values: np.ndarray, /, *, axis: int | None = None) -> np.ndarray | np.float64:
    """``np.median`` of ``values`` along ``axis`` (all entries when None): as
    :func:`nanmedian`, but NaN where a NaN is among the entries."""
    values = np.asarray(values, dtype=np.float64)
    return np.where(np.isnan(values).any(axis=axis), np.nan, nanmedian(values, axis=axis))[()]


def percentile(values: np.ndarray, q, /, *, axis: int) -> np.ndarray:
    """``np.percentile`` (its default, linear method) of ``values`` along ``axis`` at the
    percentages ``q`` (scalar or 1-D): shape ``np.shape(q)`` + the shape of ``values`` without
    ``axis``; NaN where a NaN is among the entries. The entry at (n − 1) q / 100 of the n sorted
    ones (partitioned there, not sorted), interpolated between its neighbours as numpy
    interpolates."""
    values = np.asarray(values, dtype=np.float64)
    n, q = values.shape[axis], np.asarray(q, dtype=np.float64)
    at = (n - 1) * np.true_divide(q.ravel(), 100)
    below = np.floor(at).astype(np.intp)
    above = below + 1
    below[at >= n - 1], above[at >= n - 1] = n - 1, n - 1
    kth = distinct(np.r_[below, above, n - 1]) if n else None      # the last: NaN sort last
    ordered = np.moveaxis(np.partition(values, kth, axis=axis) if n else values, axis, 0)
    gamma = (at - below).reshape(at.shape + (1,) * (ordered.ndim - 1))
    low, high = ordered[below], ordered[above]
    step = high - low
    out = np.where(gamma >= 0.5, high - step * (1 - gamma), low + step * gamma)
    return np.where(np.isnan(ordered[-1]), np.nan, out).reshape(q.shape + ordered.shape[1:])


def nanpercentile(values: np.ndarray, q, /, *, axis: int) -> np.ndarray:
    """``np.nanpercentile`` of ``values`` along ``axis`` at the percentages ``q``: as
    :func:`percentile` over the non-NaN entries of each slice; NaN where there is none."""
    values = np.moveaxis(np.asarray(values, dtype=np.float64), axis, -1)
    out = np.full(np.shape(q) + values.shape[:-1], np.nan)
    for index in np.ndindex(values.shape[:-1]):
        seen = values[index][~np.isnan(values[index])]
        if seen.size:
            out[(Ellipsis,) + index] = percentile(seen, q, axis=0)
    return out


def distinct(values: np.ndarray, /) -> np.ndarray:
    """The distinct entries of the integer array ``values``, sorted, 1-D (as ``np.unique``)."""
    ordered = np.sort(np.ravel(values))
    return ordered[np.r_[True, ordered[1:] != ordered[:-1]]] if ordered.size else ordered
