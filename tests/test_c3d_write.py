"""write_c3d: files that ezc3d (the reference reader) reads back exactly, byte-for-byte
repeatable."""

from __future__ import annotations

import numpy as np
import pytest

from mocaplib.errors import C3DError
from mocaplib.io.c3d_write import write_c3d
from mocaplib.trial import Event

ezc3d = pytest.importorskip("ezc3d")

EVENTS = [Event("Right", "Foot Off", 0.5), Event("Left", "Foot Strike", 0.25),
          Event("General", "Start", 61.5)]


def walk_like(frames=40, count=7, seed=0):
    """Markers (F, M, 3) in metres around a standing person, with gaps (NaN)."""
    rng = np.random.default_rng(seed)
    markers = rng.uniform(-2.0, 2.0, size=(frames, count, 3))
    markers[:, :, 2] = rng.uniform(0.0, 1.9, size=(frames, count))
    markers[3:9, 1] = np.nan          # a gap in the middle
    markers[:2, 2] = np.nan           # missing at the start
    markers[-1, 3] = np.nan           # missing at the end
    return markers


def ezc3d_markers(path):
    """ezc3d's points as (F, M, 3) metres (it returns (4, M, F) in the file's mm)."""
    points = ezc3d.c3d(str(path))["data"]["points"]
    return points[:3].transpose(2, 1, 0) / 1000.0


@pytest.mark.parametrize("integer", [False, True])
def test_round_trip_through_ezc3d(tmp_path, integer):
    markers = walk_like()
    labels = [f"M{i}" for i in range(markers.shape[1])]
    path = write_c3d(tmp_path / "walk.c3d", markers, labels, 120.0, events=EVENTS,
                     integer=integer, first_frame=11)
    got = ezc3d_markers(path)
    np.testing.assert_array_equal(np.isnan(got), np.isnan(markers))
    # float32 of millimetres is exact to ~1e-4 mm; integer storage rounds to half of
    # POINT:SCALE, a power of two <= 2000 mm / 32767 ~ 0.061 mm, so 0.0625 mm / 2 at most.
    atol = 3.2e-5 if integer else 1e-7
    np.testing.assert_allclose(got, markers, atol=atol, equal_nan=True)

    c3d = ezc3d.c3d(str(path))
    point = c3d["parameters"]["POINT"]
    assert point["LABELS"]["value"] == labels
    assert point["RATE"]["value"][0] == 120.0
    assert point["UNITS"]["value"] == ["mm"]
    assert (point["SCALE"]["value"][0] > 0) == integer
    assert c3d["header"]["points"]["first_frame"] == 10  # ezc3d counts frames from 0

    event = c3d["parameters"]["EVENT"]
    assert event["USED"]["value"][0] == 3
    assert event["CONTEXTS"]["value"] == ["Left", "Right", "General"]  # sorted by time
    assert event["LABELS"]["value"] == ["Foot Strike", "Foot Off", "Start"]
    np.testing.assert_array_equal(event["TIMES"]["value"], [[0, 0, 1], [0.25, 0.5, 1.5]])
    np.testing.assert_array_equal(event["ICON_IDS"]["value"], [1, 2, 0])
    np.testing.assert_array_equal(event["GENERIC_FLAGS"]["value"], [0, 0, 1])


def test_more_than_255_labels_go_to_labels2(tmp_path):
    markers = walk_like(frames=5, count=300)
    labels = [f"Subject:Marker{i:03d}" for i in range(300)]
    path = write_c3d(tmp_path / "many.c3d", markers, labels, 100.0)
    point = ezc3d.c3d(str(path))["parameters"]["POINT"]
    assert point["USED"]["value"][0] == 300
    assert point["LABELS"]["value"] + point["LABELS2"]["value"] == labels
    np.testing.assert_allclose(ezc3d_markers(path), markers, atol=1e-7, equal_nan=True)


def test_units_are_applied(tmp_path):
    markers = walk_like(frames=12, count=4)[:, :2]
    path = write_c3d(tmp_path / "metres.c3d", markers, ["A", "B"], 50.0, units="m")
    c3d = ezc3d.c3d(str(path))
    assert c3d["parameters"]["POINT"]["UNITS"]["value"] == ["m"]
    # float32 of values below 2 m: relative precision 6e-8.
    np.testing.assert_allclose(c3d["data"]["points"][:3].transpose(2, 1, 0), markers,
                               atol=2e-7, equal_nan=True)


