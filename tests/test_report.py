"""HTML report: self-contained, escaped, fallback without OpenGL, looked at in headless Chromium."""

from __future__ import annotations

import argparse
import base64
import io
import json
import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from mocaplib.library.controlspace import ControlSpace
from mocaplib.library.format import assemble_library, load_library
from mocaplib.report import figureview
from mocaplib.skeleton import DOF_NAMES

from entries import plain_entry

D = len(DOF_NAMES)
EVIL = "<script>alert('x')</script>"
HIP = DOF_NAMES.index("hip_flexion_r")
KNEE = DOF_NAMES.index("knee_flexion_r")

# (class, v, omega, v_l) of a small hand library covering the usual locomotion types.
ENTRIES = [
    ("straight", 0.6, 0.0, 0.0), ("straight", 1.2, 0.02, 0.0), ("straight", 1.8, -0.02, 0.0),
    ("curve_left", 1.2, 0.6, 0.05), ("curve_left", 1.2, 1.2, 0.1),
    ("curve_right", 1.2, -0.6, -0.05),
    ("curve_right", 1.2, -1.2, -0.1), ("spot_turn", 0.02, 1.0, 0.0), ("spot_turn", 0.02, -1.0, 0.0),
    ("sidestep", 0.4, 0.0, 0.4), ("sidestep", 0.4, 0.0, -0.4), ("diagonal", 1.0, 0.0, 0.7),
    ("diagonal", 1.0, 0.0, -0.7), ("straight", 1.2, 0.3, 0.2), (None, 0.9, -0.3, -0.2),
]


#: Build settings as a build records them (the static's name untrusted text).
SETTINGS = {"protocol": "fullbody38", "static": f"S{EVIL}.c3d", "static_pose": "neutral",
            "forward_reference": "walk.c3d", "heading_offsets": [-0.0041],
            "cutoff": "auto", "toe_off": "lift", "all_cycles": False, "qc_policy": "drop"}


def _coefficients(v: float, omega: float, n: int = 4):
    """Gait-like Fourier coefficients whose amplitude grows with speed (not linearly, so
    blending has an error to show)."""
    a, b = np.zeros((D, n + 1)), np.zeros((D, n + 1))
    a[HIP, 0], a[HIP, 1], b[HIP, 1] = 0.15, 0.3 * (0.3 + v) ** 2, 0.1
    a[KNEE, 0], a[KNEE, 2], b[KNEE, 1] = 0.35, 0.25 * (0.3 + v), 0.4 * (0.2 + v) ** 2
    a[DOF_NAMES.index("trunk_rotation"), 1] = 0.05 + 0.03 * omega ** 2
    return a, b


def make_library(folder: Path, *, source_name: str = "walk_01.c3d",
                 diagnostics: bool = True, rows=ENTRIES) -> Path:
    """A hand-assembled library of ``rows`` (and its diagnostics sidecar) in ``folder``."""
    entries = []
    for i, (cls, v, w, vl) in enumerate(rows):
        a, b = _coefficients(v, w)
        T = 1.1 - 0.15 * v
        source = source_name if i == 0 else f"cap{i:02d}.c3d"
        entries.append(plain_entry(
            id=f"{Path(source).stem}#0", source_file=source, source_sha256="0" * 64,
            cycle_index=0, start_s=0.5, end_s=0.5 + T, T=T,
            pattern={"type": "arc" if w else "line", "parameters": {}}, v=v, omega=w, v_l=vl,
            v_f=float(np.sqrt(max(v * v - vl * vl, 0.0))), a=a, b=b,
            root_drift={"u_f_m_s": v, "u_l_m_s": vl, "omega_rad_s": w},
            qc={"marker_rms_m": 0.006, "fourier_rms_rad": 0.002}, locomotion_class=cls))
    lib = assemble_library(entries, settings=SETTINGS)
    path = folder / "lib.json"
    lib.write(path)
    if diagnostics:
        _write_diagnostics(folder / "lib.diagnostics.json", lib, source_name)
    return path


def _write_diagnostics(path: Path, lib, source_name: str) -> None:
    entry_id = f"{Path(source_name).stem}#0"
    rate, T = 100.0, float(lib.table.loc[entry_id, "T"])
    t = np.arange(0, 3.0, 1 / rate)
    R, w = 2.0, 0.6                          # walking an arc of radius 2 m
    xy = np.column_stack([R * np.sin(w * t), R - R * np.cos(w * t)])
    t_cycle = np.arange(0, T, 1 / rate)  # the chosen cycle's angles, timed from its start
    q = lib.angles(entry_id, t_cycle)
    record = {
        "source": source_name, "ok": True, "error": None, "stage": None, "rate_hz": rate,
        "time_s": t.tolist(), "shoulder_mid_xy": xy.tolist(),
        "frame_rms_m": (0.006 + 0.002 * np.sin(3 * t)).tolist(),
        "events": [{"side": s, "kind": k, "time_s": float(x)}
                   for s, k, x in (("left", "toe_off", 0.5), ("right", "heel_strike", 0.6),
                                   ("right", "toe_off", 1.0), ("left", "heel_strike", 1.1),
                                   ("left", "toe_off", 0.5 + T))],
        "cycles": [{"index": 0, "start_s": 0.5, "end_s": 0.5 + T, "chosen": True,
                    "entry_id": entry_id,
                    "pattern": {"type": "arc", "parameters": {"centre": [0.0, R], "radius": R,
                                                              "turn": 1}}}],
        "angles": {"time_s": t_cycle.tolist(),
                   **{n: q[:, j].tolist() for j, n in enumerate(DOF_NAMES)}},
        "warnings": [f"label {EVIL} renamed"], "static": "Static1.c3d",
    }
    # The other captures as a build records them without series: their one cycle, chosen.
    others = [{"source": row["source_file"], "ok": True, "warnings": [],
               "cycles": [{"index": 0, "start_s": row["start_s"], "end_s": row["end_s"],
                           "chosen": True, "entry_id": entry, "pattern": {"type": "line"}}]}
              for entry, row in lib.table.drop(entry_id).iterrows()]
    # A capture whose chosen cycle (its second, index 1) QC left out of the library.
    dropped = {"source": "dropped.c3d", "ok": True, "warnings": [
        "cycle 1 (1.00-2.00 s) left out of the library: fourier_rms_rad 0.03 > 0.01745"],
        "cycles": [{"index": k, "start_s": k + 0.0, "end_s": k + 1.0, "chosen": k == 1,
                    "entry_id": None, "pattern": {"type": "line"}} for k in (0, 1)]}
    failed = {"source": "cap99.c3d", "ok": False, "error": "/lab/2024/day1/cap99.c3d: no left "
              "toe-off found", "stage": "events", "warnings": []}
    path.write_text(json.dumps({"format": "mocaplib-diagnostics", "version": 1,
                                "captures": [record, *others, dropped, failed]}))


