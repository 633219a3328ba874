"""What big libraries cost: load, validation, control space, query, coverage and report against
the number of entries.

    python benchmarks/library_scale.py [LIBRARY.json] [--samples sample_c3d] [--sizes 68 500 ...]
        [--query-entries 50000] [--quick] [--stages load validate ...] [--jobs N]
        [--markdown PATH]

Without a library, builds the quick start's one from ``--samples`` (``mocaplib build SAMPLES
--static SAMPLES/rest.c3d --static-pose neutral --forward-reference
SAMPLES/walk_straight_normal.c3d``). For each size N, :func:`jittered_entries` repeats its
entries with jittered velocities (ids suffixed, v̂ and v̂_f scaled by 1 + 5 % noise, ω̂ shifted
by 0.02 rad/s and v̂_l by 0.01 m/s of noise), and ``assemble_library(...).write`` writes them:
a real, valid, checksummed file. On it, one run times:

* load: :func:`mocaplib.library.format.load_library` (reading, with the checks that make its
  numbers usable, as ``query`` does);
* validate: :func:`mocaplib.library.validation.validate_library` on the file (``mocaplib
  validate``: reading, schema, checksum, every rule);
* control space: :meth:`ControlSpace.from_library`; query: one command, the median of 200
  (the first, which builds the locating grid, apart); coverage of the default envelope;
* report: :func:`mocaplib.report.write_report` (matplotlib 3-D view, as without OpenGL; ``--jobs
  N`` worker processes, as ``mocaplib report --jobs N``, default 1), and the size of the page
  it writes.

``--stages`` times only the stages named (of :data:`STAGES`; all by default), e.g. ``--stages
load validate`` for the reading and validation alone (each library is still written); a stage
not timed is shown as "–", and the query on ``--query-entries`` points runs only with
``query``.

Then a query on ``--query-entries`` points (default 50,000), a control space built in memory
from the library's velocities jittered the same way (a file of 50,000 entries is 700 MB).
Prints Markdown tables and the targets met or missed (5,000-entry load and validate ≤ 2 s each,
5,000-entry report ≤ 30 s, a query on 50,000 entries ≤ 50 ms); saves the times against the
entries as a log-log plot, ``docs/results/library_scale.png`` beside the page ``--markdown``
writes (:mod:`markdown_results`). ``--quick``: sizes 68, 250, 500 and 5,000 query points.
"""

from __future__ import annotations

import argparse
import io
import statistics
import subprocess
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from markdown_results import add_markdown_option, markdown_page, shown  # noqa: E402
from mocaplib.io.atomic import atomic_write_bytes  # noqa: E402
from mocaplib.library.controlspace import ControlSpace  # noqa: E402
from mocaplib.library.coverage import coverage  # noqa: E402
from mocaplib.library.format import assemble_library, load_library  # noqa: E402
from mocaplib.library.validation import validate_library  # noqa: E402
from mocaplib.report import write_report  # noqa: E402
from mocaplib.report.plan import default_envelope  # noqa: E402

SIZES, QUICK_SIZES = (68, 500, 1000, 5000), (68, 250, 500)
QUERY_ENTRIES, QUICK_QUERY_ENTRIES = 50_000, 5_000
#: Targets: (column, entries, seconds).
TARGETS = (("load", 5000, 2.0), ("validate", 5000, 2.0), ("report", 5000, 30.0))
QUERY_TARGET_S = 0.050
QUERIES = 200
#: Columns of the timing table: (key, heading).
COLUMNS = (("write", "assemble + write (s)"), ("load", "load (s)"),
           ("validate", "validate (s)"), ("control_space", "control space (s)"),
           ("first_query", "first query (ms)"), ("query", "query, median (ms)"),
           ("coverage", "coverage (s)"), ("report", "report (s)"))
MILLISECONDS = {"first_query", "query"}
#: Stages ``--stages`` can name, and the columns each one fills.
STAGES = {"load": ("load",), "validate": ("validate",), "control_space": ("control_space",),
          "query": ("first_query", "query"), "coverage": ("coverage",), "report": ("report",)}


