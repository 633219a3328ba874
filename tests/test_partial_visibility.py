"""Captures in which the subject is in view for part of the time: a 250 Hz run seen for about
1.2 strides gives an entry cut at the protocol's fallback event, flagged; gaps inside a cycle
are filled up to max_gap_s only; the build says why a capture gave no entry."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from mocaplib.build.pipeline import build_library
from mocaplib.build.settings import BuildSettings
from mocaplib.build.workflow import process_capture
from mocaplib.library.command import Command
from mocaplib.synth.capture import synthesize_capture, write_capture
from mocaplib.trial import Trial

RATE = 250.0
#: The protocol of the synthetic captures, with the fallback cycle starts a lab would name.
FALLBACK_PROTOCOL = ('extends = "fullbody38"\n[cycles]\n'
                     'fallback_starts = ["right_toe_off", "left_heel_strike", '
                     '"right_heel_strike"]\n')


def _hidden(capture, visible) -> Trial:
    """The capture's trial with every marker NaN in the frames outside ``visible`` (F,) bool."""
    trial = capture.trial
    markers = np.where(visible[:, None, None], trial.markers, np.nan)
    return Trial(markers, trial.labels, trial.rate, events=trial.events, source=trial.source)


def _truth_times(capture, side, kind) -> np.ndarray:
    return np.array([e["time_s"] for e in capture.truth["events"]
                     if e["side"] == side and e["kind"] == kind])


@pytest.fixture(scope="module", params=[3.0, 4.0], ids=["3.0m_s", "4.0m_s"])
def short_run(request, tmp_path_factory):
    """A 250 Hz run in view for 1.2 strides from 0.15 stride before its first right toe-off:
    one left toe-off, two right toe-offs. Returns (capture path, fallback protocol path,
    synthetic capture, path of the same run in view throughout)."""
    folder = tmp_path_factory.mktemp("run")
    capture = synthesize_capture(Command.from_kind("run", speed=request.param), duration=3.0,
                                 seed=3, rate=RATE)
    stride = capture.params.stride
    start = _truth_times(capture, "right", "toe_off")[0] - 0.15 * stride
    time = np.arange(capture.trial.n_frames) / RATE
    visible = (time >= start) & (time <= start + 1.2 * stride)
    path, _ = write_capture(replace(capture, trial=_hidden(capture, visible)), folder,
                            f"run_{request.param:.1f}_partial")
    full, _ = write_capture(capture, folder, f"run_{request.param:.1f}")
    protocol = folder / "fullbody38_fallback.toml"
    protocol.write_text(FALLBACK_PROTOCOL)
    return path, protocol, capture, full


@pytest.mark.slow
def test_a_short_run_at_250_hz_gives_an_entry_from_its_right_toe_off(short_run):
    from mocaplib.library.validation import control_space_warning, validate_library

    path, protocol, capture, full = short_run
    result = build_library([path], BuildSettings(protocol=str(protocol)), progress=False)
    assert result.ok and len(result.library) == 1, result.summary_text()
    entry = result.library.entries[0]
    assert entry.cycle_start == "right_toe_off" and entry.right_toe_off_s == 0.0
    # bounds and the left toe-off inside against the generator's events: within 10 ms (the
    # toe-off target; 2.5 frames at 250 Hz)
    right, left = _truth_times(capture, "right", "toe_off"), _truth_times(capture, "left",
                                                                         "toe_off")
    first = right[np.argmin(np.abs(right - entry.start_s))]
    next_right = right[right > first][0]
    np.testing.assert_allclose([entry.start_s, entry.end_s], [first, next_right], atol=0.010)
    inside = left[(left > first) & (left < next_right)]
    assert len(inside) == 1
    np.testing.assert_allclose(entry.left_toe_off_s, inside[0] - first, atol=0.010)
    # velocities against the truth of a cycle of the same steady run (the targets:
    # v̂ within 2 %, ω̂ and v̂_l within 0.02)
    truth = capture.truth["cycles"][0]
    np.testing.assert_allclose(entry.v, truth["v"], rtol=0.02)
    np.testing.assert_allclose(entry.omega, truth["omega"], atol=0.02)
    np.testing.assert_allclose(entry.T, capture.params.stride, atol=0.010)
    # v̂_l: as the same run seen in full gives it (its cycles: -0.020 to -0.033 m/s at 3 and
    # 4 m/s, calibrated from the capture itself without a static: a heading bias of the
    # self-calibration, not of the short window), within 0.005 m/s of their mean
    seen_in_full = process_capture(full, BuildSettings(all_cycles=True)).entries
    assert len(seen_in_full) >= 3
    np.testing.assert_allclose(entry.v_l, np.mean([e.v_l for e in seen_in_full]), atol=0.005)
    # a valid library: one entry spans no control space, which is said, not a problem
    assert validate_library(result.library) == []
    assert control_space_warning(result.library).startswith("no control space")


