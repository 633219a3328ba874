"""The batch pipeline: parallelism, cache, failure isolation, determinism, diagnostics, CLI.

Orchestration is tested with a small per-capture function (``fake_process``) reading tiny
JSON "captures", so these tests are fast and do not depend on the fitting stages; the real
``process_capture`` is exercised on bad files here and on the samples in the last tests.
"""

from __future__ import annotations

import json
import os
import re
import signal
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from mocaplib.build import dask_batches, pipeline, workflow
from mocaplib.cli import main
from mocaplib.errors import MocapError
from mocaplib.io import fs_text
from mocaplib.library.format import load_library
from mocaplib.library.validation import validate_library
from mocaplib.gait.qc import DEFAULT_QC_THRESHOLDS, qc_failures
from mocaplib.build.pipeline import build_library
from mocaplib.io import find_captures
from mocaplib.build.settings import BuildSettings
from mocaplib.build.workflow import CaptureResult, file_sha256, process_capture
from mocaplib.library.format import diagnostics_path
from mocaplib.skeleton import DOF_NAMES
from mocaplib.build.workers import max_jobs

from entries import plain_entry

TRIPLES = [(1.2, 0.0, 0.0), (0.6, 0.5, 0.0), (0.3, 0.0, 0.4), (0.8, -0.4, -0.2), (0.0, 1.0, 0.0)]


def fake_process(path: str, settings: BuildSettings) -> CaptureResult:
    """A stand-in for process_capture: a capture file holds JSON {"v", "omega", "v_l"}.

    Appends the file name to ``calls.log`` beside it, so tests can count how often a capture
    was processed (also from worker processes). ``{"fail": ...}`` fails the capture like a
    stage would; ``{"crash": ...}`` raises like a bug would; ``{"die": ...}`` kills the process
    running it, as the out-of-memory killer would (a worker only!), every time or, with
    ``"once"``, the first time; ``{"sleep": s}`` takes ``s`` seconds; ``{"stop": ...}``
    stops the process running it (SIGSTOP), as a hung worker (a worker only!).
    """
    path = Path(path)
    with open(path.parent / "calls.log", "a") as log:
        log.write(fs_text(path.name) + "\n")
    data = json.loads(path.read_text())
    data = {"v": 1.0, "omega": 0.0, "v_l": 0.0} | data
    result = CaptureResult(source=str(path), sha256=file_sha256(path))
    if "crash" in data:
        raise RuntimeError(data["crash"])
    if data.get("die") == "always" or data.get("die") == "once" and calls(path.parent).count(
            fs_text(path.name)) == 1:
        os.kill(os.getpid(), signal.SIGKILL)
    if "stop" in data:
        os.kill(os.getpid(), signal.SIGSTOP)
    time.sleep(data.get("sleep", 0))
    if "fail" in data:
        result.ok, result.stage, result.error = False, "import", f"{path}: {data['fail']}"
        return result
    n = 2
    rng = np.random.default_rng(int(data["v"] * 1000 + data["omega"] * 100 + data["v_l"] * 10))
    a = rng.normal(size=(len(DOF_NAMES), n + 1))
    a[:, 0] = 0  # mean pose neutral: within every DOF's range
    b = rng.normal(size=(len(DOF_NAMES), n + 1))
    b[:, 0] = 0
    entry_id = f"{path.stem}_c0"
    result.entries = [plain_entry(
        id=entry_id, source_file=path.name, source_sha256=result.sha256, cycle_index=0,
        start_s=0.2, end_s=1.3, T=1.1,
        pattern={"type": "line", "parameters": {"point": [0.0, 0.0], "direction": [1.0, 0.0],
                                                "length": 1.0},
                 "residual_m": 0.01, "arc_angle_rad": 0.0},
        v=data["v"], omega=data["omega"], v_l=data["v_l"], v_f=data["v"], a=a, b=b,
        root_drift={"u_f_m_s": data["v"], "u_l_m_s": data["v_l"], "omega_rad_s": data["omega"]},
        qc={"marker_rms_m": 0.01})]
    result.diagnostics = {"rate_hz": 100.0, "time_s": [0.0, 0.01],
                          "cycles": [{"start_s": 0.2, "end_s": 1.3, "chosen": True,
                                      "entry_id": entry_id, "pattern": {"type": "line"}}]}
    result.n_cycles, result.n_frames = 1, 150
    result.warnings = data.get("warnings", [])
    return result


def write_captures(folder: Path, triples=TRIPLES, prefix="walk") -> list[Path]:
    folder.mkdir(parents=True, exist_ok=True)
    paths = []
    for i, (v, w, vl) in enumerate(triples):
        path = folder / f"{prefix}{i:02d}.c3d"
        path.write_text(json.dumps({"v": v, "omega": w, "v_l": vl}))
        paths.append(path)
    return paths


def calls(folder: Path) -> list[str]:
    log = folder / "calls.log"
    return log.read_text().split() if log.exists() else []


def build_bytes(result, folder: Path) -> tuple[bytes, bytes]:
    library, sidecar = result.write(folder / "lib.json")
    return library.read_bytes(), sidecar.read_bytes()


