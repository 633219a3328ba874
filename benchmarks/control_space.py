"""Leave-one-out blending error and coverage of a library's control space.

    python benchmarks/control_space.py [LIBRARY.json] [--samples sample_c3d] [--markdown PATH]

Without a library, builds the quick start's one from ``--samples`` (``mocaplib build SAMPLES
--static SAMPLES/rest.c3d --static-pose neutral --forward-reference
SAMPLES/walk_straight_normal.c3d --jobs 2``). Then, on its tangential and frontal control
spaces (:class:`mocaplib.library.controlspace.ControlSpace`): each entry inside the hull of the others
rebuilt from them (:func:`mocaplib.library.blending_error.leave_one_out`), the medians over the entries
in motion of the joint-angle RMS and max, heading, root, stride, turn and period errors, the
rows rebuilt mostly (> 50 %) from another gait mode (walking from running or back), and the
worst stride error; and the share of the default envelope the library covers
(:func:`mocaplib.library.coverage.coverage`). Prints Markdown (``--markdown PATH`` also writes it
into a results page, :mod:`markdown_results`).
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from markdown_results import add_markdown_option, markdown_page  # noqa: E402
from mocaplib.gait.gaits import class_gait  # noqa: E402
from mocaplib.library.blending_error import leave_one_out  # noqa: E402
from mocaplib.library.controlspace import ControlSpace  # noqa: E402
from mocaplib.library.coverage import coverage
from mocaplib.library.format import load_library  # noqa: E402
from mocaplib.report.plan import default_envelope  # noqa: E402

#: Columns of the medians table: (column of leave_one_out, heading, format).
MEDIANS = (("rms_deg", "joint RMS (deg)", "{:.2f}"), ("max_deg", "joint max (deg)", "{:.1f}"),
           ("heading_rms_deg", "heading (deg)", "{:.2f}"), ("root_rms_mm", "root (mm)", "{:.1f}"),
           ("stride_error_mm", "stride (mm)", "{:.0f}"), ("turn_error_deg", "turn (deg)",
                                                          "{:.2f}"),
           ("T_error_s", "period (ms)", "{:.1f}"))


def tables(library_path: Path) -> None:
    """Print the leave-one-out and coverage tables of the library at ``library_path``."""
    library = load_library(library_path)
    print("| axes | entries | tested in motion | " + " | ".join(h for _, h, _ in MEDIANS)
          + " | from another gait mode | worst stride (mm, entry) |")
    print("|---|---|---|" + "---|" * len(MEDIANS) + "---|---|")
    for axes in ("tangential", "frontal"):
        cs = ControlSpace.from_library(library, axes=axes)
        rows = leave_one_out(cs)
        moving = rows[rows["inside"] & (rows["class"] != "rest")].copy()
        moving["T_error_s"] = 1000 * moving["T_error_s"].abs()
        for column in ("heading_rms_deg", "turn_error_deg"):
            moving[column] = moving[column].abs()
        gait = {i: class_gait(c) for i, c in zip(cs.ids, cs.classes)}
        other_mode = [
            row.id for row in moving.itertuples()
            if sum(w for n, w in zip(row.neighbours, row.weights)
                   if gait[n] != gait[row.id]) > 0.5]
        worst = moving.loc[moving["stride_error_mm"].idxmax()]
        print(f"| {axes} | {len(rows)} | {len(moving)} | " + " | ".join(
            fmt.format(np.nanmedian(moving[column])) for column, _, fmt in MEDIANS)
            + f" | {', '.join(other_mode) or 'none'} | {worst['stride_error_mm']:.0f} "
              f"({worst['id']}) |")
    envelope, _ = default_envelope(None)
    share = coverage(ControlSpace.from_library(library), envelope).fraction_inside
    print(f"\nCoverage of the default envelope (tangential axes): {100 * share:.1f} %")


def main() -> int:
    on_a_library(tables, __doc__, __file__)
    return 0


def on_a_library(measure, doc: str, script: str):
    """A benchmark's command line ``[LIBRARY] [--samples DIR] [--markdown PATH]``: ``measure``
    (a function of a library's path) on LIBRARY, or on the quick start's library of the samples
    built now, within the results page of ``script`` (``doc``: its docstring); its result."""
    parser = argparse.ArgumentParser(description=doc.splitlines()[0])
    parser.add_argument("library", nargs="?", type=Path, help="a built library (else built now)")
    parser.add_argument("--samples", type=Path, default=ROOT / "sample_c3d")
    add_markdown_option(parser)
    args = parser.parse_args()
    with markdown_page(args.markdown, script), tempfile.TemporaryDirectory() as tmp:
        return measure(args.library or quick_start_library(args.samples, Path(tmp) / "lib.json"))


def quick_start_library(samples: Path, out: Path) -> Path:
    """Build the quick start's library of the captures in ``samples`` into ``out`` (module
    docstring's command, without the cache) and return ``out``."""
    subprocess.run([sys.executable, "-m", "mocaplib", "build", str(samples), "--static",
                    str(samples / "rest.c3d"), "--static-pose", "neutral", "--forward-reference",
                    str(samples / "walk_straight_normal.c3d"), "-o", str(out), "--jobs", "2",
                    "--no-cache"], check=True, cwd=ROOT, capture_output=True)
    return out


if __name__ == "__main__":
    sys.exit(main())