def _images(html: str) -> list[np.ndarray]:
    from matplotlib.image import imread

    return [imread(io.BytesIO(base64.b64decode(m))) for m in
            re.findall(r'src="data:image/png;base64,([A-Za-z0-9+/=]+)"', html)]


@pytest.fixture(scope="module")
def report(tmp_path_factory):
    """One report with the pyvista renderer (auto), shared by the checks below."""
    from mocaplib.report import write_report

    folder = tmp_path_factory.mktemp("rep")
    lib = make_library(folder, source_name=f"walk{EVIL}.c3d")
    out = write_report(lib, folder / "out")
    return out, out.read_text(encoding="utf-8")


def test_report_is_self_contained(report):
    path, html = report
    assert path.name == "lib-report.html"
    # No external resources: every src is a data URI, no http(s) links or stylesheets.
    assert not re.search(r'(src|href)="(?!data:|#)', html)
    assert "http://" not in html and "https://" not in html
    images = _images(html)
    assert len(images) == 3  # projections, 3-D view, the one capture with series
    for img in images:
        assert img.ndim == 3 and img.shape[0] > 200 and img[..., :3].std() > 0.05
    # Every picture is a palette PNG (IHDR colour type 3): a few tens of kB, not hundreds.
    for data in re.findall(r'src="data:image/png;base64,([A-Za-z0-9+/=]+)"', html):
        assert base64.b64decode(data)[25] == 3


def test_report_escapes_untrusted_names(report):
    _, html = report
    assert EVIL not in html
    assert "&lt;script&gt;alert(" in html  # shown as text in the capture heading and warnings
    # The only <script> elements are the two viewers' data and code.
    assert re.findall(r"<script\b[^>]*>", html) == [
        '<script type="application/json" id="cs-data">', "<script>",
        '<script type="application/json" id="mv-data">', "<script>", "<script>"]


def test_report_contents(report):
    _, html = report
    for text in ("Capture next", "largest hole", "Blending error", "sliver tetrahedra",
                 "cap99.c3d", "no left toe-off found", "Interactive view", 'id="cs-data"',
                 "joint RMS (°)", "heading RMS (°)", "root RMS (mm)", "stride error (mm)",
                 "For comparison, on the frontal axes", "calibrated with Static1.c3d",
                 "Built with protocol fullbody38; static S&lt;script&gt;",
                 ".c3d (neutral pose); heading set by the forward reference walk.c3d "
                 "(S&lt;script&gt;alert(&#39;x&#39;)&lt;/script&gt;.c3d -0.235°); "
                 "marker low-pass by Winter&#39;s residual analysis; cycles cut at lift toe-offs; "
                 "one cycle per activity segment of each capture; QC failures dropped."):
        assert text in html, text
    data = json.loads(re.search(r'<script type="application/json" id="cs-data">(.*?)</script>',
                                html, re.S).group(1))
    assert len(data["points"]) == len(ENTRIES) and len(data["edges"]) > len(ENTRIES)


def test_report_says_the_default_target_is_not_the_labs(report):
    _, html = report
    note = html.split("Target envelope: ")[1].split("</p>")[0]
    assert "mocaplib&#39;s default" in note and "paper_plan.toml" in note
    assert "This is not a target you chose" in note and "--envelope FILE.toml" in note
    # The library's captures are not named after that plan: its captures are not listed as
    # the lab's omissions.
    assert ("None of the library's captures is named like a capture of paper_plan.toml"
            in html)
    assert "Missing (never captured" not in html
    # One number for the coverage: the summary card and the table agree.
    card = re.search(r"<b>([\d.]+) %</b>of the default target envelope covered", html).group(1)
    assert f"{card} % of" in html.split("envelope inside the library")[1].split("</tr>")[0]


def test_report_numbers_cycles_as_the_entry_ids_do(report):
    _, html = report
    walk = html.split("walk&lt;script&gt;")[-1].split("</table>")[0]
    assert "<td>0 (chosen)</td>" in walk  # cycle 0 became entry walk...#0
    dropped = html.split("<summary>dropped.c3d — ")[1].split("</details>")[0]
    assert "none in the library" in dropped.split("</summary>")[0]
    assert "cycle 1 (1.00-2.00 s) left out of the library" in dropped  # the warning ...
    assert re.search(r"<td>1 \(chosen\)</td>.*chosen but left out of the library", dropped,
                     re.S)  # ... names the row below it


def test_report_shows_no_absolute_paths(report):
    _, html = report
    assert "/lab/2024" not in html
    assert "cap99.c3d: no left toe-off found" in html