def test_serial_build_gives_a_valid_library_and_diagnostics(tmp_path):
    write_captures(tmp_path / "caps")
    result = build_library([tmp_path / "caps"], progress=False, process=fake_process)
    assert result.ok and len(result.library) == 5
    library_path, sidecar = result.write(tmp_path / "out" / "lib.json")
    assert sidecar == tmp_path / "out" / "lib.diagnostics.json"
    assert validate_library(library_path) == []
    diag = json.loads(sidecar.read_text())
    assert diag["format"] == "mocaplib-diagnostics" and diag["version"] == 1
    assert [c["source"] for c in diag["captures"]] == [f"walk{i:02d}.c3d" for i in range(5)]
    assert diag["captures"][0]["cycles"][0]["entry_id"] == "walk00_c0"
    assert set(diag["captures"][0]) >= {"source", "ok", "error", "stage", "rate_hz", "time_s",
                                        "shoulder_mid_xy", "frame_rms_m", "events", "cycles",
                                        "angles", "warnings"}
    assert result.summary()["entries"] == 5 and result.summary()["failed"] == 0


def test_a_failing_and_a_crashing_capture_do_not_stop_the_build(tmp_path):
    folder = tmp_path / "caps"
    write_captures(folder)
    (folder / "walk90.c3d").write_text(json.dumps({"fail": "truncated file"}))
    (folder / "walk91.c3d").write_text(json.dumps({"crash": "boom"}))
    result = build_library([folder], progress=False, process=fake_process)
    assert not result.ok and len(result.library) == 5
    failures = {Path(f["file"]).name: f for f in result.summary()["failures"]}
    assert failures["walk90.c3d"]["stage"] == "import"
    assert "truncated file" in failures["walk90.c3d"]["reason"]
    assert failures["walk91.c3d"]["stage"] == "worker"
    assert "RuntimeError: boom" in failures["walk91.c3d"]["reason"]
    text = result.summary_text()
    assert "failed 2" in text and "walk90.c3d [import]" in text


def test_cache_processes_only_new_or_changed_captures(tmp_path):
    folder, cache = tmp_path / "caps", tmp_path / "cache"
    write_captures(folder, TRIPLES[:4])
    first = build_library([folder], cache_dir=cache, progress=False, process=fake_process)
    assert sorted(calls(folder)) == [f"walk{i:02d}.c3d" for i in range(4)]
    again = build_library([folder], cache_dir=cache, progress=False, process=fake_process)
    assert len(calls(folder)) == 4, "nothing should be re-processed"
    assert all(c.from_cache for c in again.captures)
    assert build_bytes(first, tmp_path / "a") == build_bytes(again, tmp_path / "b")

    write_captures(folder, TRIPLES)  # adds walk04 (walk00-03 rewritten with the same bytes)
    grown = build_library([folder], cache_dir=cache, progress=False, process=fake_process)
    assert calls(folder)[4:] == ["walk04.c3d"]
    assert len(grown.library) == 5 and grown.summary()["from_cache"] == 4

    (folder / "walk01.c3d").write_text(json.dumps({"v": 0.7, "omega": 0.5, "v_l": 0.0}))
    build_library([folder], cache_dir=cache, progress=False, process=fake_process)
    assert calls(folder)[5:] == ["walk01.c3d"], "changed content must be re-processed"

    build_library([folder], BuildSettings(all_cycles=True), cache_dir=cache, progress=False,
          process=fake_process)
    assert len(calls(folder)) == 6 + 5, "other settings must re-process everything"


def test_cache_made_by_other_code_is_not_reused(tmp_path, monkeypatch):
    folder, cache = tmp_path / "caps", tmp_path / "cache"
    write_captures(folder, TRIPLES[:2])
    build_library([folder], cache_dir=cache, progress=False, process=fake_process)
    # Same version number, edited code (a development checkout): everything is re-processed.
    monkeypatch.setattr("mocaplib.build.cache.code_fingerprint", lambda: "edited")
    again = build_library([folder], cache_dir=cache, progress=False, process=fake_process)
    assert len(calls(folder)) == 4 and not any(c.from_cache for c in again.captures)


def test_failures_are_cached_but_crashes_are_not(tmp_path):
    folder, cache = tmp_path / "caps", tmp_path / "cache"
    folder.mkdir()
    (folder / "bad.c3d").write_text(json.dumps({"fail": "not a C3D"}))
    (folder / "bug.c3d").write_text(json.dumps({"crash": "bug"}))
    for _ in range(2):
        build_library([folder], cache_dir=cache, progress=False, process=fake_process)
    assert sorted(calls(folder)) == ["bad.c3d", "bug.c3d", "bug.c3d"]


def test_a_damaged_cache_file_is_recomputed_not_trusted(tmp_path):
    folder, cache = tmp_path / "caps", tmp_path / "cache"
    write_captures(folder, TRIPLES[:4])
    first = build_library([folder], cache_dir=cache, progress=False, process=fake_process)
    damaged = ["[]", '{"ok": 1}', "7", '{"source": "x"}', "{", "[" * 100000]
    for path, text in zip(sorted(cache.glob("*.json")), damaged):
        path.write_text(text)
    again = build_library([folder], cache_dir=cache, progress=False, process=fake_process)
    assert len(calls(folder)) == 8 and not any(c.from_cache for c in again.captures)
    assert build_bytes(first, tmp_path / "a") == build_bytes(again, tmp_path / "b")


def test_a_folder_named_like_a_capture_is_skipped_and_a_broken_link_fails_alone(tmp_path):
    folder, cache = tmp_path / "caps", tmp_path / "cache"
    write_captures(folder, TRIPLES[:4])
    (folder / "takes.c3d").mkdir()                        # a folder, not a capture
    (folder / "gone.c3d").symlink_to(tmp_path / "moved.c3d")  # its target was moved away
    result = build_library([folder], cache_dir=cache, progress=False)
    names = [c.file for c in result.captures]
    assert "takes.c3d" not in names
    gone = next(c for c in result.captures if c.file == "gone.c3d")
    assert not gone.ok and gone.stage == "read" and "gone.c3d: cannot read" in gone.error
    assert all(not c.ok for c in result.captures)  # the fake captures are not C3D either


