"""Mirror images on whole builds: the samples (left gaits mirrored against the captured right
ones, coverage of the default envelope) and the shared biomechZoo walks (right turns only)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from conftest import SAMPLES
from mocaplib.gait.fourier import synthesize
from mocaplib.skeleton import JOINT_ANGLES

#: The velocity targets of the library (README, Pattern and velocities): v̂ within 2 %,
#: ω̂ (rad/s) and v̂_l (m/s) within 0.02.
V_REL, OMEGA_ABS, V_L_ABS = 0.02, 0.02, 0.02
#: Symmetric gaits of the samples: each is its own mirror image but for the walker's asymmetry.
SYMMETRIC = ("walk_straight_slow", "walk_straight_normal", "walk_straight_fast", "run_2p0",
             "run_2p5", "run_3p0", "run_3p5")


@pytest.fixture(scope="module")
def mirrored_samples(tmp_path_factory):
    """The quick start's library of the 68 samples, built with --mirror."""
    from mocaplib.build.pipeline import build_library
    from mocaplib.build.settings import BuildSettings

    settings = BuildSettings(static=str(SAMPLES / "rest.c3d"), static_pose="neutral",
                             forward_reference=str(SAMPLES / "walk_straight_normal.c3d"),
                             mirror=True)
    result = build_library([SAMPLES], settings, jobs=2, progress=False)
    assert result.ok, result.summary_text()
    return result


@pytest.mark.slow
def test_every_sample_entry_meets_the_velocity_targets(mirrored_samples):
    # the targets against the truth cycle nearest in start time, on every captured
    # entry of the quick start's library (benchmarks/velocity_accuracy.py measures the same:
    # worst v̂ 0.8 %, ω̂ 0.0034 rad/s, v̂_l 0.0113 m/s)
    captured = [e for e in mirrored_samples.library.entries if not e.mirrored]
    assert len(captured) == 68
    for entry in captured:
        truth = json.loads((SAMPLES / entry.source_file).with_suffix(".truth.json").read_text())
        if not truth["cycles"]:
            continue                                   # rest: no cycle, velocities 0
        cycle = min(truth["cycles"], key=lambda c: abs(c["start_s"] - entry.start_s))
        assert abs(entry.v - cycle["v"]) <= max(V_REL * cycle["v"], V_REL), entry.id
        assert abs(entry.omega - cycle["omega"]) <= OMEGA_ABS, entry.id
        assert abs(entry.v_l - cycle["v_l"]) <= V_L_ABS, entry.id


def _joint_rms_deg(first: dict, second: dict) -> float:
    """RMS (degrees) over the joint angles and 100 phases of two entries' cycles."""
    phase = np.arange(100) / 100
    q = [synthesize(e.fourier.a, e.fourier.b, 1.0, phase) for e in (first, second)]
    return float(np.degrees(np.sqrt(np.mean((q[0] - q[1])[:, JOINT_ANGLES] ** 2))))


def _other_side(name: str) -> str:
    return name.replace("left", "@").replace("right", "left").replace("@", "right")


def _within_velocity_targets(a, b) -> list[str]:
    misses = []
    if abs(a.v - b.v) > V_REL * max(b.v, 0.05):
        misses.append(f"v {a.v:.4f} vs {b.v:.4f}")
    if abs(a.omega - b.omega) > OMEGA_ABS:
        misses.append(f"omega {a.omega:.4f} vs {b.omega:.4f}")
    if abs(a.v_l - b.v_l) > V_L_ABS:
        misses.append(f"v_l {a.v_l:.4f} vs {b.v_l:.4f}")
    return misses


#: Share of the default envelope inside the mirrored samples' gait cells, measured.
COVERAGE_MEASURED = 0.640


@pytest.mark.slow
@pytest.mark.xfail(strict=True, reason="measured 64.0 % of the default envelope: the samples' "
                   "runs are all straight, so the run cell is a sliver, and the speeds between "
                   "the walks and the runs lie in no gait cell")
def test_the_mirrored_samples_cover_99_percent_of_the_default_envelope(mirrored_samples):
    from mocaplib.library.controlspace import ControlSpace
    from mocaplib.library.coverage import coverage
    from mocaplib.report.plan import default_envelope

    envelope, _ = default_envelope(None)
    cs = ControlSpace.from_library(mirrored_samples.library)
    assert coverage(cs, envelope).fraction_inside >= 0.99