def test_entries_too_close_to_tell_apart_are_listed_and_warned_about(tmp_path):
    from mocaplib.library.controlspace import ControlSpace
    from mocaplib.library.format import load_library
    from mocaplib.report.space_sections import _close_rows, _close_warning

    # A 60° and a 120° diagonal at 1 m/s: same v̂ and v̂_l, so the same tangential point.
    rows = ENTRIES + [("diagonal", 1.0, 0.001, 0.7)]
    lib = load_library(make_library(tmp_path, rows=rows, diagnostics=False))
    close = _close_rows(ControlSpace.from_library(lib))
    assert [(c["a"], c["b"]) for c in close] == [("cap11#0", "cap15#0")]
    assert close[0]["gap"] == "0.000, 0.057, 0.000"  # |Δv̂| m/s, |Δω̂| °/s, |Δv̂_l| m/s
    assert _close_warning(close).startswith("1 pair(s) of entries nearly coincide")


def test_sliver_summary_lists_the_worst_ten():
    import pandas as pd

    from mocaplib.report.space_sections import MAX_SLIVER_ROWS, _sliver_context

    quality = np.array([0.05, 2e-4, 0.09, 5e-3, 1e-12] + [0.02] * 20)
    slivers = pd.DataFrame({"entries": [["a", "b", "c", f"e{i}"] for i in range(25)],
                            "quality": quality})
    ctx = _sliver_context(slivers)
    assert ctx["count"] == 25 and ctx["not_listed"] == 25 - MAX_SLIVER_ROWS == 15
    assert [r["quality"] for r in ctx["worst"][:3]] == [1e-12, 2e-4, 5e-3]
    assert [b["count"] for b in ctx["bands"]] == [2, 1, 22]  # < 0.001, < 0.01, < 0.1
    assert ctx["frequent"][0] == {"id": "a", "count": 25}


def test_compressed_pngs_look_the_same():
    from matplotlib.image import imread

    from mocaplib.report import figures

    fig = figures.new_figure(6, 4)                       # the report's settings
    ax = fig.subplots()
    t = np.linspace(0, 2, 300)
    for k in range(6):
        ax.plot(t, np.sin(3 * t + k), lw=3, alpha=0.4)
        ax.plot(t, np.sin(3 * t + k), lw=1)
    ax.legend([f"dof {k}" for k in range(12)], fontsize=7)
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=figures.DPI)
    original = imread(io.BytesIO(buf.getvalue()))[..., :3]
    small = figures.compress_png(buf.getvalue())
    palette = imread(io.BytesIO(small))[..., :3]
    assert len(small) < 0.6 * len(buf.getvalue())
    # Only antialiased edge pixels move: 99 % of pixels within 10/255 of the original.
    assert np.quantile(np.abs(palette - original).max(axis=2), 0.99) <= 10 / 255


def test_report_falls_back_without_opengl(tmp_path, monkeypatch):
    from mocaplib.report import write_report

    lib = make_library(tmp_path, diagnostics=False)
    monkeypatch.setenv("MOCAPLIB_NO_OPENGL", "1")
    html = write_report(lib, tmp_path / "a").read_text()
    assert "rendered with <b>matplotlib</b>" in html and "MOCAPLIB_NO_OPENGL is set" in html
    assert "no diagnostics sidecar" in html
    images = _images(html)
    assert len(images) == 2  # the projections and the 3-D view (no sidecar: no captures)
    assert all(img[..., :3].std() > 0.05 for img in images)


def test_report_detects_a_crashing_renderer(tmp_path, monkeypatch):
    from mocaplib.report import scene3d, write_report

    lib = make_library(tmp_path, diagnostics=False)
    monkeypatch.delenv("MOCAPLIB_NO_OPENGL", raising=False)
    # A renderer child process that dies on a signal, as VTK does without a usable OpenGL.
    crash = tmp_path / "crash.sh"
    crash.write_text("#!/bin/sh\nulimit -c 0\necho 'Segmentation fault' >&2\nkill -SEGV $$\n")
    crash.chmod(0o755)
    monkeypatch.setattr(scene3d.sys, "executable", str(crash))
    html = write_report(lib, tmp_path / "b").read_text()
    assert "rendered with <b>matplotlib</b>" in html
    assert "crashed (signal 11): Segmentation fault" in html


def _render_small_scene():
    """Three points in the 3-D view, with b"fallback png" standing in for matplotlib's picture."""
    from mocaplib.report import scene3d

    return scene3d.render_control_space(np.eye(3), np.eye(3), ["a", "b", "c"], ["x", "y", "z"],
                                        edges=[[0, 1]], hull_triangles=[],
                                        fallback=lambda: b"fallback png")


def test_a_blank_render_falls_back(monkeypatch):
    from matplotlib.image import imsave

    from mocaplib.report import scene3d

    def blank(scene, out):  # a renderer that "succeeds" with an all-white picture
        imsave(out, np.ones((50, 60, 3)))

    monkeypatch.delenv("MOCAPLIB_NO_OPENGL", raising=False)
    monkeypatch.setattr(scene3d, "_run_renderer", blank)
    got = _render_small_scene()
    assert got.renderer == "matplotlib" and got.png == b"fallback png"
    assert got.fallback_reason == "pyvista produced a blank image"


def test_renderer_child_failure_is_reported(monkeypatch):
    from mocaplib.report import scene3d

    # A child process that cannot even start Python's module: non-zero exit, message kept.
    monkeypatch.delenv("MOCAPLIB_NO_OPENGL", raising=False)
    monkeypatch.setattr(scene3d.sys, "executable", "/bin/false")
    got = _render_small_scene()
    assert got.renderer == "matplotlib" and got.png == b"fallback png"
    assert "failed (exit 1)" in got.fallback_reason