def test_two_jobs_give_the_same_bytes_as_one(tmp_path):
    write_captures(tmp_path / "caps")
    one = build_library([tmp_path / "caps"], jobs=1, progress=False, process=fake_process)
    two = build_library([tmp_path / "caps"], jobs=2, progress=False, process=fake_process)
    assert build_bytes(one, tmp_path / "one") == build_bytes(two, tmp_path / "two")


def test_dask_local_cluster_gives_the_same_bytes(tmp_path):
    distributed = pytest.importorskip("distributed")
    write_captures(tmp_path / "caps")
    serial = build_library([tmp_path / "caps"], progress=False, process=fake_process)
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=False,
                                  dashboard_address=None) as cluster:
        dask = build_library([tmp_path / "caps"], scheduler=cluster.scheduler_address, progress=False,
                     process=fake_process)
    assert build_bytes(serial, tmp_path / "s") == build_bytes(dask, tmp_path / "d")


def test_unreachable_scheduler_is_a_clear_error(tmp_path, monkeypatch):
    monkeypatch.setattr(dask_batches, "SCHEDULER_TIMEOUT_S", 1)
    write_captures(tmp_path / "caps", TRIPLES[:1])
    with pytest.raises(MocapError, match="cannot connect to the Dask scheduler"):
        build_library([tmp_path / "caps"], scheduler="tcp://127.0.0.1:1", progress=False,
              process=fake_process)


def test_same_file_name_in_two_folders_gets_unique_ids(tmp_path):
    write_captures(tmp_path / "day1", TRIPLES[:3])
    # day2/walk00 and walk01 are byte copies of day1/walk01 and walk02; day2/walk02 is new.
    write_captures(tmp_path / "day2", TRIPLES[1:4])
    result = build_library([tmp_path / "day1", tmp_path / "day2"], progress=False, process=fake_process)
    ids = list(result.library.table.index)
    assert len(ids) == len(set(ids)) == 4, ids
    assert sorted(i.split("@")[0] for i in ids if "@" in i) == ["walk02_c0", "walk02_c0"]
    for copy in result.captures[3:5]:
        assert not copy.entries and "same content as" in copy.warnings[0]
        assert copy.diagnostics["cycles"][0]["entry_id"] is None


def test_find_captures_recurses_sorts_and_dedupes(tmp_path):
    paths = write_captures(tmp_path / "a" / "b", TRIPLES[:2])
    (tmp_path / "a" / "notes.txt").write_text("x")
    (tmp_path / "empty").mkdir()
    found = find_captures([tmp_path / "a", paths[0]])
    assert [p.name for p in found] == ["walk00.c3d", "walk01.c3d"]
    with pytest.raises(MocapError, match="no such file or folder"):
        find_captures([tmp_path / "missing"])
    with pytest.raises(MocapError, match="no C3D captures found"):
        build_library([(tmp_path / "empty")], progress=False, process=fake_process)


def test_progress_bar_reports_captures_on_stderr(tmp_path, capsys):
    write_captures(tmp_path / "caps", TRIPLES[:2])
    build_library([tmp_path / "caps"], progress=True, process=fake_process)
    assert "2/2" in capsys.readouterr().err


def test_process_capture_returns_errors_instead_of_raising(tmp_path):
    missing = process_capture(tmp_path / "absent.c3d", BuildSettings())
    assert not missing.ok and missing.stage == "read" and "absent.c3d" in missing.error
    truncated = tmp_path / "truncated.c3d"
    truncated.write_bytes(b"\x02\x50" + bytes(300))
    result = process_capture(truncated, BuildSettings())
    assert not result.ok and result.stage == "import"
    assert "truncated.c3d" in result.error and "internal error" not in result.error
    assert result.to_dict()["ok"] is False  # JSON-ready for the cache


@pytest.mark.usefixtures("sample_dir")
def test_exchanged_left_right_labels_are_reported(tmp_path, capsys):
    # the fit exchanged them back silently: motonms Walking3's swapped acromions went unreported
    from conftest import SAMPLES
    from mocaplib.io.c3d import read_c3d
    from mocaplib.io.c3d_write import write_c3d

    trial = read_c3d(SAMPLES / "rest.c3d")
    labels = list(trial.labels)
    i, j = labels.index("LSHO"), labels.index("RSHO")
    labels[i], labels[j] = labels[j], labels[i]
    path = write_c3d(tmp_path / "swapped.c3d", trial.markers[:120], labels, trial.rate)
    result = process_capture(path, BuildSettings())
    assert result.ok, result.error
    assert any(w.startswith("labels LSHO and RSHO look exchanged") for w in result.warnings), \
        result.warnings
    assert main(["fit", str(path), "-o", str(tmp_path / "angles.csv")]) == 0
    assert "swapped.c3d: labels LSHO and RSHO look exchanged" in capsys.readouterr().err


