"""Long takes: the stages that work on a window of frames, or on blocks of frames or columns,
give the numbers of the direct computation over the whole capture, to the bit.

Each test runs the windowed or blocked computation on data long enough to need several
windows (or with the block size made small) and compares it with the direct one written out
here (or the same function with one block holding everything)."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
from conftest import SAMPLES

from mocaplib import skeleton as skeleton_module
from mocaplib.build.workflow import cycle_shapes
from mocaplib.gait import criteria, qc
from mocaplib.gait.cycles import _events_between, longest_gap, motion_cycles
from mocaplib.gait.events import _lost_stances, capture_events, lost_stance
from mocaplib.gait.foot_events import GaitEvent
from mocaplib.gait.patterns import cycle_times
from mocaplib.io.c3d import read_c3d
from mocaplib.markersets.matching import match_trial
from mocaplib.model import filtering
from mocaplib.model.fitting import fit_capture
from mocaplib.runs import frames_within, valid_runs
from mocaplib.skeleton import DOF_NAMES, Skeleton

RATES = (100.0, 120.0, 29.97, 250.0, 1000.0 / 3.0)


def mask_within(start_s, end_s, rate, n_frames):
    frames = np.arange(n_frames) / rate
    return (frames >= start_s) & (frames <= end_s)


def test_frames_within_is_the_mask_of_frame_times():
    rng = np.random.default_rng(0)
    for _ in range(3000):
        n, rate = int(rng.integers(0, 400)), float(rng.choice(RATES))
        frames = np.arange(n) / rate
        if n and rng.random() < 0.6:     # on a frame's time, or one rounding step beside it
            start, end = (frames[rng.integers(0, n)] for _ in range(2))
            start = rng.choice([start, np.nextafter(start, -1), np.nextafter(start, 9)])
            end = rng.choice([end, np.nextafter(end, -1), np.nextafter(end, 9)])
        else:
            start, end = rng.uniform(-1, n / rate + 1, 2)
        chosen = np.zeros(n, dtype=bool)
        chosen[frames_within(start, end, rate, n)] = True
        np.testing.assert_array_equal(chosen, mask_within(start, end, rate, n),
                                      err_msg=f"{start!r}..{end!r} s at {rate} Hz, {n} frames")
    for start, end in ((-np.inf, np.inf), (-np.inf, 0.5), (0.5, np.inf), (np.nan, 1.0)):
        chosen = np.zeros(300, dtype=bool)
        chosen[frames_within(start, end, 100.0, 300)] = True
        np.testing.assert_array_equal(chosen, mask_within(start, end, 100.0, 300))


def resample_every_frame(values, rate, times, jointly=False):
    """The direct computation: each column interpolated over all of its finite samples."""
    if jointly:
        values = np.where(np.isfinite(values).all(axis=1)[:, None], values, np.nan)
    frames = np.arange(len(values)) / rate
    out = np.full((len(times), values.shape[1]), np.nan)
    for column in range(values.shape[1]):
        valid = np.isfinite(values[:, column])
        if valid.any():
            out[:, column] = np.interp(times, frames[valid], values[valid, column])
    return out


@pytest.mark.parametrize("jointly", [False, True])
def test_resample_reads_a_window_and_gives_the_whole_columns_numbers(jointly):
    rng = np.random.default_rng(1)
    rate = 100.0
    values = np.cumsum(rng.normal(size=(100_000, 3)), axis=0)     # a 17-minute take
    for start, stop, column in ((500, 530, 0), (40_000, 40_900, slice(None)), (99_990, None, 1),
                                (0, 7, 2), (70_000, 70_010, 1)):
        values[start:stop, column] = np.nan
    values[:, 2][60_000:61_000] = np.nan
    cases = [np.linspace(4.2, 5.4, 90),            # a gap at the window's start (fallback)
             np.linspace(400.0, 401.1, 110),       # a gap inside the window
             np.linspace(399.95, 409.05, 200),     # the window ends in a gap
             np.linspace(999.5, 1001.0, 30),       # beyond the last finite sample
             np.linspace(-1.0, 0.2, 10),           # before the first frame
             np.array([123.456]), np.array([599.994, 600.004]), np.array([700.0, 700.05]),
             np.linspace(2.0, 1.0, 12)]            # not in order
    for times in cases:
        np.testing.assert_array_equal(
            filtering.resample(values, rate, times, jointly=jointly),
            resample_every_frame(values, rate, times, jointly), err_msg=f"{times[[0, -1]]}")


def test_resample_fuzzed_against_every_frame():
    rng = np.random.default_rng(2)
    for _ in range(1500):
        n, columns, rate = int(rng.integers(0, 150)), int(rng.integers(1, 4)), \
            float(rng.choice(RATES))
        values = rng.normal(size=(n, columns))
        for _ in range(int(rng.integers(0, 6))):
            first = int(rng.integers(0, max(n, 1)))
            values[first:first + int(rng.integers(1, 30)),
                   int(rng.integers(0, columns)) if rng.random() < 0.5 else slice(None)] = np.nan
        start = rng.uniform(-0.2, n / rate + 0.2)
        times = np.sort(np.r_[start, rng.uniform(start, start + 0.4, rng.integers(0, 12))])
        for jointly in (False, True):
            np.testing.assert_array_equal(filtering.resample(values, rate, times, jointly=jointly),
                                          resample_every_frame(values, rate, times, jointly))


def markers_with_gaps(frames=3000, markers=4, seed=3):
    """A smooth (F, M, 3) walk-like track with noise, gaps and one spike."""
    rng = np.random.default_rng(seed)
    t = np.arange(frames)[:, None, None] / 100.0
    data = (np.sin(2 * np.pi * 0.9 * t + rng.uniform(0, 6, (1, markers, 3)))
            + 0.002 * rng.normal(size=(frames, markers, 3)))
    data[700:760, 1] = np.nan
    data[1500:1504, 2, 0] = np.nan
    data[:30, 3] = np.nan
    data[2040:2042, 0] += 2.0      # a spike across a block boundary (BLOCK_SAMPLES 2048: 170
    return data                    # frames a block for 4 markers)


@pytest.fixture
def one_block(monkeypatch):
    """Run the filter's functions with every run (and every cutoff) in one block."""
    def run(function, *args):
        with monkeypatch.context() as patch:
            patch.setattr(filtering, "BLOCK_SAMPLES", 1 << 40)
            return function(*args)
    return run