@pytest.mark.slow
def test_without_a_fallback_the_short_run_gives_no_entry_and_says_why(short_run):
    path, _, _, _ = short_run
    result = process_capture(path, BuildSettings())
    assert result.ok and not result.entries
    assert result.no_entry.startswith("no complete cycle: fewer than two left toe-offs")
    # the reason names the window the subject is in view, and how to let cycles start elsewhere
    assert "the fit sees the subject in " in result.no_entry
    assert "out of the capture volume" in result.no_entry
    assert "fallback_starts" in result.no_entry


@pytest.fixture(scope="module")
def walk_with_a_hole():
    """A 100 Hz straight walk (1.2 m/s) and a function writing it with every marker missing
    for ``gap`` seconds from 3.0 s (inside the cycle 2.43-3.52 s)."""
    capture = synthesize_capture(Command.from_kind("straight", speed=1.2), duration=6.0, seed=4)

    def write(folder, gap: float):
        time = np.arange(capture.trial.n_frames) / capture.trial.rate
        hole = (time > 3.0) & (time < 3.0 + gap)
        path, _ = write_capture(replace(capture, trial=_hidden(capture, ~hole)), folder,
                                f"hole_{gap:g}")
        return path

    return write


def _spans(cycles, start, end) -> bool:
    return any(c["start_s"] < start and c["end_s"] > end for c in cycles)


@pytest.mark.slow
@pytest.mark.parametrize("gap, max_gap_s, spanned", [(0.15, 0.25, True), (0.4, 0.25, False),
                                                     (0.4, 0.5, True)])
def test_a_cycle_spans_a_gap_only_up_to_max_gap_s(walk_with_a_hole, tmp_path, gap, max_gap_s,
                                                   spanned):
    path = walk_with_a_hole(tmp_path, gap)
    result = process_capture(path, BuildSettings(all_cycles=True, qc_policy="waive",
                                                 max_gap_s=max_gap_s))
    assert result.ok, result.error
    cycles = result.diagnostics["cycles"]
    assert _spans(cycles, 3.0, 3.0 + gap) == spanned
    assert len(cycles) >= 3       # the cycles clear of the hole stay


def test_a_jump_gives_no_fallback_cycle(real_c3d, tmp_path):
    """cmu/16_07, a forward jump: both feet leave together (toe-offs 5 ms apart) and land
    together; with every fallback start allowed it still holds no stride in gait order, so it
    gives no entry, and says so."""
    protocol = tmp_path / "plugin_gait_fallback.toml"
    protocol.write_text(FALLBACK_PROTOCOL.replace("fullbody38", "plugin_gait"))
    result = process_capture(real_c3d("cmu/16_07.c3d"), BuildSettings(protocol=str(protocol)))
    assert result.ok and not result.entries
    assert result.no_entry.startswith(
        "no complete cycle: fewer than two left toe-offs were found, and no cycle from "
        "right_toe_off or left_heel_strike or right_heel_strike holds one stride's events in "
        "gait order")