def test_same_input_gives_same_bytes(tmp_path):
    markers = walk_like()
    labels = [f"M{i}" for i in range(markers.shape[1])]
    first = write_c3d(tmp_path / "a.c3d", markers, labels, 100.0, events=EVENTS).read_bytes()
    second = write_c3d(tmp_path / "b.c3d", markers, labels, 100.0, events=EVENTS).read_bytes()
    assert first == second
    assert len(first) % 512 == 0


@pytest.mark.parametrize("markers, labels, kwargs, match", [
    (np.zeros((4, 2)), ["A", "B"], {}, r"shape \(F, M, 3\)"),
    (np.zeros((4, 2, 3)), ["A"], {}, "1 labels for 2 markers"),
    (np.zeros((0, 2, 3)), ["A", "B"], {}, "nothing to write"),
    (np.zeros((4, 2, 3)), ["A", "B"], {"units": "inch"}, "units must be one of"),
    (np.zeros((4, 2, 3)), ["A", "B" * 300], {}, "longer than 255 bytes"),
    (np.full((4, 2, 3), np.inf), ["A", "B"], {}, "infinite"),
    (np.zeros((4, 2, 3)), ["A", "B"], {"first_frame": 0}, "first_frame"),
])
def test_bad_input_raises_c3derror(tmp_path, markers, labels, kwargs, match):
    with pytest.raises(C3DError, match=match):
        write_c3d(tmp_path / "bad.c3d", markers, labels, 100.0, **kwargs)
    assert not (tmp_path / "bad.c3d").exists()


def test_event_label_too_long_raises_c3derror(tmp_path):
    with pytest.raises(C3DError, match="EVENT:LABELS: a text is longer than 255 bytes"):
        write_c3d(tmp_path / "bad.c3d", np.zeros((2, 1, 3)), ["A"], 100.0,
                  events=[Event("Left", "x" * 256, 0.0)])


def test_bad_rate_raises_c3derror(tmp_path):
    with pytest.raises(C3DError, match="frame rate must be > 0"):
        write_c3d(tmp_path / "bad.c3d", np.zeros((2, 1, 3)), ["A"], 0.0)


def person_walking(frames=30, count=300):
    """Markers (F, M, 3) metres, Z up, spread like a 1.7 m person walking along +X, with gaps."""
    rng = np.random.default_rng(7)
    body = np.column_stack([rng.normal(0, 0.1, count), rng.normal(0, 0.15, count),
                            rng.uniform(0.05, 1.7, count)])
    markers = body[None] + np.linspace(0, 1.5, frames)[:, None, None] * np.array([1.0, 0, 0])
    markers[5:9, 10] = np.nan
    markers[:, 299 % count] = np.nan   # a marker never seen
    return markers


@pytest.mark.parametrize("integer, units", [(False, "mm"), (True, "mm"), (False, "m")])
def test_round_trip_through_read_c3d(tmp_path, integer, units):
    from mocaplib.io.c3d import read_c3d

    markers = person_walking()
    labels = [f"Walker:M{i}" for i in range(markers.shape[1])]
    path = write_c3d(tmp_path / "rt.c3d", markers, labels, 150.0, events=EVENTS, units=units,
                     integer=integer, first_frame=42)
    trial = read_c3d(path)
    assert trial.labels == labels                       # 255 in LABELS + 45 in LABELS2
    assert (trial.rate, trial.first_frame, trial.units) == (150.0, 42, units)
    assert trial.vertical_axis == "Z"
    assert trial.events == sorted(EVENTS, key=lambda e: e.time_s)
    np.testing.assert_array_equal(np.isnan(trial.markers), np.isnan(markers))
    # integer: half of the power-of-two SCALE (<= 1700 mm / 32767) in metres; float: float32.
    atol = 3.2e-5 if integer else 2e-7
    np.testing.assert_allclose(trial.markers, markers, atol=atol, equal_nan=True)


def test_y_up_file_reads_back_z_up(tmp_path):
    from mocaplib.io.c3d import read_c3d

    markers = person_walking(count=25)
    y_up = np.stack([markers[..., 0], markers[..., 2], -markers[..., 1]], axis=-1)
    path = write_c3d(tmp_path / "yup.c3d", y_up, [f"M{i}" for i in range(25)], 100.0)
    trial = read_c3d(path)
    assert trial.vertical_axis == "Y"
    np.testing.assert_allclose(trial.markers, markers, atol=2e-7, equal_nan=True)  # float32