@pytest.mark.parametrize("executable", ["/nonexistent/python", "/dev/null"])
def test_a_renderer_that_cannot_start_falls_back(executable, monkeypatch):
    from mocaplib.report import scene3d

    # No interpreter there, or a file that cannot be executed: OSError when spawning.
    monkeypatch.delenv("MOCAPLIB_NO_OPENGL", raising=False)
    monkeypatch.setattr(scene3d.sys, "executable", executable)
    got = _render_small_scene()
    assert got.renderer == "matplotlib" and got.png == b"fallback png"
    assert "the pyvista renderer could not be started" in got.fallback_reason


def test_report_of_a_degenerate_library_still_builds(tmp_path):
    from mocaplib.report import write_report

    entries = []
    for i, v in enumerate((0.6, 0.9, 1.2, 1.5, 1.8)):  # straight walking only: a line
        a, b = _coefficients(v, 0.0)
        entries.append(plain_entry(
            id=f"s{i}", source_file=f"s{i}.c3d", source_sha256="0" * 64, cycle_index=0,
            start_s=0.0, end_s=1.0, T=1.0, pattern={"type": "line"}, v=v, omega=0.0, v_l=0.0,
            v_f=v, a=a, b=b, root_drift={"u_f_m_s": v, "u_l_m_s": 0.0, "omega_rad_s": 0.0},
            qc={}))
    path = tmp_path / "line.json"
    assemble_library(entries, settings={}).write(path)
    html = write_report(path, tmp_path, renderer="matplotlib").read_text()
    assert "degenerate" in html and "No 3-D view" in html
    assert len(_images(html)) == 1  # the projections still show the entries


def test_capture_figure_of_a_one_frame_capture_warns_nothing():
    # a one-frame static (btkdata PiG_Calibration-FlatFoot-One) failed in the build still gets
    # its panels; matplotlib warned about an empty time axis on the terminal
    import warnings

    from matplotlib.image import imread

    from mocaplib.report import figures

    record = {"time_s": [0.0], "events": [], "cycles": [], "marker_rms_m": [0.004]}
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        png = figures.capture_figure(record, {})
    assert imread(io.BytesIO(png)).shape[0] > 100


def test_report_of_an_empty_library(tmp_path):
    from mocaplib.report import write_report

    path = tmp_path / "empty.json"
    assemble_library([], settings={}).write(path)
    html = write_report(path, tmp_path, renderer="matplotlib").read_text()
    assert "at least 4 entries" in html and "No 3-D view" in html


def test_a_broken_shipped_plan_falls_back(tmp_path, monkeypatch):
    from mocaplib.errors import MocapError
    from mocaplib.report import plan as plan_module

    broken = tmp_path / "lab_plan.toml"
    broken.write_text("[[capture]]\nname = 'x'\n")  # no class, command, duration, seed
    monkeypatch.setenv("MOCAPLIB_PROTOCOLS", str(tmp_path))
    assert plan_module.find_plan() == broken
    env, note = plan_module.default_envelope(None)
    assert "could not be read" in note["text"] and note["plan"] is None and note["default"]
    assert len(env.vertices) == len(plan_module.FALLBACK_ENVELOPE)
    with pytest.raises(MocapError, match="lab_plan.toml"):
        plan_module.default_envelope(broken)  # named explicitly: an error, not a fallback


def test_report_reads_the_plans_beside_the_protocols(tmp_path, monkeypatch):
    # An installed mocaplib has no source tree: the plans are found where the protocols are
    # (the package's data and $MOCAPLIB_PROTOCOLS), whatever the current folder.
    from mocaplib.markersets.protocols import protocols_dir
    from mocaplib.report.plan import find_plan

    shipped = find_plan()
    assert shipped is not None and shipped.parent == protocols_dir()
    plans = tmp_path / "protocols"
    plans.mkdir()
    (plans / "lab_plan.toml").write_text(
        'name = "lab"\n[[capture]]\nname = "mine"\nclass = "holonomic"\n'
        'command = { kind = "sidestep", speed = 0.4, side = "left" }\nduration = 2.0\n'
        "seed = 1\n")
    monkeypatch.setenv("MOCAPLIB_PROTOCOLS", str(plans))
    monkeypatch.chdir(tmp_path / "protocols")
    # a user's folder adds to the shipped plans: its plan comes first
    assert find_plan() == plans / "lab_plan.toml"


def test_report_command(tmp_path, capsys):
    from mocaplib.cli import report as report_cmd

    lib = make_library(tmp_path, diagnostics=False)
    parser = argparse.ArgumentParser()
    report_cmd.register(parser.add_subparsers())
    args = parser.parse_args(["report", str(lib), "-o", str(tmp_path / "r"), "--no-opengl"])
    assert args.run(args) == 0
    assert (tmp_path / "r" / "lib-report.html").is_file()
    assert "lib-report.html" in capsys.readouterr().out


def test_envelope_override(tmp_path):
    from mocaplib.report import write_report

    lib = make_library(tmp_path, diagnostics=False)
    env = tmp_path / "env.toml"
    env.write_text("[envelope]\nv = [0.0, 1.0]\nomega = [-0.5, 0.5]\nv_l = [-0.2, 0.2]\n")
    html = write_report(lib, tmp_path, envelope=env, renderer="matplotlib").read_text()
    assert "Target envelope: from env.toml." in html


CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")


def _chromium(url: str, tmp: Path, *extra: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic",
         "--no-first-run", "--disable-background-networking", "--disable-component-update",
         "--disable-sync", f"--user-data-dir={tmp / 'profile'}", *extra, url],
        capture_output=True, text=True, timeout=120)


