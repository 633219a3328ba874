"""Benchmark: how right ``mocaplib protocol draft`` is on the real files, and what a build
without any protocol written by hand yields.

For each real file (``shared/data/c3d`` beside the repository, or ``$MOCAPLIB_SHARED_C3D``),
drafts a protocol from the file alone and compares it, label by label, with the shipped
protocol the file matches (:func:`mocaplib.markersets.draft_checks.draft_agreement`): the same
landmark, the same segment, a wrong segment (and of those, on the other side), no guess. Twice:
with the labels' names as evidence, and by place and motion alone (``use_names=False``).

Then builds the folder twice, with the shipped protocols and with them hidden from detection
(the build drafts a protocol per marker set, :mod:`mocaplib.build.drafting`), and compares the
entries: per capture, whether each build gives one, and the largest velocity difference.
Last, the same two measures on a synthetic session labelled with the descriptive names of
animation marker sets (``tests/animation_names.py``), against the protocol written for it.
Prints Markdown (``--markdown PATH`` writes it into a results page, :mod:`markdown_results`).

    python benchmarks/draft_yield.py [--markdown docs/results/draft_yield.md]
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import warnings
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))  # the animation set

from markdown_results import add_markdown_option, markdown_page  # noqa: E402
import mocaplib.markersets.matching as matching  # noqa: E402
from mocaplib.build.drafting import DRAFTS_FOLDER  # noqa: E402
from mocaplib.build.pipeline import build_library  # noqa: E402
from mocaplib.build.settings import BuildSettings  # noqa: E402
from mocaplib.io.c3d import read_c3d  # noqa: E402
from mocaplib.markersets.draft import draft_protocol  # noqa: E402
from mocaplib.markersets.draft_checks import draft_agreement  # noqa: E402
from mocaplib.markersets.protocols import FOLDERS_VARIABLE, list_protocols, load_protocol  # noqa: E402

REAL_FILES = Path(os.environ.get("MOCAPLIB_SHARED_C3D",
                                 Path(__file__).resolve().parents[2] / "shared" / "data" / "c3d"))


def _counts(trial, match, *, static=None, use_names: bool) -> tuple[int, ...]:
    """(labels, landmark, segment, wrong, of those on the other side, none) of the protocol
    drafted from ``trial`` against ``match``'s (:func:`draft_agreement`)."""
    a = draft_agreement(draft_protocol(trial, static=static, use_names=use_names).entries,
                        trial, match)
    return a.total, a.landmark, a.segment, a.wrong, a.other_side, a.unassigned


def _cell(counts) -> str:
    """``landmark / segment / wrong (other side) / none`` of :func:`_counts`."""
    return "{1} / {2} / {3} ({4}) / {5}".format(*counts)


def _largest_velocity_difference(ours, theirs) -> float | None:
    """The largest difference of v̂, ω̂ or v̂_l between the entries of two builds' captures,
    paired in order (None without an entry in both)."""
    return max((abs(getattr(a, k) - getattr(b, k)) for c, d in zip(ours, theirs)
                for a, b in zip(c.entries, d.entries) for k in ("v", "omega", "v_l")),
               default=None)


def agreement_table(files: list[Path]) -> None:
    print("| file | protocol | labels | by name and place: landmark / segment / wrong "
          "(other side) / none | by place and motion alone |")
    print("|---|---|---:|---|---|")
    totals = {True: np.zeros(6, dtype=int), False: np.zeros(6, dtype=int)}
    for path in files:
        trial = read_c3d(path)
        match = matching.detect_protocol(trial)
        rows = {use_names: _counts(trial, match, use_names=use_names)
                for use_names in (True, False)}
        for use_names, row in rows.items():
            totals[use_names] += row
        print(f"| {path.relative_to(REAL_FILES).as_posix()} | {match.protocol.name} | "
              f"{rows[True][0]} | {_cell(rows[True])} | {_cell(rows[False])} |")
    print(f"| all | | {totals[True][0]} | {_cell(totals[True])} | {_cell(totals[False])} |")


def _user_protocols():
    return [name for name in list_protocols() if load_protocol(name).origin != "shipped"]