@pytest.mark.slow
def test_a_mirrored_library_of_the_samples_covers_the_default_envelope(mirrored_samples):
    """The mirror images in, flagged as such (3 straight walks, 2 runs and rest are their own
    mirror images), covering no less of the default envelope (the paper plan's commands) than
    the captured entries alone: measured 64.0 % with them. The envelope's curving runs and the
    speeds between the walks and the straight runs lie in no gait cell (a blend never mixes a
    walk with a run): the >= 99 % target is the strict xfail below."""
    from mocaplib.library.controlspace import ControlSpace
    from mocaplib.library.coverage import coverage
    from mocaplib.library.validation import validate_library
    from mocaplib.report.plan import default_envelope

    library = mirrored_samples.library
    assert validate_library(library) == []
    df = library.table
    images = df[df["mirrored"]]
    assert len(images) >= 60 and set(images["mirror_of"]) <= set(df.index[~df["mirrored"]])
    assert {library.entry(i).mirror_method for i in images.index} == {"capture"}
    assert all(i == f"{library.entry(i).source_file[:-4]}_mirror_c"
                    f"{library.entry(i).cycle_index}" for i in images.index)
    envelope, _ = default_envelope(None)
    with_images = coverage(ControlSpace.from_library(library), envelope).fraction_inside
    assert with_images >= COVERAGE_MEASURED - 0.005
    without = coverage(ControlSpace.from_library(library, mirrored=False), envelope)
    assert without.fraction_inside <= with_images


@pytest.mark.slow
def test_mirrored_left_gaits_match_the_captured_right_ones(mirrored_samples):
    """Every sample with a left and a right version (curves, side-steps, diagonals, spot
    turns, mixed): the mirror image of one meets the velocity targets against the other, and
    differs in joint angles by no more than the walker's own asymmetry, measured as the
    largest difference between a symmetric gait (straight walks, runs) and its own mirror
    image. The fitted walker is not symmetric: the session's markers sit off their places
    differently on the two sides. Measured: 60 pairs, joint RMS median 0.46°, max 0.90°;
    own asymmetry 0.55-1.11° (straight walks 0.55-0.85°, runs 0.83-1.11°); velocities within
    0.2 % (v̂), 0.0039 rad/s, 0.0062 m/s."""
    from mocaplib.library.mirror import mirror_entry

    library = mirrored_samples.library
    df = library.table
    captured = {df.loc[i, "source_file"][:-4]: library.entry(i)
                for i in df.index[~df["mirrored"] & df["chosen"]]}
    own = [_joint_rms_deg(captured[name], mirror_entry(captured[name])) for name in SYMMETRIC]
    pairs, misses = [], []
    for i in df.index[df["mirrored"]]:
        image = library.entry(i)
        other = captured.get(_other_side(image.source_file[:-4]))
        if other is None or other.source_file == image.source_file:
            continue
        pairs.append(_joint_rms_deg(image, other))
        misses += [f"{i}: {m}" for m in _within_velocity_targets(image, other)]
    assert len(pairs) == 60
    assert misses == []
    assert max(pairs) <= max(own), (max(pairs), own)
    assert np.median(pairs) <= np.median(own)


@pytest.mark.slow
def test_series_images_agree_with_the_images_cut_from_the_captures(mirrored_samples):
    """`mocaplib mirror` (the stored series shifted to the right toe-off) against build
    --mirror (the capture cut at its right toe-offs), entry by entry: they mirror different
    strides of a steady walker, so they should agree within the velocity targets and the
    Fourier encoding tolerance (0.5°). Measured: joint RMS median 0.17°, max 0.32°."""
    from mocaplib.library.mirror import mirror_entry

    library = mirrored_samples.library
    df = library.table
    rms, misses = [], []
    for i in df.index[df["mirrored"]]:
        cut = library.entry(i)
        series = mirror_entry(library.entry(cut.mirror_of))
        rms.append(_joint_rms_deg(cut, series))
        misses += [f"{i}: {m}" for m in _within_velocity_targets(series, cut)]
    assert misses == []
    assert max(rms) <= 0.5