@pytest.mark.skipif(CHROMIUM is None, reason="chromium is not installed")
def test_report_in_headless_chromium(report, tmp_path):
    from matplotlib.image import imread

    path, html = report
    shot = tmp_path / "report.png"
    _chromium(path.resolve().as_uri(), tmp_path, f"--screenshot={shot}",
              "--window-size=1280,4000")
    assert shot.is_file(), "chromium wrote no screenshot"
    img = imread(str(shot))[..., :3]
    assert img.shape[:2] == (4000, 1280)
    # A rendered page: not blank, many colours (figures), not just text on white.
    assert img.std() > 0.1
    assert len(np.unique((img.reshape(-1, 3) * 255).astype(np.uint8), axis=0)) > 500
    # Images decoded, and the interactive viewer drew every entry (the DOM after scripts ran).
    probe = tmp_path / "probe.html"
    probe.write_text(html.replace("</body>", "<script>window.addEventListener('load', () => "
                                  "{document.title = 'IMAGES:' + [...document.images].filter("
                                  "i => i.complete && i.naturalWidth > 0).length + '/' + "
                                  "document.images.length + ' DRAWN:' + document.getElementById"
                                  "('cs-viewer').getAttribute('data-drawn');});</script></body>"),
                     encoding="utf-8")
    dom = _chromium(probe.resolve().as_uri(), tmp_path, "--dump-dom",
                    "--virtual-time-budget=5000").stdout
    n = len(_images(html))
    assert f"IMAGES:{n}/{n}" in dom
    assert f"DRAWN:{len(ENTRIES)}" in dom


def test_envelope_and_planned_captures_from_a_capture_plan(tmp_path):
    from mocaplib.report import write_report
    from mocaplib.report.plan import default_envelope

    plan = tmp_path / "mini_plan.toml"
    captures = [("cap01", "nonholonomic", '{ kind = "straight", speed = 1.2 }'),
                ("cap99", "nonholonomic",
                 '{ kind = "curve", speed = 1.2, radius = 1.0, side = "left" }'),
                ("never_done", "holonomic", '{ kind = "sidestep", speed = 0.4, side = "right" }'),
                ("turn", "nonholonomic", '{ kind = "spot_turn", speed = 1.0, side = "right" }')]
    plan.write_text('name = "mini"\n' + "".join(
        f'[[capture]]\nname = "{name}"\nclass = "{cls}"\ncommand = {command}\n'
        f"duration = 2.0\nseed = {seed}\n" for seed, (name, cls, command) in enumerate(captures)))
    env, note = default_envelope(plan)
    # Hull vertices are the commands as (hypot(v_f, v_l), omega, v_l).
    np.testing.assert_allclose(env.vertices, [[1.2, 0, 0], [1.2, 1.2, 0], [0.4, 0, -0.4],
                                              [0, -1.0, 0]], atol=1e-12)
    assert list(note["plan"]["name"]) == ["cap01", "cap99", "never_done", "turn"]
    lib = make_library(tmp_path)  # its diagnostics mark cap99.c3d failed in "events"
    html = write_report(lib, tmp_path / "r", envelope=plan, renderer="matplotlib").read_text()
    assert "convex hull of the 4 commanded velocities of the capture plan mini_plan.toml" in html
    assert "1 of 4 planned captures of mini_plan.toml are in the library" in html
    assert "This is not a target you chose" not in html
    assert "cap99 — events: cap99.c3d: no left toe-off found" in html
    missing = html.split("Missing (never captured")[1].split("</ul>")[0]
    assert "never_done" in missing and "turn" in missing and "cap01" not in missing


@pytest.mark.parametrize("table, key", [
    ("v = [0.0, inf]", "v"), ("v = [0.0, nan]", "v"), ('v = "fast"', "v"), ("v = [0.0]", "v"),
    ("v = [0.0, true]", "v"), ("points = [[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, nan]]", "points"),
])
def test_an_envelope_holds_finite_numbers_only(table, key, tmp_path):
    from mocaplib.library.coverage import Envelope
    from mocaplib.errors import MocapError

    path = tmp_path / "env.toml"
    path.write_text(f"[envelope]\n{table}\nomega = [-1.0, 1.0]\nv_l = [-0.5, 0.5]\n")
    with pytest.raises(MocapError, match=f"^{re.escape(str(path))}: bad \\[envelope\\] "
                                         f"table: {key} must be"):
        Envelope.from_toml(path)


def test_the_envelope_grid_samples_zero_turn_and_zero_side_step():
    from mocaplib.library.coverage import Envelope

    scale = np.array([1.5, np.pi / 2, 0.5])
    for box in ({"v": (0, 1.8), "omega": (-1.2, 1.2), "v_l": (-0.5, 0.5)},   # symmetric
                {"v": (0, 1.8), "omega": (-0.3, 1.2), "v_l": (-0.2, 0.5)}):   # not
        samples = Envelope.box(box).sample(scale)
        straight = samples[(samples[:, 1] == 0) & (samples[:, 2] == 0)]
        assert len(straight) > 10 and straight[:, 0].max() > 1.7


def test_capture_next_finds_a_missing_straight_walk_as_one():
    from mocaplib.library.controlspace import ControlSpace
    from mocaplib.library.coverage import Envelope, coverage
    from mocaplib.report.space_sections import describe_command

    # Turns, side-steps and their mixtures both ways, no straight walking: the gap is there.
    points = [(v, w, vl) for v in (0.0, 1.6) for w in (-1.0, 1.0) for vl in (-0.4, 0.4)]
    cs = ControlSpace(np.array(points, float))
    cov = coverage(cs, Envelope(np.array(points, float)))
    first = cov.capture_next.iloc[0]
    assert first["omega"] == 0.0 and first["v_l"] == 0.0
    assert "turning" not in describe_command(first.to_dict())
    assert describe_command({"v": 1.75, "omega": 0.0, "v_l": 0.35}) == (
        "walk at 1.75 m/s heading 12° to the left of the body")  # a crab walk said so
    np.testing.assert_array_equal(cov.largest_hole[1:], [0.0, 0.0])