def test_filter_blocks_give_the_numbers_of_one_block(monkeypatch, one_block):
    data = markers_with_gaps()
    cutoffs = np.arange(1.0, 37.5, 0.5)
    whole = [one_block(filtering.lowpass, data, 100.0, 6.0),
             one_block(filtering.residual_curve, data, 100.0, cutoffs),
             one_block(filtering.remove_spikes, data, 100.0)]
    monkeypatch.setattr(filtering, "BLOCK_SAMPLES", 2048)   # 3000-frame runs one by one
    blocked = [filtering.lowpass(data, 100.0, 6.0),
               filtering.residual_curve(data, 100.0, cutoffs),
               filtering.remove_spikes(data, 100.0)]
    for name, a, b in zip(("lowpass", "residual_curve", "remove_spikes"), blocked, whole):
        np.testing.assert_array_equal(a, b, err_msg=name)
    assert np.isnan(blocked[2][2040:2042, 0]).all(), "the spike across two blocks is found"


def test_forward_and_points_by_frame_blocks(monkeypatch):
    rng = np.random.default_rng(4)
    skeleton = Skeleton.from_height(1.7)
    q = np.cumsum(rng.normal(scale=0.02, size=(1000, len(DOF_NAMES))), axis=0)
    q[10:14] = np.nan
    segments = rng.integers(0, 13, 9)
    offsets = rng.normal(scale=0.1, size=(9, 3))
    transforms = skeleton.chain(q)[0]
    chosen = transforms[:, segments]
    direct = (chosen[..., :3, :3] @ offsets[..., None])[..., 0] + chosen[..., :3, 3]
    monkeypatch.setattr(skeleton_module, "FRAME_BLOCK", 64)
    np.testing.assert_array_equal(skeleton.forward(q), transforms)
    np.testing.assert_array_equal(skeleton.forward(q, segments=[5, 2]), transforms[:, [5, 2]])
    np.testing.assert_array_equal(skeleton.points(q, segments, offsets), direct)
    np.testing.assert_array_equal(skeleton.points(q, segments, offsets, transforms=transforms),
                                  direct)
    assert skeleton.forward(q[0]).shape == (1, 13, 4, 4)


def test_segment_energies_by_frame_blocks(monkeypatch):
    rng = np.random.default_rng(5)
    skeleton = Skeleton.from_height(1.8)
    q = np.cumsum(rng.normal(scale=0.01, size=(1001, len(DOF_NAMES))), axis=0)
    direct = criteria._energies(skeleton, q, 100.0, False, criteria.bodies(skeleton))
    for block in (7, 100, 1000, 2000):             # several blocks, the last one short
        monkeypatch.setattr(criteria, "ENERGY_BLOCK", block)
        np.testing.assert_array_equal(criteria.segment_energies(skeleton, q, 100.0), direct,
                                      err_msg=f"blocks of {block} frames")


