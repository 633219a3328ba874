"""Whether a build depends on how a lab writes its captures: the shared real files rewritten
in other labs' conventions, each folder built without configuration, against the files as
they are.

    python benchmarks/lab_conventions.py [--markdown docs/results/lab_conventions.md]

Every real file (``shared/data/c3d`` beside the repository, or ``$MOCAPLIB_SHARED_C3D``) is
rewritten by :func:`mocaplib.io.c3d_write.write_c3d` (markers and events only), once as it is
(the reference) and once per convention of :data:`CONVENTIONS`: its labels written with
another subject prefix, in lower case, with the side after the name or as a word; its
coordinates in metres or centimetres, Y or X up, turned about the vertical, far from the
origin or the floor above it; stored as integers; cut from a longer take (its first frame
1,000 frames on, the events on the same lab clock); at half its frame rate (every second
frame).
Each folder is built as ``mocaplib build FOLDER`` builds it with nothing configured (a
protocol drafted for a marker set no shipped one matches), and the script prints per
convention: the entries, the captures a shipped protocol matched, and the largest difference of
v̂ (m/s), ω̂ (rad/s) and v̂_l (m/s) from the reference's entries. Prints Markdown
(``--markdown PATH`` writes it into a results page, :mod:`markdown_results`).
"""

from __future__ import annotations

import sys
import tempfile
from dataclasses import replace
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from draft_yield import REAL_FILES, real_files_page  # noqa: E402
from mocaplib.build.drafting import DRAFTS_FOLDER  # noqa: E402
from mocaplib.build.pipeline import build_library  # noqa: E402
from mocaplib.build.settings import BuildSettings  # noqa: E402
from mocaplib.io.c3d import read_c3d  # noqa: E402
from mocaplib.io.c3d_write import write_c3d  # noqa: E402

_WORDS = {"L": "Left", "R": "Right"}
#: How each side convention writes a sided label, from its side (``L`` or ``R``) and stem.
SIDES = {"side after the name (ASI_L)": lambda side, stem: f"{stem}_{side}",
         "side after, dotted (asi.l)": lambda side, stem: f"{stem}.{side}".lower(),
         "side as a word (Left ASI)": lambda side, stem: f"{_WORDS[side]} {stem}",
         "side as a joined word (LeftASI)": lambda side, stem: f"{_WORDS[side]}{stem}",
         "side as a word after (ASI-RIGHT)": lambda side, stem: f"{stem}-{_WORDS[side]}".upper()}


def _relabelled(labels: list[str], write) -> list[str]:
    """``labels`` with each one whose mirror is among them (``LASI`` and ``RASI``, after a
    subject prefix ``liu:``, kept) written by ``write(side, stem)``; the others as they are."""
    bare = [label.rpartition(":")[2] for label in labels]
    have = set(bare)
    out = []
    for label, name in zip(labels, bare):
        mirror = {"L": "R", "R": "L"}.get(name[:1], "") + name[1:]
        sided = len(name) > 2 and name[:1] in "LR" and mirror in have
        out.append(label[:len(label) - len(name)] + write(name[0], name[1:]) if sided else label)
    return out


def _turned(markers: np.ndarray, degrees: float) -> np.ndarray:
    """``markers`` (F, M, 3) turned about the vertical by ``degrees``."""
    c, s = np.cos(np.radians(degrees)), np.sin(np.radians(degrees))
    return markers @ np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]])


def _y_up(markers: np.ndarray) -> np.ndarray:
    """``markers`` (F, M, 3) in a right-handed Y-up frame: (x, z, −y)."""
    return markers[..., [0, 2, 1]] * np.array([1.0, 1.0, -1.0])


def _same(values):
    """``values`` as they are: a convention that leaves the labels or the markers alone."""
    return values


#: Each convention: its labels (M,) from the file's, its markers (F, M, 3) m from the file's,
#: and how it stores them (:func:`write_c3d`'s ``units``, ``integer`` and ``first_frame``
#: beside the file's own first frame: 0 keeps it; ``every``: one frame in so many kept, at the
#: rate divided by it).
CONVENTIONS = {
    "as the files are": (_same, _same, "mm"),
    "another subject prefix (Subj01:LASI)": (
        lambda labels: ["Subj01:" + label.rpartition(":")[2] for label in labels], _same, "mm"),
    "lower case (lasi)": (lambda labels: [label.lower() for label in labels], _same, "mm"),
    **{name: (lambda labels, write=write: _relabelled(labels, write), _same, "mm")
       for name, write in SIDES.items()},
    "in metres": (_same, _same, "m"),
    "in centimetres": (_same, _same, "cm"),
    "Y up": (_same, _y_up, "mm"),
    "X up": (_same, lambda markers: markers[..., [2, 0, 1]], "mm"),
    "turned 137° about the vertical": (_same, lambda markers: _turned(markers, 137.0), "mm"),
    "12 m from the origin": (_same, lambda markers: markers + np.array([12.0, -7.5, 0.0]), "mm"),
    "the floor 0.8 m above the origin": (_same, lambda markers: markers + np.array([0, 0, 0.8]),
                                         "mm"),
    "stored as integers": (_same, _same, "mm", {"integer": True}),
    "cut from a longer take (first frame 1001)": (_same, _same, "mm", {"first_frame": 1000}),
    "half the frame rate (every second frame)": (_same, _same, "mm", {"every": 2}),
}


def conventions_table(files: list[Path]) -> None:
    print("| captures written | entries | captures a shipped protocol matched | largest "
          "velocity difference |\n|---|---:|---:|---:|")
    reference = None
    trials = {path: read_c3d(path) for path in files}
    with tempfile.TemporaryDirectory() as folder:
        for n, (name, (labels_of, markers_of, units, *storage)) in enumerate(
                CONVENTIONS.items()):
            storage = storage[0] if storage else {}
            where = Path(folder) / str(n)
            shift, every = storage.get("first_frame", 0), storage.get("every", 1)
            for path, trial in trials.items():
                target = where / path.relative_to(REAL_FILES)
                target.parent.mkdir(parents=True, exist_ok=True)
                first = trial.first_frame + shift if every == 1 else 1   # the same lab clock
                events = [replace(e, time_s=e.time_s + shift / trial.rate
                                  - (0.0 if every == 1 else trial.start_time))
                          for e in trial.events]
                write_c3d(target, markers_of(trial.markers)[::every], labels_of(trial.labels),
                          trial.rate / every, events=events, units=units,
                          integer=storage.get("integer", False), first_frame=first)
            built = build_library([where], BuildSettings(), jobs=2, progress=False,
                                  drafts_dir=where / DRAFTS_FOLDER)
            entries = {Path(c.file).name: c.entries for c in built.captures}
            reference = reference or entries
            diff = max((abs(getattr(a, k) - getattr(b, k)) for file, ours in entries.items()
                        for a, b in zip(ours, reference[file]) for k in ("v", "omega", "v_l")),
                       default=0.0)
            shipped = sum(c.provenance.get("protocol_origin") == "shipped"
                          for c in built.captures)
            print(f"| {name} | {len(built.library)} | {shipped} of {len(built.captures)} | "
                  f"{diff:.1e} |")


def main() -> None:
    real_files_page(__file__, __doc__.splitlines()[0], conventions_table)


if __name__ == "__main__":
    main()