def test_ties_go_to_the_sample_nearest_the_centre():
    from mocaplib.library.coverage import _farthest

    distance = np.array([1.0, 2.0, 2.0, 2.0 - 1e-12, 0.5])
    off_centre = np.array([0.0, 0.9, 0.5, 0.1, 0.0])
    assert _farthest(distance, off_centre) == 3
    assert _farthest(np.array([1.0, 1.0]), np.array([0.2, 0.2])) == 0  # then the first


def test_stars_on_one_spot_share_a_label():
    from mocaplib.report.figures import star_labels

    stars = np.array([[1.0, 10.0], [1.0, 10.0], [2.0, -40.0], [1.005, 11.0], [0.0, 60.0]])
    assert [text for text, _ in star_labels(stars, (0, 2), (-60, 60))] == ["1, 2, 4", "3", "5"]


def _loo_row(entry_id, cls, rms, neighbours=(), weights=()):
    return {"id": entry_id, "class": cls, "inside": bool(neighbours), "neighbours": neighbours,
            "weights": weights, "rms_deg": rms, "max_deg": 2 * rms, "worst_dof": "hip",
            "heading_rms_deg": 0.1, "root_rms_mm": 1.0, "stride_error_mm": 10.0,
            "turn_error_deg": -0.5, "T_error_s": 0.01}


def test_the_headline_blending_error_leaves_rest_out_and_flags_cross_mode_blends():
    import pandas as pd

    from mocaplib.report.space_sections import _loo_context

    df = pd.DataFrame([
        _loo_row("rest_a", "rest", 25.0, ["rest_b", "w1", "w2", "w3"], [1.0, 0, 0, 0]),
        _loo_row("walk_fast", "nonholonomic", 14.0, ["run", "w1", "w2", "w3"],
                 [0.76, 0.1, 0.1, 0.04]),
        _loo_row("w1", "holonomic", 1.0, ["w2", "w3", "side", "run"], [0.4, 0.3, 0.2, 0.1]),
        _loo_row("w2", "mixed", 2.0, ["w1", "w3", "side", "rest_a"], [0.4, 0.3, 0.2, 0.1]),
        _loo_row("w3", None, 3.0, ["run", "rest_a", "rest_b", "w1"], [0.5, 0.2, 0.2, 0.1]),
        _loo_row("run", "running", np.nan), _loo_row("rest_b", "rest", np.nan),
        _loo_row("side", "holonomic", np.nan)])
    ctx = _loo_context(df)
    assert ctx["n_inside"] == 5 and ctx["n_rest"] == 1 and ctx["n_headline"] == 4
    assert ctx["median_rms"] == 2.5 and ctx["rest_median_rms"] == 25.0  # rest apart
    assert ctx["max_rms"] == 14.0
    # walking rebuilt 76 % from running is flagged; 10 % from another mode, or an entry of
    # unknown class (w3, half from running), is not
    flagged = {r["id"]: r["cross"] for r in ctx["rows"] if r["cross"]}
    assert flagged == {"walk_fast": {"mode": "running", "share": 0.76}}
    assert ctx["n_cross"] == 1 and ctx["same_mode_median_rms"] == 2.0
    assert ctx["median"]["turn_error_deg"] == 0.5  # medians of |signed errors|


def test_entries_at_the_fourier_order_cap_are_flagged():
    from mocaplib.library.format import assemble_library
    from mocaplib.gait.fourier import ANGLE_TOLERANCE, MAX_ORDER as cap
    from mocaplib.report.html import _entry_rows, _summary

    assert (cap, round(np.degrees(ANGLE_TOLERANCE), 6)) == (20, 0.5)  # the encoder's defaults
    entries = []
    for n in (3, cap):
        a, b = np.zeros((D, n + 1)), np.zeros((D, n + 1))
        a[HIP, n] = 0.01
        entries.append(plain_entry(
            id=f"e{n}", source_file=f"e{n}.c3d", source_sha256="0" * 64, cycle_index=0,
            start_s=0.0, end_s=1.0, T=1.0, pattern={"type": "line"}, v=1.0, omega=0.0, v_l=0.0,
            v_f=1.0, a=a, b=b, root_drift={"u_f_m_s": 1.0, "u_l_m_s": 0.0, "omega_rad_s": 0.0},
            qc={}))
    lib = assemble_library(entries, settings={})
    rows = _entry_rows(lib.entries, lambda i: "unknown")
    assert [(r["fourier_n"], r["at_cap"]) for r in rows] == [(cap, True), (3, False)]
    assert _summary(lib, None, None)["at_cap"] == [f"e{cap}"]


def test_a_sidecar_of_another_build_is_not_used(tmp_path):
    from mocaplib.library.format import load_library
    from mocaplib.report.diagnostics import read_diagnostics

    lib_path = make_library(tmp_path)
    library = load_library(lib_path)
    sidecar = tmp_path / "lib.diagnostics.json"
    diagnostics, warnings = read_diagnostics(lib_path, library)
    assert diagnostics is not None and warnings == []
    document = json.loads(sidecar.read_text())
    walk, cap01 = document["captures"][:2]
    assert cap01["source"] == "cap01.c3d"
    subset = {**document, "captures": [walk, *document["captures"][-2:]]}  # a smaller build
    cap01["cycles"][0]["entry_id"] = "other_c0"                    # a build of other captures
    for edited, why in ((subset, "14 of the library's 15 entries are not in it"),
                        (document, "it names 1 entry the library lacks, e.g. other_c0")):
        sidecar.write_text(json.dumps(edited))
        diagnostics, warnings = read_diagnostics(lib_path, library)
        assert diagnostics is None and len(warnings) == 1
        assert "does not belong to this library" in warnings[0] and why in warnings[0]


