"""The landmark catalogue page (``docs/guide/landmarks.md``) is generated from the catalogue by
the MkDocs hook ``docs/hooks/landmarks.py``: every landmark, its segment and its names."""

from __future__ import annotations

import importlib.util
from pathlib import Path

from mocaplib.markersets.draft import names
from mocaplib.markersets.protocols import load_landmarks

HOOK = Path(__file__).resolve().parents[1] / "docs" / "hooks" / "landmarks.py"
PAGE = HOOK.parents[1] / "guide" / "landmarks.md"


def _hook():
    spec = importlib.util.spec_from_file_location("landmarks_hook", HOOK)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_the_page_lists_every_landmark_with_its_segment_and_names():
    hook = _hook()
    page = hook.on_page_markdown(PAGE.read_text(), None, None, None)
    assert hook.PLACEHOLDER not in page
    rows = {line.split("|")[1].strip(" `"): line for line in page.splitlines()
            if line.startswith("| `")}
    catalogue = load_landmarks()
    listed = set(rows) | {f"R_{name[2:]}" for name in rows if name.startswith("L_")}
    assert listed == set(catalogue)
    for name, row in rows.items():
        assert f"| {catalogue[name].segment} |" in row and catalogue[name].description in row
    # every label name of label_names.toml is on the row of each landmark it points to
    for stem, keys in names().items():
        for key in keys:
            row = rows.get(key) or rows[f"L_{key}"]
            assert f"`{stem}`" in row, (stem, key)


def test_the_page_is_linked_from_the_marker_set_guide_and_the_draft_command():
    from mocaplib.cli.protocol import LANDMARK_CATALOGUE_PAGE

    assert (HOOK.parents[2] / LANDMARK_CATALOGUE_PAGE) == PAGE
    assert "(landmarks.md)" in (PAGE.parent / "marker-sets.md").read_text()