def jittered_entries(entries: list, n: int, rng: np.random.Generator) -> list:
    """``n`` entries: ``entries`` first, then copies of them in turn with jittered
    velocities (id ``<id>_j<k>``; v̂, v̂_f × (1 + 0.05 N(0, 1)); ω̂ + 0.02 N(0, 1) rad/s;
    v̂_l + 0.01 N(0, 1) m/s); a null velocity stays null."""
    out = list(entries[:n])
    for k in range(len(out), n):
        e = entries[k % len(entries)]
        speed = 1.0 + 0.05 * rng.standard_normal()
        omega, lateral = 0.02 * rng.standard_normal(), 0.01 * rng.standard_normal()
        out.append(replace(e, id=f"{e.id}_j{k}",
                           v=None if e.v is None else e.v * speed,
                           v_f=None if e.v_f is None else e.v_f * speed,
                           omega=None if e.omega is None else e.omega + omega,
                           v_l=None if e.v_l is None else e.v_l + lateral))
    return out


def timed(function, *args, **kwargs):
    """``function(*args, **kwargs)`` and the seconds it took."""
    start = time.perf_counter()
    result = function(*args, **kwargs)
    return result, time.perf_counter() - start


def query_times(cs: ControlSpace, rng: np.random.Generator) -> tuple[float, float]:
    """Seconds of the first query (builds the locating grid) and the median of
    :data:`QUERIES` more, at commands drawn inside the entries' bounding box."""
    lo, hi = cs.points.min(axis=0), cs.points.max(axis=0)
    commands = rng.uniform(lo, hi, (QUERIES + 1, 3))
    _, first = timed(cs.query, commands[0])
    return first, statistics.median(timed(cs.query, c)[1] for c in commands[1:])


def measure(base, n: int, folder: Path, rng: np.random.Generator, envelope,
            stages=tuple(STAGES), jobs: int = 1) -> dict:
    """The time of each of ``stages`` (:data:`STAGES`) on a library of ``n`` jittered entries
    of ``base``, by column (and the write's); the report by ``jobs`` processes."""
    path = folder / f"library_{n}.json"
    entries = jittered_entries(base.entries, n, rng)
    _, write = timed(lambda: assemble_library(entries, settings=base.settings,
                                              qc_thresholds=base.document["qc_thresholds"])
                     .write(path))
    row = {"entries": n, "megabytes": path.stat().st_size / 1e6, "write": write}
    library, row["load"] = timed(load_library, path)
    if "validate" in stages:
        problems, row["validate"] = timed(validate_library, path)
        if problems:
            raise SystemExit(f"the {n}-entry library is not valid: {problems[0]}")
    if {"control_space", "query", "coverage"} & set(stages):
        cs, row["control_space"] = timed(ControlSpace.from_library, library)
        if "query" in stages:
            row["first_query"], row["query"] = query_times(cs, rng)
        if "coverage" in stages:
            _, row["coverage"] = timed(coverage, cs, envelope)
    if "report" in stages:
        page, row["report"] = timed(write_report, path, folder / "report", renderer="matplotlib",
                                    jobs=jobs)
        row["page_megabytes"] = Path(page).stat().st_size / 1e6
    path.unlink()
    return row


def big_query(base, n: int, rng: np.random.Generator) -> dict:
    """Control space of ``n`` jittered velocities of ``base`` built in memory, and its query
    times."""
    entries = [e for e in jittered_entries(base.entries, n, rng)
               if None not in (e.v, e.omega, e.v_l) and e.chosen]
    points = np.array([[e.v, e.omega, e.v_l] for e in entries], dtype=float)
    cs, build = timed(ControlSpace, points, scale=base.control_scale)
    first, median = query_times(cs, rng)
    return {"entries": len(points), "tetrahedra": len(cs.tri.simplices), "build": build,
            "first_query": first, "query": median}


def cell(row: dict, key: str) -> str:
    """A timing table's cell: ``row[key]`` in its column's unit, "–" when not timed."""
    if key not in row:
        return "–"
    return f"{1000 * row[key]:.1f}" if key in MILLISECONDS else f"{row[key]:.2f}"