@pytest.mark.usefixtures("sample_dir")
def test_a_neutral_static_is_calibrated_once_but_every_capture_is_checked(tmp_path):
    # build calibrates a neutral static once per worker (the model depends on the static and
    # the protocol alone); a later capture of another subject must still be refused
    from conftest import SAMPLES, plan_capture

    taller, _ = plan_capture("walk_straight_normal", 1.85, tmp_path)
    settings = BuildSettings(static=str(SAMPLES / "rest.c3d"), static_pose="neutral")
    workflow._neutral_model.cache_clear()
    result = build_library([SAMPLES / "walk_straight_normal.c3d", SAMPLES / "turn_spot_left_normal.c3d",
                    taller], settings, jobs=1, cache_dir=None, progress=False)
    assert workflow._neutral_model.cache_info().misses == 1          # calibrated once
    walk, turn, other = result.captures
    assert walk.ok and turn.ok and walk.static == turn.static == "rest.c3d", walk.error
    # the taller subject's capture is not this static's: calibrated from itself, said so
    assert other.ok and other.static is None and other.entries, other.error
    assert any(w.startswith("calibrated from the capture itself: no static shows its subject")
               and "rest.c3d" in w for w in other.warnings), other.warnings
    required = build_library([taller], replace(settings, require_static=True), jobs=1, cache_dir=None,
                     progress=False).captures[0]
    assert not required.ok and required.stage == "calibrate" and required.static is None
    assert "walk_straight_normal_1.85.c3d" in required.error and "rest.c3d" in required.error


@pytest.mark.usefixtures("sample_dir")
def test_several_statics_each_capture_gets_its_subjects(tmp_path):
    # a batch of two subjects, each with its own static: each capture is calibrated with the
    # static that shows its subject; a capture of a third subject fails, naming every static
    from conftest import SAMPLES, plan_capture

    taller_walk, _ = plan_capture("walk_straight_normal", 1.85, tmp_path)
    taller_rest, _ = plan_capture("rest", 1.85, tmp_path)
    shorter_walk, _ = plan_capture("walk_straight_normal", 1.55, tmp_path)
    settings = BuildSettings(static=[SAMPLES / "rest.c3d", taller_rest], static_pose="neutral")
    assert settings.statics == (str(SAMPLES / "rest.c3d"), str(taller_rest))
    result = build_library([SAMPLES / "walk_straight_normal.c3d", taller_walk, shorter_walk], settings,
                   jobs=1, cache_dir=None, progress=False)
    walk, taller, shorter = result.captures
    assert walk.ok and walk.static == "rest.c3d", walk.error
    assert taller.ok and taller.static == "rest_1.85.c3d", taller.error
    assert walk.entries[0].segment_lengths_m != taller.entries[0].segment_lengths_m
    assert shorter.ok and shorter.static is None and shorter.entries, shorter.error
    warning = next(w for w in shorter.warnings if w.startswith("calibrated from the capture"))
    assert "none of the 2 static trials" in warning
    assert re.search(r"rest\.c3d \d+\.\d mm; rest_1\.85\.c3d \d+\.\d mm", warning)
    assert result.library.settings["static"] == ["rest.c3d", "rest_1.85.c3d"]
    assert [c["static"] for c in result.diagnostics()["captures"]] == \
        ["rest.c3d", "rest_1.85.c3d", None]
    required = build_library([shorter_walk], replace(settings, require_static=True), jobs=1,
                     cache_dir=None, progress=False)
    assert not required.ok and "none of the 2 static trials" in required.failures[0].error
    assert result.summary()["statics"] == {"rest.c3d": 1, "rest_1.85.c3d": 1}
    assert "captures per static: rest.c3d 1, rest_1.85.c3d 1" in result.summary_text()


@pytest.mark.usefixtures("sample_dir")
def test_statics_are_named_apart_and_read_errors_name_them(tmp_path):
    # two sessions' statics of one name are told apart by their folders; the same file given
    # twice counts once; an empty value is no static; an unreadable static is named
    from conftest import SAMPLES

    for session in ("S1", "S2"):
        (tmp_path / session).mkdir()
        (tmp_path / session / "Static.c3d").write_bytes((SAMPLES / "rest.c3d").read_bytes())
    settings = BuildSettings(static=[tmp_path / "S1" / "Static.c3d", tmp_path / "S2" / "Static.c3d",
                                     str(tmp_path / "S1" / ".." / "S1" / "Static.c3d")])
    assert settings.to_dict()["static"] == ["S1/Static.c3d", "S2/Static.c3d"]
    assert BuildSettings(static="").static is None and BuildSettings(static=[]).static is None
    missing = process_capture(SAMPLES / "walk_straight_normal.c3d",
                              BuildSettings(static=str(tmp_path / "gone.c3d")))
    assert not missing.ok and missing.stage == "import"
    assert missing.error.startswith(str(tmp_path / "gone.c3d")) and "cannot read" in missing.error