def build_table() -> None:
    with tempfile.TemporaryDirectory() as folder:
        shipped = build_library([REAL_FILES], BuildSettings(), progress=False)
        real_list = matching.list_protocols
        os.environ[FOLDERS_VARIABLE] = ""
        matching.list_protocols = _user_protocols
        try:
            drafted = build_library([REAL_FILES], BuildSettings(), progress=False,
                                    drafts_dir=Path(folder) / DRAFTS_FOLDER)
        finally:
            matching.list_protocols = real_list
        n_drafts = len(list((Path(folder) / DRAFTS_FOLDER).glob("*.toml")))
    ours = {c.file: c for c in drafted.captures}
    print(f"\n{n_drafts} protocols drafted (one per label set). Entries per capture, with the "
          "shipped protocols and with them hidden (drafted), and the largest difference of "
          "v̂ (m/s), ω̂ (rad/s), v̂_l (m/s) between the two:\n")
    print("| capture | shipped | drafted | largest velocity difference |")
    print("|---|---:|---:|---:|")
    for c in shipped.captures:
        d = ours[c.file]
        diff = _largest_velocity_difference([c], [d])
        print(f"| {Path(c.file).name} | {len(c.entries)} | {len(d.entries)} | "
              f"{'' if diff is None else f'{diff:.4f}'} |")
    print(f"| all | {len(shipped.library)} | {len(drafted.library)} | |")


def animation_table() -> None:
    """The draft and the build on a synthetic session labelled as animation marker sets label
    theirs (``tests/animation_names.py``: ``WaistLFront``, ``LKneeOut``...), which no shipped
    protocol knows: the labels against the protocol written for them, and the entries of a
    build with that protocol against those of a build that drafts one."""
    from animation_names import PROTOCOL_NAME, write_protocol, write_session

    with tempfile.TemporaryDirectory() as folder:
        protocols, captures = Path(folder) / "protocols", Path(folder) / "captures"
        protocols.mkdir()
        captures.mkdir()
        write_protocol(protocols)
        os.environ[FOLDERS_VARIABLE] = str(protocols)
        walk, _, rest = write_session(captures)
        trial, static = read_c3d(walk), read_c3d(rest)
        match = matching.match_protocol(trial, load_protocol(PROTOCOL_NAME))
        written = build_library([captures], BuildSettings(), progress=False)
        os.environ[FOLDERS_VARIABLE] = ""
        named, placed = (_counts(trial, match, static=static, use_names=use_names)
                         for use_names in (True, False))
        drafted = build_library([captures], BuildSettings(), progress=False,
                                drafts_dir=Path(folder) / DRAFTS_FOLDER)
    print("\nA synthetic session (a straight walk, a 2 m curve, the static) labelled as "
          "animation marker sets label theirs (`tests/animation_names.py`: `WaistLFront`, "
          "`LKneeOut`, `RToeIn`...), which no shipped protocol knows, against the protocol "
          "written for it:\n")
    print("| labels | by name and place: landmark / segment / wrong (other side) / none | "
          "by place and motion alone | entries: protocol written / drafted | largest "
          "velocity difference |\n|---:|---|---|---|---:|")
    diff = _largest_velocity_difference(written.captures, drafted.captures)
    print(f"| {named[0]} | {_cell(named)} | {_cell(placed)} | {len(written.library)} / "
          f"{len(drafted.library)} | {diff:.4f} |")


def real_files_page(script: str, description: str, tables) -> None:
    """A script's ``main``: parse ``--markdown``, find the real files (:data:`REAL_FILES`; exit
    when there are none) and print ``tables(files)`` (also into the page of ``script``)."""
    parser = argparse.ArgumentParser(description=description)
    add_markdown_option(parser)
    args = parser.parse_args()
    files = sorted(REAL_FILES.rglob("*.c3d"))
    if not files:
        sys.exit(f"no real files at {REAL_FILES}")
    warnings.simplefilter("ignore")
    with markdown_page(args.markdown, script):
        tables(files)


def main() -> None:
    real_files_page(__file__, __doc__.splitlines()[0],
                    lambda files: (agreement_table(files), build_table(), animation_table()))


if __name__ == "__main__":
    main()