def test_the_capture_figure_draws_the_pattern_the_sidecar_stores():
    from mocaplib.gait.patterns import fit_pattern
    from mocaplib.report.figures import pattern_curve

    angle = np.linspace(0.0, 1.2, 60)
    path = np.column_stack([1.0 + 2.0 * np.cos(angle), -0.5 + 2.0 * np.sin(angle)])
    stored = json.loads(json.dumps(fit_pattern(path).to_dict()))   # as in the sidecar
    curve = pattern_curve(stored, path)
    assert stored["type"] == "arc" and curve is not None and len(curve) > 10
    np.testing.assert_allclose(np.hypot(curve[:, 0] - 1.0, curve[:, 1] + 0.5), 2.0, atol=1e-6)
    assert pattern_curve({"type": "arc", "parameters": {}}, path) is None


def test_capture_figures_drawn_by_two_processes_are_those_drawn_by_one(tmp_path):
    from mocaplib.library.format import load_library
    from mocaplib.report.html import _captures
    from mocaplib.report.diagnostics import read_diagnostics

    path = make_library(tmp_path)
    library = load_library(path)
    diagnostics = read_diagnostics(path, library)[0]
    series = diagnostics["captures"][0]
    diagnostics["captures"][1:1] = [{**series, "source": f"copy{k}.c3d",
                                     "frame_rms_m": (np.array(series["frame_rms_m"])
                                                     + 0.004 * (k + 1)).tolist()}
                                    for k in range(3)]
    one, two = (_captures(diagnostics, library, jobs=jobs) for jobs in (1, 2))
    figures = [c["figure"] for c in one if c["figure"]]
    assert len(figures) == 4 and len(set(figures)) == 4     # four different figures, in order
    assert [c["figure"] for c in two if c["figure"]] == figures
    assert [c["source"] for c in two] == [c["source"] for c in one]


def test_the_capture_figure_draws_both_ankles_poulaines_measured_and_modelled():
    from matplotlib.image import imread

    from mocaplib.report import figures
    from test_library import poulaine as stored_poulaine
    from mocaplib.gait.poulaine import Poulaine

    model = Poulaine.from_dict(stored_poulaine())
    phase = np.linspace(0.0, 1.0, 40)
    measured = model(phase)
    record = {"time_s": [0.0, 1.0], "events": [], "cycles": [],
              "poulaine": {"phase": phase.tolist(), "left_m": measured[:, 0].tolist(),
                           "right_m": measured[:, 1].tolist()}}
    drawn = {"path": model(np.linspace(0.0, 1.0, 121)),
             "points": np.stack([model.left.points, model.right.points])}

    def coloured(png, colour) -> int:      # pixels of ``colour`` in the bottom row of panels
        image = imread(io.BytesIO(png))[..., :3]
        bottom = image[int(0.72 * len(image)):]
        return int(np.sum(np.abs(bottom - np.asarray(colour) / 255).max(axis=-1) < 0.08))

    left, right = (31, 119, 180), (255, 127, 14)           # tab:blue, tab:orange: the model
    pale = (188, 214, 232)                                  # tab:blue at 30 %: measured, left
    with_both = figures.capture_figure(record, {}, drawn)
    assert coloured(with_both, left) > 300 and coloured(with_both, right) > 300
    assert coloured(with_both, pale) > 300
    measured_only = figures.capture_figure(record, {}, None)
    assert coloured(measured_only, pale) > 300 and coloured(measured_only, left) == 0
    without = figures.capture_figure({**record, "poulaine": None}, {}, None)
    assert coloured(without, left) == coloured(without, right) == coloured(without, pale) == 0


def test_report_marks_mirror_images_and_counts_coverage_without_them(tmp_path):
    """Two right curves flagged as the series mirror images of the left ones: the Entries
    table names their sources, the coverage is given without them too (as computed on the
    captured entries alone), and the sidecar, which names no series image, is still used."""
    from mocaplib.library.controlspace import ControlSpace
    from mocaplib.library.coverage import coverage
    from mocaplib.library.format import load_library
    from mocaplib.report import write_report
    from mocaplib.report.plan import default_envelope

    path = make_library(tmp_path)
    document = json.loads(path.read_text())
    images = {"cap05#0": "cap03#0", "cap06#0": "cap04#0"}
    for entry in document["entries"]:
        if entry["id"] in images:
            entry.update(mirrored=True, mirror_of=images[entry["id"]], mirror_method="series")
    path.write_text(json.dumps(document))
    sidecar = tmp_path / "lib.diagnostics.json"      # as `mocaplib mirror` copies it: no
    diagnostics = json.loads(sidecar.read_text())   # capture record names a series image
    diagnostics["captures"] = [c for c in diagnostics["captures"]
                               if c["source"] not in ("cap05.c3d", "cap06.c3d")]
    sidecar.write_text(json.dumps(diagnostics))
    html = write_report(path, tmp_path / "out", renderer="matplotlib").read_text()
    assert "mirror image of cap03#0" in html and "mirror image of cap04#0" in html
    envelope, _ = default_envelope(None)
    library = load_library(path)
    both = coverage(ControlSpace.from_library(library), envelope).fraction_inside
    alone = coverage(ControlSpace.from_library(library, mirrored=False), envelope)
    assert alone.fraction_inside < both
    assert (f"{100 * both:.1f} %</b>of the default target envelope covered "
            f"({100 * alone.fraction_inside:.1f} % without the 2 mirror images)") in html
    assert "does not belong to this library" not in html and "quality plots of walk_01" in html