def longest_gap_every_frame(filled, rate, start_s, end_s):
    """The direct computation: every run of filled frames of the capture, counted inside."""
    inside = mask_within(start_s, end_s, rate, len(filled))
    longest = 0.0
    for first, stop in valid_runs(filled).tolist():
        n = int(inside[first:stop].sum())
        if n and (first == 0 or stop == len(filled)):
            return float("inf")
        if n:
            longest = max(longest, (n + 1) / rate)
    return longest


def test_longest_gap_looks_at_the_cycle_only():
    rng = np.random.default_rng(6)
    for _ in range(2000):
        n = int(rng.integers(1, 300))
        filled = rng.random(n) < rng.choice([0.05, 0.5, 0.95])
        start = rng.uniform(-0.1, n / 100.0)
        end = start + rng.uniform(0, 1.5)
        assert longest_gap(filled, 100.0, start, end) == \
            longest_gap_every_frame(filled, 100.0, start, end), (filled.tolist(), start, end)


def test_events_between_are_those_a_scan_finds():
    rng = np.random.default_rng(7)
    times = np.round(rng.uniform(0, 60, 400), 2)          # ties included
    events = [GaitEvent(str(rng.choice(["left", "right"])), "toe_off", float(t), 0, 1.0)
              for t in times]                              # in no order
    between = _events_between(events)
    for start, end in [(0.0, 60.0), (-1, 0.0)] + [tuple(sorted(rng.uniform(-1, 61, 2)))
                                                  for _ in range(300)]:
        assert between(start, end) == [e for e in events if start <= e.time_s <= end]


def lost_stances_every_pair(airborne, rate, n_frames):
    """The direct computation: every span of one foot against every swing of the other."""
    out = []
    for side, other in ((a, b) for a in airborne for b in airborne if a != b):
        for start, end in airborne[side]:
            for inner_start, inner_end in airborne[other]:
                if start < inner_start and inner_end < end:
                    out += lost_stance(side, (start, end), other, (inner_start, inner_end),
                                       rate, n_frames)
    return out


def test_lost_stances_search_the_other_foots_swings_by_time():
    rng = np.random.default_rng(8)
    for _ in range(300):
        airborne = {}
        for side in ("left", "right"):
            edges = np.sort(rng.choice(5000, size=2 * int(rng.integers(0, 40)), replace=False))
            airborne[side] = [(int(a), int(b)) for a, b in edges.reshape(-1, 2)]
        assert _lost_stances(airborne, 100.0, 5000) == \
            lost_stances_every_pair(airborne, 100.0, 5000)


def test_outlier_samples_by_frame_blocks(monkeypatch):
    rng = np.random.default_rng(9)
    residuals = np.abs(rng.normal(scale=0.003, size=(1000, 6)))
    residuals[rng.random(residuals.shape) < 0.02] += 0.05          # spikes
    residuals[100:140, 2] = np.nan
    motion = SimpleNamespace(residuals=residuals, rejected=rng.random(residuals.shape) < 0.01)
    whole = qc.outlier_samples(motion)
    for block in (7, 256, 999):
        monkeypatch.setattr(qc, "OUTLIER_BLOCK", block)
        np.testing.assert_array_equal(qc.outlier_samples(motion), whole,
                                      err_msg=f"blocks of {block} frames")
    monkeypatch.setattr(qc, "OUTLIER_BLOCK", 1 << 30)
    np.testing.assert_array_equal(qc.outlier_samples(motion), whole)


@pytest.mark.usefixtures("sample_dir")
def test_cycle_shapes_give_the_numbers_of_each_cycle_alone():
    # every cycle of a take from one unwrapping of the whole motion
    trial = read_c3d(SAMPLES / "turn_spot_left_normal.c3d")
    match = match_trial(trial)
    motion = fit_capture(trial, protocol=match.protocol).motion
    events, ground = capture_events(trial, match, motion=motion)
    cycles = motion_cycles(events, motion, ground=ground)
    assert len(cycles) >= 2
    shapes = cycle_shapes(motion, cycles)
    for cycle in cycles:   # the direct computation: the whole take unwrapped for each cycle
        times = cycle_times(cycle.start_s, cycle.end_s, motion.rate)[:-1]
        q = filtering.resample(np.unwrap(motion.q, axis=0), motion.rate, times)
        direct = cycle.encoding.drift.remove(q, times - cycle.start_s)
        assert np.array_equal(shapes[cycle.index]["q"], direct)
        assert np.array_equal(shapes[cycle.index]["phase"],
                              (times - cycle.start_s) / cycle.period)