# --------------------------------------------------------------------------- CLI
def test_cli_exit_codes(tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(pipeline, "process_capture", fake_process)
    folder = tmp_path / "caps"
    write_captures(folder)
    out = tmp_path / "lib.json"
    assert main(["build", str(folder), "-o", str(out), "--no-cache", "-q"]) == 0
    assert "entries 5" in capsys.readouterr().out
    assert main(["validate", str(out)]) == 0

    (folder / "bad.c3d").write_text(json.dumps({"fail": "truncated"}))
    assert main(["build", str(folder), "-o", str(out), "--no-cache", "-q"]) == 1
    assert "bad.c3d [import]" in capsys.readouterr().out
    assert len(load_library(out)) == 5, "the good captures still make the library"

    for usage in (["build", str(folder)], ["build", str(folder), "-o", str(out), "-j", "0"],
                  ["build", str(folder), "-o", str(out), "--no-cache", "--cache-dir", "x"]):
        assert main(usage) == 2
    assert main(["build", str(folder), "-o", str(out), "--protocol", "no_such_set"]) == 2
    assert main(["build", str(folder), "-o", str(out), "--static", str(tmp_path / "x.c3d")]) == 2
    assert f"--static: {tmp_path / 'x.c3d'}: no such file" in capsys.readouterr().err
    real_static = tmp_path / "real.c3d"
    real_static.write_bytes(b"")
    assert main(["build", str(folder), "-o", str(out), "--static", str(real_static),
                 "--static", str(tmp_path / "y.c3d")]) == 2
    error = capsys.readouterr().err
    assert f"--static: {tmp_path / 'y.c3d'}: no such file" in error and "real.c3d" not in error
    # a static that is there but not a C3D file: named before any capture is processed
    assert main(["build", str(folder), "-o", str(tmp_path / "z.json"), "--static",
                 str(real_static)]) == 2
    error = capsys.readouterr().err
    assert f"--static: {real_static}" in error and not (tmp_path / "z.json").exists()


def test_cli_validate_prints_problems(tmp_path, capsys):
    write_captures(tmp_path / "caps", TRIPLES[:2])
    path, _ = build_library([tmp_path / "caps"], progress=False, process=fake_process).write(
        tmp_path / "small")
    # two entries: valid, without a control space (a warning naming why and what to do)
    assert main(["validate", str(path)]) == 0
    printed = capsys.readouterr()
    assert "valid" in printed.out and "no control space" in printed.err
    assert "needs at least 4 entries with distinct velocities, got 2" in printed.err
    assert main(["validate", str(path), "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["valid"] is True and report["problems"] == []
    assert report["warnings"][0].startswith("no control space")
    document = json.loads(path.read_text())
    document["entries"][0]["T"] = 0.0
    path.write_text(json.dumps(document))
    assert main(["validate", str(path)]) == 1
    assert "period must be finite and > 0" in capsys.readouterr().out
    assert main(["validate", str(tmp_path / "absent")]) == 2   # a usage error: no such file


# --------------------------------------------------------------------------- real stages
@pytest.fixture(scope="module")
def synthetic_folder(tmp_path_factory) -> Path:
    """Three synthetic captures of the paper plan (a side-step, a curve, rest) with truth."""
    from mocaplib.markersets.protocols import protocols_dir
    from mocaplib.synth.plan import generate_plan, load_plan

    folder = tmp_path_factory.mktemp("synthetic")
    generate_plan(load_plan(protocols_dir() / "paper_plan.toml"), folder,
                  only=["side_left_normal", "walk_curve_r1_left_slow", "rest"])
    return folder


def test_cli_build_runs_every_stage_and_matches_the_truth(synthetic_folder, tmp_path, capsys):
    truncated = tmp_path / "broken.c3d"
    truncated.write_bytes((synthetic_folder / "rest.c3d").read_bytes()[:3000])
    out = tmp_path / "lib.json"
    code = main(["build", str(synthetic_folder), str(truncated), "-o", str(out), "--no-cache",
                 "-q"])
    assert code == 1, "one capture failed"
    printed = capsys.readouterr().out
    assert "broken.c3d [import]" in printed and "captures 4  ok 3  failed 1" in printed
    lib = load_library(out)
    table = lib.table
    assert sorted(table["locomotion_class"]) == ["holonomic", "nonholonomic", "rest"]
    for entry_id, row in table.iterrows():
        truth = json.loads((synthetic_folder / row["source_file"]).with_suffix(".truth.json")
                           .read_text())
        command = truth["command"]
        # The velocity targets on synthetic captures: v within 2 % (0.02 m/s near 0),
        # omega within 0.02 rad/s, v_l within 0.02 m/s; rest is exactly zero.
        speed = float(np.hypot(command["v_f"], command["v_l"]))
        assert abs(row["v"] - speed) <= max(0.02 * speed, 0.02), entry_id
        assert abs(row["omega"] - command["omega"]) <= 0.02, entry_id
        assert abs(row["v_l"] - command["v_l"]) <= 0.02, entry_id
        assert row["chosen"] and row["T"] > 0 and row["source_sha256"] == file_sha256(
            synthetic_folder / row["source_file"])
        a, b = lib.coefficients(entry_id)
        assert a.shape == (len(DOF_NAMES), lib.n_harmonics + 1) and np.isfinite(a).all()
    diag = json.loads(diagnostics_path(out).read_text())
    by_name = {c["source"]: c for c in diag["captures"]}
    side = by_name["side_left_normal.c3d"]
    assert side["ok"] and side["rate_hz"] == 100.0
    assert 0 < side["marker_cutoff_hz"] < 50  # Winter's residual cutoff, below Nyquist
    assert {e["kind"] for e in side["events"]} == {"toe_off", "heel_strike"}
    chosen = [c for c in side["cycles"] if c["chosen"]]
    assert len(chosen) == 1 and chosen[0]["entry_id"] in table.index
    assert set(side["angles"]) == {"time_s", *DOF_NAMES}
    assert len(side["time_s"]) == len(side["shoulder_mid_xy"]) == len(side["frame_rms_m"])
    assert not by_name["broken.c3d"]["ok"] and by_name["broken.c3d"]["stage"] == "import"
    # every entry's QC has the internal power; the moving ones a poulaine, measured in the
    # sidecar (the chosen cycle's ankle paths) and modelled in the library within 5 mm
    assert table["qc_internal_power_w_kg"].notna().all()
    for entry_id, row in table.iterrows():
        model = lib.poulaine(entry_id)
        record = by_name[row["source_file"]]
        if row["locomotion_class"] == "rest":
            assert model is None and record["poulaine"] is None
            continue
        measured = record["poulaine"]
        assert len(measured["phase"]) == len(measured["left_m"]) == len(measured["right_m"])
        assert 30 <= len(measured["phase"]) <= 60
        np.testing.assert_allclose(model(np.asarray(measured["phase"])),
                                   np.stack([measured["left_m"], measured["right_m"]], axis=1),
                                   atol=0.03)   # the speed profile's error, a few mm RMS
        assert row["poulaine_fit_rms_m"] <= 0.005


def test_real_capture_failing_qc_is_dropped_or_waived(monkeypatch, real_c3d):
    path = real_c3d("btkdata/Gait.c3d")
    # 1 mm marker RMS: no real capture with skin markers meets it, so QC must fail.
    strict = {**DEFAULT_QC_THRESHOLDS, "marker_rms_m": 0.001}
    # the policy acts only on the entries: process once, keep the cycles for the other policy
    stage, entries = {}, workflow._entries

    def recorded(path, result, cycles, qcs, settings, *args):
        stage.update(path=path, cycles=cycles, qcs=qcs, args=args)
        return entries(path, result, cycles, qcs, settings, *args)

    monkeypatch.setattr(workflow, "_entries", recorded)
    kept = process_capture(path, BuildSettings(qc_policy="waive", qc_thresholds=strict))
    assert kept.ok and len(kept.entries) == 1
    entry = kept.entries[0]
    assert entry.qc["marker_rms_m"] > 0.001
    failing = sorted(qc_failures(entry.qc, strict))
    assert sorted(entry.qc_waived) == sorted(f.split()[0] for f in failing)
    assert "marker_rms_m" in entry.qc_waived
    assert any("kept with QC waived" in w for w in kept.warnings)
    assert [c["entry_id"] for c in kept.diagnostics["cycles"] if c["chosen"]] == [entry.id]
    dropped = CaptureResult(source=str(path))
    drop = BuildSettings(qc_policy="drop", qc_thresholds=strict)
    assert entries(stage["path"], dropped, stage["cycles"], stage["qcs"], drop,
                   *stage["args"]) == []
    # the marker behind a marker metric is named: the one to check in the capture
    motion = stage["args"][0]
    named = [re.search(r"marker_rms_m [0-9.]+ > 0\.001 \(([^ )]+)\)", w)
             for w in dropped.warnings if "left out of the library" in w]
    assert named and all(m and m.group(1) in motion.marker_labels for m in named), named


def test_a_capture_contributes_its_steadiest_cycle_that_passes_qc(synthetic_folder):
    path = synthetic_folder / "side_left_normal.c3d"
    every = process_capture(path, BuildSettings(all_cycles=True)).entries
    closure = {e.cycle_index: e.qc["cycle_closure_rad"] for e in every}
    steadiest = next(e.cycle_index for e in every if e.chosen)
    others = [i for i in closure if closure[i] < closure[steadiest]]
    assert len(every) >= 2 and others  # a cycle that closes better than the steadiest
    # a closure limit the steadiest cycle fails and another passes: that one is chosen
    limit = 0.5 * (closure[steadiest] + max(closure[i] for i in others))
    strict = BuildSettings(qc_thresholds={**DEFAULT_QC_THRESHOLDS, "cycle_closure_rad": limit})
    result = process_capture(path, strict)
    assert len(result.entries) == 1
    assert result.entries[0].cycle_index in others and result.entries[0].chosen
    assert not any("left out" in w for w in result.warnings)
    # when no cycle passes, the steadiest is still the chosen one, and it is left out
    none_pass = BuildSettings(qc_thresholds={**DEFAULT_QC_THRESHOLDS,
                                             "cycle_closure_rad": 0.5 * min(closure.values())})
    result = process_capture(path, none_pass)
    assert result.entries == []
    assert any(f"cycle {steadiest} " in w and "left out" in w for w in result.warnings)


@pytest.mark.parametrize("toe_off", ["foot_velocity", "lift"])
def test_process_capture_gives_the_cycles_of_mocaplib_cycles(synthetic_folder, capsys, toe_off):
    path = synthetic_folder / "walk_curve_r1_left_slow.c3d"
    assert main(["cycles", str(path), "--json", "--toe-off", toe_off]) == 0
    expected = json.loads(capsys.readouterr().out)["cycles"]
    result = process_capture(path, BuildSettings(all_cycles=True, toe_off=toe_off))
    got = {e.cycle_index: e for e in result.entries}
    assert len(got) == len(expected) == result.n_cycles
    for cycle in expected:
        entry = got[cycle["index"]]
        # The same stages on the same file: equal up to the library's 10 significant digits.
        for key in ("start_s", "end_s", "v", "omega", "v_l", "v_f"):
            np.testing.assert_allclose(getattr(entry, key), cycle[key], rtol=1e-9, atol=1e-12)
        assert entry.chosen == cycle["chosen"]
        assert entry.fourier.n == cycle["fourier_n"]
        assert cycle["qc_failures"] == qc_failures(entry.qc, DEFAULT_QC_THRESHOLDS)
        # one JSON shape for a pattern: the library's
        assert entry.pattern.to_json().keys() == cycle["pattern"].keys()
        assert entry.pattern.parameters.keys() == cycle["pattern"]["parameters"].keys()
        np.testing.assert_allclose(entry.pattern.arc_angle_rad,
                                   cycle["pattern"]["arc_angle_rad"], rtol=1e-9, atol=1e-12)


def test_with_one_static_and_auto_every_command_resolves_the_protocol_on_the_capture(
        synthetic_folder, tmp_path, capsys):
    # fit detected the protocol on the static (calibrate's choice), build and cycles on the
    # capture: a static with one more Plug-in Gait label (RBAK) made fit use plugin_gait
    from mocaplib.model.calibration import calibrate
    from mocaplib.io.c3d import read_c3d
    from mocaplib.io.c3d_write import write_c3d
    from mocaplib.markersets.matching import detect_protocol

    rest = read_c3d(synthetic_folder / "rest.c3d")
    back = rest.markers[:, [rest.labels.index("T10")]] + [-0.05, -0.05, 0.0]
    static = write_c3d(tmp_path / "static_rbak.c3d", np.concatenate([rest.markers, back], 1),
                       [*rest.labels, "RBAK"], rest.rate)
    assert detect_protocol(read_c3d(static)).protocol.name == "plugin_gait"
    path = synthetic_folder / "side_left_normal.c3d"
    model = calibrate(read_c3d(path), protocol="auto", static=read_c3d(static))
    assert model.protocol.name == "fullbody38"      # the Python API resolves it as the CLI
    assert main(["fit", str(path), "--static", str(static), "-o", str(tmp_path / "a.csv"),
                 "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["protocol"] == "fullbody38"
    assert main(["cycles", str(path), "--static", str(static), "--json"]) == 0
    expected = json.loads(capsys.readouterr().out)["cycles"]
    result = process_capture(path, BuildSettings(static=str(static), all_cycles=True))
    assert result.ok and result.static == "static_rbak.c3d"
    got = {e.cycle_index: e for e in result.entries}
    assert len(got) == len(expected) == result.n_cycles
    for cycle in expected:
        for key in ("start_s", "end_s", "v", "omega", "v_l", "v_f"):
            np.testing.assert_allclose(getattr(got[cycle["index"]], key), cycle[key], rtol=1e-9,
                                       atol=1e-12)


def test_a_capture_missing_required_landmarks_fails_alone_naming_them(synthetic_folder,
                                                                      tmp_path):
    # it went through silently: the shoulders of the cycles' velocities came from a guess
    from mocaplib.io.c3d import read_c3d
    from mocaplib.io.c3d_write import write_c3d

    trial = read_c3d(synthetic_folder / "side_left_normal.c3d")
    renamed = {"LSHO": "LSHX", "LASI": "L_ASIS_X"}
    bad = write_c3d(tmp_path / "renamed.c3d", trial.markers,
                    [renamed.get(label, label) for label in trial.labels], trial.rate)
    result = build_library([bad, synthetic_folder / "rest.c3d"], BuildSettings(), progress=False)
    failed, rest = result.captures
    assert not failed.ok and failed.stage == "protocol" and rest.ok and len(result.library) == 1
    assert failed.error.startswith(
        f"{bad}: the capture has no label for required landmarks of protocol 'fullbody38': "
        "L_ASIS (expects LASI); L_ACROMION (expects LSHO)")
    assert all(remedy in failed.error for remedy in ("rename", "alias", "--protocol"))


def test_build_cuts_cycles_where_the_toes_leave_and_records_the_definition(synthetic_folder,
                                                                           tmp_path):
    # The synthetic toe-off is the toes' tips leaving the floor, which the default finds
    # (docs/guide/events-cycles.md): every cycle starts within a frame of a true left toe-off.
    # `lift` finds the forefoot's fastest upswing, before the toes leave a rolling foot, so its
    # cycles start early; the library records the definition it was cut with.
    path = synthetic_folder / "walk_curve_r1_left_slow.c3d"
    truth = json.loads(path.with_suffix(".truth.json").read_text())
    true_offs = np.array([e["time_s"] for e in truth["events"]
                          if e["side"] == "left" and e["kind"] == "toe_off"])

    def start_errors(toe_off):
        entries = process_capture(path, BuildSettings(all_cycles=True, toe_off=toe_off)).entries
        assert entries
        return np.array([np.abs(true_offs - e.start_s).min() * 100.0 for e in entries])

    assert start_errors("foot_velocity").max() <= 1.0
    assert start_errors("lift").min() > 1.0
    out = tmp_path / "lib.json"
    # one entry: a valid library without a control space (exit 0, with a warning)
    assert main(["build", str(path), "-o", str(out), "--toe-off", "lift", "--no-cache",
                 "-q"]) == 0
    assert load_library(out).settings["toe_off"] == "lift"
    with pytest.raises(MocapError, match="toe_off must be one of foot_velocity, lift"):
        BuildSettings(toe_off="heel")


def test_a_capture_without_a_cycle_keeps_its_series_in_the_diagnostics(synthetic_folder,
                                                                        tmp_path):
    from mocaplib.io.c3d import read_c3d
    from mocaplib.io.c3d_write import write_c3d

    # The first 0.6 s of a side-step: feet move, but there are not two left toe-offs.
    trial = read_c3d(synthetic_folder / "side_left_normal.c3d")
    short = tmp_path / "short.c3d"
    write_c3d(short, trial.markers[:60], trial.labels, trial.rate)
    result = process_capture(short, BuildSettings())
    # no complete cycle: no entry, and why, but not a failure
    assert result.ok and result.stage is None and result.error is None
    assert "fewer than two left toe-offs" in result.no_entry
    diag = result.diagnostics
    assert diag["rate_hz"] == 100.0 and len(diag["time_s"]) == 60 and diag["events"]
    assert "cycles" not in diag and result.entries == []


# --------------------------------------------------------------------------- reliability
needs_two = pytest.mark.skipif(max_jobs() < 2, reason="needs two processors for two workers")


@needs_two
def test_a_dead_worker_fails_its_capture_alone_after_one_more_try(tmp_path):
    # one worker killed every time it takes walk90 (as an out-of-memory kill would), another
    # killed once under walk91: the rest of the batch is built, walk91 on its second try
    folder = tmp_path / "caps"
    write_captures(folder)
    (folder / "walk90.c3d").write_text(json.dumps({"die": "always"}))
    (folder / "walk91.c3d").write_text(json.dumps({"die": "once", "v": 0.9}))
    result = build_library([folder], jobs=2, progress=False, process=fake_process)
    assert [c.file for c in result.failures] == ["walk90.c3d"]
    dead = result.failures[0]
    assert dead.stage == "worker" and "died, 2 times" in dead.error and "SIGKILL" in dead.error
    assert len(result.library) == 6 and "walk91_c0" in result.library.table.index
    assert calls(folder).count("walk90.c3d") == 2 and calls(folder).count("walk91.c3d") == 2


def blas_threads(path: str, settings: BuildSettings) -> CaptureResult:
    """fake_process, noting the BLAS thread counts it ran with in its warnings."""
    from threadpoolctl import threadpool_info

    result = fake_process(path, settings)
    result.warnings = [f"threads {sorted({p['num_threads'] for p in threadpool_info()})}"]
    return result


@pytest.mark.parametrize("jobs", [1, 2])
def test_every_capture_runs_with_one_blas_thread_whatever_the_jobs(tmp_path, jobs):
    write_captures(tmp_path / "caps", TRIPLES[:2])
    result = build_library([tmp_path / "caps"], jobs=jobs, progress=False, process=blas_threads)
    assert [c.warnings for c in result.captures] == [["threads [1]"]] * 2


def test_one_and_two_jobs_give_the_same_bytes_on_sample_captures(tmp_path):
    # the real stages on a few samples: -j 1 runs them here, -j 2 in workers
    from conftest import SAMPLES

    samples = [SAMPLES / f"{name}.c3d" for name in
               ("walk_straight_normal", "walk_curve_r1_left_fast", "side_left_normal",
                "turn_spot_right_slow")]
    one = build_library(samples, jobs=1, progress=False)
    two = build_library(samples, jobs=2, progress=False)
    assert one.ok and len(one.library) == 4
    assert build_bytes(one, tmp_path / "one") == build_bytes(two, tmp_path / "two")


def edit_cache_entry(cache: Path, edit) -> Path:
    """Apply ``edit`` to the JSON of the only cache entry (keeping it valid JSON)."""
    [path] = cache.glob("*.json")
    data = json.loads(path.read_text())
    edit(data)
    path.write_text(json.dumps(data))
    return path


def test_a_hand_edited_cache_entry_is_recomputed_with_a_note(tmp_path):
    folder, cache = tmp_path / "caps", tmp_path / "cache"
    write_captures(folder, TRIPLES[:1])
    first = build_library([folder], cache_dir=cache, progress=False, process=fake_process)

    def faster(data):  # still a result of the right shape, with another speed
        data["result"]["entries"][0]["v"] = 3.0

    edit_cache_entry(cache, faster)
    again = build_library([folder], cache_dir=cache, progress=False, process=fake_process)
    assert calls(folder) == ["walk00.c3d"] * 2 and not again.captures[0].from_cache
    assert "does not match its hash" in again.notes[0] and "walk00.c3d" in again.notes[0]
    assert build_bytes(first, tmp_path / "a") == build_bytes(again, tmp_path / "b")
    third = build_library([folder], cache_dir=cache, progress=False, process=fake_process)
    assert third.captures[0].from_cache and not third.notes  # the entry was written afresh


def test_a_cache_entry_stored_under_another_key_is_not_trusted(tmp_path):
    folder, cache = tmp_path / "caps", tmp_path / "cache"
    write_captures(folder, TRIPLES[:2])
    build_library([folder], cache_dir=cache, progress=False, process=fake_process)
    first, second = sorted(cache.glob("*.json"))
    second.write_bytes(first.read_bytes())  # a whole, self-consistent entry of the other file
    again = build_library([folder], cache_dir=cache, progress=False, process=fake_process)
    assert sum(c.from_cache for c in again.captures) == 1
    assert any("stored for other inputs or code" in note for note in again.notes)
    assert [e.split("_")[0] for e in again.library.table.index] == ["walk00", "walk01"]


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="no named pipes here")
@pytest.mark.parametrize("kind", ["pipe", "link to /dev/zero", "link to a file"])
def test_a_cache_entry_that_is_no_regular_file_is_refused_unopened(tmp_path, kind):
    folder, cache = tmp_path / "caps", tmp_path / "cache"
    write_captures(folder, TRIPLES[:1])
    build_library([folder], cache_dir=cache, progress=False, process=fake_process)
    [entry] = cache.glob("*.json")
    kept = entry.rename(tmp_path / "entry.json")
    if kind == "pipe":
        os.mkfifo(entry)  # reading it would wait forever for a writer
    elif kind == "link to /dev/zero":
        entry.symlink_to("/dev/zero")  # reading it would never end
    else:
        entry.symlink_to(kept)  # even a valid entry: the cache holds its own files only
    again = build_library([folder], cache_dir=cache, progress=False, process=fake_process)
    assert not again.captures[0].from_cache and len(calls(folder)) == 2
    assert "its cached result was not used" in again.notes[0]
    assert ("not a regular file" if kind == "pipe" else "symbolic link") in again.notes[0]


def test_a_capture_whose_name_is_not_utf8_is_built_and_stored_as_text(tmp_path):
    folder = tmp_path / "caps"
    write_captures(folder, TRIPLES[:1])
    latin1 = os.path.join(os.fsencode(folder), b"gehen_\xe4.c3d")
    with open(latin1, "wb") as handle:
        handle.write(json.dumps({"v": 0.6, "omega": 0.5, "v_l": 0.0}).encode())
    result = build_library([folder], progress=False, process=fake_process)
    library, sidecar = result.write(tmp_path / "lib.json")
    assert "gehen_ä_c0" in load_library(library).table.index
    assert "gehen_ä.c3d" in {c["source"] for c in json.loads(sidecar.read_text())["captures"]}