@pytest.mark.slow
@pytest.mark.skipif(CHROMIUM is None, reason="chromium is not installed")
def test_the_motion_viewer_animates_and_blends_in_headless_chromium(report, tmp_path):
    """The report in a real browser (DevTools protocol, tests/browser.py): no console error;
    the figure moves (two screenshots 0.4 s apart differ in its canvas); a click in the pick
    panel plays a blend, with its weights shown, which changes the pose; the weights the page
    finds for a point are the control space's. Screenshots stay in the test's tmp_path."""
    from browser import Browser
    from mocaplib.library.controlspace import ControlSpace
    from mocaplib.library.format import load_library
    from matplotlib.image import imread

    path, _ = report
    pose = ("(() => { const p = window.mocapViewer.playing; const d = JSON.parse(document."
            "getElementById('mv-data').textContent); return MocapMotion.forward(d.skeleton, "
            "MocapMotion.synthesize(p.a, p.b, p.T, 0.3 * p.T)).map(w => [w[3], w[7], w[11]]);"
            " })()")
    browser = Browser(tmp_path / "profile")
    try:
        browser.open(path.resolve().as_uri())
        browser.evaluate("new Promise(r => setTimeout(r, 300))")
        figure = browser.rect("#mv-figure")
        first = imread(io.BytesIO(browser.screenshot(figure, tmp_path / "figure-1.png")))
        browser.evaluate("new Promise(r => setTimeout(r, 400))")
        second = imread(io.BytesIO(browser.screenshot(figure, tmp_path / "figure-2.png")))
        assert first.shape == second.shape and first.shape[0] > 400
        moved = np.abs(first[..., :3] - second[..., :3]).max(axis=2) > 0.1
        assert moved.sum() > 200, "the figure did not move between the screenshots"
        before = np.array(browser.evaluate(pose))
        pick = browser.rect("#mv-pick")
        browser.click(pick["x"] + 0.5 * pick["width"], pick["y"] + 0.45 * pick["height"])
        shown = browser.evaluate("document.getElementById('mv-weights').textContent")
        assert "blend of" in shown, shown
        assert browser.evaluate("window.mocapViewer.playing.label").startswith("blend at")
        # posed on the locks the page looked for on it (this hand-made library's feet never
        # stand still: none; tests/test_viewer_blends.py measures real blends' feet)
        assert browser.evaluate("Array.isArray(window.mocapViewer.playing.locks)")
        after = np.array(browser.evaluate(pose))
        assert np.abs(after - before).max() > 0.01        # metres: another motion
        browser.evaluate("new Promise(r => setTimeout(r, 300))")
        browser.screenshot(browser.rect("div.motion"), tmp_path / "blend.png")
        point = (1.1, 0.3, 0.05)
        weights = browser.evaluate(f"window.mocapViewer.pick{point}")
        cs = ControlSpace.from_library(load_library(path.parent.parent / "lib.json"))
        found = cs.query(np.array([point]))
        expected = {cs.ids[i]: w for i, w in zip(found.entries[0], found.weights[0])}
        assert weights.keys() == expected.keys()
        np.testing.assert_allclose([weights[k] for k in expected], list(expected.values()),
                                   atol=1e-9)
        assert browser.console_errors == []
    finally:
        browser.close()


def test_a_cycle_from_a_fallback_event_says_so_in_the_capture_section():
    from mocaplib.report.html import _captures

    diagnostics = {"captures": [{"source": "run.c3d", "ok": True, "cycles": [
        {"index": 0, "start_s": 0.59, "end_s": 1.30, "chosen": True, "entry_id": None,
         "start_event": "right_toe_off", "pattern": {"type": "line"}},
        {"index": 1, "start_s": 1.30, "end_s": 2.0, "chosen": False, "entry_id": None,
         "start_event": "left_toe_off", "pattern": {"type": "line"}}]}]}
    from types import SimpleNamespace

    cycles = _captures(diagnostics, SimpleNamespace(entries=[]))[0]["cycles"]
    assert [c["start_event"] for c in cycles] == ["right toe off", None]


def test_the_viewers_cycles_planted_by_two_jobs_are_those_of_one(monkeypatch):
    # tasks of 3 cycles over two worker processes give every entry's planted series of one
    # process, in the library's order
    library = load_library(Path(__file__).parents[1] / "js" / "test" / "fixtures"
                           / "library.json")
    cs = ControlSpace.from_library(library)
    classes = ["walk"] * len(library.entries)
    monkeypatch.setattr(figureview, "PLANTED_PER_TASK", 3)
    one = figureview.viewer_data(library, cs, classes, {}, jobs=1)["entries"]
    two = figureview.viewer_data(library, cs, classes, {}, jobs=2)["entries"]
    assert len(library.entries) > 6
    assert [e["id"] for e in two] == [e.id for e in library.entries]
    assert one == two


def test_the_default_jobs_grow_with_the_entries_and_captures(monkeypatch):
    from mocaplib.report import html

    monkeypatch.setattr(html, "max_jobs", lambda: 8)
    assert html.default_jobs(68, 0) == 1                  # planted before a worker starts
    assert html.default_jobs(68, 68) == 8                 # the quick start: 68 figures to draw
    assert html.default_jobs(5000, 0) == 8 and html.default_jobs(1200, 0) == 3
    monkeypatch.setattr(html, "max_jobs", lambda: 2)
    assert html.default_jobs(5000, 0) == 2 and html.default_jobs(0, 0) == 1
