"""The shipped synthetic captures (sample_c3d/*.c3d + *.truth.json), read once per session."""

from __future__ import annotations

import json
from functools import lru_cache

from conftest import SAMPLES


@lru_cache(maxsize=1)
def _load():
    from mocaplib.gait.events import capture_events
    from mocaplib.io.c3d import read_c3d
    from mocaplib.markersets.matching import detect_protocol

    out = []
    for path in sorted(SAMPLES.glob("*.c3d")):
        truth_path = path.with_suffix(".truth.json")
        if not truth_path.is_file():
            continue
        trial = read_c3d(path)
        match = detect_protocol(trial)
        events, _ = capture_events(trial, match)     # the default toe-off definition
        out.append((path.stem, trial, match, events, json.loads(truth_path.read_text())))
    return out


def samples():
    """[(name, trial, protocol match, events (default definitions), truth dict)] of every shipped
    capture (a test using it takes the ``sample_dir`` fixture)."""
    found = _load()
    assert found, f"no synthetic captures with truth in {SAMPLES}"
    return found