@pytest.mark.slow
def test_the_mirror_command_adds_the_series_images_once(mirrored_samples, tmp_path, capsys):
    from mocaplib.cli import main
    from mocaplib.library.format import load_library

    document = mirrored_samples.library.document
    captured = {**document, "entries": [e for e in document["entries"]
                                        if not e.get("mirrored")]}
    source = tmp_path / "lib.json"
    source.write_text(json.dumps(captured))
    assert main(["mirror", str(source), "-o", str(tmp_path / "mirrored.json")]) == 0
    out = capsys.readouterr().out
    mirrored = load_library(tmp_path / "mirrored.json")
    images = mirrored.table[mirrored.table["mirrored"]]
    symmetric = out.count("left out")
    assert len(images) + symmetric == len(captured["entries"])
    assert {"rest_c0", "walk_straight_normal_c1"} <= {line.split(":")[1].strip() for line in
                                                      out.splitlines()
                                                      if line.startswith("note:")}
    assert main(["mirror", str(tmp_path / "mirrored.json"), "-o",
                 str(tmp_path / "again.json")]) == 0
    assert len(load_library(tmp_path / "again.json")) == len(mirrored)
    assert "0 mirror images added" in capsys.readouterr().out


def test_the_right_turns_of_a_real_session_gain_left_turns(real_c3d):
    """biomechZoo's walks turn right only (HC030A22, −88°). Its chosen right turn (ω̂ −0.21
    rad/s) has as mirror image, cut at right toe-offs, the stride into the turn (ω̂ +0.63
    rad/s), whose marker_max_m is 45 mm, over the 40 mm limit: kept with --qc waive. The
    series image of the chosen turn keeps its QC: ω̂ +0.21 rad/s."""
    from mocaplib.library.controlspace import ControlSpace
    from mocaplib.library.mirror import mirror_library
    from mocaplib.build.pipeline import build_library
    from mocaplib.build.settings import BuildSettings

    static = real_c3d("biomechzoo/HC030A01.c3d")
    walks = [real_c3d("biomechzoo/HC030A05.c3d"), real_c3d("biomechzoo/HC030A22.c3d")]
    result = build_library(walks, BuildSettings(static=str(static), mirror=True, qc_policy="waive"),
                   progress=False)
    df = result.library.table
    chosen = df[df["chosen"]]
    assert chosen.loc[~chosen["mirrored"], "omega"].max() < 0.1       # no left turn captured
    assert chosen.loc[chosen["mirrored"], "omega"].max() > 0.5        # the mirror's left turn
    assert ControlSpace.from_library(result.library).points[:, 1].max() > 0.5
    document = result.library.document
    captured = type(result.library)({**document, "entries": [
        e for e in document["entries"] if not e.get("mirrored")]})
    series, _ = mirror_library(captured)
    image = series.entry("HC030A22_mirror_c3")
    assert image.omega == pytest.approx(-captured.entry("HC030A22_c3").omega)
    assert image.omega > 0.2


@pytest.mark.slow
def test_the_report_of_the_mirrored_samples_stays_small(mirrored_samples, tmp_path):
    """Target: the report with the motion viewer <= 5 MB for the samples' library; measured
    on its 130-entry mirrored version (a superset of the 68-entry one): 4.95 MB, of which
    3.89 MB the captures' quality plots and the rest mostly the viewer's data (planted cycles
    and their feet's locks, the control space's tetrahedra and frontal tetrahedra, JSON
    without spaces). The viewer's
    data are in it and mark the images."""
    from mocaplib.report import write_report

    library, _ = mirrored_samples.write(tmp_path / "library.json")
    html = write_report(library, tmp_path, renderer="matplotlib", jobs=2)
    assert html.stat().st_size <= 5_000_000, html.stat().st_size
    text = html.read_text(encoding="utf-8")
    data = json.loads(text.split('<script type="application/json" id="mv-data">')[1]
                      .split("</script>")[0])
    assert len(data["entries"]) == len(mirrored_samples.library)
    assert sum(e["mirror_of"] is not None for e in data["entries"]) == int(
        mirrored_samples.library.table["mirrored"].sum())