def print_tables(rows: list[dict], big: dict | None) -> None:
    print("| entries | file (MB) | " + " | ".join(h for _, h in COLUMNS)
          + " | report page (MB) |")
    print("|---|---|" + "---|" * (len(COLUMNS) + 1))
    for row in rows:
        page = f"{row['page_megabytes']:.1f}" if "page_megabytes" in row else "–"
        print(f"| {row['entries']:,} | {row['megabytes']:.1f} | "
              + " | ".join(cell(row, k) for k, _ in COLUMNS) + f" | {page} |")
    if big is not None:
        print(f"\nQuery on {big['entries']:,} entries (control space built in memory: "
              f"{big['tetrahedra']:,} tetrahedra in {big['build']:.1f} s): first query "
              f"{1000 * big['first_query']:.1f} ms (builds the locating grid), median of "
              f"{QUERIES} {1000 * big['query']:.2f} ms.")
    print("\n| target | measured | |")
    print("|---|---|---|")
    by_size = {row["entries"]: row for row in rows}
    for key, n, limit in TARGETS:
        if key in by_size.get(n, {}):
            seconds = by_size[n][key]
            print(f"| {key}, {n:,} entries ≤ {limit:g} s | {seconds:.2f} s | "
                  f"{'met' if seconds <= limit else 'MISSED'} |")
    if big is not None and big["entries"] >= QUERY_ENTRIES:
        print(f"| query, {QUERY_ENTRIES:,} entries ≤ {1000 * QUERY_TARGET_S:g} ms | "
              f"{1000 * big['query']:.2f} ms | "
              f"{'met' if big['query'] <= QUERY_TARGET_S else 'MISSED'} |")


def save_plot(rows: list[dict], path: Path) -> Path:
    """Log-log plot of each stage's time against the entries, written to ``path``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 4.5))
    n = [row["entries"] for row in rows]
    for key, heading in COLUMNS:
        if key in rows[0]:
            ax.loglog(n, [row[key] for row in rows], "o-",
                      label=heading.replace(" (ms)", "").replace(" (s)", ""))
    for key, size, limit in TARGETS:
        if key in rows[0]:
            ax.plot([size], [limit], "k_", ms=14)
    ax.set_xlabel("entries")
    ax.set_ylabel("seconds")
    ax.set_title("Library size and what it costs (targets: black bars)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7, loc="upper left")
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=110, bbox_inches="tight")
    plt.close(fig)
    return atomic_write_bytes(path, buffer.getvalue())


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("library", nargs="?", type=Path, help="a built library (else built now)")
    parser.add_argument("--samples", type=Path, default=ROOT / "sample_c3d")
    parser.add_argument("--sizes", type=int, nargs="+", help=f"entries (default {SIZES})")
    parser.add_argument("--query-entries", type=int,
                        help=f"entries of the in-memory query (default {QUERY_ENTRIES:,})")
    parser.add_argument("--quick", action="store_true",
                        help=f"sizes {QUICK_SIZES}, {QUICK_QUERY_ENTRIES:,} query entries")
    parser.add_argument("--jobs", type=int, default=1, metavar="N",
                        help="worker processes of the report (default 1)")
    parser.add_argument("--stages", nargs="+", choices=STAGES, default=list(STAGES),
                        help="time only these stages (default: all); load is always timed")
    add_markdown_option(parser)
    args = parser.parse_args()
    sizes = args.sizes or (QUICK_SIZES if args.quick else SIZES)
    query_entries = args.query_entries or (QUICK_QUERY_ENTRIES if args.quick else QUERY_ENTRIES)
    rng = np.random.default_rng(0)
    envelope, _ = default_envelope(None)
    with markdown_page(args.markdown, __file__), tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        library = args.library
        if library is None:
            library = folder / "base.json"
            subprocess.run([sys.executable, "-m", "mocaplib", "build", str(args.samples),
                            "--static", str(args.samples / "rest.c3d"), "--static-pose",
                            "neutral", "--forward-reference",
                            str(args.samples / "walk_straight_normal.c3d"), "-o", str(library),
                            "--jobs", "2", "--no-cache"], check=True, cwd=ROOT,
                           capture_output=True)
        base = load_library(library)
        rows = [measure(base, n, folder, rng, envelope, args.stages, args.jobs) for n in sizes]
        big = big_query(base, query_entries, rng) if "query" in args.stages else None
        print_tables(rows, big)
        if args.markdown is not None:
            plot = save_plot(rows, args.markdown.with_suffix(".png"))
            print(f"\n![Time against entries, log-log]({plot.name})")
            print(f"\n(plot: {shown(plot)})", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
